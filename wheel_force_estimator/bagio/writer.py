# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Write recordings as rosbag2 (version 8, Jazzy types) that ``ros2 bag`` on Jazzy reads.

The bag is written in bulk: every sample topic is a constant CDR payload template plus a few
fields at fixed byte offsets (header stamp, x/y/z; :mod:`.plan`), and the storage writers
(:mod:`.mcap_writer`, :mod:`.sqlite_writer`) stamp those fields into whole blocks of messages
with numpy, never building one Python object per message.  The first and last payload of every
topic are checked bit-exactly against rosbags' serialiser before anything is written.

Messages are in time order like a live recording: all topics of a sample together (topic
order as given), an event just before the first sample whose stamp is not earlier.  Bag
timestamps equal header stamps.  Storage layout, metadata.yaml and the metadata kept inside the
storage file follow what rosbags' ``Writer`` (version 8) writes for the same messages.
"""
import contextlib
from pathlib import Path
import sqlite3
from typing import Optional, Sequence

import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_CHANNELS
from wheel_force_estimator.bagio.blocks import BlockWindow
from wheel_force_estimator.bagio.blocks import RowSource
from wheel_force_estimator.bagio.blocks import SignalBlocks
from wheel_force_estimator.bagio.cdr import IMU_RATE
from wheel_force_estimator.bagio.cdr import WRENCH_TORQUE
from wheel_force_estimator.bagio.fastcdr import IMU
from wheel_force_estimator.bagio.fastcdr import STRING_TYPE
from wheel_force_estimator.bagio.fastcdr import WRENCH
from wheel_force_estimator.bagio.mcap_writer import write_mcap
from wheel_force_estimator.bagio.plan import BagPlan
from wheel_force_estimator.bagio.plan import connection
from wheel_force_estimator.bagio.plan import dense_topic
from wheel_force_estimator.bagio.plan import make_imu
from wheel_force_estimator.bagio.plan import make_wrench
from wheel_force_estimator.bagio.plan import travel_topic
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.sqlite_writer import write_sqlite
from wheel_force_estimator.bagio.topics import default_topic_config
from wheel_force_estimator.bagio.travel import TRAVEL_CHANNELS
from wheel_force_estimator.bagio.travel import TRAVEL_TYPE
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.validation import as_signals
import yaml

ROSBAG2_VERSION = 8  # Jazzy's rosbag2 reads up to 9; 8 keeps Humble/Iron readers happy too
# storage identifier -> (file suffix, bulk storage writer)
STORAGES = {'mcap': ('.mcap', write_mcap), 'sqlite3': ('.db3', write_sqlite)}
# What rosbags' Writer records as the distro; kept so metadata equals rosbags' output.
ROS_DISTRO = 'rosbags'
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
                    output: bool = False, compression: str = '',
                    travel_m=None, torque_nm=None, rate_radps=None,
                    rate_variance: Optional[float] = None, spin_radps=None) -> Path:
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
    force_n : array_like, shape (12, n), or SignalBlocks, optional
        Forces in ``OUTPUT_CHANNELS`` order [N]; written as geometry_msgs/WrenchStamped.
        A :class:`.blocks.SignalBlocks` stream is consumed while the bag is written.
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
    compression : {'', 'zstd'}
        mcap chunk compression ('' = none, as ``ros2 bag record`` writes by default; zstd
        is read by ros2 bag's mcap plugin, rosbags and this package).  Ignored for sqlite3.
    travel_m : array_like, shape (4, n), optional
        Suspension compression per corner [m], positive in bump; written as
        sensor_msgs/JointState (``{corner}_suspension``) on ``topics.travel_topic``.
    torque_nm : array_like, shape (12, n), optional
        Wheel moments in ``MOMENT_CHANNELS`` order [N m]: ``wrench.torque`` of the force
        messages (zero when not given); needs ``force_n`` as an array.
    rate_radps : array_like, shape (12, n), optional
        Spindle angular rates in ``RATE_CHANNELS`` order [rad/s]: ``Imu.angular_velocity``
        with covariance ``diag(rate_variance)`` (REP-145); without them the covariance says
        "not provided" (element 0 = -1).
    rate_variance : float, optional
        Gyro noise variance [(rad/s)^2] (default 0: known, not estimated).
    spin_radps : array_like, shape (4, n), optional
        Wheel spin rates [rad/s]: ``velocity`` of the ``{corner}_wheel`` joints on
        ``topics.travel_topic`` (with the suspension joints when ``travel_m`` is given).

    Returns
    -------
    pathlib.Path
        The bag directory.

    Raises
    ------
    BagError
        Path exists, stamps invalid, or the storage cannot be written (nothing is left
        behind then).
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
    if compression not in ('', 'zstd'):
        raise ConfigError(f"{path}: compression must be '' or 'zstd', got {compression!r}")
    if path.exists():
        raise BagError(f'{path}: exists already, not overwriting')
    stamp = _check_stamps(path, stamp_ns)
    store = jazzy_typestore()
    stamp_fields = ((stamp // _NS_PER_S).astype('<i4'), (stamp % _NS_PER_S).astype('<u4'))
    connections, dense = [], []
    if accel_mps2 is not None:
        accel = as_signals(accel_mps2, f'{path}: accel_mps2', INPUT_CHANNELS)
        _check_length(path, 'accel_mps2', accel, stamp)
        frames = _frame_ids(imu_frame_ids, 'spindle', 'imu_frame_ids')
        rate = None
        if rate_radps is not None:
            rate = as_signals(rate_radps, f'{path}: rate_radps', RATE_CHANNELS)
            _check_length(path, 'rate_radps', rate, stamp)
            rate_variance = 0.0 if rate_variance is None else float(rate_variance)
        for i, topic in enumerate(topics.imu_topics):
            connections.append(connection(topic, IMU.msgtype))
            extra = () if rate is None else ((IMU_RATE.value_offset, rate[3 * i:3 * i + 3].T),)
            dense.append(dense_topic(
                IMU, make_imu(store, frames[i], None if rate is None else rate_variance),
                stamp_fields, accel[3 * i:3 * i + 3].T, extra))
    if isinstance(force_n, SignalBlocks):
        if tuple(force_n.channels) != tuple(OUTPUT_CHANNELS) or force_n.n_samples != stamp.size:
            raise BagError(f'{path}: streamed force_n has {force_n.n_samples} samples of '
                           f'{tuple(force_n.channels)}; expected {stamp.size} of '
                           f'{tuple(OUTPUT_CHANNELS)}')
        window = BlockWindow(force_n, f'{path}: force_n')
        force = [RowSource(window, 3 * i) for i in range(len(CORNERS))]
    elif force_n is not None:
        force = as_signals(force_n, f'{path}: force_n', OUTPUT_CHANNELS)
        _check_length(path, 'force_n', force, stamp)
        force = [force[3 * i:3 * i + 3].T for i in range(len(CORNERS))]
    if force_n is not None:
        if output:
            frames = _frame_ids(wrench_frame_ids or topics.frame_ids, 'wheel',
                                'wrench_frame_ids')
        else:
            frames = _frame_ids(wrench_frame_ids, 'wheel', 'wrench_frame_ids')
        names = topics.output_topics if output else topics.wft_topics
        torque = None
        if torque_nm is not None:
            if isinstance(force_n, SignalBlocks):
                raise ConfigError(f'{path}: torque_nm needs force_n as an array, not a stream')
            torque = as_signals(torque_nm, f'{path}: torque_nm', MOMENT_CHANNELS)
            _check_length(path, 'torque_nm', torque, stamp)
        for i, topic in enumerate(names):
            connections.append(connection(topic, WRENCH.msgtype))
            extra = () if torque is None else (
                (WRENCH_TORQUE.value_offset, torque[3 * i:3 * i + 3].T),)
            dense.append(dense_topic(WRENCH, make_wrench(store, frames[i]), stamp_fields,
                                     force[i], extra))
    elif torque_nm is not None:
        raise ConfigError(f'{path}: torque_nm needs force_n')
    if travel_m is not None or spin_radps is not None:
        travel = spin = None
        if travel_m is not None:
            travel = as_signals(travel_m, f'{path}: travel_m', TRAVEL_CHANNELS)
            _check_length(path, 'travel_m', travel, stamp)
            travel = np.ascontiguousarray(travel.T)
        if spin_radps is not None:
            spin = as_signals(spin_radps, f'{path}: spin_radps', SPIN_CHANNELS)
            _check_length(path, 'spin_radps', spin, stamp)
            spin = np.ascontiguousarray(spin.T)
        connections.append(connection(topics.travel_topic, TRAVEL_TYPE))
        dense.append(travel_topic(stamp_fields, travel, spin))
    event_list = _check_events(path, events)
    sparse = []
    if event_list:
        connections.append(connection(topics.event_topic, STRING_TYPE))
        string_t = store.types[STRING_TYPE]
        sparse = [(len(dense), t, bytes(store.serialize_cdr(string_t(data=name), STRING_TYPE)))
                  for t, name in event_list]
    # An event goes before the first sample whose stamp is not earlier (ties: event first).
    sparse_at = np.searchsorted(stamp, np.array([t for _, t, _ in sparse], np.int64), 'left')
    plan = BagPlan(tuple(connections), stamp, tuple(dense), tuple(sparse),
                   sparse_at.astype(np.int64))
    _write(path, storage, plan, compression)
    return path


def write_forces(path, stamp_ns, force_n, topics=None, storage: str = 'mcap') -> Path:
    """Write forces on the output (virtual WFT) topics: ``wheel-force predict``'s bag."""
    return write_recording(path, stamp_ns, force_n=force_n, topics=topics, storage=storage,
                           output=True)


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


def bag_metadata(plan: BagPlan, storage: str, file_name: str) -> dict:
    """
    Return the ``rosbag2_bagfile_information`` mapping rosbags' Writer (version 8) writes.

    Parameters
    ----------
    plan : BagPlan
        The bag's content.
    storage : {'mcap', 'sqlite3'}
        Storage identifier.
    file_name : str
        Name of the storage file inside the bag directory.

    """
    counts = plan.message_counts()
    start, end = plan.time_range()
    duration = max(0, end - start)
    return {
        'version': ROSBAG2_VERSION,
        'storage_identifier': storage,
        'relative_file_paths': [file_name],
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(counts),
        'topics_with_message_count': [
            {'topic_metadata': {'name': c.topic, 'type': c.msgtype,
                                'serialization_format': 'cdr',
                                'offered_qos_profiles': c.qos,
                                'type_description_hash': c.rihs01},
             'message_count': count}
            for c, count in zip(plan.connections, counts)],
        'compression_format': '',
        'compression_mode': '',
        'files': [{'path': file_name, 'starting_time': {'nanoseconds_since_epoch': start},
                   'duration': {'nanoseconds': duration}, 'message_count': sum(counts)}],
        'custom_data': None,
        'ros_distro': ROS_DISTRO,
    }


def _write(path: Path, storage: str, plan: BagPlan, compression: str = '') -> None:
    suffix, write_storage = STORAGES[storage]
    try:
        path.mkdir(mode=0o755, parents=True)
    except FileExistsError as err:
        raise BagError(f'{path}: exists already, not overwriting') from err
    except OSError as err:
        raise BagError(f'{path}: cannot create bag directory: {err.strerror or err}') from err
    file = path / f'{path.name}{suffix}'
    meta_path = path / 'metadata.yaml'
    tmp_path = path / 'metadata.yaml.tmp'
    info = bag_metadata(plan, storage, file.name)
    try:
        text = yaml.safe_dump(info, default_flow_style=False).strip()
        if storage == 'mcap':
            write_storage(file, plan, ROSBAG2_VERSION, text, compression)
        else:
            write_storage(file, plan, ROSBAG2_VERSION, text)
        tmp_path.write_text(yaml.safe_dump({'rosbag2_bagfile_information': info},
                                           default_flow_style=False), 'utf8')
        tmp_path.replace(meta_path)
    except BaseException as err:
        # the directory is ours (created above): leave nothing half-written behind, even
        # when interrupted
        with contextlib.suppress(OSError):
            for leftover in (file, tmp_path, meta_path):
                leftover.unlink(missing_ok=True)
            path.rmdir()
        if isinstance(err, (OSError, sqlite3.Error)):
            reason = getattr(err, 'strerror', None) or err
            raise BagError(f'{path}: cannot write bag: {reason}') from err
        raise
