# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The one CDR codec of the package: fixed-layout stamped messages, in bulk, with numpy.

``sensor_msgs/Imu`` and ``geometry_msgs/WrenchStamped`` are a Header followed by float64
fields only, so once the frame_id length is known every field sits at a fixed byte offset.
The layouts (:data:`IMU`, :data:`WRENCH`) and offsets (:func:`body_offset`) are defined here
once; the bag readers and writer (:mod:`.fastcdr`) and the live node (raw subscriptions: a
Python message object costs ~3x more than the raw bytes, DESIGN.md) both use them.  No ROS
import: plain numpy.  Only the fields the package uses are interpreted; layout (XCDR1 / plain
CDR, as every ROS 2 Jazzy RMW writes it)::

    4 bytes   encapsulation header (0x00 0x01 = little endian, 0x00 0x00 = big endian)
    int32     header.stamp.sec          uint32  header.stamp.nanosec
    uint32    len(frame_id) + 1         char[]  frame_id + NUL
    padding   to a multiple of 8 counted from the end of the encapsulation header
    float64[] message body (Imu: 37 doubles, linear_acceleration at 25..27;
              WrenchStamped: force xyz, torque xyz)

A message whose length, encapsulation or nanoseconds do not fit this layout is reported as
malformed, never guessed at.
"""
from dataclasses import dataclass
import functools
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ShapeError

IMU_TYPE = 'sensor_msgs/msg/Imu'
WRENCH_TYPE = 'geometry_msgs/msg/WrenchStamped'
STRING_TYPE = 'std_msgs/msg/String'


@dataclass(frozen=True)
class Layout:
    """
    Where the three float64 values we need sit in a fixed-layout stamped message.

    Attributes
    ----------
    msgtype : str
        ROS 2 message type name.
    tail_bytes : int
        Bytes after the (8-aligned) header: all float64 fields.
    value_offset : int
        Offset of the x, y, z values from the start of the tail.
    vector_path : tuple of str
        Attribute path to the Vector3 in a deserialised message (for the generic path).

    """

    msgtype: str
    tail_bytes: int
    value_offset: int
    vector_path: Tuple[str, ...]


# Imu tail: orientation(4) + cov(9) + angular_velocity(3) + cov(9) + linear_acceleration(3)
# + cov(9) float64; linear_acceleration starts after 25 doubles.
IMU = Layout(IMU_TYPE, 37 * 8, 25 * 8, ('linear_acceleration',))
# WrenchStamped tail: force(3) + torque(3) float64.
WRENCH = Layout(WRENCH_TYPE, 6 * 8, 0, ('wrench', 'force'))
LAYOUTS = {IMU_TYPE: IMU, WRENCH_TYPE: WRENCH}
# The other vectors of the same messages (six components, issue 33): the Imu's
# angular_velocity (after orientation(4) + cov(9)), the first three elements of its
# covariance (element 0 = -1: not provided, REP-145), and the wrench torque.
IMU_RATE = Layout(IMU_TYPE, 37 * 8, 13 * 8, ('angular_velocity',))
IMU_RATE_COVARIANCE = Layout(IMU_TYPE, 37 * 8, 16 * 8, ('angular_velocity_covariance',))
WRENCH_TORQUE = Layout(WRENCH_TYPE, 6 * 8, 3 * 8, ('wrench', 'torque'))


def body_offset(strlen: int) -> int:
    """
    Byte offset of the first float64 after a header whose frame_id has ``strlen`` bytes.

    ``strlen`` counts the terminating NUL, as CDR does.
    """
    return 4 + (12 + strlen + 7) // 8 * 8


def payload_length(layout: Layout, strlen: int) -> int:
    """Return the serialised length for a frame_id of ``strlen`` bytes (NUL included)."""
    return body_offset(strlen) + layout.tail_bytes


_IMU_BODY_BYTES = IMU.tail_bytes
_IMU_ACCEL_FROM_END = IMU.tail_bytes - IMU.value_offset
_IMU_RATE_FROM_END = IMU_RATE.tail_bytes - IMU_RATE.value_offset
_IMU_RATE_COV_FROM_END = IMU_RATE_COVARIANCE.tail_bytes - IMU_RATE_COVARIANCE.value_offset
_WRENCH_BODY_BYTES = WRENCH.tail_bytes
_ENCAPSULATION = 4
_HEADER_FIXED = 12          # sec, nanosec, string length
_NS_PER_S = 1_000_000_000


def _frame_bytes(frame_id: str) -> bytes:
    raw = frame_id.encode('utf-8')
    if b'\x00' in raw:
        raise ShapeError(f'frame id {frame_id!r} contains a NUL character')
    return raw + b'\x00'


@dataclass(frozen=True, eq=False)
class DecodedImu:
    """
    Fields of a batch of serialized Imu messages, in arrival order.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` [ns] (0 where malformed).
    accel_mps2 : numpy.ndarray, shape (3, n), float64
        ``linear_acceleration`` x, y, z [m/s²] (NaN where malformed).
    malformed : numpy.ndarray, shape (n,), bool
        The bytes do not fit the Imu layout.
    wrong_frame : numpy.ndarray, shape (n,), bool
        ``header.frame_id`` differs from the expected one (never set when none is expected).
    nonfinite : numpy.ndarray, shape (n,), bool
        A well-formed message whose acceleration (or, when decoded, angular velocity) holds
        NaN or infinity.
    rate_radps : numpy.ndarray, shape (3, n), float64, or None
        ``angular_velocity`` x, y, z [rad/s] when asked for (``decode_imu(rates=True)``).
    no_angular_rate : numpy.ndarray, shape (n,), bool, or None
        A well-formed message whose angular velocity is flagged "not provided"
        (``angular_velocity_covariance[0] == -1``, REP-145); None when rates were not asked
        for.

    """

    stamp_ns: np.ndarray
    accel_mps2: np.ndarray
    malformed: np.ndarray
    wrong_frame: np.ndarray
    nonfinite: np.ndarray
    rate_radps: Optional[np.ndarray] = None
    no_angular_rate: Optional[np.ndarray] = None

    @property
    def valid(self) -> np.ndarray:
        """Messages that are usable samples."""
        bad = self.malformed | self.wrong_frame | self.nonfinite
        return ~(bad if self.no_angular_rate is None else bad | self.no_angular_rate)

    def values(self) -> np.ndarray:
        """Return the acceleration, then the angular rates if decoded: (3 or 6, n)."""
        if self.rate_radps is None:
            return self.accel_mps2
        return np.concatenate([self.accel_mps2, self.rate_radps])

    def sliced(self, lo: int, hi: int) -> 'DecodedImu':
        """Return messages ``lo:hi``."""
        return DecodedImu(
            self.stamp_ns[lo:hi], self.accel_mps2[:, lo:hi], self.malformed[lo:hi],
            self.wrong_frame[lo:hi], self.nonfinite[lo:hi],
            None if self.rate_radps is None else self.rate_radps[:, lo:hi],
            None if self.no_angular_rate is None else self.no_angular_rate[lo:hi])


@functools.lru_cache(maxsize=64)
def _layout(length: int, order: str, value_from_end: int, n_values: int,
            frame_len: int) -> np.dtype:
    """Structured dtype viewing one serialized message of ``length`` bytes in place."""
    names = ['encapsulation', 'sec', 'nsec', 'slen', 'values']
    formats = [('u1', (2,)), order + 'i4', order + 'u4', order + 'u4',
               (order + 'f8', (n_values,))]
    offsets = [0, 4, 8, 12, length - value_from_end]
    if frame_len and 16 + frame_len <= length:
        names.append('frame')
        formats.append(('u1', (frame_len,)))
        offsets.append(16)
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                     'itemsize': length})


def _decode_group(blob: bytes, length: int, body_bytes: int, value_from_end: int,
                  n_values: int, expected_frame: Optional[bytes]):
    """Decode messages of equal length; returns stamps, values (n, n_values), bad, wrong."""
    n = len(blob) // length
    if length < _ENCAPSULATION + _HEADER_FIXED + 1 + body_bytes:
        return (np.zeros(n, dtype=np.int64), np.full((n, n_values), np.nan),
                np.ones(n, dtype=bool), np.zeros(n, dtype=bool))
    frame_len = 0 if expected_frame is None else len(expected_frame)
    rec = np.frombuffer(blob, dtype=_layout(length, '<', value_from_end, n_values, frame_len))
    enc = rec['encapsulation']
    little = (enc[:, 0] == 0) & (enc[:, 1] == 1)
    if not little.all():
        # Rare: a big-endian writer (or garbage); decode those rows with the other layout.
        big = (enc[:, 0] == 0) & (enc[:, 1] == 0)
        rec_be = np.frombuffer(blob, dtype=_layout(length, '>', value_from_end, n_values,
                                                   frame_len))
        rec = np.where(big, rec_be.astype(rec.dtype), rec)
        known = little | big
    else:
        known = True
    sec = rec['sec'].astype(np.int64)
    nsec = rec['nsec'].astype(np.int64)
    slen = rec['slen'].astype(np.int64)
    # The body offset is fixed by the length; the string length must agree with it.
    fits = (known & (slen >= 1) & (nsec < _NS_PER_S)
            & (_ENCAPSULATION + ((_HEADER_FIXED + slen + 7) // 8) * 8 == length - body_bytes))
    stamps = np.where(fits, sec * _NS_PER_S + nsec, 0)
    values = np.where(fits[:, None], rec['values'], np.nan)
    if expected_frame is None:
        wrong = np.zeros(n, dtype=bool)
    elif 'frame' in rec.dtype.names:
        same = (slen == frame_len) & (
            rec['frame'] == np.frombuffer(expected_frame, dtype=np.uint8)).all(axis=1)
        wrong = fits & ~same
    else:
        wrong = fits.copy()
    return stamps, values, ~fits, wrong


def _decode_batch(raws: Sequence[bytes], body_bytes: int, value_from_end: int, n_values: int,
                  expected_frame_id: Optional[str]):
    n = len(raws)
    expected = None if not expected_frame_id else _frame_bytes(expected_frame_id)
    stamps = np.zeros(n, dtype=np.int64)
    values = np.full((n, n_values), np.nan)
    bad = np.ones(n, dtype=bool)
    wrong = np.zeros(n, dtype=bool)
    if n == 0:
        return stamps, values, bad, wrong
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=n)
    first = int(lengths[0])
    # Messages of one publisher share a frame id and hence a length: one reshape decodes all.
    groups = [(first, None)] if (lengths == first).all() else [
        (int(length), np.flatnonzero(lengths == length)) for length in np.unique(lengths)]
    for length, idx in groups:
        if length == 0:
            continue
        chunk = raws if idx is None else [raws[i] for i in idx]
        result = _decode_group(b''.join(chunk), length, body_bytes, value_from_end, n_values,
                               expected)
        target = slice(None) if idx is None else idx
        stamps[target], values[target], bad[target], wrong[target] = result
    return stamps, values, bad, wrong


def decode_imu(raws: Sequence[bytes], expected_frame_id: Optional[str] = None,
               rates: bool = False) -> DecodedImu:
    """
    Decode a batch of serialized ``sensor_msgs/Imu`` messages.

    Parameters
    ----------
    raws : sequence of bytes
        Serialized messages (``raw=True`` subscription callbacks), any count.
    expected_frame_id : str, optional
        Accepted ``header.frame_id``; ``None`` or ``''`` accepts any.
    rates : bool
        Also decode ``angular_velocity`` and flag the messages whose covariance says it is
        not provided (six-component models, issue 33).

    Returns
    -------
    DecodedImu

    """
    stamps, accel, bad, wrong = _decode_batch(raws, _IMU_BODY_BYTES, _IMU_ACCEL_FROM_END, 3,
                                              expected_frame_id)
    accel = np.ascontiguousarray(accel.T)
    nonfinite = ~bad & ~np.isfinite(accel).all(axis=0)
    if not rates:
        return DecodedImu(stamps, accel, bad, wrong & ~bad, nonfinite & ~wrong)
    _, rate, _, _ = _decode_batch(raws, _IMU_BODY_BYTES, _IMU_RATE_FROM_END, 3, None)
    _, cov, _, _ = _decode_batch(raws, _IMU_BODY_BYTES, _IMU_RATE_COV_FROM_END, 1, None)
    rate = np.ascontiguousarray(rate.T)
    no_rate = ~bad & ~wrong & (cov[:, 0] == -1.0)
    nonfinite |= ~bad & ~no_rate & ~np.isfinite(rate).all(axis=0)
    return DecodedImu(stamps, accel, bad, wrong & ~bad, nonfinite & ~wrong, rate, no_rate)


def decode_wrench(raws: Sequence[bytes]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Decode a batch of serialized ``geometry_msgs/WrenchStamped`` messages.

    Parameters
    ----------
    raws : sequence of bytes
        Serialized messages.

    Returns
    -------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` [ns].
    wrench : numpy.ndarray, shape (6, n), float64
        Force x, y, z [N] and torque x, y, z [N·m] (NaN where malformed).
    malformed : numpy.ndarray, shape (n,), bool
        The bytes do not fit the WrenchStamped layout.

    """
    stamps, wrench, bad, _ = _decode_batch(raws, _WRENCH_BODY_BYTES, _WRENCH_BODY_BYTES, 6,
                                           None)
    return stamps, np.ascontiguousarray(wrench.T), bad


def _encode(stamp_ns, body: np.ndarray, frame_id: str) -> List[bytes]:
    """Serialize rows of ``body`` (n, n_doubles) behind a Header; little-endian CDR."""
    stamps = np.asarray(stamp_ns, dtype=np.int64)
    if stamps.ndim != 1 or body.shape[0] != stamps.size:
        raise ShapeError(f'encode: {stamps.shape} stamps for {body.shape[0]} messages')
    if stamps.size and stamps.min() < 0:
        raise ShapeError(f'encode: negative stamp {int(stamps.min())} ns cannot be a ROS time')
    frame = _frame_bytes(frame_id)
    offset = body_offset(len(frame))
    length = offset + 8 * body.shape[1]
    n = stamps.size
    buf = np.zeros((n, length), dtype=np.uint8)
    buf[:, 1] = 1
    sec, nsec = np.divmod(stamps, _NS_PER_S)
    if n and sec.max() > np.iinfo(np.int32).max:
        raise ShapeError(f'encode: stamp {int(stamps.max())} ns beyond int32 seconds')
    buf[:, 4:8] = sec.astype('<i4').view(np.uint8).reshape(n, 4)
    buf[:, 8:12] = nsec.astype('<u4').view(np.uint8).reshape(n, 4)
    buf[:, 12:16] = np.frombuffer(np.uint32(len(frame)).astype('<u4').tobytes(), np.uint8)
    buf[:, 16:16 + len(frame)] = np.frombuffer(frame, dtype=np.uint8)
    buf[:, offset:] = np.ascontiguousarray(body, dtype='<f8').view(np.uint8).reshape(n, -1)
    blob = buf.tobytes()
    return [blob[i:i + length] for i in range(0, n * length, length)]


def encode_wrench(stamp_ns, force_n, frame_id: str, torque_nm=None) -> List[bytes]:
    """
    Serialize ``geometry_msgs/WrenchStamped`` messages, one per sample.

    Parameters
    ----------
    stamp_ns : array_like, shape (n,), int
        ``header.stamp`` of each message [ns], >= 0.
    force_n : array_like, shape (3, n)
        Force x, y, z [N].
    frame_id : str
        ``header.frame_id`` of every message.
    torque_nm : array_like, shape (3, n), optional
        Torque x, y, z [N·m]; zero when omitted.

    Returns
    -------
    list of bytes
        One serialized message per sample, publishable with ``Publisher.publish``.

    Raises
    ------
    ShapeError
        Mismatched shapes, a negative stamp or a NUL in ``frame_id``.

    """
    force = np.asarray(force_n, dtype=np.float64)
    n = force.shape[1] if force.ndim == 2 else -1
    torque = np.zeros((3, max(n, 0))) if torque_nm is None else np.asarray(torque_nm, float)
    if force.ndim != 2 or force.shape[0] != 3 or torque.shape != force.shape:
        raise ShapeError(f'encode_wrench: force {force.shape} / torque {torque.shape}, '
                         f'expected (3, n) each')
    return _encode(stamp_ns, np.concatenate([force, torque]).T, frame_id)


def encode_imu(stamp_ns, accel_mps2, frame_id: str, rate_radps=None) -> List[bytes]:
    """
    Serialize ``sensor_msgs/Imu`` messages carrying a linear acceleration (and rates).

    Orientation is marked as not provided (covariance element 0 = -1, REP-145), and so is the
    angular velocity unless ``rate_radps`` is given (then its covariance is 0: unknown); the
    acceleration covariance is 0 (unknown).

    Parameters
    ----------
    stamp_ns : array_like, shape (n,), int
        ``header.stamp`` [ns], >= 0.
    accel_mps2 : array_like, shape (3, n)
        Linear acceleration x, y, z [m/s²].
    frame_id : str
        ``header.frame_id`` of every message.
    rate_radps : array_like, shape (3, n), optional
        Angular velocity x, y, z [rad/s].

    Returns
    -------
    list of bytes
        One serialized message per sample.

    Raises
    ------
    ShapeError
        Mismatched shapes, a negative stamp or a NUL in ``frame_id``.

    """
    accel = np.asarray(accel_mps2, dtype=np.float64)
    if accel.ndim != 2 or accel.shape[0] != 3:
        raise ShapeError(f'encode_imu: acceleration {accel.shape}, expected (3, n)')
    body = np.zeros((accel.shape[1], 37))
    body[:, 4] = -1.0       # orientation_covariance[0]: no orientation estimate
    if rate_radps is None:
        body[:, 16] = -1.0  # angular_velocity_covariance[0]: no angular velocity
    else:
        rate = np.asarray(rate_radps, dtype=np.float64)
        if rate.shape != accel.shape:
            raise ShapeError(f'encode_imu: angular velocity {rate.shape}, expected '
                             f'{accel.shape}')
        body[:, 13:16] = rate.T
    body[:, 25:28] = accel.T
    return _encode(stamp_ns, body, frame_id)
