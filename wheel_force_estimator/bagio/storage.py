# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bulk access to the raw message payloads of a rosbag2 recording (sqlite3 and mcap).

rosbags yields one ``(connection, timestamp, bytes)`` tuple per message, which caps a reader at
a few hundred thousand messages per second before any decoding.  Here payloads come out in
batches of numpy arrays: sqlite3 through aggregate queries over rowid ranges (SQLite itself
concatenates the blobs); mcap memory-mapped, chunks located through the summary's chunk
indexes and messages through each chunk's message indexes, the records of all chunks in a
~64 MiB batch checked with one vectorised pass per channel, and every chunk's CRC computed
by a worker thread one batch ahead.  Each batch is handed to a per-topic sink as (buffer,
payload starts, lengths), valid during the call: a raw collector here, or a decoder
(:class:`.fastcdr.TopicDecoder`) that reads only the fields it needs in place.

Topics are matched by name (and type), as ``ros2 bag`` does; QoS profiles are not compared.
Whatever this module cannot do in bulk (file/message compression, an mcap file without
summary or message indexes) raises :class:`FastPathUnavailable` and the caller uses the
generic rosbags reader instead.  Structural damage raises :class:`BagError` naming the file.
"""
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import mmap
from pathlib import Path
from pathlib import PurePath
import sqlite3
import struct
import sys
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.bagio.checksum import crc32
from wheel_force_estimator.bagio.fastcdr import gather_bytes
from wheel_force_estimator.core.errors import BagError
import yaml

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


class FastPathUnavailable(Exception):
    """The recording cannot be read in bulk here; use the generic rosbags reader."""


@dataclass(frozen=True)
class RawTopic:
    """
    All raw payloads of one topic, in (bag timestamp, storage) order.

    Attributes
    ----------
    msgtype : str
        Message type name.
    log_time_ns : numpy.ndarray, shape (n,), int64
        Bag (receive) timestamps.
    groups : tuple of (numpy.ndarray, numpy.ndarray)
        ``(positions, rows)`` per payload length: positions (k,) into the topic's message
        order and rows (k, L) uint8 payloads.

    """

    msgtype: str
    log_time_ns: np.ndarray
    groups: Tuple[Tuple[np.ndarray, np.ndarray], ...]

    @property
    def n(self) -> int:
        """Return the number of messages."""
        return len(self.log_time_ns)

    def payload(self, i: int) -> bytes:
        """Return the payload of message ``i`` (slow; for tests and small topics)."""
        for pos, rows in self.groups:
            hit = np.flatnonzero(pos == i)
            if hit.size:
                return rows[hit[0]].tobytes()
        raise IndexError(i)


@dataclass(frozen=True)
class BagLayout:
    """What metadata.yaml says about a rosbag2 directory (or a bare storage file)."""

    storage: str
    files: Tuple[Path, ...]
    topic_types: Dict[str, str]
    topic_counts: Dict[str, int]


def bag_layout(path: Path) -> BagLayout:
    """
    Describe a rosbag2 directory or a bare ``.mcap`` / ``.db3`` file.

    Raises
    ------
    FastPathUnavailable
        Not a rosbag2 recording this module reads in bulk (ROS 1 bag, compressed bag).
    BagError
        metadata.yaml is unreadable or lists files that are missing.

    """
    if path.is_file():
        storage = {'.mcap': 'mcap', '.db3': 'sqlite3'}.get(path.suffix)
        if storage is None:
            raise FastPathUnavailable(f'{path}: not a rosbag2 storage file')
        return BagLayout(storage, (path,), {}, {})
    meta_path = path / 'metadata.yaml'
    try:
        doc = yaml.safe_load(meta_path.read_text(encoding='utf-8'))
        info = doc['rosbag2_bagfile_information']
        storage = info['storage_identifier']
        files = tuple(path / PurePath(p).name for p in info['relative_file_paths'])
        mode = str(info.get('compression_mode') or '').lower()
        types, counts = {}, {}
        for entry in info.get('topics_with_message_count') or ():
            meta = entry['topic_metadata']
            types[meta['name']] = meta['type']
            counts[meta['name']] = counts.get(meta['name'], 0) + int(entry['message_count'])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as err:
        raise BagError(f'{path}: cannot read rosbag2 metadata.yaml: {err!r}') from err
    if mode not in ('', 'none'):
        raise FastPathUnavailable(f'{path}: compression mode {mode!r}')
    if storage not in ('mcap', 'sqlite3'):
        raise FastPathUnavailable(f'{path}: storage {storage!r}')
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise BagError(f'{path}: storage files listed in metadata.yaml are missing: {missing}')
    return BagLayout(storage, files, types, counts)


class _Collector:
    """Accumulates (log_time, length-grouped rows) batches of one topic across files/chunks."""

    def __init__(self, msgtype: str):
        self.msgtype = msgtype
        self.times: List[np.ndarray] = []
        self.rows: Dict[int, List[Tuple[int, np.ndarray, np.ndarray]]] = {}
        self.count = 0

    def add(self, log_time: np.ndarray, lengths: np.ndarray, buf: np.ndarray,
            starts: np.ndarray, head: Optional[np.ndarray] = None):
        """Add a batch: payload ``i`` is ``buf[starts[i]:starts[i] + lengths[i]]``."""
        del head  # raw payloads are kept whole
        for length in np.unique(lengths):
            idx = np.flatnonzero(lengths == length)
            self.rows.setdefault(int(length), []).append(
                (self.count, idx, gather_bytes(buf, starts[idx], int(length))))
        self.times.append(np.asarray(log_time, np.int64))
        self.count += len(log_time)

    def finish(self) -> RawTopic:
        times = np.concatenate(self.times) if self.times else np.zeros(0, np.int64)
        order = np.argsort(times, kind='stable')
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        groups = []
        for length in sorted(self.rows):
            parts = self.rows[length]
            pos = np.concatenate([base + idx for base, idx, _ in parts])
            rows = parts[0][2] if len(parts) == 1 else np.concatenate([r for _, _, r in parts])
            groups.append((rank[pos], rows))
        return RawTopic(self.msgtype, times[order], tuple(groups))


class _Sinks(dict):
    """Topic -> sink, created on first use (raw collector unless ``make_sink`` says else)."""

    def __init__(self, make_sink, expected_counts: Optional[Dict[str, int]] = None):
        super().__init__()
        self.make_sink = make_sink
        self.expected_counts = expected_counts or {}

    def sink(self, topic: str, msgtype: str):
        if topic not in self:
            made = self.make_sink(topic, msgtype) if self.make_sink else None
            if made is not None and hasattr(made, 'reserve') and (
                    self.expected_counts.get(topic, 0) > 0):
                made.reserve(self.expected_counts[topic])
            self[topic] = made if made is not None else _Collector(msgtype)
        return self[topic]


def read_raw_topics(path: Path, topics: Sequence[str], make_sink=None):
    """
    Read every payload of the given topics of a rosbag2 recording in bulk.

    Parameters
    ----------
    path : pathlib.Path
        rosbag2 directory, or a bare ``.mcap`` / ``.db3`` file.
    topics : sequence of str
        Topic names; topics absent from the storage are absent from the result.
    make_sink : callable, optional
        ``make_sink(topic, msgtype)`` returns the object receiving that topic's batches
        (``add(log_time, lengths, buf, starts, head=None)`` with payload ``i`` at
        ``buf[starts[i]:starts[i] + lengths[i]]``, valid only during the call, optionally its
        first 16 bytes already gathered in ``head`` (k, 16), and
        ``finish()``; e.g. a decoder), or None to keep the raw payloads.

    Returns
    -------
    present : dict
        Every topic in the storage: name to message type.
    raw : dict
        Requested topic name to :class:`RawTopic` (or the sink's ``finish()`` result).

    Raises
    ------
    FastPathUnavailable
        Use the generic reader for this recording.
    BagError
        Truncated or corrupt storage (file and offset named), or message counts that
        disagree with metadata.yaml.

    """
    layout = bag_layout(path)
    collectors = _Sinks(make_sink, layout.topic_counts)
    present: Dict[str, str] = {}
    for file in layout.files:
        if layout.storage == 'sqlite3':
            found = _read_sqlite(file, topics, collectors)
        else:
            found = _McapFile(file).read(topics, collectors)
        for name, msgtype in found.items():
            if present.setdefault(name, msgtype) != msgtype:
                raise BagError(f'{path}: topic {name} recorded with two types '
                               f'{present[name]} and {msgtype}')
    raw = {name: col.finish() for name, col in collectors.items()}
    for name in topics:
        if name in layout.topic_counts:
            got = raw[name].n if name in raw else 0
            if got != layout.topic_counts[name]:
                raise BagError(
                    f'{path}: metadata.yaml lists {layout.topic_counts[name]} messages on '
                    f'{name} but the storage holds {got}: truncated or inconsistent bag')
    return present, raw


# Rows per sqlite3 query: bounds memory and stays far below SQLITE_MAX_LENGTH (1e9 bytes)
# for the concatenated payloads of one batch.
_SQLITE_BATCH = 20000
# Read pages through mmap instead of copying them into SQLite's page cache.
_SQLITE_MMAP = 1 << 30


def _read_sqlite(file: Path, topics: Sequence[str], collectors: '_Sinks'):
    try:
        con = sqlite3.connect(f'file:{file}?immutable=1', uri=True, check_same_thread=False)
    except sqlite3.Error as err:
        raise BagError(f'{file}: cannot open sqlite3 storage: {err}') from err
    try:
        rows = con.execute('SELECT id, name, type FROM topics').fetchall()
        present = {}
        for _, name, typ in rows:
            if present.setdefault(name, typ) != typ:
                raise BagError(f'{file}: topic {name} recorded with two types '
                               f'{present[name]} and {typ}')
        ids = {tid: (name, typ) for tid, name, typ in rows if name in topics}
        if ids:
            _read_sqlite_messages(con, file, ids, collectors)
    except sqlite3.Error as err:
        raise BagError(f'{file}: corrupt sqlite3 storage: {err}') from err
    finally:
        con.close()
    return present


def _read_sqlite_messages(con, file, ids, collectors):
    # One pass per batch: SQLite concatenates the payloads itself and lists (topic id, length)
    # packed in one integer and the timestamps as text, so Python never touches a row.  All
    # aggregates step over the same rows in the same order (an ascending rowid range scan),
    # which keeps them consistent and gives rosbag2's (timestamp, id) order after a stable
    # sort on timestamp.  Fewer, integer-only group_concats are the cheapest form found.
    query = (
        "SELECT CAST(group_concat(data, x'') AS BLOB), "
        "group_concat((topic_id << 32) + length(data), ' '), group_concat(timestamp, ' ') "
        f"FROM messages WHERE id >= ? AND id < ? AND topic_id IN ({','.join('?' * len(ids))})")
    con.execute(f'PRAGMA mmap_size = {_SQLITE_MMAP}')

    def fetch(first):
        """Return one batch's (blob, packed, stamps) and the first id of the next batch."""
        row = con.execute(query, (first, first + _SQLITE_BATCH, *ids)).fetchone()
        # ids are normally 1..n; jumping to the next existing id also copes with holes
        following = con.execute('SELECT min(id) FROM messages WHERE id >= ?',
                                (first + _SQLITE_BATCH,)).fetchone()[0]
        return row, following

    # SQLite releases the GIL while it scans: a worker runs the next batch's query while this
    # thread decodes the current one (only the worker touches the connection meanwhile).
    with ThreadPoolExecutor(max_workers=1) as pool:
        first = con.execute('SELECT min(id) FROM messages').fetchone()[0]
        upcoming = pool.submit(fetch, first) if first is not None else None
        while upcoming is not None:
            (blob, *columns), following = upcoming.result()
            upcoming = pool.submit(fetch, following) if following is not None else None
            if blob is not None:
                _deliver_sqlite(file, ids, collectors, blob, columns)


def _deliver_sqlite(file, ids, collectors, blob: bytes, columns) -> None:
    packed, stamp = (np.fromstring(c, np.int64, sep=' ') for c in columns)
    lengths = packed & 0xFFFFFFFF
    if packed.size != stamp.size or lengths.sum() != len(blob):
        raise BagError(f'{file}: corrupt sqlite3 storage: payload lengths do not add up')
    table = np.stack([packed >> 32, stamp, lengths], axis=1)
    buf = np.frombuffer(blob, np.uint8)
    offsets = np.concatenate(([0], np.cumsum(table[:, 2])[:-1]))
    for tid, (name, typ) in ids.items():
        sel = np.flatnonzero(table[:, 0] == tid)
        if sel.size:
            collectors.sink(name, typ).add(table[sel, 1], table[sel, 2], buf, offsets[sel])


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


class _McapFile:
    """Just enough of the MCAP format to pull message payloads out by channel in bulk."""

    def __init__(self, file: Path):
        self.file = file

    def _fail(self, what: str, offset: Optional[int] = None) -> BagError:
        where = f' at offset {offset}' if offset is not None else ''
        return BagError(f'{self.file}: corrupt or truncated mcap: {what}{where}')

    def read(self, topics: Sequence[str], collectors: '_Sinks'):
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
        for cid, parts in pending.items():
            if not parts:
                continue
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
            parts.clear()


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
