# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The message records of a run of MCAP chunks, checked and delivered per channel in one pass.

A run is consecutive chunks whose records share one buffer: the mapped file (uncompressed
chunks) or the decompressed records of the run joined.  Per chunk only a few integers are
kept (where its message index array lies, how many entries); the index entries, the record
headers and the payloads of the whole run are then gathered and checked with one vectorised
pass per channel, so the cost is per run, not per chunk: 4 KiB chunks cost what 1 MiB ones
do.  An index entry that does not match its record (opcode, channel, length, log time, or an
offset outside the chunk) makes the chunk be read through its own records
(:func:`.mcap_records.scan_messages`): indexes are optional and outside the chunk CRC.
"""
from typing import Callable, Dict, List, Tuple

import numpy as np

from wheel_force_estimator.bagio.fastcdr import gather_bytes
from wheel_force_estimator.bagio.mcap_records import OP_MESSAGE
from wheel_force_estimator.bagio.mcap_records import Registry
from wheel_force_estimator.bagio.mcap_records import scan_messages

# Message record: opcode(1) length(8) channel(2) sequence(4) log_time(8) publish_time(8)
MSG_HEADER = 31
_RECORD_DTYPE = np.dtype({'names': ['opcode', 'length', 'channel', 'log_time'],
                          'formats': ['u1', '<u8', '<u2', '<i8'], 'offsets': [0, 1, 9, 15],
                          'itemsize': 23})


class ChunkGroup:
    """
    Chunks whose records live in one buffer, and where their wanted messages are.

    Attributes
    ----------
    compressed : bool
        Records decompressed into ``pieces`` (joined on delivery) or read in place.
    chunks : dict
        Chunk file offset -> ``(base, end)``: its records in the group's buffer.
    indexed : dict
        Channel -> list of ``(index array positions in the index buffer, entry counts,
        chunk offsets)`` arrays.
    scanned : dict
        Channel -> list of ``(log times, record starts, chunk)`` found by walking records.

    """

    def __init__(self, compressed: bool):
        self.compressed = compressed
        self.pieces: List[np.ndarray] = []
        self.size = 0
        self.chunks: Dict[int, Tuple[int, int]] = {}
        self.indexed: Dict[int, list] = {}
        self.scanned: Dict[int, list] = {}

    def add_records(self, start: int, base: int, usize: int) -> None:
        """Register chunk ``start`` whose records are ``[base, base + usize)``."""
        self.chunks[start] = (base, base + usize)

    def add_scanned(self, start: int, found: dict, shift: int) -> None:
        """Add ``scan_messages`` results of chunk ``start`` (offsets + ``shift`` = starts)."""
        for cid, (times, offsets) in found.items():
            self.scanned.setdefault(cid, []).append(
                (np.asarray(times, np.int64), np.asarray(offsets, np.int64) + shift, start))

    def channels(self):
        """Return the channels with pending messages."""
        return set(self.indexed) | set(self.scanned)

    def buffer(self, mapped: np.ndarray) -> np.ndarray:
        """Return the buffer the records live in."""
        if not self.compressed:
            return mapped
        return self.pieces[0] if len(self.pieces) == 1 else np.concatenate(self.pieces)


def _messages(group: ChunkGroup, index_buf: np.ndarray, cid: int):
    """Flat ``(log_time, starts, chunk, base, end)`` of one channel's pending messages."""
    parts = []
    entries = group.indexed.get(cid, ())
    if entries:
        pos, count, owner, base, end = (np.concatenate([e[i] for e in entries])
                                        for i in range(5))
        first = np.concatenate(([0], np.cumsum(count)[:-1]))
        at = np.repeat(pos - 16 * first, count) + 16 * np.arange(int(count.sum()))
        pairs = gather_bytes(index_buf, at, 16).view('<i8').reshape(-1, 2)
        base = np.repeat(base, count)
        parts.append((pairs[:, 0], base + pairs[:, 1], np.repeat(owner, count), base,
                      np.repeat(end, count)))
    for t, s, c in group.scanned.get(cid, ()):
        lo, hi = group.chunks[c]
        parts.append((t, s, np.full(len(t), c, np.int64), np.full(len(t), lo, np.int64),
                      np.full(len(t), hi, np.int64)))
    flat = tuple(np.concatenate([p[i] for p in parts]) for i in range(5))
    if len(parts) > 1:
        order = np.argsort(flat[2], kind='stable')  # storage order across both kinds
        flat = tuple(x[order] for x in flat)
    return flat


def _check(buf: np.ndarray, cid: int, log_time, starts, chunk, base, end):
    """Return the chunks with a bad entry, and the gathered headers if there is none."""
    outside = (starts < base) | (starts + MSG_HEADER > end)
    if outside.any():
        return set(chunk[outside].tolist()), None
    # One gather per message for the record header and the CDR header after it (each pass
    # over scattered messages is a cache miss per message); the CDR part is only meaningful
    # for payloads of >= 16 bytes, which is all its user reads.
    combined = bool(starts.size) and int(starts.max()) + MSG_HEADER + 16 <= buf.size
    rows = gather_bytes(buf, starts, MSG_HEADER + 16 if combined else MSG_HEADER)
    head = rows[:, :23].view(_RECORD_DTYPE)[:, 0]
    rec_len = head['length'].astype(np.int64)
    bad = head['opcode'] != OP_MESSAGE
    bad |= head['channel'] != cid
    bad |= (rec_len < 22) | (rec_len > end - starts - 9)
    bad |= head['log_time'] != log_time  # an index entry that is not this record's
    if bad.any():
        return set(chunk[bad].tolist()), None
    return set(), (rec_len, rows, combined)


def deliver(group: ChunkGroup, index_buf: np.ndarray, buf: np.ndarray, cid: int, sink,
            fail: Callable[[str, int], Exception]) -> int:
    """
    Check one channel's pending records of ``group`` and hand them to ``sink``.

    Chunks whose index entries do not match their records are read through their records
    instead; a record found that way that is still inconsistent raises ``fail``'s error.

    Returns
    -------
    int
        Messages delivered.

    """
    msgs = _messages(group, index_buf, cid)
    bad, checked = _check(buf, cid, *msgs)
    if bad:
        keep = ~np.isin(msgs[2], list(bad))
        parts = [tuple(x[keep] for x in msgs)]
        for start in sorted(bad):
            lo, hi = group.chunks[start]
            scan = scan_messages(buf, lo, hi, cid.__eq__, Registry(),
                                 lambda what, at, start=start: fail(
                                     f'{what} (record {at} of the chunk)', start))
            t, o = scan.get(cid, ([], []))
            n = len(t)
            parts.append((np.asarray(t, np.int64), np.asarray(o, np.int64),
                          np.full(n, start, np.int64), np.full(n, lo, np.int64),
                          np.full(n, hi, np.int64)))
        msgs = tuple(np.concatenate([p[i] for p in parts]) for i in range(5))
        order = np.argsort(msgs[2], kind='stable')
        msgs = tuple(x[order] for x in msgs)
        bad, checked = _check(buf, cid, *msgs)
        if bad:
            raise fail(f'bad message record for channel {cid} in chunk', min(bad))
    log_time, starts = msgs[0], msgs[1]
    if not starts.size:
        return 0
    rec_len, rows, combined = checked
    sink.add(log_time, rec_len - 22, buf, starts + MSG_HEADER,
             head=rows[:, MSG_HEADER:] if combined else None)
    return int(starts.size)


_CHUNK_DTYPE = np.dtype({'names': ['opcode', 'record_length', 'usize', 'crc', 'clen'],
                         'formats': ['u1', '<u8', '<u8', '<u4', '<u4'],
                         'offsets': [0, 1, 25, 33, 37], 'itemsize': 41})
#: A chunk index's message index offsets map: (channel id, file offset) pairs, packed.
INDEX_OFFSETS = np.dtype([('channel', '<u2'), ('offset', '<u8')])
_INDEX_DTYPE = np.dtype({'names': ['opcode', 'channel', 'array_length'],
                         'formats': ['u1', '<u2', '<u4'], 'offsets': [0, 9, 11],
                         'itemsize': 15})


def chunk_headers(buf: np.ndarray, rel: np.ndarray, end: np.ndarray, comp: np.ndarray,
                  names):
    """
    Parse the Chunk record headers of a batch at once.

    Parameters
    ----------
    buf : numpy.ndarray of uint8
        The batch.
    rel, end : numpy.ndarray of int64
        Each chunk record's start and the end of its message indexes in ``buf``.
    comp : numpy.ndarray of int64
        Each chunk's compression as its chunk index lists it: a position in ``names``.
    names : sequence of str
        Compression names.

    Returns
    -------
    first, usize, crc : numpy.ndarray of int64
        Start of the (compressed) records in ``buf``, uncompressed size, CRC (0: none).
    bad : numpy.ndarray of int
        Positions of chunks whose header is inconsistent (the caller names the fault).

    """
    name_len = np.array([len(name.encode()) for name in names] or [0], np.int64)
    clen = name_len[comp]
    fits = (rel >= 0) & (rel + 49 + clen <= np.minimum(end, buf.size))
    at = np.where(fits, rel, 0)
    if buf.size < 49 + int(clen.max(initial=0)):
        return at, at, at, np.arange(rel.size)
    head = gather_bytes(buf, at, 41).view(_CHUNK_DTYPE)[:, 0]
    csize = gather_bytes(buf, at + 41 + np.where(fits, clen, 0), 8).view('<u8')[:, 0]
    csize = csize.astype(np.int64)
    usize = head['usize'].astype(np.int64)
    first = at + 49 + clen
    ok = fits & (head['opcode'] == 0x06) & (head['clen'] == clen)
    ok &= (csize >= 0) & (first + csize <= end)
    ok &= head['record_length'].astype(np.int64) + at + 9 <= end
    ok &= (clen > 0) | (csize == usize)
    for code, name in enumerate(names):  # the header names the compression the index does
        if not name:
            continue
        sel = np.flatnonzero(ok & (comp == code))
        text = np.frombuffer(name.encode(), np.uint8)
        same = (gather_bytes(buf, at[sel] + 41, text.size) == text).all(axis=1)
        ok[sel[~same]] = False
    return first, usize, head['crc'].astype(np.int64), np.flatnonzero(~ok)


def offsets_table(summary: np.ndarray, chunks, wanted):
    """
    Gather the message index offsets of wanted channels of all chunk indexes in one table.

    ``chunks`` is a :class:`.mcap_index.ChunkTable`: where each chunk's offsets map lies in
    ``summary`` and its entries.  Returns ``(chunk position in chunks, channel, file
    offset)`` arrays, ordered by chunk position.
    """
    pos, count = chunks.map_pos, chunks.map_count
    first = np.concatenate(([0], np.cumsum(count)[:-1]))
    at = np.repeat(pos - 10 * first, count) + 10 * np.arange(int(count.sum()))
    table = gather_bytes(summary, at, 10).view(INDEX_OFFSETS)[:, 0]
    owner = np.repeat(np.arange(len(chunks)), count)
    mine = np.isin(table['channel'], np.fromiter(wanted, np.int64, len(wanted)))
    return (owner[mine], table['channel'][mine].astype(np.int64),
            table['offset'][mine].astype(np.int64))


def index_entries(buf: np.ndarray, shift: int, rel, length, end, indexed, table, first: int):
    """
    Locate and check the message index of every wanted channel of every chunk of a batch.

    Parameters
    ----------
    buf : numpy.ndarray of uint8
        The batch.
    shift : int
        File offset of ``buf[0]``.
    rel, length, end : numpy.ndarray of int64
        Per chunk: record start in ``buf``, record length, end of its message indexes in
        ``buf``.
    indexed : numpy.ndarray of bool
        Chunks whose chunk index lists message indexes at all.
    table : tuple of numpy.ndarray
        :func:`offsets_table` of the chunks read, of which the batch's are the chunk
        positions ``first`` to ``first + rel.size - 1``.
    first : int
        Position of the batch's first chunk in ``table``.

    Returns
    -------
    usable : numpy.ndarray of bool
        Chunks whose message indexes can be used (the others are read record by record).
    entries : dict
        Channel -> ``(array positions in buf, entry counts, chunk positions)``.

    """
    usable = indexed.copy()
    owner, cid, off = table
    lo, hi = np.searchsorted(owner, [first, first + rel.size])
    j, cid, pos = owner[lo:hi] - first, cid[lo:hi], off[lo:hi] - shift
    if not j.size:
        return usable, {}
    end = end[j]
    ok = (pos >= (rel + length)[j]) & (pos + 15 <= end)
    head = gather_bytes(buf, np.where(ok, pos, 0), 15).view(_INDEX_DTYPE)[:, 0]
    size = head['array_length'].astype(np.int64)
    ok &= (head['opcode'] == 0x07) & (head['channel'] == cid)
    ok &= (pos + 15 + size <= end) & (size % 16 == 0)
    usable[j[~ok]] = False
    keep = np.flatnonzero(usable[j])
    if not keep.size:
        return usable, {}
    # grouped by channel, in storage order within each (a stable radix sort of 16-bit ids)
    keep = keep[np.argsort(cid[keep].astype(np.uint16), kind='stable')]
    ids = cid[keep]
    cuts = np.concatenate(([0], np.flatnonzero(ids[1:] != ids[:-1]) + 1, [ids.size])).tolist()
    entries = {}
    for a, b in zip(cuts[:-1], cuts[1:]):
        sel = keep[a:b]
        entries[int(ids[a])] = (pos[sel] + 15, size[sel] // 16, j[sel])
    return usable, entries
