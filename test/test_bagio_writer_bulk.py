# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The bulk rosbag2 writer against rosbags' own Writer and three independent readers.

Reference bags are written here message by message with ``rosbags.rosbag2.Writer`` from
messages serialised one at a time by the Jazzy typestore, so nothing of the bulk path (CDR
templates, record arithmetic, SQL expansion) is shared with the reference.  Every comparison
is exact: payload bytes, stamps, counts, metadata.  Small chunk / batch sizes are forced so
that chunk and batch boundaries, and events falling on them, are exercised.
"""
import functools
import io
import sqlite3
import struct
import zlib

from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.records import MessageIndex
from mcap.stream_reader import StreamReader
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer
from rosbags.typesys import get_typestore
from rosbags.typesys import Stores

from wheel_force_estimator import CORNERS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import mcap_writer
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import sqlite_writer
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_forces
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.bagio import writer
from wheel_force_estimator.bagio.blocks import SignalBlocks
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import NonFiniteError
import yaml

STORE = get_typestore(Stores.ROS2_JAZZY)
TOPICS = TopicConfig()
IMU = 'sensor_msgs/msg/Imu'
WRENCH = 'geometry_msgs/msg/WrenchStamped'
STRING = 'std_msgs/msg/String'
PERIOD_NS = 1_953_125  # 512 Hz
T0_NS = 1_700_000_000 * 10**9 + 77  # epoch-like stamp with odd nanoseconds
N = 240


def _data(n=N, seed=21):
    rng = np.random.default_rng(seed)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    accel = rng.standard_normal((12, n))
    edge = (np.finfo(float).tiny, -0.0, np.finfo(float).max, 5e-324)  # must survive bit-exactly
    accel[0, :4] = edge[:min(n, 4)]
    force = 1e3 * rng.standard_normal((12, n))
    # before the first sample, tied with samples (event goes first), mid, after the last
    mid, tie = n * 2 // 5, n * 5 // 8
    events = [(int(stamp[0]) - 5, 'start'), (int(stamp[0]), 'tie_first'),
              (int(stamp[mid]) + 1, 'mid'), (int(stamp[tie]), 'tie'), (int(stamp[tie]), 'tie2'),
              (int(stamp[-1]) + 10**6, 'after')]
    return stamp, accel, force, events


def _msg(msgtype, stamp_ns, xyz, frame_id):
    t = STORE.types
    header = t['std_msgs/msg/Header'](
        stamp=t['builtin_interfaces/msg/Time'](sec=int(stamp_ns) // 10**9,
                                               nanosec=int(stamp_ns) % 10**9),
        frame_id=frame_id)
    vec = t['geometry_msgs/msg/Vector3']
    v = vec(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))
    zero = vec(x=0.0, y=0.0, z=0.0)
    if msgtype == IMU:
        flagged = np.r_[-1.0, np.zeros(8)]  # REP-145 "not measured", as the writer promises
        return t[IMU](header=header, orientation=t['geometry_msgs/msg/Quaternion'](
            x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=flagged,
            angular_velocity=zero, angular_velocity_covariance=flagged,
            linear_acceleration=v, linear_acceleration_covariance=np.zeros(9))
    return t[WRENCH](header=header, wrench=t['geometry_msgs/msg/Wrench'](force=v, torque=zero))


def _expected(stamp, accel, force, events, topics=TOPICS, force_topics=None):
    """(topic, msgtype, [(log time, payload)]) per topic, serialised one by one by rosbags."""
    streams = []
    for values, names, msgtype, suffix in (
            (accel, topics.imu_topics, IMU, 'spindle'),
            (force, force_topics or topics.wft_topics, WRENCH, 'wheel')):
        if values is None:
            continue
        for k, (topic, corner) in enumerate(zip(names, CORNERS)):
            msgs = [(int(t), bytes(STORE.serialize_cdr(
                _msg(msgtype, t, values[3 * k:3 * k + 3, i], f'{corner}_{suffix}'), msgtype)))
                for i, t in enumerate(stamp)]
            streams.append((topic, msgtype, msgs))
    if events:
        string_t = STORE.types[STRING]
        streams.append((topics.event_topic, STRING, [
            (t, bytes(STORE.serialize_cdr(string_t(data=name), STRING)))
            for t, name in sorted(events, key=lambda e: e[0])]))
    return streams


def _order(streams, n):
    """Messages in the order the writer promises: events first, then samples topic-wise."""
    dense = [s for s in streams if len(s[2]) == n and s[1] != STRING]
    sparse = [(t, data) for topic, msgtype, msgs in streams if msgtype == STRING
              for t, data in msgs]
    out, j = [], 0
    for i in range(n):
        while j < len(sparse) and sparse[j][0] <= dense[0][2][i][0]:
            out.append(('ev', sparse[j]))
            j += 1
        out.extend((topic, msgs[i]) for topic, _, msgs in dense)
    out.extend(('ev', m) for m in sparse[j:])
    return out


def _write_reference(path, storage, streams, n):
    """Write the streams message by message with rosbags' Writer, in the promised order."""
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(path, version=8, storage_plugin=plugin) as ref:
        conns = {topic: ref.add_connection(topic, msgtype, typestore=STORE)
                 for topic, msgtype, _ in streams}
        ev = streams[-1][0]
        for topic, (t, data) in _order(streams, n):
            ref.write(conns[ev if topic == 'ev' else topic], t, data)
    return path


def _rosbags_messages(path):
    """Topic -> [(log time, payload)] and decoded messages, via rosbags' AnyReader."""
    out, decoded = {}, {}
    with AnyReader([path], default_typestore=STORE) as reader:
        for conn, t, data in reader.messages():
            out.setdefault(conn.topic, []).append((t, bytes(data)))
            decoded.setdefault(conn.topic, []).append(reader.deserialize(data, conn.msgtype))
    return out, decoded


@pytest.fixture(params=['mcap', 'sqlite3'])
def storage(request):
    return request.param


@pytest.fixture
def small_blocks(monkeypatch):
    # ~5 samples per mcap chunk / sqlite batch: many boundaries, events on some of them
    monkeypatch.setattr(mcap_writer, 'CHUNK_BYTES', 5 * 1900)
    monkeypatch.setattr(sqlite_writer, 'BATCH_BYTES', 5 * 1400)


def _meta(path):
    return yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def test_messages_and_metadata_equal_rosbags_writer(tmp_path, storage, small_blocks):
    stamp, accel, force, events = _data()
    path = write_recording(tmp_path / 'bulk' / 'bag', stamp, accel, force, events=events,
                           storage=storage)
    streams = _expected(stamp, accel, force, events)
    ref = _write_reference(tmp_path / 'ref' / 'bag', storage, streams, N)
    got, decoded = _rosbags_messages(path)
    assert got == _rosbags_messages(ref)[0]  # every payload and log time, bit-exact
    assert got == {topic: msgs for topic, _, msgs in streams}
    # same directory name: metadata.yaml equal as a whole (times, counts, hashes, paths)
    assert _meta(path) == _meta(ref)
    assert sorted(p.name for p in path.iterdir()) == sorted(p.name for p in ref.iterdir())
    for k, topic in enumerate(TOPICS.wft_topics):
        msgs = decoded[topic]
        assert [m.header.frame_id for m in msgs] == [f'{CORNERS[k]}_wheel'] * N
        got_force = np.array([(m.wrench.force.x, m.wrench.force.y, m.wrench.force.z)
                              for m in msgs]).T
        assert np.array_equal(got_force.view(np.int64), force[3 * k:3 * k + 3].view(np.int64))
    assert [m.data for m in decoded[TOPICS.event_topic]] == [
        name for _, name in sorted(events, key=lambda e: e[0])]


def test_project_reader_bulk_and_generic(tmp_path, storage, small_blocks):
    stamp, accel, force, events = _data(seed=4)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, events=events,
                           storage=storage)
    for bulk in (True, False):
        rec = read_recording(path, bulk=bulk)
        seg, = rec.segments
        assert np.array_equal(seg.stamp_ns, stamp)
        assert np.array_equal(seg.accel_mps2.view(np.int64), accel.view(np.int64))
        assert np.array_equal(seg.force_n.view(np.int64), force.view(np.int64))
        assert rec.events == tuple(sorted(events, key=lambda e: e[0]))
        assert rec.n_bulk == (8 * N if bulk else 0)
    out = write_forces(tmp_path / 'out', stamp, force, storage=storage)
    for bulk in (True, False):
        got_stamp, got_force = read_wrench_topics(out, TOPICS.output_topics, bulk=bulk)
        assert np.array_equal(got_stamp, stamp)
        assert np.array_equal(got_force.view(np.int64), force.view(np.int64))


def _file_records(path):
    with path.open('rb') as fh:
        return list(StreamReader(fh, validate_crcs=True, emit_chunks=True).records)


def _chunk_data(chunk):
    if chunk.compression == 'zstd':
        import zstandard  # installed with the mcap package
        return zstandard.ZstdDecompressor().decompress(
            chunk.data, max_output_size=chunk.uncompressed_size)
    assert chunk.compression == ''
    return chunk.data


@pytest.mark.parametrize('compression', ['', 'zstd'])
def test_mcap_structure_with_independent_reader(tmp_path, monkeypatch, small_blocks,
                                                compression):
    stamp, accel, force, events = _data(seed=9)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, events=events,
                           compression=compression)
    streams = _expected(stamp, accel, force, events)
    file = path / 'bag.mcap'
    with file.open('rb') as fh:
        reader = make_reader(fh, validate_crcs=True)
        summary = reader.get_summary()
        by_topic = {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            assert message.log_time == message.publish_time
            by_topic.setdefault(channel.topic, []).append((message.log_time, message.data))
        rosbag2_meta, = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
    assert by_topic == {topic: msgs for topic, _, msgs in streams}
    assert [(c.topic, c.message_encoding, summary.schemas[c.schema_id].name)
            for c in summary.channels.values()] == [
        (topic, 'cdr', msgtype) for topic, msgtype, _ in streams]
    assert list(summary.channels) == list(range(1, 10))
    assert {s.name: s.id for s in summary.schemas.values()} == {IMU: 1, WRENCH: 2, STRING: 3}
    assert all(s.encoding == 'ros2msg' for s in summary.schemas.values())
    stats = summary.statistics
    assert stats.message_count == 8 * N + len(events)
    assert stats.channel_message_counts == {**{c: N for c in range(1, 9)}, 9: len(events)}
    assert (stats.message_start_time, stats.message_end_time) == (
        min(events)[0], max(events)[0])
    assert stats.chunk_count == len(summary.chunk_indexes) > 40  # boundaries were exercised
    assert yaml.safe_load(rosbag2_meta.metadata['serialized_metadata']) == _meta(path)

    # file order: chunks with their message indexes, every message in the promised order
    records = _file_records(file)
    chunks = [r for r in records if isinstance(r, Chunk)]
    assert len(chunks) == stats.chunk_count
    in_file = []
    for chunk, index in zip(chunks, summary.chunk_indexes):
        data = _chunk_data(chunk)
        assert zlib.crc32(data) == chunk.uncompressed_crc != 0
        assert (index.compression, index.uncompressed_size) == (compression, len(data))
        inner = _chunk_messages(data)
        times = [m[1] for m in inner]
        assert (chunk.message_start_time, chunk.message_end_time) == (min(times), max(times))
        assert (index.message_start_time, index.message_end_time) == (min(times), max(times))
        in_file += [(cid, t, payload) for cid, t, payload in inner]
        # each message index entry points at a Message record of its channel and time
        n_indexed = 0
        for cid, offset in index.message_index_offsets.items():
            mi = next(r for r in _records_at(file, offset))
            assert isinstance(mi, MessageIndex) and mi.channel_id == cid
            for log_time, pos in mi.records:
                op, _, chan, _, t = struct.unpack_from('<BQHIQ', data, pos)
                assert (op, chan, t) == (0x05, cid, log_time)
            n_indexed += len(mi.records)
        assert n_indexed == len(inner)
    ids = {topic: i + 1 for i, (topic, _, _) in enumerate(streams)}
    assert in_file == [(ids[TOPICS.event_topic if t == 'ev' else t], m[0], m[1])
                       for t, m in _order(streams, N)]

    # footer: summary CRC over summary section .. summary_offset_start, as the spec defines
    raw = file.read_bytes()
    summary_start, offsets_start, crc = struct.unpack_from('<QQI', raw, len(raw) - 8 - 20)
    assert crc == zlib.crc32(raw[summary_start:len(raw) - 8 - 4])
    assert offsets_start > summary_start


def _chunk_messages(data):
    """(channel, log time, payload) of the Message records of a chunk, walking the bytes."""
    out, pos = [], 0
    while pos < len(data):
        op, length, cid, _, log_time, publish_time = struct.unpack_from('<BQHIQQ', data, pos)
        assert op == 0x05 and publish_time == log_time
        out.append((cid, log_time, data[pos + 31:pos + 9 + length]))
        pos += 9 + length
    assert pos == len(data)
    return out


def _records_at(file, offset):
    with file.open('rb') as fh:
        fh.seek(offset)
        op, length = struct.unpack('<BQ', fh.read(9))
        body = fh.read(length)
    stream = io.BytesIO(struct.pack('<BQ', op, length) + body)
    return StreamReader(stream, skip_magic=True).records


def test_sqlite_tables_equal_rosbags_writer(tmp_path, small_blocks):
    stamp, accel, force, events = _data(n=60, seed=2)
    path = write_recording(tmp_path / 'bulk' / 'bag', stamp, accel, force, events=events,
                           storage='sqlite3')
    ref = _write_reference(tmp_path / 'ref' / 'bag', 'sqlite3',
                           _expected(stamp, accel, force, events), 60)

    def dump(bag):
        con = sqlite3.connect(bag / 'bag.db3')
        try:
            schema = sorted((kind, name, ' '.join(sql.split()))
                            for kind, name, sql in con.execute(
                                'SELECT type, name, sql FROM sqlite_master'))
            tables = {name: con.execute(f'SELECT * FROM {name} ORDER BY 1').fetchall()
                      for name in ('schema', 'topics', 'message_definitions', 'messages')}
            (version, text), = con.execute('SELECT metadata_version, metadata FROM metadata')
        finally:
            con.close()
        return schema, tables, version, yaml.safe_load(text)

    # identical schema and rows: ids in (timestamp, id) order, stored metadata too
    assert dump(path) == dump(ref)
    assert dump(path)[3] == _meta(path)


def test_sqlite_executemany_path_is_identical(tmp_path, monkeypatch, small_blocks):
    stamp, accel, force, events = _data(n=50, seed=5)
    a = write_recording(tmp_path / 'json' / 'bag', stamp, accel, force, events=events,
                        storage='sqlite3')
    monkeypatch.setitem(writer.STORAGES, 'sqlite3', ('.db3', functools.partial(
        sqlite_writer.write_sqlite, use_json=False)))
    b = write_recording(tmp_path / 'many' / 'bag', stamp, accel, force, events=events,
                        storage='sqlite3')

    def rows(bag):
        con = sqlite3.connect(bag / 'bag.db3')
        try:
            return con.execute('SELECT * FROM messages ORDER BY id').fetchall()
        finally:
            con.close()
    assert rows(a) == rows(b) and len(rows(a)) == 8 * 50 + len(events)


def test_refuses_to_overwrite_and_leaves_nothing_on_failure(tmp_path, storage, monkeypatch):
    stamp, accel, force, _ = _data(n=20)
    (tmp_path / 'bag').mkdir()
    with pytest.raises(BagError, match=r'bag: exists already, not overwriting'):
        write_recording(tmp_path / 'bag', stamp, accel, force, storage=storage)
    assert not any((tmp_path / 'bag').iterdir())
    # the storage writers refuse an existing file themselves too
    (tmp_path / 'x.mcap').write_bytes(b'keep')
    with pytest.raises(FileExistsError):
        mcap_writer.write_mcap(tmp_path / 'x.mcap', None, 8, '')
    (tmp_path / 'x.db3').write_bytes(b'keep')
    with pytest.raises(FileExistsError):
        sqlite_writer.write_sqlite(tmp_path / 'x.db3', None, 8, '')
    assert (tmp_path / 'x.mcap').read_bytes() == (tmp_path / 'x.db3').read_bytes() == b'keep'

    def disk_full(file, *args):
        file.write_bytes(b'partial')
        raise OSError(28, 'No space left on device')
    suffix = writer.STORAGES[storage][0]
    monkeypatch.setitem(writer.STORAGES, storage, (suffix, disk_full))
    with pytest.raises(BagError, match=r'full: cannot write bag: No space left on device'):
        write_recording(tmp_path / 'full', stamp, accel, force, storage=storage)
    assert not (tmp_path / 'full').exists()


def test_imu_only_and_single_sample(tmp_path, storage):
    stamp, accel, _, _ = _data(n=1)
    path = write_recording(tmp_path / 'bag', stamp, accel, storage=storage,
                           events=[(int(stamp[0]) + 1, 'late')])
    got, _ = _rosbags_messages(path)
    expected = _expected(stamp, accel, None, [(int(stamp[0]) + 1, 'late')])
    assert got == {topic: msgs for topic, _, msgs in expected}
    meta = _meta(path)
    assert meta['message_count'] == 5 and meta['duration'] == {'nanoseconds': 1}


def _split(force, sizes):
    """Consecutive column blocks of ``force`` with the given sizes (the last takes the rest)."""
    edges = np.concatenate(([0], np.cumsum(sizes)[:-1], [force.shape[1]]))
    edges = np.minimum(edges, force.shape[1])
    return [force[:, a:b] for a, b in zip(edges[:-1], edges[1:])]


def test_streamed_forces_write_the_same_bag(tmp_path, storage, small_blocks):
    """Forces handed over as irregular blocks give the same storage file as one array."""
    stamp, accel, force, events = _data(seed=4)
    # same bag name: metadata.yaml and the storage's copy of it name the file
    whole = write_recording(tmp_path / 'whole' / 'bag', stamp, accel, force, events=events,
                            storage=storage)
    blocks = _split(force, [1, 0, 7, 3, 40, 2, 1, N])  # empty, inside and across chunks
    streamed = write_recording(
        tmp_path / 'streamed' / 'bag', stamp, accel,
        SignalBlocks(OUTPUT_CHANNELS, N, iter(blocks)), events=events, storage=storage)
    suffix = writer.STORAGES[storage][0]
    assert (streamed / f'bag{suffix}').read_bytes() == (whole / f'bag{suffix}').read_bytes()
    assert (streamed / 'metadata.yaml').read_text() == (whole / 'metadata.yaml').read_text()


def test_streamed_forces_wrong_length_refused(tmp_path):
    stamp, _, force, _ = _data(n=N)
    with pytest.raises(BagError, match=r'streamed force_n has 239 samples .* expected 240'):
        write_recording(tmp_path / 'a', stamp, force_n=SignalBlocks(
            OUTPUT_CHANNELS, N - 1, iter(_split(force, [10, N]))), output=True)
    short = iter(_split(force[:, :N - 1], [10, N]))
    with pytest.raises(BagError, match=r'force_n: the stream ended after 239 of 240 samples'):
        write_recording(tmp_path / 'b', stamp, force_n=SignalBlocks(OUTPUT_CHANNELS, N, short),
                        output=True)
    long = iter(_split(force, [10, N]) + [force[:, :1]])
    with pytest.raises(BagError, match=r'force_n: the stream holds more than 240 samples'):
        write_recording(tmp_path / 'c', stamp, force_n=SignalBlocks(OUTPUT_CHANNELS, N, long),
                        output=True)
    assert not any((tmp_path / name).exists() for name in 'abc')  # nothing half-written


def test_streamed_forces_non_finite_block_refused(tmp_path):
    stamp, _, force, _ = _data(n=N)
    force = force.copy()
    force[4, N - 3] = np.nan
    src = SignalBlocks(OUTPUT_CHANNELS, N, iter(_split(force, [N // 2, N])))
    with pytest.raises(NonFiniteError, match=r'block at sample 120.*rf_fy'):
        write_recording(tmp_path / 'bag', stamp, force_n=src, output=True)
    assert not (tmp_path / 'bag').exists()
