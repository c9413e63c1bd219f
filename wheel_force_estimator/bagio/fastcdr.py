# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk decoding of recorded messages, checked against the rosbags (de)serialiser.

The layouts and byte offsets are :mod:`.cdr`'s (the one codec, which the live node uses
too); this module adds what reading and writing *bags* needs on top.

sensor_msgs/Imu and geometry_msgs/WrenchStamped are a Header (int32 sec, uint32 nanosec,
string frame_id) followed by float64 fields only.  Once the frame_id length is known, every
field sits at a fixed byte offset, so equal-length payloads stacked as an ``(n, L)`` uint8
matrix can be read with one structured numpy view instead of one Python call per message.

Offsets follow the XCDR1 rules: a 4-byte encapsulation header, then alignment relative to
the byte after it (float64 on 8 bytes).  The fast path is only trusted after it agreed
bit-exactly with the generic rosbags deserialiser on the first messages of each layout group;
anything it does not recognise (big-endian payloads, unexpected lengths, a disagreement) is
decoded message by message by the generic deserialiser instead.
"""
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

import numpy as np

from wheel_force_estimator.bagio.cdr import body_offset
from wheel_force_estimator.bagio.cdr import IMU  # noqa: F401 (the bag readers' names)
from wheel_force_estimator.bagio.cdr import IMU_TYPE  # noqa: F401
from wheel_force_estimator.bagio.cdr import Layout
from wheel_force_estimator.bagio.cdr import LAYOUTS  # noqa: F401
from wheel_force_estimator.bagio.cdr import STRING_TYPE  # noqa: F401
from wheel_force_estimator.bagio.cdr import WRENCH  # noqa: F401
from wheel_force_estimator.bagio.cdr import WRENCH_TYPE  # noqa: F401

# Messages per layout group compared field by field with the generic deserialiser.
N_VALIDATE = 3
_NS_PER_S = 1_000_000_000
_CDR_LE = 0x0001  # encapsulation id, read big-endian from bytes 0..1
# Encapsulation and the header fields before the frame_id characters.
_HEAD_DTYPE = np.dtype({'names': ['enc', 'sec', 'nsec', 'strlen'],
                        'formats': ['>u2', '<i4', '<u4', '<u4'],
                        'offsets': [0, 4, 8, 12], 'itemsize': 16})


def extract(layout: Layout, msg) -> Tuple[int, Tuple[float, float, float]]:
    """Return ``(stamp_ns, (x, y, z))`` of a deserialised message (generic path)."""
    vec = msg
    for name in layout.vector_path:
        vec = getattr(vec, name)
    stamp = msg.header.stamp
    if isinstance(vec, np.ndarray):  # a covariance: its first three elements
        values = tuple(float(v) for v in vec[:3])
    else:
        values = (vec.x, vec.y, vec.z)
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec), values


def _same_bits(a, b) -> bool:
    """Bitwise equality of float64 sequences (NaN payloads included)."""
    return np.array_equal(np.asarray(a, np.float64).view(np.int64),
                          np.asarray(b, np.float64).view(np.int64))


def gather_bytes(buf: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """Copy ``buf[s:s + length]`` for every start into a (k, length) uint8 matrix."""
    if length == 0 or not len(starts):
        return np.zeros((len(starts), length), np.uint8)
    # One void item of `length` bytes starting at every byte: indexing copies whole items
    # (memcpy each) instead of walking a 2-D byte window element by element.
    items = np.ndarray(shape=(buf.size - length + 1,), dtype=np.dtype((np.void, length)),
                       buffer=buf, strides=(1,))
    return items[starts].view(np.uint8).reshape(len(starts), length)


def decode_rows(layout: Layout, rows: np.ndarray,
                deserialize: Callable[[bytes], object], verdicts: Optional[dict] = None):
    """
    Decode stacked equal-length payloads of one message type.

    Parameters
    ----------
    layout : Layout
        Message layout (``IMU`` or ``WRENCH``).
    rows : numpy.ndarray, shape (n, L), uint8
        One serialised CDR payload per row.
    deserialize : callable
        ``deserialize(raw_bytes) -> message``: the generic deserialiser used to validate the
        fast path and to decode whatever it does not recognise.
    verdicts : dict, optional
        ``(payload length, frame_id length) -> bool`` validation results carried between
        calls for one connection, so each layout is checked against ``deserialize`` once.

    Returns
    -------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` in ns.
    values : numpy.ndarray, shape (n, 3), float64
        The x, y, z values (linear_acceleration or wrench.force).
    n_fast : int
        How many rows were decoded by the bulk path.

    """
    n, length = rows.shape
    buf = np.ascontiguousarray(rows).reshape(-1)
    return decode_records(layout, buf, np.arange(n, dtype=np.int64) * length, length,
                          deserialize, verdicts)


def decode_records(layout: Layout, buf: np.ndarray, starts: np.ndarray, length: int,
                   deserialize: Callable[[bytes], object], verdicts: Optional[dict] = None,
                   head: Optional[np.ndarray] = None):
    """
    Decode equal-length payloads lying anywhere in one byte buffer, without copying them.

    Only the bytes that are needed (header, frame_id terminator, three values) are read, at
    the payload starts given, so a storage chunk is decoded in place.

    Parameters
    ----------
    layout : Layout
        Message layout (``IMU`` or ``WRENCH``).
    buf : numpy.ndarray, shape (m,), uint8
        Buffer holding the payloads.
    starts : numpy.ndarray, shape (n,), int64
        Offset of each payload in ``buf``; ``starts + length <= m`` (checked by the caller).
    length : int
        Length of every payload.
    deserialize, verdicts
        As for :func:`decode_rows`.
    head : numpy.ndarray, shape (n, 16), uint8, optional
        The first 16 bytes of every payload when the caller gathered them already.

    Returns
    -------
    stamp_ns, values, n_fast
        As for :func:`decode_rows`.

    """
    n = len(starts)
    stamp_ns = np.empty(n, np.int64)
    values = np.empty((n, 3), np.float64)
    done = np.zeros(n, bool)
    if length >= 16 and n:
        # one gather of the 16 header bytes: each pass over the payloads is a cache miss
        if head is None:
            head = gather_bytes(buf, starts, 16)
        head = head.view(_HEAD_DTYPE)[:, 0]
        strlen = head['strlen'].astype(np.int64)
        fits = head['enc'] == _CDR_LE
        fits &= (4 + ((12 + strlen + 7) // 8) * 8 + layout.tail_bytes) == length
        uniform = bool(fits.all()) and strlen.min() == strlen.max()
        for s in strlen[:1] if uniform else np.unique(strlen[fits]):
            sel = slice(None) if uniform else np.flatnonzero(fits & (strlen == s))
            at = starts[sel]
            # frame_id must be NUL terminated, as every ROS 2 serialiser writes it
            if s < 1 or buf[at + 15 + s].any():
                continue
            st = head['sec'][sel].astype(np.int64) * _NS_PER_S + head['nsec'][sel]
            vals = gather_bytes(buf, at + body_offset(int(s)) + layout.value_offset,
                                24).view('<f8')
            key = (length, int(s))
            if verdicts is None or key not in verdicts:
                ok = _agrees(layout, gather_bytes(buf, at[:N_VALIDATE], length), st, vals,
                             deserialize)
                if verdicts is not None:
                    verdicts[key] = ok
            if not (verdicts[key] if verdicts is not None else ok):
                continue
            if uniform:
                stamp_ns, values = st, vals.astype(np.float64, copy=False)
                done[:] = True
            else:
                stamp_ns[sel] = st
                values[sel] = vals
                done[sel] = True
    n_fast = int(done.sum())
    for i in np.flatnonzero(~done):
        row = buf[starts[i]:starts[i] + length].tobytes()
        stamp_ns[i], values[i] = extract(layout, deserialize(row))
    return stamp_ns, values, n_fast


def _agrees(layout, group, st, vals, deserialize) -> bool:
    for j in range(min(N_VALIDATE, len(st))):
        ref_stamp, ref_values = extract(layout, deserialize(group[j].tobytes()))
        if ref_stamp != st[j] or not _same_bits(ref_values, vals[j]):
            return False
    return True


@dataclass(frozen=True)
class DecodedTopic:
    """
    Decoded samples of one topic in bag order.

    Attributes
    ----------
    log_time_ns : numpy.ndarray, shape (n,), int64
        Bag (receive) timestamps.
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp``.
    values : numpy.ndarray, shape (n, 3), float64
        x, y, z values.
    n_fast : int
        Messages decoded by the bulk path.

    """

    log_time_ns: np.ndarray
    stamp_ns: np.ndarray
    values: np.ndarray
    n_fast: int

    @property
    def n(self) -> int:
        """Return the number of messages."""
        return len(self.log_time_ns)


class TopicDecoder:
    """
    Storage sink that decodes each batch of payloads as it arrives.

    Keeps only stamps and values, not the payloads, so memory stays ~32 bytes per message
    whatever the recording length.  ``add``/``finish`` follow the storage sink protocol.
    """

    def __init__(self, layout: Layout, deserialize: Callable[[bytes], object],
                 values_out: Optional[Callable[[int], Optional[np.ndarray]]] = None):
        self.layout = layout
        self.deserialize = deserialize
        self.values_out = values_out
        self.verdicts: dict = {}
        self.parts: List[Tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.n_fast = 0
        self._filled = 0
        self._reserved: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None

    def reserve(self, n: int) -> None:
        """
        Allocate the result for ``n`` messages up front (e.g. the count in metadata.yaml).

        Batches are then decoded straight into it instead of being concatenated at the end,
        which halves the peak memory of a long recording (and fresh memory is what costs most
        on a VM: ~2 s per GB on first touch on the benchmark machine).  A wrong count is
        harmless: batches beyond it are kept aside and everything is joined as before.
        ``values_out(n)``, when given at construction, may supply the (n, 3) values array
        (e.g. three rows of a shared corner-stacked array).
        """
        if n > 0 and self._reserved is None and not self.parts:
            values = self.values_out(n) if self.values_out is not None else None
            self._reserved = (np.empty(n, np.int64), np.empty(n, np.int64),
                              np.empty((n, 3), np.float64) if values is None else values)

    def add(self, log_time: np.ndarray, lengths: np.ndarray, buf: np.ndarray,
            starts: np.ndarray, head: Optional[np.ndarray] = None):
        """
        Decode one batch: payload ``i`` is ``buf[starts[i]:starts[i] + lengths[i]]``.

        ``head`` (k, 16), if given, holds the first 16 bytes of every payload.
        """
        if len(lengths) and lengths.min() == lengths.max():
            groups = [(int(lengths[0]), slice(None))]
        else:
            groups = [(int(v), np.flatnonzero(lengths == v)) for v in np.unique(lengths)]
        stamp = values = None
        for length, idx in groups:
            st, vals, n_fast = decode_records(self.layout, buf, starts[idx], length,
                                              self.deserialize, self.verdicts,
                                              None if head is None else head[idx])
            self.n_fast += n_fast
            if isinstance(idx, slice):
                stamp, values = st, vals
                break
            if stamp is None:
                stamp = np.empty(len(log_time), np.int64)
                values = np.empty((len(log_time), 3), np.float64)
            stamp[idx] = st
            values[idx] = vals
        if stamp is None:
            return
        k = len(stamp)
        if self._reserved is not None and not self.parts and (
                self._filled + k <= len(self._reserved[0])):
            for out, part in zip(self._reserved, (log_time, stamp, values)):
                out[self._filled:self._filled + k] = part
            self._filled += k
        else:
            self.parts.append((np.asarray(log_time, np.int64), stamp, values))

    def finish(self) -> DecodedTopic:
        """Join the batches in bag-time order (stable: storage order breaks ties)."""
        parts = list(self.parts)
        if self._reserved is not None:
            filled = tuple(a[:self._filled] for a in self._reserved)
            parts.insert(0, filled)
            self._reserved = None
        if not parts:
            return DecodedTopic(np.zeros(0, np.int64), np.zeros(0, np.int64),
                                np.zeros((0, 3)), 0)
        if len(parts) == 1:
            log_time, stamp, values = parts[0]
        else:
            log_time, stamp, values = (np.concatenate(x) for x in zip(*parts))
        self.parts = []
        if np.any(np.diff(log_time) < 0):
            order = np.argsort(log_time, kind='stable')
            log_time, stamp, values = log_time[order], stamp[order], values[order]
        return DecodedTopic(log_time, stamp, values, self.n_fast)
