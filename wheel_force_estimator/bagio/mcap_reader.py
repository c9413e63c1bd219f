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

The summary's chunk indexes are parsed into arrays (:mod:`.mcap_index`).  The records of
all chunks in a ~64 MiB batch are checked with one vectorised pass per channel (the
decompressed records of a batch's chunks are joined first, so the cost is per batch, not per
chunk; a run of zstd chunks with CRCs is decompressed in one call), and every uncompressed
chunk's CRC is computed by a worker thread one batch ahead.  Batches go to the per-topic
sinks of :mod:`.storage`.
"""
from concurrent.futures import ThreadPoolExecutor
import mmap
import os
from pathlib import Path
import struct
from typing import Dict, List, Optional, Sequence

import numpy as np

from wheel_force_estimator.bagio.checksum import crc32
from wheel_force_estimator.bagio.compression import chunk_decompressor
from wheel_force_estimator.bagio.compression import DECOMPRESS
from wheel_force_estimator.bagio.compression import decompress_joined
from wheel_force_estimator.bagio.fastpath import FastPathUnavailable
from wheel_force_estimator.bagio.mcap_group import chunk_headers
from wheel_force_estimator.bagio.mcap_group import ChunkGroup
from wheel_force_estimator.bagio.mcap_group import deliver
from wheel_force_estimator.bagio.mcap_group import index_entries
from wheel_force_estimator.bagio.mcap_group import offsets_table
from wheel_force_estimator.bagio.mcap_index import batches as batches_of
from wheel_force_estimator.bagio.mcap_index import chunk_table
from wheel_force_estimator.bagio.mcap_index import locate
from wheel_force_estimator.bagio.mcap_index import OP_CHUNK_INDEX
from wheel_force_estimator.bagio.mcap_index import runs
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
# Bytes of nearby chunks read and checked together: large enough that per-batch Python work
# vanishes (one vectorised check and decode per channel), small enough to bound memory.
_BATCH_BYTES = 64 << 20
# Bytes of unwanted records between two wanted chunks still read rather than skipped.
_MAX_SKIP = 1 << 20


def decode_threads(n_channels: int) -> int:
    """
    Return how many threads decode the channels of a batch side by side.

    One per CPU this process may run on (its affinity mask, e.g. a container's cpuset; else
    ``os.cpu_count()``), never more than there are channels: numpy's gathers, comparisons
    and copies release the GIL, so each thread keeps one CPU busy.
    """
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:      # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, n_channels))


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
                self._decoders = ThreadPoolExecutor(max_workers=decode_threads(len(topics)))
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
        summary = np.frombuffer(summary, np.uint8)
        registry, chunks, stats = self._summary(summary, summary_start)
        present, wanted = self._present(registry, topics)
        if not wanted:
            return present
        if not len(chunks):  # messages outside chunks (or no chunk index): read every record
            return self._scan_file(fh, summary_start, topics, collectors)
        if (chunks.start[1:] < chunks.start[:-1]).any():  # summary not in file order
            chunks = chunks.take(np.argsort(chunks.start, kind='stable'))
        owner, cid, offset = offsets_table(summary, chunks, wanted)
        # chunks that may hold wanted messages: indexed for one, or without message indexes
        # (those may hold any channel: they are read record by record)
        listed = np.zeros(len(chunks), bool)
        listed[owner] = True
        keep = np.flatnonzero((chunks.map_count == 0) | listed)
        todo = chunks.take(keep)
        position = np.zeros(len(chunks), np.int64)
        position[keep] = np.arange(keep.size)
        self._table = (position[owner], cid, offset)  # owners: positions in todo
        beyond = np.flatnonzero(todo.end > size)
        if beyond.size:  # named with the offset as written (the table caps huge values)
            (start,) = struct.unpack_from('<Q', summary, int(todo.map_pos[beyond[0]]) - 20)
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

    def _summary(self, data: np.ndarray, base: int):
        """Return the summary's registry, chunk indexes and message counts (or None)."""
        op, body, length = locate(data, 0, data.size,
                                  lambda what, at: self._fail(f'summary {what}', base + at))
        registry = Registry()
        stats = None
        view = memoryview(data)
        for k in np.flatnonzero((op == OP_SCHEMA) | (op == OP_CHANNEL) | (op == 0x0B)).tolist():
            at, end = int(body[k]), int(body[k] + length[k])
            try:
                if op[k] == 0x0B:
                    (map_len,) = struct.unpack_from('<I', view[:end], at + 42)
                    if at + 46 + map_len > end:
                        raise struct.error('channel message counts overrun the record')
                    stats = dict(struct.iter_unpack('<HQ', view[at + 46:at + 46 + map_len]))
                else:
                    registry.add(int(op[k]), view, at)
            except (struct.error, UnicodeDecodeError) as err:
                raise self._fail(f'unreadable summary ({err})', base + at - 9) from err
        sel = op == OP_CHUNK_INDEX
        chunks = chunk_table(data, body[sel], length[sel],
                             lambda what, at: self._fail(what, base + at))
        return registry, chunks, stats

    def _read_chunks(self, fh, chunks, wanted, collectors, counts):
        # The file is memory-mapped (no copy into a buffer) and read in batches of nearby
        # chunks.  A worker thread computes the CRCs one batch ahead of the decoding (zlib
        # releases the GIL), which also faults the pages in for it; a batch's pages are
        # released once its CRCs are checked, so the resident set stays at a few batches.
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        batches = [(chunks.take(slice(a, b)), a, lo, hi)
                   for a, b, lo, hi in batches_of(chunks, _BATCH_BYTES, _MAX_SKIP)]
        previous: List[tuple] = []
        previous_range = (0, 0)
        pool = ThreadPoolExecutor(max_workers=1)
        # The channels of a batch are checked and decoded in parallel (numpy's gathers,
        # comparisons and copies release the GIL); every sink exists before that starts.
        for topic, msgtype in wanted.values():
            collectors.sink(topic, msgtype)
        try:
            upcoming = self._submit_crcs(mm, batches[0], pool)
            for k, (batch, first, lo, hi) in enumerate(batches):
                checks, headers = upcoming
                if k + 1 < len(batches):
                    upcoming = self._submit_crcs(mm, batches[k + 1], pool)
                try:
                    self._read_batch(memoryview(mm)[lo:hi], lo, batch, first, headers, wanted,
                                     collectors, counts)
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

    def _submit_crcs(self, mm, batch, pool):
        """
        Parse a batch's chunk headers and queue the CRC of every uncompressed chunk.

        Returns ``([(start, crc, future), ...], headers)`` (:meth:`_headers`).
        """
        chunks, _, lo, hi = batch
        view = memoryview(mm)[lo:hi]
        headers = start, first, usize, crc = self._headers(view, lo, chunks)
        plain = np.array([not name for name in chunks.names], bool)[chunks.comp] & (crc != 0)
        k = np.flatnonzero(plain)
        return [(s, c, pool.submit(crc32, view[f:f + u]))
                for s, f, u, c in zip(start[k].tolist(), first[k].tolist(), usize[k].tolist(),
                                      crc[k].tolist())], headers

    def _headers(self, view, lo: int, chunks):
        """Chunk offsets and the header fields of a batch; a bad header is named."""
        start = chunks.start
        rel = start - lo
        end = chunks.end - lo
        first, usize, crc, bad = chunk_headers(np.frombuffer(view, np.uint8), rel, end,
                                               chunks.comp, chunks.names)
        for k in bad.tolist():  # the exact fault, from the one-by-one parser
            self._chunk_header(view, int(rel[k]), int(end[k]), int(start[k]))
            raise self._fail('chunk header disagrees with its chunk index', int(start[k]))
        return start, first, usize, crc

    def _check_crcs(self, checks):
        for start, crc, future in checks:
            if future.result() != crc:
                raise self._fail('chunk CRC mismatch', start)

    def _read_batch(self, view, lo, batch, first_chunk, headers, wanted, collectors, counts):
        buf = np.frombuffer(view, np.uint8)
        start, first, usize, crc = headers
        rel = start - lo
        end = batch.end - lo
        usable, entries = index_entries(buf, lo, rel, batch.length, end, batch.map_count > 0,
                                        self._table, first_chunk)
        for a, b in runs(batch.comp):
            comp = batch.names[batch.comp[a]]
            group = ChunkGroup(bool(comp))
            if comp:  # CRCs checked on decompression
                records = self._decompress_run(view, comp, first[a:b], usize[a:b],
                                               crc[a:b], start[a:b])
                group.pieces.append(records)
                group.size = records.size
                base = np.concatenate(([0], np.cumsum(usize[a:b])[:-1]))
            else:  # CRCs checked by the caller
                records, base = view, first[a:b]
            group.chunks.update(zip(start[a:b].tolist(),
                                    zip(base.tolist(), (base + usize[a:b]).tolist())))
            for cid, (pos, count, owner) in entries.items():
                sel = (owner >= a) & (owner < b)
                if sel.any():
                    k = owner[sel]
                    lo_k = base[k - a]
                    group.indexed[cid] = [(pos[sel], count[sel], start[k], lo_k,
                                           lo_k + usize[k])]
            for k in np.flatnonzero(~usable[a:b]).tolist():
                # no usable message index: the chunk's own records
                lo_k = int(base[k])
                group.add_scanned(int(start[a + k]), scan_messages(
                    records, lo_k, lo_k + int(usize[a + k]), wanted.__contains__, Registry(),
                    self._chunk_fail(int(start[a + k]))), 0)
            self._deliver_all(group, buf, wanted, collectors, counts)

    def _chunk_fail(self, start: int):
        def fail(what: str, at: int) -> BagError:
            return self._fail(f'{what} (record {at} of the chunk)', start)
        return fail

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

    def _decompress_run(self, view, comp: str, first, usize, crc, start) -> np.ndarray:
        """Decompress consecutive chunks into one array (per-chunk cost kept to a minimum)."""
        if comp not in DECOMPRESS:
            raise BagError(f'{self.file}: unsupported mcap chunk compression {comp!r}')
        fast, refused = chunk_decompressor(comp)
        general = DECOMPRESS[comp]
        check = crc32
        ends = np.cumsum(usize)
        csize = np.frombuffer(view, np.uint8)[
            (first[:, None] - 8 + np.arange(8)).reshape(-1)].view('<u8').tolist()
        out = np.empty(int(ends[-1]) if ends.size else 0, np.uint8)
        target = memoryview(out)
        if crc.all() and self._joined(view, comp, first.tolist(), csize, usize.tolist(),
                                      crc.tolist(), ends.tolist(), target):
            return out
        # Each chunk is copied into place at once: its bytes object is freed and its memory
        # reused by the next one, so only `out` is new memory (fresh pages cost ~2 s/GB on
        # the benchmark VM, more than the decompression).
        for f, n, u, c, s, e in zip(first.tolist(), csize, usize.tolist(), crc.tolist(),
                                    start.tolist(), ends.tolist()):
            try:
                try:
                    data = fast(view[f:f + n])
                except refused:  # several frames, no content size, or damage
                    data = general(view[f:f + n])
            except (ValueError, RuntimeError, OSError):  # the exact fault, from the slow path
                self._decompress(view, f, comp, u, c, s)
                raise
            if len(data) != u:
                raise self._fail(f'chunk holds {len(data)} bytes, header says {u}', s)
            if c and check(data) != c:
                raise self._fail('chunk CRC mismatch', s)
            target[e - u:e] = data
        return out

    @staticmethod
    def _joined(view, comp: str, first, csize, usize, crc, ends, target) -> bool:
        """
        Decompress a run's chunks in one call, if its compression allows; True if all good.

        Only for chunks that all have a CRC: each is checked over the bytes at its place in
        ``target``, so a chunk that decodes to another size than its header says (which
        shifts its bytes and those of the chunks after it) fails its CRC or the total size.
        On any fault the caller decodes chunk by chunk, which names the fault exactly.
        """
        frames = b''.join([view[f:f + n] for f, n in zip(first, csize)])
        if not decompress_joined(comp, frames, target):
            return False
        check = crc32
        return all(check(target[e - u:e]) == c for u, c, e in zip(usize, crc, ends))

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

    def _deliver_all(self, group: ChunkGroup, buf: np.ndarray, wanted, collectors, counts):
        """Check the pending message records of every channel and hand them to the sinks."""
        records = group.buffer(buf)
        jobs = [(cid, self._decoders.submit(deliver, group, buf, records, cid,
                                            collectors.sink(*wanted[cid]), self._fail))
                for cid in sorted(group.channels())]
        for _, job in jobs:  # every job ends before an error (the first channel's) is raised
            job.exception()
        for cid, job in jobs:
            counts[cid] = counts.get(cid, 0) + job.result()

    def _scan_file(self, fh, data_end: int, topics, collectors):
        """Read every record from the start: files without summary, indexes or chunks."""
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        view = memoryview(mm)
        buf = np.frombuffer(mm, np.uint8)
        registry = Registry()

        def wanted(cid):
            channel = registry.channels.get(cid)
            return channel is not None and channel[0] in topics

        counts: Dict[int, int] = {}
        loose: Dict[int, tuple] = {}  # messages outside chunks: (times, offsets)
        group: Optional[ChunkGroup] = None  # consecutive chunks, delivered together

        def flush():
            """Deliver the chunks and then the loose messages so far (storage order kept)."""
            nonlocal group
            channels = {c: ch for c, ch in registry.channels.items() if ch[0] in topics}
            if group is not None:
                self._deliver_all(group, buf, channels, collectors, counts)
                group = None
            if loose:
                first = min(o[0] for _, o in loose.values())
                run = ChunkGroup(False)
                run.add_records(first, 0, data_end)
                run.add_scanned(first, dict(loose), 0)
                loose.clear()
                self._deliver_all(run, buf, channels, collectors, counts)
        try:
            for op, body, length in walk(view, 8, data_end, self._fail):
                if op == OP_DATA_END:
                    break
                if op == OP_MESSAGE:
                    if length < 22:
                        raise self._fail('message record too short', body - 9)
                    cid, _, log_time = struct.unpack_from('<HIQ', view, body)
                    if wanted(cid):
                        if group is not None:
                            flush()
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
                    if loose:
                        flush()
                    group = self._scan_chunk(view, body - 9, body + length, wanted, registry,
                                             group, flush)
            flush()
            present, _ = self._present(registry, topics)
            return present
        finally:
            buf = view = None  # release the exports of the map before closing it
            try:
                mm.close()
            except BufferError:  # views still referenced by a traceback: unmapped by GC
                pass

    def _scan_chunk(self, view, start: int, end: int, wanted, registry, group,
                    flush) -> ChunkGroup:
        """Add a chunk's wanted records to ``group`` (flushed first if it cannot take them)."""
        first, usize, crc, comp = self._chunk_header(view, start, end, start)
        if group is not None and (group.compressed != bool(comp) or group.size > _BATCH_BYTES):
            flush()
            group = None
        group = group or ChunkGroup(bool(comp))
        if comp:
            records = self._decompress(view, first, comp, usize, crc, start)
            scanned = scan_messages(records, 0, usize, wanted, registry,
                                    self._chunk_fail(start))
            group.add_records(start, group.size, usize)
            group.add_scanned(start, scanned, group.size)
            group.pieces.append(records)
            group.size += usize
            return group
        if crc and crc32(view[first:first + usize]) != crc:
            raise self._fail('chunk CRC mismatch', start)
        group.add_records(start, first, usize)
        group.add_scanned(start, scan_messages(view, first, first + usize, wanted, registry,
                                               self._chunk_fail(start)), 0)
        return group


def _release(mm: mmap.mmap, lo: int, hi: int):
    """Drop the mapped pages of ``[lo, hi)`` from the resident set (they stay cached)."""
    lo -= lo % mmap.PAGESIZE
    if hi > lo and hasattr(mm, 'madvise') and hasattr(mmap, 'MADV_DONTNEED'):
        mm.madvise(mmap.MADV_DONTNEED, lo, hi - lo)
