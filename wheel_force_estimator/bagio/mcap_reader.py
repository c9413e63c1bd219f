# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk payloads of an MCAP storage file, memory-mapped.

Chunks are located through the summary's chunk indexes and messages through each chunk's
message indexes.  Message indexes are optional in MCAP and not covered by any CRC, so a chunk
without them, or whose index does not match the records it points at (opcode, channel,
length and log time are checked for every message), is read through its own records instead
(:mod:`.mcap_records`); its CRC is checked either way.  A file without a summary or chunk
indexes, or with messages outside chunks, is read record by record from start to end
(``scan=True`` forces that for every file: the independent fallback path).

The records of all chunks in a ~64 MiB batch are checked with one vectorised pass per channel
(the decompressed records of a batch's chunks are joined first, so the cost is per batch,
not per chunk), and every uncompressed chunk's CRC is computed by a worker thread one batch
ahead.  Batches go to the per-topic sinks of :mod:`.storage`.
"""
from concurrent.futures import ThreadPoolExecutor
import mmap
from pathlib import Path
import struct
from typing import Dict, List, Optional, Sequence

import numpy as np

from wheel_force_estimator.bagio.checksum import crc32
from wheel_force_estimator.bagio.compression import DECOMPRESS
from wheel_force_estimator.bagio.fastcdr import gather_bytes
from wheel_force_estimator.bagio.fastpath import FastPathUnavailable
from wheel_force_estimator.bagio.mcap_records import OP_CHANNEL
from wheel_force_estimator.bagio.mcap_records import OP_CHUNK
from wheel_force_estimator.bagio.mcap_records import OP_DATA_END
from wheel_force_estimator.bagio.mcap_records import OP_MESSAGE
from wheel_force_estimator.bagio.mcap_records import OP_SCHEMA
from wheel_force_estimator.bagio.mcap_records import Registry
from wheel_force_estimator.bagio.mcap_records import scan_messages
from wheel_force_estimator.bagio.mcap_records import walk
from wheel_force_estimator.core.errors import BagError

_MCAP_MAGIC = b'\x89MCAP0\r\n'
_FOOTER_LEN = 1 + 8 + 20 + 8  # opcode, length, footer fields, magic
# Message record: opcode(1) length(8) channel(2) sequence(4) log_time(8) publish_time(8)
_MSG_HEADER = 31
_RECORD_DTYPE = np.dtype({'names': ['opcode', 'length', 'channel', 'log_time'],
                          'formats': ['u1', '<u8', '<u2', '<i8'], 'offsets': [0, 1, 9, 15],
                          'itemsize': 23})
# Bytes of nearby chunks read and checked together: large enough that per-batch Python work
# vanishes (one vectorised check and decode per channel), small enough to bound memory.
_BATCH_BYTES = 64 << 20
# Bytes of unwanted records between two wanted chunks still read rather than skipped.
_MAX_SKIP = 1 << 20
# Threads decoding the channels of a batch side by side (the machine has 2 cores).
_DECODE_THREADS = 2


class _Group:
    """
    Message records of consecutive chunks that live in one buffer, delivered together.

    Uncompressed chunks are read in place from the mapped batch; compressed chunks' records
    are decompressed into ``pieces`` and joined into one buffer on delivery.  ``pending``
    holds, per channel, parts ``(log_time, record starts, base, end, chunk offset)``:
    records of one chunk at ``[base, end)`` of the group's buffer.
    """

    def __init__(self, compressed: bool):
        self.compressed = compressed
        self.pieces: List[np.ndarray] = []
        self.size = 0
        self.pending: Dict[int, list] = {}

    def add(self, parts: dict, base: int, usize: int, start: int) -> None:
        for cid, (times, offsets) in parts.items():
            self.pending.setdefault(cid, []).append(
                (np.asarray(times, np.int64), base + np.asarray(offsets, np.int64), base,
                 base + usize, start))


class McapFile:
    """Just enough of the MCAP format to pull message payloads out by channel in bulk."""

    def __init__(self, file: Path, scan: bool = False):
        self.file = file
        self.scan = scan

    def _fail(self, what: str, offset: Optional[int] = None) -> BagError:
        where = f' at offset {offset}' if offset is not None else ''
        return BagError(f'{self.file}: corrupt or truncated mcap: {what}{where}')

    def read(self, topics: Sequence[str], collectors):
        """Deliver the payloads of ``topics`` to ``collectors``; return ``{topic: type}``."""
        try:
            with self.file.open('rb') as fh:
                self._decoders = ThreadPoolExecutor(max_workers=_DECODE_THREADS)
                try:
                    return self._read(fh, topics, collectors)
                finally:
                    self._decoders.shutdown(wait=True, cancel_futures=True)
        except OSError as err:
            raise BagError(f'{self.file}: cannot read mcap: {err.strerror or err}') from err

    def _read(self, fh, topics, collectors):
        size = fh.seek(0, 2)
        fh.seek(0)
        if fh.read(8) != _MCAP_MAGIC:
            raise self._fail('bad start magic', 0)
        if size < 8 + _FOOTER_LEN:
            raise self._fail('file too short', size)
        fh.seek(size - _FOOTER_LEN)
        footer = fh.read(_FOOTER_LEN)
        if footer[-8:] != _MCAP_MAGIC or footer[0] != 0x02:
            raise self._fail('bad footer magic (file truncated?)', size - _FOOTER_LEN)
        summary_start, _ = struct.unpack_from('<QQ', footer, 9)
        if summary_start and not 8 <= summary_start <= size - _FOOTER_LEN:
            raise self._fail('summary offset out of range', size - _FOOTER_LEN)
        if self.scan or summary_start == 0:
            return self._scan_file(fh, summary_start or size - _FOOTER_LEN, topics, collectors)
        fh.seek(summary_start)
        summary = fh.read(size - _FOOTER_LEN - summary_start)
        registry, chunks, stats = self._summary(summary, summary_start)
        present, wanted = self._present(registry, topics)
        if not wanted:
            return present
        if not chunks:  # messages outside chunks (or no chunk index): read every record
            return self._scan_file(fh, summary_start, topics, collectors)
        # chunks without message indexes may hold any channel: they are read record by record
        todo = [c for c in sorted(chunks, key=lambda c: c[0])
                if not c[2] or any(cid in wanted for cid in c[2])]
        for start, length, _, index_length, _ in todo:
            if start + length + index_length > size:
                raise self._fail('chunk beyond end of file', start)
        counts = dict.fromkeys(wanted, 0)
        self._read_chunks(fh, todo, wanted, collectors, counts)
        if stats is not None and any(counts[c] != stats.get(c, 0) for c in wanted):
            # indexes that list fewer messages than the statistics count (or messages
            # outside chunks): only reading every record finds them all
            raise FastPathUnavailable(f'{self.file}: mcap indexes miss messages')
        return present

    def _present(self, registry: Registry, topics):
        wanted = {}
        present: Dict[str, str] = {}
        for cid, (topic, msgtype) in registry.channels.items():
            if present.setdefault(topic, msgtype) != msgtype:
                raise BagError(f'{self.file}: topic {topic} recorded with two types '
                               f'{present[topic]} and {msgtype}')
            if topic in topics:
                wanted[cid] = (topic, msgtype)
        return present, wanted

    def _summary(self, data: bytes, base: int):
        registry = Registry()
        chunks = []
        stats = None
        pos = 0
        try:
            for op, body, length in walk(data, 0, len(data), lambda what, at: self._fail(
                    f'summary {what}', base + at)):
                pos = body - 9
                if op in (OP_SCHEMA, OP_CHANNEL):
                    registry.add(op, data, body)
                elif op == 0x08:
                    chunks.append(self._chunk_index(data, body))
                elif op == 0x0B:
                    (map_len,) = struct.unpack_from('<I', data, body + 42)
                    stats = dict(struct.iter_unpack('<HQ', data[body + 46:body + 46 + map_len]))
        except (struct.error, UnicodeDecodeError) as err:
            raise self._fail(f'unreadable summary ({err})', base + pos) from err
        return registry, chunks, stats

    @staticmethod
    def _chunk_index(data: bytes, pos: int):
        start_offset, length, map_len = struct.unpack_from('<QQI', data, pos + 16)
        pos += 36
        pairs = struct.iter_unpack('<HQ', data[pos:pos + map_len])
        index_offsets = dict(pairs)
        pos += map_len
        index_length, clen = struct.unpack_from('<QI', data, pos)
        compression = data[pos + 12:pos + 12 + clen].decode()
        return start_offset, length, index_offsets, index_length, compression

    def _read_chunks(self, fh, chunks, wanted, collectors, counts):
        # The file is memory-mapped (no copy into a buffer) and read in batches of nearby
        # chunks.  A worker thread computes the CRCs one batch ahead of the decoding (zlib
        # releases the GIL), which also faults the pages in for it; a batch's pages are
        # released once its CRCs are checked, so the resident set stays at a few batches.
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        batches = list(_batches(chunks))
        previous: List[tuple] = []
        previous_range = (0, 0)
        pool = ThreadPoolExecutor(max_workers=1)
        # The channels of a batch are checked and decoded in parallel (numpy's gathers,
        # comparisons and copies release the GIL); every sink exists before that starts.
        for topic, msgtype in wanted.values():
            collectors.sink(topic, msgtype)
        try:
            upcoming = self._submit_crcs(mm, batches[0], pool)
            for k, (batch, lo, hi) in enumerate(batches):
                checks = upcoming
                if k + 1 < len(batches):
                    upcoming = self._submit_crcs(mm, batches[k + 1], pool)
                try:
                    self._read_batch(memoryview(mm)[lo:hi], lo, batch, wanted, collectors,
                                     counts)
                except BagError:
                    self._check_crcs(previous + checks)  # a CRC mismatch explains it better
                    raise
                self._check_crcs(previous)
                _release(mm, *previous_range)
                previous, previous_range = checks, (lo, hi)
            self._check_crcs(previous)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            try:
                mm.close()
            except BufferError:  # views still referenced by a traceback: unmapped by GC
                pass

    def _submit_crcs(self, mm, batch, pool) -> List[tuple]:
        """Queue the CRC of every uncompressed chunk of a batch: ``(start, crc, future)``."""
        chunks, lo, hi = batch
        view = memoryview(mm)[lo:hi]
        checks = []
        for start, length, _, index_length, _ in chunks:
            rel = start - lo
            first, usize, crc, comp = self._chunk_header(view, rel, rel + length + index_length,
                                                         start)
            if crc and not comp:
                checks.append((start, crc, pool.submit(crc32, view[first:first + usize])))
        return checks

    def _check_crcs(self, checks):
        for start, crc, future in checks:
            if future.result() != crc:
                raise self._fail('chunk CRC mismatch', start)

    def _read_batch(self, view, lo, batch, wanted, collectors, counts):
        buf = np.frombuffer(view, np.uint8)
        group: Optional[_Group] = None
        for start, length, index_offsets, index_length, _ in batch:
            rel = start - lo
            end = rel + length + index_length
            first, usize, crc, comp = self._chunk_header(view, rel, end, start)
            if group is None or group.compressed != bool(comp) or group.size > _BATCH_BYTES:
                if group is not None:  # storage order is kept across buffers
                    self._deliver_all(group, buf, wanted, collectors, counts)
                group = _Group(bool(comp))
            if comp:
                records = self._decompress(view, first, comp, usize, crc, start)
                base, src, src_first = group.size, records, 0
                group.pieces.append(records)
                group.size += usize
            else:  # CRC checked by the caller
                base, src, src_first = first, view, first
            parts = self._indexed(view, rel, length, end, index_offsets, wanted, usize, start)
            if parts is None:  # no usable message index: the chunk's own records
                parts = scan_messages(src, src_first, src_first + usize,
                                      wanted.__contains__, Registry(),
                                      self._chunk_fail(start))
                parts = {cid: (t, np.asarray(o, np.int64) - src_first)
                         for cid, (t, o) in parts.items()}
            group.add(parts, base, usize, start)
        if group is not None:
            self._deliver_all(group, buf, wanted, collectors, counts)

    def _chunk_fail(self, start: int):
        def fail(what: str, at: int) -> BagError:
            return self._fail(f'{what} (record {at} of the chunk)', start)
        return fail

    def _indexed(self, view, rel: int, length: int, end: int, index_offsets, wanted,
                 usize: int, start: int):
        """Messages of wanted channels per the chunk's message indexes, or None if unusable."""
        if not index_offsets:
            return None
        parts = {}
        for cid, offset in index_offsets.items():
            if cid not in wanted:
                continue
            found = self._message_index(view, rel + offset - start, rel + length, end, cid)
            if found is None:
                return None
            log_time, offsets = found
            if offsets.size and (offsets.min() < 0 or offsets.max() + _MSG_HEADER > usize):
                return None
            parts[cid] = (log_time, offsets)
        return parts

    def _message_index(self, view, pos: int, lo: int, hi: int, cid: int):
        try:
            if pos < lo:
                return None
            op, _, index_cid, arr_len = struct.unpack_from('<BQHI', view, pos)
        except struct.error:
            return None
        if op != 0x07 or index_cid != cid or pos + 15 + arr_len > hi or arr_len % 16:
            return None
        pairs = np.frombuffer(view, '<u8', count=arr_len // 8, offset=pos + 15)
        # a view (times and offsets are far below 2**63): _deliver copies what it keeps
        # before the batch's pages are released
        pairs = pairs.view(np.int64).reshape(-1, 2)
        return pairs[:, 0], pairs[:, 1]

    def _chunk_header(self, view, rel: int, end: int, start: int):
        try:
            if view[rel] != OP_CHUNK:
                raise self._fail('chunk record expected', start)
            (rec_len, _, _, usize, crc, clen) = struct.unpack_from('<QQQQII', view, rel + 1)
            comp = bytes(view[rel + 41:rel + 41 + clen]).decode()
            (csize,) = struct.unpack_from('<Q', view, rel + 41 + clen)
        except (struct.error, UnicodeDecodeError, IndexError) as err:
            raise self._fail(f'unreadable chunk header ({err})', start) from err
        first = rel + 49 + clen
        if first + csize > end or rel + 9 + rec_len > end:
            raise self._fail('chunk data overruns the chunk record', start)
        if not comp and csize != usize:
            raise self._fail(f'chunk holds {csize} bytes, header says {usize}', start)
        return first, usize, crc, comp

    def _decompress(self, view, first: int, comp: str, usize: int, crc: int, start: int):
        (csize,) = struct.unpack_from('<Q', view, first - 8)
        data = bytes(view[first:first + csize])
        if comp not in DECOMPRESS:
            raise BagError(f'{self.file}: unsupported mcap chunk compression {comp!r}')
        try:
            data = DECOMPRESS[comp](data)
        except (ValueError, RuntimeError, OSError) as err:
            raise self._fail(f'chunk does not decompress ({err})', start) from err
        if len(data) != usize:
            raise self._fail(f'chunk holds {len(data)} bytes, header says {usize}', start)
        if crc and crc32(data) != crc:
            raise self._fail('chunk CRC mismatch', start)
        return np.frombuffer(data, np.uint8)

    def _deliver_all(self, group: _Group, buf: np.ndarray, wanted, collectors, counts):
        """Check the pending message records of every channel and hand them to the sinks."""
        if group.compressed:
            buf = group.pieces[0] if len(group.pieces) == 1 else np.concatenate(group.pieces)
        jobs = [(cid, self._decoders.submit(self._deliver, buf, cid, parts, wanted,
                                            collectors))
                for cid, parts in group.pending.items() if parts]
        for _, job in jobs:  # every job ends before an error (the first channel's) is raised
            job.exception()
        for cid, job in jobs:
            counts[cid] = counts.get(cid, 0) + job.result()
        group.pending.clear()

    def _check(self, buf: np.ndarray, cid: int, parts):
        """Gather and check the records of ``parts``; return them and the bad chunks."""
        log_time, starts = (np.concatenate([p[i] for p in parts]) for i in (0, 1))
        sizes = [len(p[1]) for p in parts]
        ends = np.repeat([p[3] for p in parts], sizes)
        # One gather per message for the record header and the CDR header after it
        # (each pass over scattered messages is a cache miss per message); the CDR part
        # is only meaningful for payloads of >= 16 bytes, which is all its user reads.
        combined = bool(starts.size) and int(starts.max()) + _MSG_HEADER + 16 <= buf.size
        rows = gather_bytes(buf, starts, _MSG_HEADER + 16 if combined else _MSG_HEADER)
        head = rows[:, :23].view(_RECORD_DTYPE)[:, 0]
        rec_len = head['length'].astype(np.int64)
        bad = head['opcode'] != OP_MESSAGE
        bad |= head['channel'] != cid
        bad |= (rec_len < 22) | (rec_len > ends - starts - 9)
        bad |= head['log_time'] != log_time  # an index entry that is not this record's
        bad_chunks = set(np.repeat([p[4] for p in parts], sizes)[bad].tolist())
        return bad_chunks, (log_time, rec_len, starts, rows, combined)

    def _deliver(self, buf: np.ndarray, cid: int, parts, wanted, collectors) -> int:
        """Check one channel's pending message records and hand them to its sink."""
        bad, checked = self._check(buf, cid, parts)
        if bad:
            # the message index of these chunks does not match their records (indexes are
            # outside the chunk CRC): read the chunks' own records instead
            parts = [p if p[4] not in bad else self._rescan(buf, cid, p) for p in parts]
            parts = [p for p in parts if len(p[1])]
            if not parts:
                return 0
            bad, checked = self._check(buf, cid, parts)
            if bad:
                raise self._fail(f'bad message record for channel {cid} in chunk', min(bad))
        log_time, rec_len, starts, rows, combined = checked
        topic, msgtype = wanted[cid]
        collectors.sink(topic, msgtype).add(
            log_time, rec_len - 22, buf, starts + _MSG_HEADER,
            head=rows[:, _MSG_HEADER:] if combined else None)
        return int(starts.size)

    def _rescan(self, buf: np.ndarray, cid: int, part) -> tuple:
        _, _, base, end, start = part
        found = scan_messages(buf, base, end, cid.__eq__, Registry(), self._chunk_fail(start))
        times, offsets = found.get(cid, ([], []))
        return (np.asarray(times, np.int64), np.asarray(offsets, np.int64), base, end, start)

    def _scan_file(self, fh, data_end: int, topics, collectors):
        """Read every record from the start: files without summary, indexes or chunks."""
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        view = memoryview(mm)
        buf = np.frombuffer(mm, np.uint8)
        registry = Registry()

        def wanted(cid):
            channel = registry.channels.get(cid)
            return channel is not None and channel[0] in topics

        def channels():
            return {cid: ch for cid, ch in registry.channels.items() if ch[0] in topics}

        counts: Dict[int, int] = {}
        group: Optional[_Group] = None
        loose: Dict[int, tuple] = {}  # messages outside chunks: (times, offsets)

        def flush_loose():
            nonlocal group
            if loose:
                group = self._switch(group, False, buf, channels(), collectors, counts)
                for cid, (times, offsets) in loose.items():
                    group.add({cid: (times, offsets)}, 0, data_end, offsets[0])
                loose.clear()
        try:
            for op, body, length in walk(view, 8, data_end, self._fail):
                if op == OP_DATA_END:
                    break
                if op == OP_MESSAGE:
                    if length < 22:
                        raise self._fail('message record too short', body - 9)
                    cid, _, log_time = struct.unpack_from('<HIQ', view, body)
                    if wanted(cid):
                        times, offsets = loose.setdefault(cid, ([], []))
                        times.append(log_time)
                        offsets.append(body - 9)
                elif op in (OP_SCHEMA, OP_CHANNEL):
                    try:
                        registry.add(op, view, body)
                    except (struct.error, UnicodeDecodeError) as err:
                        raise self._fail(f'unreadable schema/channel record ({err})',
                                         body - 9) from err
                elif op == OP_CHUNK:
                    flush_loose()
                    start = body - 9
                    first, usize, crc, comp = self._chunk_header(view, start, body + length,
                                                                 start)
                    if comp:
                        records = self._decompress(view, first, comp, usize, crc, start)
                        src, src_first = records, 0
                    else:
                        if crc and crc32(view[first:first + usize]) != crc:
                            raise self._fail('chunk CRC mismatch', start)
                        src, src_first = view, first
                    parts = scan_messages(src, src_first, src_first + usize, wanted, registry,
                                          self._chunk_fail(start))
                    group = self._switch(group, bool(comp), buf, channels(), collectors,
                                         counts)
                    if comp:
                        base = group.size
                        group.pieces.append(records)
                        group.size += usize
                    else:
                        base = src_first
                    group.add({c: (t, np.asarray(o, np.int64) - src_first)
                               for c, (t, o) in parts.items()}, base, usize, start)
            flush_loose()
            if group is not None:
                self._deliver_all(group, buf, channels(), collectors, counts)
            present, _ = self._present(registry, topics)
            return present
        finally:
            buf = view = None  # release the exports of the map before closing it
            try:
                mm.close()
            except BufferError:  # views still referenced by a traceback: unmapped by GC
                pass

    def _switch(self, group, compressed: bool, buf, wanted, collectors, counts) -> _Group:
        """Return ``group``, or a new one after delivering it if it cannot take more."""
        if group is not None and group.compressed == compressed and group.size <= _BATCH_BYTES:
            return group
        if group is not None:
            self._deliver_all(group, buf, wanted, collectors, counts)
        return _Group(compressed)


def _release(mm: mmap.mmap, lo: int, hi: int):
    """Drop the mapped pages of ``[lo, hi)`` from the resident set (they stay cached)."""
    lo -= lo % mmap.PAGESIZE
    if hi > lo and hasattr(mm, 'madvise') and hasattr(mmap, 'MADV_DONTNEED'):
        mm.madvise(mmap.MADV_DONTNEED, lo, hi - lo)


def _batches(chunks):
    """Group sorted chunk indexes into ``(chunks, lo, hi)`` runs of nearby chunks."""
    batch: list = []
    hi = 0
    for chunk in chunks:
        end = chunk[0] + chunk[1] + chunk[3]
        if batch and (chunk[0] - hi > _MAX_SKIP or end - batch[0][0] > _BATCH_BYTES):
            yield batch, batch[0][0], hi
            batch = []
        hi = end if not batch else max(hi, end)
        batch.append(chunk)
    if batch:
        yield batch, batch[0][0], hi
