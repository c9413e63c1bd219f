# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Suspension travel: the optional ``suspension/joint_states`` topic (sensor_msgs/JointState).

One message per sample of the data logger, ``name`` = ``{corner}_suspension`` for the four
corners (any order, matched by name), ``position`` = compression [m], positive in bump
(DESIGN.md).  Decoding is bulk where the payloads allow it: all messages of one serialised
length whose bytes equal the first one's outside the stamp and the four positions share its
names and layout, which the Jazzy deserialiser decodes once per group.  On the recording's
sample clock, a sample whose travel is missing or not finite is dropped from every channel
and counted; nothing is filled in.
"""
import dataclasses
from typing import List, Tuple

import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator.core.errors import BagError

TRAVEL_TYPE = 'sensor_msgs/msg/JointState'
#: Joint names expected in the travel topic, corner order.
JOINT_NAMES = tuple(f'{c}_suspension' for c in CORNERS)
#: Channel names of the travel signals (rows of ``Segment.travel_m``).
TRAVEL_CHANNELS = tuple(f'{c}_travel' for c in CORNERS)
#: Joints whose ``velocity`` is the wheel spin rate [rad/s] (six components, issue 33).
WHEEL_JOINT_NAMES = tuple(f'{c}_wheel' for c in CORNERS)


@dataclasses.dataclass(frozen=True)
class JointField:
    """Which JointState joints and field to read: travel (default) or wheel spin."""

    joints: Tuple[str, ...] = JOINT_NAMES
    field: str = 'position'


SPIN_FIELD = JointField(WHEEL_JOINT_NAMES, 'velocity')
_NS_PER_S = 1_000_000_000


def _positions(path, topic: str, msg, which: JointField = JointField()) -> np.ndarray:
    """Return the four values of one message in corner order (names checked)."""
    names = tuple(msg.name)
    position = np.asarray(getattr(msg, which.field), np.float64).reshape(-1)
    if not set(which.joints) <= set(names) or len(set(names)) != len(names):
        raise BagError(f'{path}: {topic}: joint names {list(names)} do not match the corners; '
                       f'expected {list(which.joints)} (any order, other joints allowed)')
    if position.size != len(names):
        raise BagError(f'{path}: {topic}: {position.size} {which.field} values for joints '
                       f'{list(names)}')
    return position[[names.index(n) for n in which.joints]]


def _stamp(msg) -> int:
    return int(msg.header.stamp.sec) * _NS_PER_S + int(msg.header.stamp.nanosec)


def decode_messages(path, topic: str, msgs,
                    which: JointField = JointField()) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(stamp_ns (n,), values (n, 4))`` of deserialised JointState messages."""
    msgs = list(msgs)
    stamp = np.fromiter((_stamp(m) for m in msgs), np.int64, len(msgs))
    travel = np.array([_positions(path, topic, m, which) for m in msgs],
                      np.float64).reshape(-1, 4)
    return stamp, travel


def decode_rows(path, topic: str, groups, n: int, deserialize,
                serialize, which: JointField = JointField()) -> Tuple[np.ndarray, np.ndarray]:
    """
    Decode a raw topic's payload groups (``storage.RawTopic.groups``) in bulk.

    Each length group is checked byte for byte against its first message outside the stamp
    and position bytes; a group that differs anywhere else is decoded message by message.
    """
    stamp = np.empty(n, np.int64)
    travel = np.empty((n, 4))
    for pos, rows in groups:
        first = deserialize(rows[0].tobytes())
        values = _positions(path, topic, first, which)
        at = _position_offset(first, serialize, rows[0], which.field)
        width = len(getattr(first, which.field))
        same = None
        if at is not None and rows[0][:2].tobytes() == b'\x00\x01':  # little-endian CDR
            mask = np.ones(rows.shape[1], bool)
            mask[4:12] = False
            # every float array of the message may vary (travel and spin share messages)
            for name in ('position', 'velocity', 'effort'):
                other = (at if name == which.field
                         else _position_offset(first, serialize, rows[0], name))
                if other is not None:
                    mask[other:other + 8 * len(getattr(first, name))] = False
            same = (rows[:, mask] == rows[0, mask]).all()
        if not same:
            part = decode_messages(path, topic, (deserialize(r.tobytes()) for r in rows), which)
            stamp[pos], travel[pos] = part
            continue
        sec = rows[:, 4:8].copy().view('<i4')[:, 0].astype(np.int64)
        nsec = rows[:, 8:12].copy().view('<u4')[:, 0].astype(np.int64)
        stamp[pos] = sec * _NS_PER_S + nsec
        raw = rows[:, at:at + 8 * width].copy().view('<f8')
        order = [list(first.name).index(name) for name in which.joints]
        travel[pos] = raw[:, order]
        if not np.array_equal(travel[pos[0]], values, equal_nan=True):
            raise BagError(f'{path}: {topic}: bulk JointState decoding disagrees with the '
                           'deserialiser')
    return stamp, travel


_PROBE = np.array([1.0000000000000002, -3.0e-300, 7.5e200, -12345.678901234567])


def _position_offset(msg, serialize, row: np.ndarray, field: str = 'position'):
    """Byte offset of ``field[0]`` in ``row``, found with a distinctive probe, or None."""
    width = len(getattr(msg, field))
    if width < _PROBE.size:
        return None
    marker = np.concatenate([_PROBE, np.arange(1, width - _PROBE.size + 1) * -7.25e-101])
    probe = np.frombuffer(bytes(serialize(dataclasses.replace(msg, **{field: marker}))),
                          np.uint8)
    if probe.size != row.size:
        return None
    pattern = np.frombuffer(_PROBE.astype('<f8').tobytes(), np.uint8)
    hits = [i for i in range(4, probe.size - pattern.size + 1, 4)
            if np.array_equal(probe[i:i + pattern.size], pattern)]
    return hits[0] if len(hits) == 1 else None


def on_clock(path, topic: str, clock_ns: np.ndarray, stamp_ns: np.ndarray,
             travel: np.ndarray, rate_tolerance: float):
    """
    Put travel on the sample clock of the other topics.

    Parameters
    ----------
    path, topic :
        For messages.
    clock_ns : numpy.ndarray, shape (n,), int64
        Strictly increasing sample stamps of the Imu (reference) topic.
    stamp_ns : numpy.ndarray, shape (m,), int64
        Strictly increasing travel stamps.
    travel : numpy.ndarray, shape (m, 4)
        Compression per corner [m], NaN allowed.
    rate_tolerance : float
        Relative tolerance of the sample-rate comparison.

    Returns
    -------
    travel_m : numpy.ndarray, shape (4, n)
        Travel at every clock sample (NaN where missing or not finite: these samples are
        dropped by the caller, never filled).
    n_missing, n_not_finite : int
        Clock samples without a travel message, and with a NaN / infinite travel.

    Raises
    ------
    BagError
        Travel at stamps that are not samples of the clock (the first named), or sampled at
        another rate.

    """
    if stamp_ns.size >= 2 and clock_ns.size >= 2:
        ref = float(np.median(np.diff(clock_ns)))
        own = float(np.median(np.diff(stamp_ns)))
        if abs(own - ref) > rate_tolerance * ref:
            raise BagError(f'{path}: {topic} is sampled at {_NS_PER_S / own:.6g} Hz but the '
                           f'spindle topics at {_NS_PER_S / ref:.6g} Hz; nothing is resampled')
    at = np.searchsorted(clock_ns, stamp_ns)
    inside = at < clock_ns.size
    found = np.zeros(stamp_ns.size, bool)
    found[inside] = clock_ns[at[inside]] == stamp_ns[inside]
    if not found.all():
        i = int(np.argmin(found))
        raise BagError(f'{path}: {topic}: stamp {int(stamp_ns[i])} ns ({stamp_ns[i] / 1e9:.6f} s)'
                       f' is not a sample of the spindle topics ({int((~found).sum())} such); '
                       'travel must come from the same logger clock')
    out = np.full((clock_ns.size, 4), np.nan)
    out[at] = travel
    n_missing = clock_ns.size - stamp_ns.size
    n_not_finite = int((~np.isfinite(travel)).any(axis=1).sum())
    return np.ascontiguousarray(out.T), int(n_missing), n_not_finite


def usable(travel_m: np.ndarray) -> np.ndarray:
    """Clock samples with a finite travel at every corner (the others are dropped)."""
    return np.isfinite(travel_m).all(axis=0)


__all__: List[str] = ['JOINT_NAMES', 'JointField', 'SPIN_FIELD', 'TRAVEL_CHANNELS',
                      'TRAVEL_TYPE', 'WHEEL_JOINT_NAMES', 'decode_messages', 'decode_rows',
                      'on_clock', 'usable']
