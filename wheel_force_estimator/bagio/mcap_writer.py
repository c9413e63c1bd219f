# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Write a rosbag2 MCAP storage file in bulk.

Message records of one sample (all dense topics) have a fixed total size, so a chunk is a
(samples, record bytes) uint8 matrix: the constant bytes (opcode, record length, channel id,
payload template) are laid down once in a reusable block, and per chunk only sequence, log /
publish time and the payload fields are stamped in through strided numpy views.  The few
sparse messages (events) are spliced in between sample rows.  Message indexes are computed
from the same arithmetic, so nothing is ever handled one message at a time.

File layout (MCAP spec, profile ``ros2``), as rosbags' ``McapWriter`` lays it out except that
Schema and Channel records precede the first chunk instead of sitting inside it (both are
allowed): magic, Header, Schemas, Channels, then per chunk a Chunk record (zstd or
uncompressed, CRC32 of its uncompressed records) followed by one MessageIndex per channel in
it, the ``rosbag2`` Metadata record, DataEnd (data section CRC 0 = not computed, the C++
writer's default), and the summary (Schemas, Channels, ChunkIndexes, MetadataIndex, Statistics),
SummaryOffsets, Footer (with summary CRC) and magic.

``plan`` is :class:`.plan.BagPlan` (duck-typed here to keep the import one-way).
"""
from collections import deque
from concurrent.futures import Future
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import struct
import sys
from typing import BinaryIO, Callable, Dict, List, Optional, Tuple

import numpy as np

from wheel_force_estimator.bagio.checksum import crc32

MAGIC = b'\x89MCAP0\r\n'
PROFILE = 'ros2'
LIBRARY = 'wheel_force_estimator bagio'
# Uncompressed bytes per chunk: large enough that per-chunk Python work vanishes, small
# enough that readers (which load a chunk at a time) stay light.  rosbags uses 1 MiB.
CHUNK_BYTES = 4 << 20
# Default chunk compression, '' (none, rosbags' and ros2 bag's default) or 'zstd'.  zstd at
# level -3 packs ~1.4 GB/s per core (in a worker thread, overlapped with assembly) to 29 %
# (WrenchStamped) - 40 % (Imu) of the size: constant headers, frame ids, covariances.  It pays
# whenever new page-cache memory or the disk is slower than that: on the benchmark VM each
# fresh GB costs ~2 s of first-touch page faults, so `wheel-force predict` compresses.
COMPRESSION = ''
ZSTD_LEVEL = -3
# Chunks compressed ahead of the one being written (memory: this many x CHUNK_BYTES).
_CHUNKS_AHEAD = 2
MESSAGE_ENCODING = 'cdr'
SCHEMA_ENCODING = 'ros2msg'
# Message record: opcode(1) length(8) channel(2) sequence(4) log_time(8) publish_time(8)
MESSAGE_HEADER = 31

_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
_MESSAGE_INDEX, _CHUNK_INDEX, _STATISTICS, _METADATA = 0x07, 0x08, 0x0B, 0x0C
_METADATA_INDEX, _SUMMARY_OFFSET, _DATA_END = 0x0D, 0x0E, 0x0F


def _zstd_compressor() -> Optional[Callable[[bytes], bytes]]:
    """Return a zstd compressor from whichever module rosbags' environment provides."""
    if sys.version_info >= (3, 14):
        from compression import zstd
    else:
        try:
            from backports import zstd  # a rosbags dependency before Python 3.14
        except ImportError:
            return None

    def compress(data: bytes) -> bytes:
        return zstd.compress(data, level=ZSTD_LEVEL)
    return compress


def _string(text: str) -> bytes:
    data = text.encode()
    return struct.pack('<I', len(data)) + data


def _record(opcode: int, body: bytes) -> bytes:
    return struct.pack('<BQ', opcode, len(body)) + body


def _column(block: np.ndarray, offset: int, dtype: str, shape=None) -> np.ndarray:
    """Strided view of one fixed-offset field in every row of a (rows, width) uint8 block."""
    return np.ndarray(shape or (block.shape[0],), dtype, block, offset, (block.strides[0],))


class _Output:
    """File handle that keeps its own position (the offsets MCAP indexes point to)."""

    def __init__(self, fh: BinaryIO):
        self.fh = fh
        self.pos = 0

    def write(self, data) -> int:
        """Write bytes or a contiguous array; return the offset it starts at."""
        start = self.pos
        self.fh.write(data)
        self.pos += memoryview(data).nbytes
        return start


class _Chunks:
    """Chunk assembly for one plan: the reusable constant block and the message indexes."""

    def __init__(self, plan, channel_ids: List[int]):
        self.plan = plan
        self.channel_ids = channel_ids
        lengths = [topic.length for topic in plan.dense]
        self.columns = np.concatenate(([0], np.cumsum([MESSAGE_HEADER + n for n in lengths])))
        self.row_bytes = int(self.columns[-1])
        n = plan.stamp_ns.size
        self.rows_per_chunk = max(1, CHUNK_BYTES // max(self.row_bytes, 1))
        self.block = np.zeros((min(self.rows_per_chunk, n), self.row_bytes), np.uint8)
        for k, topic in enumerate(plan.dense if n else ()):
            col = int(self.columns[k])
            self.block[:, col] = _MESSAGE
            _column(self.block, col + 1, '<u8')[...] = MESSAGE_HEADER - 9 + topic.length
            _column(self.block, col + 9, '<u2')[...] = channel_ids[k]
            self.block[:, col + MESSAGE_HEADER:col + MESSAGE_HEADER + topic.length] = (
                topic.template)
        self.sparse_records = []
        seq: Dict[int, int] = {}
        for index, t, payload in plan.sparse:
            seq[index] = seq.get(index, -1) + 1
            body = struct.pack('<HIQQ', channel_ids[index], seq[index] & 0xFFFFFFFF, t, t)
            self.sparse_records.append(_record(_MESSAGE, body + payload))

    def ranges(self):
        """Yield ``(first, stop, sparse indexes)`` per chunk, covering every message once."""
        n = self.plan.stamp_ns.size
        at = self.plan.sparse_at
        bounds = list(range(0, n, self.rows_per_chunk)) + [n]
        if n == 0:
            bounds = [0, 0] if len(at) else [0]
        for i, (first, stop) in enumerate(zip(bounds[:-1], bounds[1:])):
            last = i == len(bounds) - 2
            sel = np.flatnonzero((at >= first) & ((at < stop) | (last & (at == stop))))
            yield first, stop, sel

    def fill(self, first: int, stop: int) -> np.ndarray:
        """Stamp sequence, times and payload fields of samples ``first..stop-1``."""
        block = self.block[:stop - first]
        if stop == first:
            return block
        stamp = self.plan.stamp_ns[first:stop]
        # sequence = per-channel message counter (one message per sample on dense channels)
        seq = (np.arange(first, stop, dtype=np.int64) & 0xFFFFFFFF).astype('<u4')
        for k, topic in enumerate(self.plan.dense):
            col = int(self.columns[k])
            _column(block, col + 11, '<u4')[...] = seq
            _column(block, col + 15, '<u8')[...] = stamp
            _column(block, col + 23, '<u8')[...] = stamp
            topic.fill(block, col + MESSAGE_HEADER, first, stop)
        return block

    def assemble(self, first: int, stop: int, sel: np.ndarray):
        """
        Return the pieces of one chunk's records and each channel's (log time, offset) pairs.

        Sparse message ``s`` goes right before sample ``sparse_at[s]``; the offsets of the
        dense messages after it shift by its record size.
        """
        block = self.fill(first, stop)
        at = self.plan.sparse_at[sel]
        sizes = np.array([len(self.sparse_records[s]) for s in sel], np.int64)
        cum = np.concatenate(([0], np.cumsum(sizes)))
        pieces = []
        cur = first
        for j, s in enumerate(sel):
            pieces.append(block[cur - first:at[j] - first])
            pieces.append(self.sparse_records[s])
            cur = int(at[j])
        pieces.append(block[cur - first:])
        index: Dict[int, List[Tuple[np.ndarray, np.ndarray]]] = {}
        rows = np.arange(stop - first, dtype=np.int64)
        base = rows * self.row_bytes
        if sel.size:
            base += cum[np.searchsorted(at, rows + first, side='right')]
        stamp = self.plan.stamp_ns[first:stop]
        for k in range(len(self.plan.dense)):
            if stop > first:
                index[self.channel_ids[k]] = [(stamp, base + int(self.columns[k]))]
        for j, s in enumerate(sel):
            index.setdefault(self.channel_ids[self.plan.sparse[s][0]], []).append((
                np.array([self.plan.sparse[s][1]], np.int64),
                np.array([(at[j] - first) * self.row_bytes + cum[j]], np.int64)))
        return pieces, index


def write_mcap(file: Path, plan, version: int, metadata_text: str,
               compression: str = COMPRESSION) -> None:
    """
    Write ``plan`` as a new MCAP file (refused if it exists).

    Parameters
    ----------
    file : pathlib.Path
        The ``.mcap`` file.
    plan : BagPlan
        Connections and messages.
    version : int
        rosbag2 version (only recorded in the ``rosbag2`` metadata record's text).
    metadata_text : str
        ``rosbag2_bagfile_information`` YAML (rosbags stores it in a ``rosbag2`` Metadata
        record under ``serialized_metadata``).
    compression : {'zstd', ''}
        Chunk compression; zstd falls back to none when no zstd module is installed.

    Raises
    ------
    ValueError
        Unknown compression.
    OSError
        The file exists or cannot be written.

    """
    del version  # part of metadata_text already; the signature is shared with sqlite3
    if compression not in ('zstd', ''):
        raise ValueError(f'{file}: unknown mcap chunk compression {compression!r}')
    with file.open('xb') as fh:
        _write(_Output(fh), plan, metadata_text, compression)


def _write(out: _Output, plan, metadata_text: str, compression: str) -> None:
    out.write(MAGIC)
    out.write(_record(_HEADER, _string(PROFILE) + _string(LIBRARY)))
    schema_ids: Dict[str, int] = {}
    schemas, channels = [], []
    for conn in plan.connections:
        if conn.msgtype not in schema_ids:
            schema_ids[conn.msgtype] = len(schema_ids) + 1
            schemas.append(_record(_SCHEMA, struct.pack('<H', schema_ids[conn.msgtype])
                                   + _string(conn.msgtype) + _string(SCHEMA_ENCODING)
                                   + _string(conn.msgdef)))
    channel_ids = list(range(1, len(plan.connections) + 1))
    for cid, conn in zip(channel_ids, plan.connections):
        meta = _string('offered_qos_profiles') + _string(conn.qos)
        channels.append(_record(_CHANNEL, struct.pack('<HH', cid, schema_ids[conn.msgtype])
                                + _string(conn.topic) + _string(MESSAGE_ENCODING)
                                + struct.pack('<I', len(meta)) + meta))
    for rec in schemas + channels:
        out.write(rec)
    chunks = _Chunks(plan, channel_ids)
    compress = _zstd_compressor() if compression == 'zstd' else None
    if compress is None:
        compression = ''
    chunk_indexes = []
    if compression:
        # CRC and compression of a chunk (both release the GIL) run in a worker while the
        # next chunk is assembled; the reused assembly block is copied out first.
        with ThreadPoolExecutor(max_workers=1) as pool:
            queued: deque = deque()
            for r in chunks.ranges():
                pieces, index = chunks.assemble(*r)
                data = b''.join(pieces)
                queued.append((pool.submit(_crc_and_compress, data, compress), len(data),
                               index))
                if len(queued) > _CHUNKS_AHEAD:
                    chunk_indexes.append(_write_chunk(out, compression, *queued.popleft()))
            while queued:
                chunk_indexes.append(_write_chunk(out, compression, *queued.popleft()))
    else:
        for r in chunks.ranges():
            pieces, index = chunks.assemble(*r)
            size = sum(memoryview(p).nbytes for p in pieces)
            crc = 0
            for piece in pieces:
                crc = crc32(piece, crc)
            chunk_indexes.append(_write_chunk(out, compression, (crc, pieces), size, index))
    metadata_start = out.write(_record(_METADATA, _string('rosbag2') + _map(
        {'serialized_metadata': metadata_text})))
    metadata_length = out.pos - metadata_start
    out.write(_record(_DATA_END, struct.pack('<I', 0)))

    summary = bytearray()
    groups = []  # (opcode, start, length) for the summary offsets
    counts = plan.message_counts()
    start_time, end_time = plan.time_range()
    stats = struct.pack('<QHIIIIQQ', sum(counts), len(schemas), len(channels), 0, 1,
                        len(chunk_indexes), start_time, end_time)
    channel_counts = b''.join(struct.pack('<HQ', cid, n) for cid, n in zip(channel_ids, counts))
    for opcode, records in (
            (_SCHEMA, schemas), (_CHANNEL, channels),
            (_CHUNK_INDEX, [_record(_CHUNK_INDEX, c) for c in chunk_indexes]),
            (_METADATA_INDEX, [_record(_METADATA_INDEX, struct.pack(
                '<QQ', metadata_start, metadata_length) + _string('rosbag2'))]),
            (_STATISTICS, [_record(_STATISTICS, stats + struct.pack(
                '<I', len(channel_counts)) + channel_counts)])):
        if records:
            groups.append((opcode, out.pos + len(summary), sum(len(r) for r in records)))
            summary += b''.join(records)
    summary_start = out.pos
    offsets_start = summary_start + len(summary)
    for opcode, start, length in groups:
        summary += _record(_SUMMARY_OFFSET, struct.pack('<BQQ', opcode, start, length))
    footer = struct.pack('<BQQQ', _FOOTER, 8 + 8 + 4, summary_start, offsets_start)
    crc = crc32(footer, crc32(summary))
    out.write(bytes(summary) + footer + struct.pack('<I', crc) + MAGIC)


def _map(entries: Dict[str, str]) -> bytes:
    body = b''.join(_string(k) + _string(v) for k, v in entries.items())
    return struct.pack('<I', len(body)) + body


def _crc_and_compress(data: bytes, compress) -> Tuple[int, List[bytes]]:
    return crc32(data), [compress(data)]


def _write_chunk(out: _Output, compression: str, stored_pieces, size: int, index) -> bytes:
    """
    Write one Chunk record and its MessageIndex records; return the ChunkIndex body.

    ``stored_pieces`` is ``(crc of the uncompressed records, pieces as stored)`` or a future
    of it; ``size`` is the uncompressed size.
    """
    if isinstance(stored_pieces, Future):
        stored_pieces = stored_pieces.result()
    crc, pieces = stored_pieces
    stored = sum(memoryview(p).nbytes for p in pieces)
    times = [t for pairs in index.values() for t, _ in pairs if t.size]
    start_time = min(int(t.min()) for t in times) if times else 0
    end_time = max(int(t.max()) for t in times) if times else 0
    body_head = struct.pack('<QQQI', start_time, end_time, size, crc) + _string(compression)
    chunk_start = out.write(_record_head(_CHUNK, len(body_head) + 8 + stored) + body_head
                            + struct.pack('<Q', stored))
    for piece in pieces:
        if memoryview(piece).nbytes:
            out.write(piece)
    chunk_length = out.pos - chunk_start
    index_offsets = []
    for cid in sorted(index):
        parts = index[cid]
        pairs = np.empty((sum(t.size for t, _ in parts), 2), '<u8')
        pairs[:, 0] = np.concatenate([t for t, _ in parts])
        pairs[:, 1] = np.concatenate([o for _, o in parts])
        if len(parts) > 1:  # keep each index in record order
            pairs = pairs[np.argsort(pairs[:, 1], kind='stable')]
        head = _record_head(_MESSAGE_INDEX, 2 + 4 + pairs.nbytes)
        index_offsets.append((cid, out.write(head + struct.pack('<HI', cid, pairs.nbytes))))
        out.write(pairs)
    index_length = out.pos - chunk_start - chunk_length
    offsets = b''.join(struct.pack('<HQ', cid, off) for cid, off in index_offsets)
    return (struct.pack('<QQQQI', start_time, end_time, chunk_start, chunk_length, len(offsets))
            + offsets + struct.pack('<Q', index_length) + _string(compression)
            + struct.pack('<QQ', stored, size))


def _record_head(opcode: int, length: int) -> bytes:
    return struct.pack('<BQ', opcode, length)
