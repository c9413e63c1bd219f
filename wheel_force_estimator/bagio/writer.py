# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Write recordings as rosbag2 (version 8, Jazzy types) that ``ros2 bag`` on Jazzy reads.

Payloads are serialised in bulk (:func:`.fastcdr.encode_rows`, checked against rosbags'
serialiser) and handed to rosbags' Writer sample by sample, all topics of a sample together,
so the bag is in time order like a live recording.  Bag timestamps equal header stamps.
"""
from pathlib import Path
from typing import Optional, Sequence

import numpy as np
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer
from rosbags.rosbag2 import WriterError

from wheel_force_estimator import CORNERS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio.fastcdr import encode_rows
from wheel_force_estimator.bagio.fastcdr import IMU
from wheel_force_estimator.bagio.fastcdr import STRING_TYPE
from wheel_force_estimator.bagio.fastcdr import WRENCH
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.topics import default_topic_config
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.validation import as_signals

ROSBAG2_VERSION = 8  # Jazzy's rosbag2 reads up to 9; 8 keeps Humble/Iron readers happy too
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
_NS_PER_S = 1_000_000_000
# header.stamp.sec is an int32
_MAX_STAMP_NS = (2 ** 31) * _NS_PER_S


def _frame_ids(given, default_suffix: str, name: str):
    if given is None:
        return tuple(f'{c}_{default_suffix}' for c in CORNERS)
    given = tuple(given)
    if len(given) != len(CORNERS) or not all(isinstance(f, str) and f for f in given):
        raise ConfigError(f'{name} must be {len(CORNERS)} non-empty strings, got {given!r}')
    return given


def _make_imu(store, frame_id: str):
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']
    header_t = types['std_msgs/msg/Header']
    quat = types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)
    vec3 = types['geometry_msgs/msg/Vector3']
    no_estimate = np.zeros(9)
    no_estimate[0] = -1.0  # REP-145: covariance[0] = -1 means "this field is not measured"
    unknown = np.zeros(9)
    zero = vec3(x=0.0, y=0.0, z=0.0)

    def make(stamp_ns, xyz):
        return types['sensor_msgs/msg/Imu'](
            header=header_t(stamp=time_t(sec=int(stamp_ns // _NS_PER_S),
                                         nanosec=int(stamp_ns % _NS_PER_S)),
                            frame_id=frame_id),
            orientation=quat, orientation_covariance=no_estimate,
            angular_velocity=zero, angular_velocity_covariance=no_estimate,
            linear_acceleration=vec3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
            linear_acceleration_covariance=unknown)
    return make


def _make_wrench(store, frame_id: str):
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']
    header_t = types['std_msgs/msg/Header']
    vec3 = types['geometry_msgs/msg/Vector3']
    zero = vec3(x=0.0, y=0.0, z=0.0)

    def make(stamp_ns, xyz):
        return types['geometry_msgs/msg/WrenchStamped'](
            header=header_t(stamp=time_t(sec=int(stamp_ns // _NS_PER_S),
                                         nanosec=int(stamp_ns % _NS_PER_S)),
                            frame_id=frame_id),
            wrench=types['geometry_msgs/msg/Wrench'](
                force=vec3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])), torque=zero))
    return make


def _check_stamps(path: Path, stamp_ns) -> np.ndarray:
    stamp = np.asarray(stamp_ns)
    if stamp.ndim != 1 or not np.issubdtype(stamp.dtype, np.integer):
        raise BagError(f'{path}: stamp_ns must be a 1-D integer array (ns), got '
                       f'{stamp.dtype} {stamp.shape}')
    stamp = stamp.astype(np.int64)
    if stamp.size and (stamp[0] < 0 or stamp[-1] >= _MAX_STAMP_NS):
        raise BagError(f'{path}: stamps must lie in [0, 2^31) s for header.stamp')
    bad = np.flatnonzero(np.diff(stamp) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise BagError(f'{path}: stamp_ns not strictly increasing at sample {i} '
                       f'({stamp[i]} ns after {stamp[i - 1]} ns)')
    return stamp


def write_recording(path, stamp_ns, accel_mps2=None, force_n=None, topics=None,
                    events: Sequence = (), storage: str = 'mcap',
                    imu_frame_ids: Optional[Sequence[str]] = None,
                    wrench_frame_ids: Optional[Sequence[str]] = None,
                    output: bool = False) -> Path:
    """
    Write accelerations / forces on one sample clock as a new rosbag2.

    Parameters
    ----------
    path : str or pathlib.Path
        New rosbag2 directory; refused if it exists.
    stamp_ns : array_like, shape (n,), int
        Sample stamps [ns], strictly increasing; used as header and bag timestamps.
    accel_mps2 : array_like, shape (12, n), optional
        Accelerations in ``INPUT_CHANNELS`` order [m/s²]; written as sensor_msgs/Imu
        (linear_acceleration; orientation and angular velocity flagged as not measured).
    force_n : array_like, shape (12, n), optional
        Forces in ``OUTPUT_CHANNELS`` order [N]; written as geometry_msgs/WrenchStamped.
    topics : TopicConfig, optional
        Topic names (defaults: DESIGN.md).
    events : sequence of (int, str)
        ``(stamp_ns, name)`` written as std_msgs/String on ``topics.event_topic``.
    storage : {'mcap', 'sqlite3'}
        rosbag2 storage plugin.
    imu_frame_ids, wrench_frame_ids : sequence of 4 str, optional
        Frame ids per corner (defaults ``{corner}_spindle`` and ``{corner}_wheel``, or
        ``topics.frame_ids`` when ``output`` is True).
    output : bool
        Write the forces on ``topics.output_topics`` (virtual WFT, ``wheel-force predict``)
        instead of ``topics.wft_topics``.

    Returns
    -------
    pathlib.Path
        The bag directory.

    Raises
    ------
    BagError
        Path exists, stamps invalid, or rosbags cannot write.
    ShapeError, NonFiniteError
        Arrays of the wrong shape or with NaN / infinity.
    ConfigError
        Unknown storage, bad frame ids, or nothing to write.

    """
    path = Path(path)
    topics = default_topic_config(topics)
    if storage not in STORAGES:
        raise ConfigError(f'storage must be one of {sorted(STORAGES)}, got {storage!r}')
    if accel_mps2 is None and force_n is None:
        raise ConfigError(f'{path}: nothing to write (accel_mps2 and force_n are None)')
    if path.exists():
        raise BagError(f'{path}: exists already, not overwriting')
    stamp = _check_stamps(path, stamp_ns)
    store = jazzy_typestore()
    streams = []  # (topic, msgtype, rows)
    if accel_mps2 is not None:
        accel = as_signals(accel_mps2, f'{path}: accel_mps2', INPUT_CHANNELS)
        _check_length(path, 'accel_mps2', accel, stamp)
        frames = _frame_ids(imu_frame_ids, 'spindle', 'imu_frame_ids')
        for i, topic in enumerate(topics.imu_topics):
            rows = encode_rows(IMU, stamp, accel[3 * i:3 * i + 3].T,
                               _make_imu(store, frames[i]), _serializer(store, IMU.msgtype))
            streams.append((topic, IMU.msgtype, rows))
    if force_n is not None:
        force = as_signals(force_n, f'{path}: force_n', OUTPUT_CHANNELS)
        _check_length(path, 'force_n', force, stamp)
        if output:
            frames = _frame_ids(wrench_frame_ids or topics.frame_ids, 'wheel',
                                'wrench_frame_ids')
        else:
            frames = _frame_ids(wrench_frame_ids, 'wheel', 'wrench_frame_ids')
        names = topics.output_topics if output else topics.wft_topics
        for i, topic in enumerate(names):
            rows = encode_rows(WRENCH, stamp, force[3 * i:3 * i + 3].T,
                               _make_wrench(store, frames[i]),
                               _serializer(store, WRENCH.msgtype))
            streams.append((topic, WRENCH.msgtype, rows))
    event_list = _check_events(path, events)
    _write(path, storage, store, stamp, streams, topics.event_topic, event_list)
    return path


def write_forces(path, stamp_ns, force_n, topics=None, storage: str = 'mcap') -> Path:
    """Write forces on the output (virtual WFT) topics: ``wheel-force predict``'s bag."""
    return write_recording(path, stamp_ns, force_n=force_n, topics=topics, storage=storage,
                           output=True)


def _serializer(store, msgtype):
    def serialize(msg):
        return store.serialize_cdr(msg, msgtype)
    return serialize


def _check_length(path, name, arr, stamp):
    if arr.shape[1] != stamp.size:
        raise BagError(f'{path}: {name} has {arr.shape[1]} samples but stamp_ns has '
                       f'{stamp.size}')


def _check_events(path, events):
    out = []
    for item in events:
        try:
            stamp, name = item
        except (TypeError, ValueError) as err:
            raise BagError(f'{path}: events must be (stamp_ns, name) pairs, got {item!r}') from err
        if not isinstance(name, str) or not 0 <= int(stamp) < _MAX_STAMP_NS:
            raise BagError(f'{path}: invalid event {item!r}')
        out.append((int(stamp), name))
    return sorted(out, key=lambda e: e[0])


def _write(path, storage, store, stamp, streams, event_topic, events):
    try:
        writer = Writer(path, version=ROSBAG2_VERSION, storage_plugin=STORAGES[storage])
        with writer:
            conns = [writer.add_connection(topic, msgtype, typestore=store)
                     for topic, msgtype, _ in streams]
            event_conn = (writer.add_connection(event_topic, STRING_TYPE, typestore=store)
                          if events else None)
            string_t = store.types[STRING_TYPE]
            datas = [rows.tobytes() for _, _, rows in streams]
            lengths = [rows.shape[1] for _, _, rows in streams]
            k = 0
            for i, t in enumerate(stamp.tolist()):
                while k < len(events) and events[k][0] <= t:
                    writer.write(event_conn, events[k][0], bytes(
                        store.serialize_cdr(string_t(data=events[k][1]), STRING_TYPE)))
                    k += 1
                for conn, data, length in zip(conns, datas, lengths):
                    writer.write(conn, t, data[i * length:(i + 1) * length])
            for ev_stamp, name in events[k:]:
                writer.write(event_conn, ev_stamp, bytes(
                    store.serialize_cdr(string_t(data=name), STRING_TYPE)))
    except WriterError as err:
        raise BagError(f'{path}: cannot write bag: {err}') from err
    except OSError as err:
        raise BagError(f'{path}: cannot write bag: {err.strerror or err}') from err
