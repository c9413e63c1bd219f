# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Valid bags other tools write (issue #18), read identically to the original on both paths.

Each bag is our own short recording rewritten by an independent writer: the official ``mcap``
package (chunk indexes without message indexes, unchunked, small chunks, lz4/zstd, foreign
protobuf channels) or rosbags (jittered receive order, message-compressed sqlite3 with a
topic of an unknown type and no definition).  Every case is read with the bulk path and the
fallback path (``bulk=False``) and compared bit for bit with the original recording.
"""
from pathlib import Path

from mcap.reader import make_reader
from mcap.records import MessageIndex
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType
from mcap.writer import IndexType
from mcap.writer import Writer as McapWriter
import numpy as np
import pytest
from rosbags.rosbag2 import CompressionFormat
from rosbags.rosbag2 import CompressionMode
from rosbags.rosbag2 import Reader as Reader2
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Rosbag2Writer

from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.bagio.order import MAX_REORDER_NS
from wheel_force_estimator.core.errors import BagError

N = 600
PERIOD_NS = 1_953_125  # 512 Hz
T0_NS = 7_000_000_000


@pytest.fixture(scope='module')
def original(tmp_path_factory):
    rng = np.random.default_rng(18)
    stamp = T0_NS + PERIOD_NS * np.arange(N, dtype=np.int64)
    path = write_recording(tmp_path_factory.mktemp('orig') / 'bag', stamp,
                           rng.standard_normal((12, N)), 1e3 * rng.standard_normal((12, N)),
                           events=[(int(stamp[7]), 'belgian_block')], storage='mcap')
    return path, read_recording(path)


def _same(rec, ref):
    assert len(rec.segments) == len(ref.segments)
    for a, b in zip(rec.segments, ref.segments):
        assert np.array_equal(a.stamp_ns, b.stamp_ns)
        assert np.array_equal(a.accel_mps2.view(np.int64), b.accel_mps2.view(np.int64))
        assert np.array_equal(a.force_n.view(np.int64), b.force_n.view(np.int64))
    assert rec.events == ref.events


def _read_both(path, ref):
    out = []
    for bulk in (True, False):
        rec = read_recording(path, bulk=bulk)
        _same(rec, ref)
        out.append(rec)
    return out


def _rewrite_mcap(src_bag: Path, out_dir: Path, foreign_every=0, **writer_args) -> Path:
    """Copy every message with the official mcap writer (optionally adding a protobuf topic)."""
    out_dir.mkdir()
    out = out_dir / 'rewritten.mcap'
    with next(src_bag.glob('*.mcap')).open('rb') as fi, out.open('wb') as fo:
        reader = make_reader(fi)
        writer = McapWriter(fo, **writer_args)
        writer.start('ros2', '')
        summary = reader.get_summary()
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data)
                   for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                 schemas[c.schema_id], c.metadata)
                    for cid, c in summary.channels.items()}
        if foreign_every:
            proto = writer.register_channel(
                '/camera/detections', 'protobuf',
                writer.register_schema('foxglove.SceneUpdate', 'protobuf', b'\x0a\x00'))
        for i, (_, channel, msg) in enumerate(reader.iter_messages(log_time_order=False)):
            writer.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time,
                               msg.sequence)
            if foreign_every and i % foreign_every == 0:
                writer.add_message(proto, msg.log_time, b'\x08\x96\x01', msg.publish_time)
        writer.finish()
    return out


@pytest.mark.parametrize('compression', [CompressionType.ZSTD, CompressionType.LZ4,
                                         CompressionType.NONE], ids=['zstd', 'lz4', 'none'])
def test_chunk_index_without_message_indexes(tmp_path, original, compression):
    # index_types=CHUNK: the chunks are listed, the messages are not (MCAP makes message
    # indexes optional).  Before #18 this read 0 messages and failed.
    path = _rewrite_mcap(original[0], tmp_path / 'b', index_types=IndexType.CHUNK,
                         compression=compression, chunk_size=16 << 10)
    with path.open('rb') as fh:
        assert not any(isinstance(r, MessageIndex) for r in StreamReader(fh).records)
    _read_both(path, original[1])


@pytest.mark.parametrize('chunk_size', [4 << 10, 64 << 10])
@pytest.mark.parametrize('compression', [CompressionType.ZSTD, CompressionType.LZ4],
                         ids=['zstd', 'lz4'])
def test_small_chunks(tmp_path, original, compression, chunk_size):
    path = _rewrite_mcap(original[0], tmp_path / 'b', compression=compression,
                         chunk_size=chunk_size)
    bulk, _ = _read_both(path, original[1])
    assert bulk.n_bulk == 8 * N  # decoded in bulk, not handed to a slower path


def test_unchunked_mcap_with_a_protobuf_channel(tmp_path, original):
    # Before #18: KeyError 'protobuf'.  The foreign channel is never decoded, only listed.
    path = _rewrite_mcap(original[0], tmp_path / 'b', foreign_every=25, use_chunking=False)
    for rec in _read_both(path, original[1]):
        assert rec.skipped_topics == (
            ('/camera/detections', 'foxglove.SceneUpdate (protobuf encoding)'),)
        assert '/camera/detections (foxglove.SceneUpdate (protobuf encoding))' in rec.summary()


def test_mcap_without_summary(tmp_path, original):
    path = _rewrite_mcap(original[0], tmp_path / 'b', use_summary_offsets=False,
                         use_statistics=False, index_types=IndexType.NONE,
                         repeat_channels=False, repeat_schemas=False)
    _read_both(path, original[1])


def _message_indexes(path: Path):
    """Offsets (in the file) of every MessageIndex record."""
    data = path.read_bytes()
    pos, found = 8, []
    while pos < len(data) - 8:
        op, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], 'little')
        if op == 0x07:
            found.append(pos)
        if op == 0x0F:  # data end
            break
        pos += 9 + length
    return data, found


# Byte offsets inside a MessageIndex record: opcode, channel id, array length, first log
# time, first message offset.
@pytest.mark.parametrize('where', [0, 9, 11, 15, 23],
                         ids=['opcode', 'channel', 'array_length', 'log_time', 'offset'])
def test_flipped_byte_in_lz4_message_index(tmp_path, original, where):
    # Message indexes lie outside the chunk CRC: a damaged one must not hide intact
    # messages.  The chunk (CRC checked) is read through its own records instead.
    path = _rewrite_mcap(original[0], tmp_path / 'b', compression=CompressionType.LZ4,
                         chunk_size=8 << 10)
    data, indexes = _message_indexes(path)
    damaged = bytearray(data)
    target = indexes[len(indexes) // 2] + where
    damaged[target] ^= 0x5A
    path.write_bytes(bytes(damaged))
    _read_both(path, original[1])


def test_flipped_byte_in_chunk_data_still_fails_with_offset(tmp_path, original):
    # Really broken input: the chunk CRC names the chunk whatever the indexes say.
    path = _rewrite_mcap(original[0], tmp_path / 'b', compression=CompressionType.NONE,
                         index_types=IndexType.CHUNK, chunk_size=8 << 10)
    with path.open('rb') as fh:
        chunk_index = make_reader(fh).get_summary().chunk_indexes[2]
    damaged = bytearray(path.read_bytes())
    damaged[chunk_index.chunk_start_offset + chunk_index.chunk_length - 20] ^= 0x01
    path.write_bytes(bytes(damaged))
    for bulk in (True, False):
        with pytest.raises(BagError, match=rf'{path}: corrupt or truncated mcap: chunk CRC '
                                           rf'mismatch at offset '
                                           rf'{chunk_index.chunk_start_offset}'):
            read_recording(path, bulk=bulk)


def _small_zstd_chunks(tmp_path, original, **writer_args):
    path = _rewrite_mcap(original[0], tmp_path / 'b', compression=CompressionType.ZSTD,
                         chunk_size=4 << 10, **writer_args)
    with path.open('rb') as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) > 50
    return path, chunks[len(chunks) // 2]


# Chunk record: opcode(1) length(8) start/end time(16) uncompressed size(8) CRC(4) ...
@pytest.mark.parametrize('field, at, fault', [
    ('crc', 33, 'chunk CRC mismatch'),
    ('uncompressed_size', 25, r'chunk holds \d+ bytes, header says \d+'),
    ('compressed_data', -30, r'chunk (CRC mismatch|does not decompress \(.*\))'),
])
def test_damaged_small_zstd_chunk_is_named(tmp_path, original, field, at, fault):
    # The chunks of a run are decompressed in one call; a damaged one is then found chunk by
    # chunk and named as before (#18 item 4).
    path, chunk = _small_zstd_chunks(tmp_path, original)
    damaged = bytearray(path.read_bytes())
    start = chunk.chunk_start_offset
    damaged[start + at if at > 0 else start + chunk.chunk_length + at] ^= 0x01
    path.write_bytes(bytes(damaged))
    with pytest.raises(BagError, match=rf'{path}: corrupt or truncated mcap: {fault} at offset '
                                       rf'{start}$'):
        read_recording(path)


def test_small_zstd_chunks_without_crcs(tmp_path, original):
    # no CRC to check each chunk's place in a joined decompression: decoded chunk by chunk
    path, _ = _small_zstd_chunks(tmp_path, original, enable_crcs=False)
    bulk, _ = _read_both(path, original[1])
    assert bulk.n_bulk == 8 * N


def test_truncated_unchunked_mcap_names_the_offset(tmp_path, original):
    path = _rewrite_mcap(original[0], tmp_path / 'b', use_chunking=False)
    data = path.read_bytes()
    # keep the footer but cut the data section in the middle of a message record
    cut = data[:len(data) // 2] + data[-37:]
    path.write_bytes(cut)
    for bulk in (True, False):
        with pytest.raises(BagError, match=rf'{path}: corrupt or truncated mcap: .* at offset '
                                           r'\d+'):
            read_recording(path, bulk=bulk)


def _copy_rosbag2(src: Path, dst: Path, storage: str, log_time=None, compression=None,
                  foreign=False) -> Path:
    """Rewrite a rosbag2 with rosbags' Writer, optionally with other receive times."""
    writer = Rosbag2Writer(dst, version=9, storage_plugin=(
        StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3))
    if compression is not None:
        writer.set_compression(compression, CompressionFormat.ZSTD)
    with Reader2(src) as reader, writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data,
                                             rihs01=c.digest)
                 for c in reader.connections}
        if foreign:
            other = writer.add_connection('/vendor/blob', 'vendor_msgs/msg/Unknown', msgdef='',
                                          rihs01='RIHS01_' + '0' * 64)
        msgs = []
        for k, (conn, t, data) in enumerate(reader.messages()):
            msgs.append((log_time(conn.topic, k, t) if log_time else t, k, conns[conn.id], data))
            if foreign and k % 40 == 0:
                msgs.append((t, k, other, b'\x00\x01\x00\x00\xde\xad'))
        for t, _, conn, data in sorted(msgs, key=lambda m: (m[0], m[1])):
            writer.write(conn, t, data)
    return dst


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_receive_order_jittered_within_delivery(tmp_path, original, storage):
    # Receive times jittered by up to 40 ms (20 periods): the storage order is no longer the
    # stamp order (before #18: "stamp goes backwards").  Each topic is put in stamp order.
    rng = np.random.default_rng(5)
    jitter = rng.integers(0, 40_000_000, 100_000)

    def late(topic, k, t):
        return t if topic.endswith('event') else t + int(jitter[k])
    path = _copy_rosbag2(original[0], tmp_path / 'b', storage, log_time=late)
    for rec in _read_both(path, original[1]):
        assert set(rec.n_reordered) == set(rec.n_read), rec.n_reordered
        assert all(n > N // 4 for n in rec.n_reordered.values()), rec.n_reordered
        assert 'put back in stamp order (stored late): /spindle/lf/imu' in rec.summary()


def test_reorder_limit_is_the_documented_one(tmp_path, original):
    # A message moved back by just under the limit is delivery; just over it is a loop.
    for shift, ok in ((MAX_REORDER_NS - 5 * PERIOD_NS, True),
                      (MAX_REORDER_NS + 5 * PERIOD_NS, False)):
        def late(topic, k, t, shift=shift):
            return t + shift if topic == '/wft/lr/wrench' and t == T0_NS + 3 * PERIOD_NS else t
        path = _copy_rosbag2(original[0], tmp_path / f'b{ok}', 'mcap', log_time=late)
        if ok:
            assert read_recording(path).n_reordered == {'/wft/lr/wrench': 1}
        else:
            with pytest.raises(BagError, match=r'/wft/lr/wrench: stamp goes backwards at '
                                               r'message \d+ \(bag order\) by 1\.00\d s'):
                read_recording(path)


def test_message_compressed_sqlite3_with_unknown_undefined_type(tmp_path, original):
    # Before #18: KeyError 'unknown'.  The foreign topic has no definition and is never
    # decoded; the needed ones are decompressed message by message.
    path = _copy_rosbag2(original[0], tmp_path / 'b', 'sqlite3',
                         compression=CompressionMode.MESSAGE, foreign=True)
    bulk, fallback = _read_both(path, original[1])
    for rec in (bulk, fallback):
        assert ('/vendor/blob', 'vendor_msgs/msg/Unknown') in rec.skipped_topics
    assert (bulk.n_bulk, fallback.n_bulk) == (8 * N, 0)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_file_compressed_bag(tmp_path, original, storage):
    path = _copy_rosbag2(original[0], tmp_path / 'b', storage, compression=CompressionMode.FILE,
                         foreign=True)
    _read_both(path, original[1])


def test_needed_topic_in_another_encoding_is_named(tmp_path, original):
    # A needed topic recorded as protobuf cannot be decoded: topic, type and encoding named.
    src = _rewrite_mcap(original[0], tmp_path / 'a')
    out = tmp_path / 'b' / 'b.mcap'
    out.parent.mkdir()
    with src.open('rb') as fi, out.open('wb') as fo:
        reader = make_reader(fi)
        writer = McapWriter(fo)
        writer.start('ros2', '')
        summary = reader.get_summary()
        channels = {}
        for cid, c in summary.channels.items():
            s = summary.schemas[c.schema_id]
            protobuf = c.topic == '/spindle/rf/imu'
            sid = writer.register_schema(s.name, 'protobuf' if protobuf else s.encoding, s.data)
            channels[cid] = writer.register_channel(
                c.topic, 'protobuf' if protobuf else c.message_encoding, sid, c.metadata)
        for _, channel, msg in reader.iter_messages():
            writer.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time)
        writer.finish()
    for bulk in (True, False):
        with pytest.raises(BagError, match=r'topic /spindle/rf/imu has type sensor_msgs/msg/Imu '
                                           r'\(protobuf encoding\), expected '
                                           r'sensor_msgs/msg/Imu'):
            read_recording(out, bulk=bulk)
