# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The records of an MCAP summary located in bulk, and its chunk indexes as arrays.

A file written in small chunks has one Chunk Index record per chunk in its summary (10 715
for 200 k messages in 4 KiB chunks).  Walking and unpacking them one by one in Python costs
as much as reading the chunks, so here the cost is per run of records, not per record:

- :func:`locate` walks the records, but a record followed by records of the same opcode and
  length (a writer writes its chunk indexes alike) is extended by checking the headers at
  the predicted positions with numpy: the same records, opcodes and lengths a one-by-one walk
  finds, every record header checked against its container as :func:`.mcap_records.walk`
  does.
- :func:`chunk_table` gathers the fields of all chunk indexes at their body offsets.  A record
  whose fields overrun it, with a bad offsets map or an undecodable compression name, is
  named with the exact fault found by the one-record parser :func:`chunk_index_fields`.

The chunk indexes stay arrays (:class:`ChunkTable`) through batching and reading.
"""
from dataclasses import dataclass
import struct
from typing import Callable, List, Optional, Tuple

import numpy as np

from wheel_force_estimator.bagio.fastcdr import gather_bytes

OP_CHUNK_INDEX = 0x08
#: Fixed part of a Chunk Index body: start/end time, chunk offset, chunk length, map length.
_FIXED = 36
_FIXED_DTYPE = np.dtype({'names': ['start', 'length', 'map_len'],
                         'formats': ['<u8', '<u8', '<u4'], 'offsets': [16, 24, 32],
                         'itemsize': _FIXED})
_TAIL_DTYPE = np.dtype({'names': ['index_length', 'clen'], 'formats': ['<u8', '<u4'],
                        'offsets': [0, 8], 'itemsize': 12})
# Offsets and lengths at or above this are beyond any file (kept exact for the comparisons
# made with them: sums of three stay below 2**63).
_HUGE = 1 << 60
# Records checked at once at first when a run of equal records starts (doubled as it goes on).
_FIRST_PROBE = 8


def locate(data: np.ndarray, pos: int, end: int, fail: Callable[[str, int], Exception]
           ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return ``(opcodes, body starts, body lengths)`` of every record in ``data[pos:end]``.

    Parameters
    ----------
    data : numpy.ndarray of uint8
        Buffer holding the records.
    pos, end : int
        Record range in ``data``.
    fail : callable
        ``fail(what, offset_in_data)`` builds the error to raise.

    Returns
    -------
    opcodes, bodies, lengths : numpy.ndarray of int64
        One entry per record, in storage order.

    Raises
    ------
    BagError
        (from ``fail``) A record header or body that overruns ``end``.

    """
    runs: List[Tuple[int, int, int, int]] = []  # (opcode, first body, length, records)
    unpack = struct.unpack_from
    while pos < end:
        if end - pos < 9:
            raise fail('record header cut off', pos)
        op, length = unpack('<BQ', data, pos)
        if length > end - pos - 9:
            raise fail(f'record (opcode 0x{op:02x}) overruns its container', pos)
        stride = 9 + length
        count = 1
        nxt = pos + stride
        if end - nxt >= stride and unpack('<BQ', data, nxt) == (op, length):
            count = _run(data, pos, end, op, length)
        runs.append((op, pos + 9, length, count))
        pos += count * stride
    if not runs:
        empty = np.zeros(0, np.int64)
        return empty, empty, empty
    op, body, length, count = (np.array(x, np.int64) for x in zip(*runs))
    first = np.repeat(body - (9 + length) * np.concatenate(([0], np.cumsum(count)[:-1])),
                      count)
    step = np.repeat(9 + length, count)
    bodies = first + step * np.arange(int(count.sum()))
    return np.repeat(op, count), bodies, np.repeat(length, count)


def _run(data: np.ndarray, pos: int, end: int, op: int, length: int) -> int:
    """Count the records from ``pos`` on that have opcode ``op`` and body ``length``."""
    stride = 9 + length
    head = np.frombuffer(struct.pack('<BQ', op, length), np.uint8)
    count = 1
    probe = _FIRST_PROBE
    while True:
        fits = (end - pos) // stride - count  # further whole records of this size
        k = min(probe, fits)
        if k <= 0:
            return count
        at = pos + stride * (count + np.arange(k, dtype=np.int64))
        same = (gather_bytes(data, at, 9) == head).all(axis=1)
        if not same.all():
            return count + int(np.argmin(same))
        count += k
        probe *= 2


def chunk_index_fields(data, body: int, end: int):
    """
    Parse one Chunk Index body in ``data[body:end]``, one field after the other.

    Returns
    -------
    tuple
        ``(chunk start, chunk length, (offsets map position, map entries), message index
        length, compression)``.

    Raises
    ------
    struct.error
        A field overruns the record, or an offsets map of a bad length.
    UnicodeDecodeError
        A compression name that is not UTF-8.

    """
    data = memoryview(data)[:end]
    start, length, map_len = struct.unpack_from('<QQI', data, body + 16)
    pos = body + _FIXED
    if map_len % 10:
        raise struct.error('message index offsets map of a bad length')
    index_offsets = (pos, map_len // 10)
    pos += map_len
    index_length, clen = struct.unpack_from('<QI', data, pos)
    if pos + 12 + clen > end:
        raise struct.error('compression name overruns the record')
    compression = bytes(data[pos + 12:pos + 12 + clen]).decode()
    return start, length, index_offsets, index_length, compression


@dataclass(frozen=True, eq=False)
class ChunkTable:
    """
    Chunk indexes of a summary, one array entry per chunk.

    Attributes
    ----------
    start, length, index_length : numpy.ndarray of int64
        Chunk record offset in the file, its length, the length of its message indexes
        (values of 2**60 and more are stored as 2**60: beyond any file).
    map_pos, map_count : numpy.ndarray of int64
        Position of its message index offsets map in the summary, and its entries.
    comp : numpy.ndarray of int64
        Compression, as a position in ``names``.
    names : tuple of str
        Compression names ('' for none).

    """

    start: np.ndarray
    length: np.ndarray
    index_length: np.ndarray
    map_pos: np.ndarray
    map_count: np.ndarray
    comp: np.ndarray
    names: Tuple[str, ...]

    def __len__(self) -> int:
        """Return the number of chunks."""
        return int(self.start.size)

    @property
    def end(self) -> np.ndarray:
        """File offset one past each chunk's message indexes."""
        return self.start + self.length + self.index_length

    def take(self, which) -> 'ChunkTable':
        """Return the chunks selected by ``which`` (index array, mask or slice)."""
        return ChunkTable(self.start[which], self.length[which], self.index_length[which],
                          self.map_pos[which], self.map_count[which], self.comp[which],
                          self.names)

    def compression(self) -> List[str]:
        """Return each chunk's compression name."""
        return [self.names[c] for c in self.comp.tolist()]


def chunk_table(data: np.ndarray, body: np.ndarray, length: np.ndarray,
                fail: Callable[[str, int], Exception]) -> ChunkTable:
    """
    Parse the Chunk Index records with bodies ``data[body:body + length]`` at once.

    Returns
    -------
    ChunkTable
        In record order.

    Raises
    ------
    BagError
        (from ``fail``) The first record that cannot be parsed, with the fault
        :func:`chunk_index_fields` finds, named at the record's start.

    """
    n = body.size
    ok = length >= _FIXED + 12
    fixed = np.zeros(n, _FIXED_DTYPE)
    tail = np.zeros(n, _TAIL_DTYPE)
    if ok.any():
        fixed = gather_bytes(data, np.where(ok, body, 0), _FIXED).view(_FIXED_DTYPE)[:, 0]
    map_len = fixed['map_len'].astype(np.int64)
    ok &= (map_len % 10 == 0) & (_FIXED + map_len + 12 <= length)
    tail_at = body + _FIXED + map_len
    if ok.any():
        tail = gather_bytes(data, np.where(ok, tail_at, 0), 12).view(_TAIL_DTYPE)[:, 0]
    clen = tail['clen'].astype(np.int64)
    ok &= _FIXED + map_len + 12 + clen <= length
    comp = np.zeros(n, np.int64)
    names: List[str] = []
    for size in np.unique(clen[ok]).tolist():
        sel = np.flatnonzero(ok & (clen == size))
        if not size:  # sizes come sorted: '' is the first name
            comp[sel] = len(names)
            names.append('')
            continue
        text = gather_bytes(data, tail_at[sel] + 12, size)
        while sel.size:  # one pass per distinct name (a file has one or two)
            same = (text == text[0]).all(axis=1)
            try:
                name = text[0].tobytes().decode()
            except UnicodeDecodeError:
                ok[sel[same]] = False
            else:
                comp[sel[same]] = len(names)
                names.append(name)
            sel, text = sel[~same], text[~same]
    bad = _first_bad(ok)
    if bad is not None:
        at = int(body[bad])
        try:
            chunk_index_fields(data, at, at + int(length[bad]))
        except (struct.error, UnicodeDecodeError) as err:
            raise fail(f'unreadable summary ({err})', at - 9) from err
        raise fail('unreadable summary (chunk index fields overrun the record)', at - 9)

    def exact(values):
        return np.minimum(values, _HUGE).astype(np.int64)
    return ChunkTable(exact(fixed['start']), exact(fixed['length']),
                      exact(tail['index_length']), body + _FIXED, map_len // 10, comp,
                      tuple(names))


def _first_bad(ok: np.ndarray) -> Optional[int]:
    if ok.all():
        return None
    return int(np.argmin(ok))


def batches(table: ChunkTable, batch_bytes: int, max_skip: int):
    """
    Split chunks sorted by start into runs of nearby chunks read together.

    A run ends before a chunk that starts more than ``max_skip`` bytes after the end of the
    chunks before it, or that would make the run span more than ``batch_bytes`` (a run holds
    at least one chunk).

    Returns
    -------
    list of tuple
        ``(a, b, lo, hi)``: chunks ``a..b-1`` and the file range ``[lo, hi)`` they cover.

    """
    start, end = table.start, table.end
    n = start.size
    if not n:
        return []
    reach = np.maximum.accumulate(end)
    gaps = np.flatnonzero(start[1:] - reach[:-1] > max_skip) + 1  # chunks that start a run
    out = []
    a = 0
    while a < n:
        b0 = int(start[a])
        g = gaps[np.searchsorted(gaps, a, side='right'):][:1]
        stop = min(int(g[0]) if g.size else n,
                   int(np.searchsorted(start, b0 + batch_bytes, side='right')))
        over = np.flatnonzero(end[a + 1:stop] - b0 > batch_bytes)
        b = a + 1 + int(over[0]) if over.size else max(stop, a + 1)
        out.append((a, b, b0, int(end[a:b].max())))
        a = b
    return out


def runs(comp: np.ndarray):
    """Return ``(a, b)`` index ranges of consecutive chunks with the same compression."""
    cut = np.flatnonzero(comp[1:] != comp[:-1]) + 1
    bounds = np.concatenate(([0], cut, [comp.size])).tolist()
    return list(zip(bounds[:-1], bounds[1:]))
