# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Write recordings as rosbag2 (version 8, Jazzy types) that ``ros2 bag`` on Jazzy reads.

The bag is written in bulk: every sample topic is a constant CDR payload template plus a few
fields at fixed byte offsets (header stamp, x/y/z), and the storage writers
(:mod:`.mcap_writer`, :mod:`.sqlite_writer`) stamp those fields into whole blocks of messages
with numpy, never building one Python object per message.  The first and last payload of every
topic are checked bit-exactly against rosbags' serialiser before anything is written.

Messages are in time order like a live recording: all topics of a sample together (topic
order as given), an event just before the first sample whose stamp is not earlier.  Bag
timestamps equal header stamps.  Storage layout, metadata.yaml and the metadata kept inside the
storage file follow what rosbags' ``Writer`` (version 8) writes for the same messages.
"""
import contextlib
from dataclasses import dataclass
import functools
from pathlib import Path
import sqlite3
from typing import Optional, Sequence, Tuple

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
from wheel_force_estimator.bagio.cdr import payload_length
from wheel_force_estimator.bagio.cdr import WRENCH_TORQUE
from wheel_force_estimator.bagio.fastcdr import body_offset
from wheel_force_estimator.bagio.fastcdr import IMU
from wheel_force_estimator.bagio.fastcdr import Layout
from wheel_force_estimator.bagio.fastcdr import STRING_TYPE
from wheel_force_estimator.bagio.fastcdr import WRENCH
from wheel_force_estimator.bagio.mcap_writer import write_mcap
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.sqlite_writer import write_sqlite
from wheel_force_estimator.bagio.topics import default_topic_config
from wheel_force_estimator.bagio.travel import JOINT_NAMES
from wheel_force_estimator.bagio.travel import TRAVEL_CHANNELS
from wheel_force_estimator.bagio.travel import TRAVEL_TYPE
from wheel_force_estimator.bagio.travel import WHEEL_JOINT_NAMES
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


@dataclass(frozen=True)
class Connection:
    """
    One topic of the bag as rosbag2 registers it.

    Attributes
    ----------
    topic, msgtype : str
        Topic name and ROS 2 message type.
    msgdef : str
        Message definition text (``ros2msg``), as rosbags' typestore generates it.
    rihs01 : str
        Type description hash (``RIHS01_...``).
    qos : str
        Offered QoS profiles as stored (rosbags writes ``''`` when none are given).

    """

    topic: str
    msgtype: str
    msgdef: str
    rihs01: str
    qos: str = ''


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields, not objects
class DenseTopic:
    """
    A topic with one fixed-length message per sample: a payload template plus fields.

    Attributes
    ----------
    template : numpy.ndarray, shape (L,), uint8
        Serialised message with the variable fields zeroed.
    fields : tuple of (int, numpy.dtype, numpy.ndarray)
        ``(byte offset in the payload, dtype, source)``; ``source[i]`` (scalar or row) is the
        field value of sample ``i`` and already has ``dtype``.

    """

    template: np.ndarray
    fields: Tuple[Tuple[int, np.dtype, np.ndarray], ...]

    @property
    def length(self) -> int:
        """Return the payload length [bytes]."""
        return self.template.size

    def fill(self, out: np.ndarray, column: int, first: int, stop: int) -> None:
        """
        Write the fields of samples ``first..stop-1`` into rows of ``out``.

        ``out`` is a C-contiguous (rows, width) uint8 block whose row ``j`` holds sample
        ``first + j`` with this topic's payload at ``column``; the template bytes must be in
        place already (storage writers keep them across blocks).
        """
        if stop == first:
            return
        for offset, dtype, source in self.fields:
            part = source[first:stop]
            inner = (dtype.itemsize,) if part.ndim == 2 else ()
            view = np.ndarray(part.shape, dtype, out, column + offset, (out.strides[0],) + inner)
            view[...] = part

    def payloads(self, first: int, stop: int) -> np.ndarray:
        """Return the payloads of samples ``first..stop-1`` as a (k, L) uint8 matrix."""
        out = np.tile(self.template, (stop - first, 1))
        self.fill(out, 0, first, stop)
        return out


@dataclass(frozen=True, eq=False)
class BagPlan:
    """
    Everything a storage writer writes, in message order.

    Attributes
    ----------
    connections : tuple of Connection
        Channel / topic ``i`` gets id ``i + 1``; schemas are numbered by first appearance.
    stamp_ns : numpy.ndarray, shape (n,), int64
        Sample clock: log time of every dense message.
    dense : tuple of DenseTopic
        Payloads of ``connections[:len(dense)]``, one message per sample each.
    sparse : tuple of (int, int, bytes)
        ``(connection index, log time, payload)`` of the few other messages (events), sorted
        by time; connection indexes ``>= len(dense)``.
    sparse_at : numpy.ndarray, shape (len(sparse),), int64
        Sample index each sparse message precedes (``n`` = after the last sample).

    """

    connections: Tuple[Connection, ...]
    stamp_ns: np.ndarray
    dense: Tuple[DenseTopic, ...]
    sparse: Tuple[Tuple[int, int, bytes], ...]
    sparse_at: np.ndarray

    def message_counts(self) -> Tuple[int, ...]:
        """Return the number of messages per connection."""
        counts = [self.stamp_ns.size] * len(self.dense)
        counts += [0] * (len(self.connections) - len(self.dense))
        for index, _, _ in self.sparse:
            counts[index] += 1
        return tuple(counts)

    def time_range(self) -> Tuple[int, int]:
        """Return the first and last log time (rosbags' defaults when empty)."""
        times = [int(t) for t in self.stamp_ns[[0, -1]]] if self.stamp_ns.size else []
        times += [t for _, t, _ in self.sparse]
        return (min(times), max(times)) if times else (2 ** 63 - 1, 0)


def _frame_ids(given, default_suffix: str, name: str):
    if given is None:
        return tuple(f'{c}_{default_suffix}' for c in CORNERS)
    given = tuple(given)
    if len(given) != len(CORNERS) or not all(isinstance(f, str) and f for f in given):
        raise ConfigError(f'{name} must be {len(CORNERS)} non-empty strings, got {given!r}')
    return given


def _make_imu(store, frame_id: str, rate_variance: Optional[float] = None):
    """
    Return ``make(stamp_ns, accel[, rate])`` building Imu messages.

    Without ``rate_variance`` the angular velocity is flagged as not measured (REP-145:
    ``covariance[0] = -1``); with it the rates are written and the covariance is
    ``diag(rate_variance)`` [(rad/s)^2].
    """
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']
    header_t = types['std_msgs/msg/Header']
    quat = types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)
    vec3 = types['geometry_msgs/msg/Vector3']
    no_estimate = np.zeros(9)
    no_estimate[0] = -1.0  # REP-145: covariance[0] = -1 means "this field is not measured"
    unknown = np.zeros(9)
    zero = vec3(x=0.0, y=0.0, z=0.0)
    rate_cov = no_estimate if rate_variance is None else np.diag([float(rate_variance)] * 3
                                                                 ).reshape(-1)

    def make(stamp_ns, xyz, rate=None):
        return types['sensor_msgs/msg/Imu'](
            header=header_t(stamp=time_t(sec=int(stamp_ns // _NS_PER_S),
                                         nanosec=int(stamp_ns % _NS_PER_S)),
                            frame_id=frame_id),
            orientation=quat, orientation_covariance=no_estimate,
            angular_velocity=zero if rate is None else vec3(
                x=float(rate[0]), y=float(rate[1]), z=float(rate[2])),
            angular_velocity_covariance=rate_cov,
            linear_acceleration=vec3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
            linear_acceleration_covariance=unknown)
    return make


def _make_wrench(store, frame_id: str):
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']
    header_t = types['std_msgs/msg/Header']
    vec3 = types['geometry_msgs/msg/Vector3']
    zero = vec3(x=0.0, y=0.0, z=0.0)

    def make(stamp_ns, xyz, torque=None):
        return types['geometry_msgs/msg/WrenchStamped'](
            header=header_t(stamp=time_t(sec=int(stamp_ns // _NS_PER_S),
                                         nanosec=int(stamp_ns % _NS_PER_S)),
                            frame_id=frame_id),
            wrench=types['geometry_msgs/msg/Wrench'](
                force=vec3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                torque=zero if torque is None else vec3(
                    x=float(torque[0]), y=float(torque[1]), z=float(torque[2]))))
    return make


def _travel_topic(stamp_fields, travel: Optional[np.ndarray],
                  spin: Optional[np.ndarray] = None) -> DenseTopic:
    """
    Describe the ``suspension/joint_states`` JointState as a dense topic (rosbags-checked).

    ``travel`` (n, 4): ``{corner}_suspension`` positions; ``spin`` (n, 4): ``{corner}_wheel``
    velocities [rad/s] (their positions, the wheel angles, are not logged: NaN).  With both,
    the suspension velocities are NaN (not measured) as JointState needs one per name.
    """
    store = jazzy_typestore()
    types = store.types
    time_t = types['builtin_interfaces/msg/Time']
    header_t = types['std_msgs/msg/Header']
    names = (list(JOINT_NAMES) if travel is not None else []) + (
        list(WHEEL_JOINT_NAMES) if spin is not None else [])
    n_travel = 4 if travel is not None else 0

    def serialize(stamp_ns, position, velocity):
        msg = types[TRAVEL_TYPE](
            header=header_t(stamp=time_t(sec=int(stamp_ns // _NS_PER_S),
                                         nanosec=int(stamp_ns % _NS_PER_S)), frame_id=''),
            name=list(names), position=np.asarray(position, np.float64),
            velocity=np.asarray(velocity, np.float64), effort=np.zeros(0))
        return np.frombuffer(bytes(store.serialize_cdr(msg, TRAVEL_TYPE)), np.uint8)

    def rows(i, pos_marker=None, vel_marker=None):
        pos = np.full(len(names), np.nan)
        vel = np.full(len(names) if spin is not None else 0, np.nan)
        if travel is not None:
            pos[:4] = travel[i] if pos_marker is None else pos_marker
        if spin is not None:
            vel[n_travel:] = spin[i] if vel_marker is None else vel_marker
        return pos, vel

    marker = np.array([1.0000000000000002, -3.0e-300, 7.5e200, -12345.678901234567])
    pattern = np.frombuffer(marker.tobytes(), np.uint8)

    def offset_of(probe):
        return next(i for i in range(4, probe.size, 4)
                    if np.array_equal(probe[i:i + pattern.size], pattern))
    sec, nanosec = stamp_fields
    fields = [(4, np.dtype('<i4'), sec), (8, np.dtype('<u4'), nanosec)]
    zeros = np.zeros(4)
    if travel is not None:
        fields.append((offset_of(serialize(0, *rows(0, marker, zeros))), np.dtype('<f8'),
                       travel))
    if spin is not None:
        pos, vel = rows(0, zeros, marker)
        fields.append((offset_of(serialize(0, pos, vel)), np.dtype('<f8'), spin))
    template = serialize(0, *rows(0, zeros, zeros))
    topic = DenseTopic(template, tuple(fields))
    n = len(travel) if travel is not None else len(spin)
    for i in sorted({0, n - 1}) if n else ():
        stamp_ns = int(sec[i]) * _NS_PER_S + int(nanosec[i])
        if not np.array_equal(serialize(stamp_ns, *rows(i)), topic.payloads(i, i + 1)[0]):
            raise BagError(f'{TRAVEL_TYPE}: bulk CDR encoding differs from rosbags at sample {i}')
    return topic


@functools.lru_cache(maxsize=None)
def _connection_type(msgtype: str) -> Tuple[str, str]:
    """Return rosbags' ``(msgdef, rihs01)`` for a Jazzy type (what its Writer stores)."""
    store = jazzy_typestore()
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    return msgdef, store.hash_rihs01(msgtype)


def _connection(topic: str, msgtype: str) -> Connection:
    msgdef, rihs01 = _connection_type(msgtype)
    return Connection(topic, msgtype, msgdef, rihs01)


def _dense_topic(layout: Layout, make_msg, stamp_fields, values, extra=()) -> DenseTopic:
    """
    Describe one Imu / WrenchStamped topic as template + fields, checked against rosbags.

    ``values`` is (n, 3) float64 or a streamed :class:`.blocks.RowSource`; ``stamp_fields``
    the shared (sec int32, nanosec uint32); ``extra`` more ``(offset in the float64 tail
    [bytes], (n, 3) values)`` vectors that ``make_msg`` takes after ``values`` (the torque
    of a wrench, the angular velocity of an Imu).
    """
    store = jazzy_typestore()

    def serialize(stamp_ns, xyz, *more):
        return bytes(store.serialize_cdr(make_msg(stamp_ns, xyz, *more), layout.msgtype))

    zero = (0.0, 0.0, 0.0)
    template = np.frombuffer(serialize(0, zero, *[zero for _ in extra]), np.uint8)
    strlen = int(template[12:16].view('<u4')[0])  # frame_id length, NUL included
    if template.size != payload_length(layout, strlen):
        raise BagError(f'{layout.msgtype}: unexpected serialised length {template.size}')
    sec, nanosec = stamp_fields
    body = body_offset(strlen)
    topic = DenseTopic(template, (
        (4, np.dtype('<i4'), sec), (8, np.dtype('<u4'), nanosec),
        (body + layout.value_offset, np.dtype('<f8'), values)) + tuple(
            (body + at, np.dtype('<f8'), vals) for at, vals in extra))
    # First and last sample against rosbags' serialiser (a streamed source is checked with
    # stand-in values at those stamps: it cannot be read ahead)
    rows = sorted({0, len(values) - 1}) if len(values) else []
    if isinstance(values, np.ndarray):
        probe_values = values[rows]
    else:
        probe_values = np.array([[1.5, -2.25, 3.0e5]] * len(rows))
    probe_extra = [vals[rows] for _, vals in extra]
    probe = DenseTopic(template, ((4, np.dtype('<i4'), sec[rows]),
                                  (8, np.dtype('<u4'), nanosec[rows]),
                                  (topic.fields[2][0], np.dtype('<f8'), probe_values)) + tuple(
        (field[0], np.dtype('<f8'), vals) for field, vals in zip(topic.fields[3:],
                                                                 probe_extra)))
    for j, i in enumerate(rows):
        stamp_ns = int(sec[i]) * _NS_PER_S + int(nanosec[i])
        if serialize(stamp_ns, tuple(probe_values[j]), *[tuple(v[j]) for v in probe_extra]) \
                != probe.payloads(j, j + 1).tobytes():
            raise BagError(f'{layout.msgtype}: bulk CDR encoding differs from rosbags at '
                           f'sample {i}')
    return topic


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
            connections.append(_connection(topic, IMU.msgtype))
            extra = () if rate is None else ((IMU_RATE.value_offset, rate[3 * i:3 * i + 3].T),)
            dense.append(_dense_topic(
                IMU, _make_imu(store, frames[i], None if rate is None else rate_variance),
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
            connections.append(_connection(topic, WRENCH.msgtype))
            extra = () if torque is None else (
                (WRENCH_TORQUE.value_offset, torque[3 * i:3 * i + 3].T),)
            dense.append(_dense_topic(WRENCH, _make_wrench(store, frames[i]), stamp_fields,
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
        connections.append(_connection(topics.travel_topic, TRAVEL_TYPE))
        dense.append(_travel_topic(stamp_fields, travel, spin))
    event_list = _check_events(path, events)
    sparse = []
    if event_list:
        connections.append(_connection(topics.event_topic, STRING_TYPE))
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
