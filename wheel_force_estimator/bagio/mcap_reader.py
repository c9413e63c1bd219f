# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk payloads of an MCAP storage file, memory-mapped.

Chunks are located through the summary's chunk indexes and messages through each chunk's
message indexes; the records of all chunks in a ~64 MiB batch are checked with one vectorised
pass per channel, and every chunk's CRC is computed by a worker thread one batch ahead.
Batches go to the per-topic sinks of :mod:`.storage`.
"""
from concurrent.futures import ThreadPoolExecutor
import mmap
import os
from pathlib import Path
import struct
import sys
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.bagio.checksum import crc32
from wheel_force_estimator.bagio.fastcdr import gather_bytes
from wheel_force_estimator.bagio.fastpath import FastPathUnavailable
from wheel_force_estimator.core.errors import BagError

_MCAP_MAGIC = b'\x89MCAP0\r\n'
_FOOTER_LEN = 1 + 8 + 20 + 8  # opcode, length, footer fields, magic
# Message record: opcode(1) length(8) channel(2) sequence(4) log_time(8) publish_time(8)
_MSG_HEADER = 31
_RECORD_DTYPE = np.dtype({'names': ['opcode', 'length', 'channel'],
                          'formats': ['u1', '<u8', '<u2'], 'offsets': [0, 1, 9], 'itemsize': 11})
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


def _zstd_decompress(data: bytes) -> bytes:
    if sys.version_info >= (3, 14):
        from compression import zstd
        return zstd.decompress(data)
    try:
        from backports import zstd
        return zstd.decompress(data)
    except ImportError:
        import zstandard  # older rosbags releases depend on this one
        return zstandard.ZstdDecompressor().decompress(data)


def _lz4_decompress(data: bytes) -> bytes:
    from lz4.frame import decompress
    return decompress(data)


class McapFile:
    """Just enough of the MCAP format to pull message payloads out by channel in bulk."""

    def __init__(self, file: Path):
        self.file = file

    def _fail(self, what: str, offset: Optional[int] = None) -> BagError:
        where = f' at offset {offset}' if offset is not None else ''
        return BagError(f'{self.file}: corrupt or truncated mcap: {what}{where}')

    def read(self, topics: Sequence[str], collectors):
        try:
            with self.file.open('rb') as fh:
                return self._read(fh, topics, collectors)
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
        if summary_start == 0:
            raise FastPathUnavailable(f'{self.file}: mcap without summary')
        if not 8 <= summary_start <= size - _FOOTER_LEN:
            raise self._fail('summary offset out of range', size - _FOOTER_LEN)
        fh.seek(summary_start)
        summary = fh.read(size - _FOOTER_LEN - summary_start)
        schemas, channels, chunks, stats = self._summary(summary, summary_start)
        if not channels:
            raise FastPathUnavailable(f'{self.file}: mcap summary lists no channels')
        wanted = {}
        present = {}
        for cid, (schema_id, topic) in channels.items():
            msgtype = schemas.get(schema_id, '')
            if present.setdefault(topic, msgtype) != msgtype:
                raise BagError(f'{self.file}: topic {topic} recorded with two types '
                               f'{present[topic]} and {msgtype}')
            if topic in topics:
                wanted[cid] = (topic, msgtype)
        if wanted and (not chunks or (stats is None and any(not c[3] for c in chunks))):
            raise FastPathUnavailable(f'{self.file}: mcap without chunk or message indexes')
        counts = dict.fromkeys(wanted, 0)
        todo = [c for c in sorted(chunks, key=lambda c: c[0])
                if any(cid in wanted for cid in c[2])]
        for start, length, _, index_length, _ in todo:
            if start + length + index_length > size:
                raise self._fail('chunk beyond end of file', start)
        self._read_chunks(fh, todo, wanted, collectors, counts)
        if stats is not None and any(counts[c] != stats.get(c, 0) for c in wanted):
            # message indexes are optional in MCAP: without them we cannot find messages
            raise FastPathUnavailable(f'{self.file}: mcap message indexes incomplete')
        return present

    def _summary(self, data: bytes, base: int):
        schemas: Dict[int, str] = {}
        channels: Dict[int, Tuple[int, str]] = {}
        chunks = []
        stats = None
        pos = 0
        try:
            while pos < len(data):
                op, length = struct.unpack_from('<BQ', data, pos)
                body = pos + 9
                if body + length > len(data):
                    raise self._fail('summary record overruns the summary', base + pos)
                if op == 0x03:
                    sid, nlen = struct.unpack_from('<HI', data, body)
                    schemas[sid] = data[body + 6:body + 6 + nlen].decode()
                elif op == 0x04:
                    cid, sid, tlen = struct.unpack_from('<HHI', data, body)
                    channels[cid] = (sid, data[body + 8:body + 8 + tlen].decode())
                elif op == 0x08:
                    chunks.append(self._chunk_index(data, body))
                elif op == 0x0B:
                    (map_len,) = struct.unpack_from('<I', data, body + 42)
                    stats = dict(struct.iter_unpack('<HQ', data[body + 46:body + 46 + map_len]))
                pos = body + length
        except (struct.error, UnicodeDecodeError) as err:
            raise self._fail(f'unreadable summary ({err})', base + pos) from err
        return schemas, channels, chunks, stats

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
        if not chunks:
            return
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        batches = list(_batches(chunks))
        previous: List[tuple] = []
        previous_range = (0, 0)
        pool = ThreadPoolExecutor(max_workers=1)
        # The channels of a batch are checked and decoded in parallel (numpy's gathers,
        # comparisons and copies release the GIL); every sink exists before that starts.
        for topic, msgtype in wanted.values():
            collectors.sink(topic, msgtype)
        self._decoders = ThreadPoolExecutor(max_workers=decode_threads(len(wanted)))
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
            self._decoders.shutdown(wait=True, cancel_futures=True)
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
        pending: Dict[int, list] = {cid: [] for cid in wanted}
        for chunk in batch:
            start, length, index_offsets, index_length, _ = chunk
            rel = start - lo
            end = rel + length + index_length
            first, usize, crc, comp = self._chunk_header(view, rel, end, start)
            if comp:
                # decompressed records live in their own buffer: deliver what is pending
                # first so that storage order is kept
                self._deliver_all(buf, pending, wanted, collectors)
                records = self._decompress(view, first, comp, usize, crc, start)
                base = 0
            else:  # CRC checked by the caller
                records, base = buf, first
            for cid in index_offsets:
                if cid not in wanted:
                    continue
                log_time, offsets = self._message_index(
                    view, rel + index_offsets[cid] - start, rel + length, end, cid, start)
                if offsets.size and (offsets.min() < 0 or offsets.max() + _MSG_HEADER > usize):
                    raise self._fail(f'message offset outside chunk for channel {cid}', start)
                counts[cid] += len(offsets)
                pending[cid].append((log_time, base + offsets, base + usize, start))
            if comp:
                self._deliver_all(records, pending, wanted, collectors)
        self._deliver_all(buf, pending, wanted, collectors)

    def _chunk_header(self, view, rel: int, end: int, start: int):
        try:
            if view[rel] != 0x06:
                raise self._fail('chunk record expected', start)
            (rec_len, _, _, usize, crc, clen) = struct.unpack_from('<QQQQII', view, rel + 1)
            comp = bytes(view[rel + 41:rel + 41 + clen]).decode()
            (csize,) = struct.unpack_from('<Q', view, rel + 41 + clen)
        except (struct.error, UnicodeDecodeError) as err:
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
        try:
            if comp == 'zstd':
                data = _zstd_decompress(data)
            elif comp == 'lz4':
                data = _lz4_decompress(data)
            else:
                raise BagError(f'{self.file}: unsupported mcap chunk compression {comp!r}')
        except (ValueError, RuntimeError, OSError) as err:
            raise self._fail(f'chunk does not decompress ({err})', start) from err
        if len(data) != usize:
            raise self._fail(f'chunk holds {len(data)} bytes, header says {usize}', start)
        if crc and crc32(data) != crc:
            raise self._fail('chunk CRC mismatch', start)
        return np.frombuffer(data, np.uint8)

    def _message_index(self, view, pos: int, lo: int, hi: int, cid: int, start: int):
        try:
            if pos < lo:
                raise struct.error('before the end of the chunk')
            op, _, index_cid, arr_len = struct.unpack_from('<BQHI', view, pos)
        except struct.error as err:
            raise self._fail('message index out of range', start + pos - lo) from err
        if op != 0x07 or index_cid != cid or pos + 15 + arr_len > hi or arr_len % 16:
            raise self._fail(f'bad message index for channel {cid}', start + pos - lo)
        pairs = np.frombuffer(view, '<u8', count=arr_len // 8, offset=pos + 15)
        # a view (times and offsets are far below 2**63): _deliver_all copies what it keeps
        # before the batch's pages are released
        pairs = pairs.view(np.int64).reshape(-1, 2)
        return pairs[:, 0], pairs[:, 1]

    def _deliver_all(self, buf: np.ndarray, pending, wanted, collectors):
        """Check the pending message records of every channel and hand them to the sinks."""
        jobs = [(cid, self._decoders.submit(self._deliver, buf, cid, list(parts), wanted,
                                            collectors))
                for cid, parts in pending.items() if parts]
        for _, job in jobs:  # every job ends before an error (the first channel's) is raised
            job.exception()
        for cid, job in jobs:
            job.result()
            pending[cid].clear()

    def _deliver(self, buf: np.ndarray, cid: int, parts, wanted, collectors):
        """Check one channel's pending message records and hand them to its sink."""
        log_time, starts = (np.concatenate([p[i] for p in parts]) for i in (0, 1))
        ends = np.repeat([p[2] for p in parts], [len(p[1]) for p in parts])
        # One gather per message for the record header and the CDR header after it
        # (each pass over scattered messages is a cache miss per message); the CDR part
        # is only meaningful for payloads of >= 16 bytes, which is all its user reads.
        combined = starts.size and int(starts.max()) + _MSG_HEADER + 16 <= buf.size
        rows = gather_bytes(buf, starts, _MSG_HEADER + 16 if combined else 11)
        head = rows[:, :11].view(_RECORD_DTYPE)[:, 0]
        rec_len = head['length'].astype(np.int64)
        bad = head['opcode'] != 0x05
        bad |= head['channel'] != cid
        bad |= (rec_len < 22) | (rec_len > ends - starts - 9)
        if bad.any():
            i = int(np.argmax(bad))
            chunk = parts[int(np.searchsorted(np.cumsum([len(p[1]) for p in parts]), i,
                                              side='right'))][3]
            raise self._fail(f'bad message record for channel {cid} in chunk', chunk)
        topic, msgtype = wanted[cid]
        collectors.sink(topic, msgtype).add(
            log_time, rec_len - 22, buf, starts + _MSG_HEADER,
            head=rows[:, _MSG_HEADER:] if combined else None)


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
