# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
What a bag writer writes (:class:`BagPlan`), and its topics as payload templates plus fields.

Every sample topic is one constant CDR payload (:class:`DenseTopic`: the message serialised by
rosbags with its variable fields zeroed) plus the byte offsets of those fields (header stamp,
the x/y/z vectors, joint positions and velocities).  :func:`dense_topic` and
:func:`travel_topic` find the offsets from rosbags' own serialisation and check the first and
last message of the topic bit-exactly against it before anything is written, so the bulk
encoding cannot drift from what ``ros2 bag`` reads.  The storage writers
(:mod:`.mcap_writer`, :mod:`.sqlite_writer`) then stamp the fields into whole blocks of
messages; :mod:`.writer` plans a recording into a :class:`BagPlan`.
"""
from dataclasses import dataclass
import functools
from typing import Optional, Tuple

import numpy as np

from wheel_force_estimator.bagio.cdr import payload_length
from wheel_force_estimator.bagio.fastcdr import body_offset
from wheel_force_estimator.bagio.fastcdr import Layout
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.travel import JOINT_NAMES
from wheel_force_estimator.bagio.travel import TRAVEL_TYPE
from wheel_force_estimator.bagio.travel import WHEEL_JOINT_NAMES
from wheel_force_estimator.core.errors import BagError

_NS_PER_S = 1_000_000_000


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


def make_imu(store, frame_id: str, rate_variance: Optional[float] = None):
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


def make_wrench(store, frame_id: str):
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


def travel_topic(stamp_fields, travel: Optional[np.ndarray],
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
def connection_type(msgtype: str) -> Tuple[str, str]:
    """Return rosbags' ``(msgdef, rihs01)`` for a Jazzy type (what its Writer stores)."""
    store = jazzy_typestore()
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    return msgdef, store.hash_rihs01(msgtype)


def connection(topic: str, msgtype: str) -> Connection:
    msgdef, rihs01 = connection_type(msgtype)
    return Connection(topic, msgtype, msgdef, rihs01)


def dense_topic(layout: Layout, make_msg, stamp_fields, values, extra=()) -> DenseTopic:
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
