# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""write_recording -> real rosbag2 (mcap / sqlite3) -> read_recording, bit-exact."""
import sqlite3

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_forces
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.storage import read_raw_topics
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
import yaml

PERIOD_NS = 1_953_125  # 512 Hz
T0_NS = 1_700_000_000 * 10**9 + 123  # a realistic epoch stamp with odd nanoseconds
N = 400


def _data(n=N, seed=7):
    rng = np.random.default_rng(seed)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    accel = rng.standard_normal((12, n))
    accel[2::3] += 9.81
    # extreme but finite doubles must survive bit-exactly too
    accel[0, :3] = (np.finfo(float).tiny, -0.0, np.finfo(float).max)
    force = 1e3 * rng.standard_normal((12, n))
    return stamp, accel, force


@pytest.fixture(params=['mcap', 'sqlite3'])
def storage(request):
    return request.param


def test_roundtrip_bit_exact(tmp_path, storage):
    stamp, accel, force = _data()
    events = [(int(stamp[200]), 'pothole'), (int(stamp[0]), 'belgian_block')]
    path = write_recording(tmp_path / 'bag', stamp, accel, force, events=events,
                           storage=storage)
    meta = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 8 and meta['storage_identifier'] == storage
    rec = read_recording(path)
    seg, = rec.segments
    assert seg.stamp_ns.dtype == np.int64 and np.array_equal(seg.stamp_ns, stamp)
    assert np.array_equal(seg.accel_mps2.view(np.int64), accel.view(np.int64))
    assert np.array_equal(seg.force_n.view(np.int64), force.view(np.int64))
    assert rec.fs_hz == 512.0
    assert rec.events == tuple(sorted(events))
    assert rec.n_read == {t: N for t in TopicConfig().imu_topics + TopicConfig().wft_topics}
    assert rec.n_used == N and rec.gaps == () and rec.n_bulk == 8 * N
    assert f'used {N} of {N} samples read' in rec.summary()
    assert 'gaps: none' in rec.summary()


def test_bulk_equals_generic_deserialiser(tmp_path, storage):
    stamp, accel, force = _data(seed=11)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, storage=storage)
    fast = read_recording(path)
    slow = read_recording(path, bulk=False)
    assert fast.n_bulk == 8 * N and slow.n_bulk == 0
    for a, b in zip(fast.segments, slow.segments):
        assert np.array_equal(a.stamp_ns, b.stamp_ns)
        assert np.array_equal(a.accel_mps2.view(np.int64), b.accel_mps2.view(np.int64))
        assert np.array_equal(a.force_n.view(np.int64), b.force_n.view(np.int64))


def test_written_messages_are_canonical(tmp_path, storage):
    """Every payload decodes to the intended message and re-serialises to the same bytes."""
    stamp, accel, force = _data(n=60)
    topics = TopicConfig()
    path = write_recording(tmp_path / 'bag', stamp, accel, force, storage=storage)
    store = jazzy_typestore()
    present, raw = read_raw_topics(path, topics.imu_topics + topics.wft_topics)
    assert present == {**dict.fromkeys(topics.imu_topics, 'sensor_msgs/msg/Imu'),
                       **dict.fromkeys(topics.wft_topics, 'geometry_msgs/msg/WrenchStamped')}
    for k, corner in enumerate(CORNERS):
        for topic, msgtype, values, frame in (
                (topics.imu_topics[k], 'sensor_msgs/msg/Imu', accel, f'{corner}_spindle'),
                (topics.wft_topics[k], 'geometry_msgs/msg/WrenchStamped', force,
                 f'{corner}_wheel')):
            assert np.array_equal(raw[topic].log_time_ns, stamp)  # bag time == header stamp
            for i in range(60):
                data = raw[topic].payload(i)
                msg = store.deserialize_cdr(data, msgtype)
                assert bytes(store.serialize_cdr(msg, msgtype)) == data
                assert msg.header.frame_id == frame
                assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp[i]
                vec = msg.linear_acceleration if 'Imu' in msgtype else msg.wrench.force
                assert (vec.x, vec.y, vec.z) == tuple(values[3 * k:3 * k + 3, i])
                if 'Imu' in msgtype:  # REP-145: orientation / angular velocity not measured
                    assert msg.orientation_covariance[0] == -1.0
                    assert msg.angular_velocity_covariance[0] == -1.0


def test_gap_splits_into_segments(tmp_path, storage):
    stamp, accel, force = _data()
    keep = np.r_[0:100, 105:N]  # samples 100..104 missing on every topic
    path = write_recording(tmp_path / 'bag', stamp[keep], accel[:, keep], force[:, keep],
                           storage=storage)
    rec = read_recording(path)
    assert [s.n_samples for s in rec.segments] == [100, N - 105]
    assert np.array_equal(rec.segments[1].accel_mps2, accel[:, 105:])
    gap, = rec.gaps
    assert (gap.before_ns, gap.after_ns, gap.missing_samples) == (stamp[99], stamp[105], 5)
    assert rec.n_used == N - 5 and rec.fs_hz == 512.0
    assert f'used {N - 5} of {N - 5} samples read' in rec.summary()
    assert '5 sample(s) missing' in rec.summary()


def test_split_is_derived_per_segment_never_across_the_gap(tmp_path):
    # issue 29: the traction/braking split of each gap-free segment is that segment's own
    # (its low-pass starts at the segment's first sample); with no rate given, the segment's
    # median step is the rate (bug caught: one filter run over the concatenated segments)
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.derived import traction_braking
    stamp, accel, force = _data()
    accel[0::3] += np.linspace(-3.0, 3.0, N)[None]          # braking, then traction
    keep = np.r_[0:100, 105:N]
    rec = read_recording(write_recording(tmp_path / 'bag', stamp[keep], accel[:, keep],
                                         force[:, keep]))
    for seg, (lo, hi) in zip(rec.segments, ((0, 100), (105, N))):
        expected = traction_braking(accel[:, lo:hi], 512.0)
        got = seg.signals(INPUT_CHANNELS + SPLIT_CHANNELS, 512.0)
        np.testing.assert_array_equal(got[:12], accel[:, lo:hi])
        np.testing.assert_array_equal(got[12:], expected)
        np.testing.assert_allclose(seg.signals(SPLIT_CHANNELS[::-1]), expected[::-1],
                                   rtol=0, atol=1e-12)


def test_single_sample_segment_is_reported(tmp_path):
    stamp, accel, force = _data()
    keep = np.r_[0:95, 100, 106:N]  # sample 100 alone between two gaps
    rec = read_recording(write_recording(tmp_path / 'bag', stamp[keep], accel[:, keep],
                                         force[:, keep]))
    assert [s.n_samples for s in rec.segments] == [95, N - 106]
    assert rec.short_segments == ((int(stamp[100]), 1),)
    assert len(rec.gaps) == 2 and rec.n_used == N - 106 + 95
    assert 'left out: segment of 1 sample(s)' in rec.summary()


def test_imu_only_and_remapped_topics(tmp_path, storage):
    stamp, accel, _ = _data()
    topics = TopicConfig(imu_topics=tuple(f'/car/{c}/acc' for c in CORNERS))
    path = write_recording(tmp_path / 'bag', stamp, accel, topics=topics, storage=storage,
                           imu_frame_ids=[f'{c}_knuckle' for c in CORNERS])
    rec = read_recording(path, topics, require_wft=False)
    assert rec.segments[0].force_n is None
    assert np.array_equal(rec.segments[0].accel_mps2, accel)
    with pytest.raises(BagError, match=r'/wft/lf/wrench .*not found.*/car/lf/acc'):
        read_recording(path, topics)


def test_output_topics_for_predict(tmp_path, storage):
    stamp, _, force = _data(n=50)
    topics = TopicConfig(frame_ids=tuple(f'{c}_virtual' for c in CORNERS))
    path = write_forces(tmp_path / 'bag', stamp, force, topics, storage)
    with AnyReader([path], default_typestore=jazzy_typestore()) as reader:
        assert sorted(reader.topics) == sorted(topics.output_topics)
        got = {t: [] for t in topics.output_topics}
        for conn, t_ns, data in reader.messages():
            msg = reader.deserialize(data, conn.msgtype)
            k = topics.output_topics.index(conn.topic)
            assert msg.header.frame_id == f'{CORNERS[k]}_virtual'
            assert t_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            got[conn.topic].append((msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z))
    for k, topic in enumerate(topics.output_topics):
        assert np.array_equal(np.array(got[topic]).T, force[3 * k:3 * k + 3])
    for bulk in (True, False):
        got_stamp, got_force = read_wrench_topics(path, topics.output_topics, bulk=bulk)
        assert np.array_equal(got_stamp, stamp) and np.array_equal(got_force, force)


def test_read_wrench_topics_keeps_gaps_and_checks_clock(tmp_path):
    stamp, _, force = _data(n=50)
    keep = np.r_[0:20, 30:50]
    path = write_forces(tmp_path / 'bag', stamp[keep], force[:, keep])
    got_stamp, got_force = read_wrench_topics(path, TopicConfig().output_topics)
    assert np.array_equal(got_stamp, stamp[keep]) and np.array_equal(got_force, force[:, keep])
    swapped = TopicConfig().output_topics[:3] + ('/nope',)
    with pytest.raises(BagError, match=r'/nope .*not found'):
        read_wrench_topics(path, swapped)


def test_writer_refuses_bad_input(tmp_path):
    stamp, accel, force = _data(n=20)
    write_recording(tmp_path / 'bag', stamp, accel, force)
    with pytest.raises(BagError, match=r'bag: exists already, not overwriting'):
        write_recording(tmp_path / 'bag', stamp, accel, force)
    bad = accel.copy()
    bad[4, 3] = np.nan
    with pytest.raises(NonFiniteError, match=r'rf_ay at sample 3'):
        write_recording(tmp_path / 'nan', stamp, bad)
    with pytest.raises(BagError, match=r'not strictly increasing at sample 5'):
        write_recording(tmp_path / 'dup', np.r_[stamp[:5], stamp[4:19]], accel)
    with pytest.raises(ShapeError, match=r'expected 12 channels'):
        write_recording(tmp_path / 'shape', stamp, accel[:11])
    with pytest.raises(BagError, match=r'force_n has 19 samples but stamp_ns has 20'):
        write_recording(tmp_path / 'len', stamp, force_n=force[:, :19])
    with pytest.raises(ConfigError, match=r'storage must be one of'):
        write_recording(tmp_path / 'st', stamp, accel, storage='rosbag1')
    with pytest.raises(ConfigError, match=r'nothing to write'):
        write_recording(tmp_path / 'none', stamp)
    assert not any((tmp_path / d).exists() for d in ('nan', 'dup', 'shape', 'len', 'st'))


def test_sqlite_id_order_and_holes(tmp_path):
    """rosbag2 order is (timestamp, id): rows stored out of time order or with id holes."""
    stamp, accel, force = _data(seed=5)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, storage='sqlite3')
    con = sqlite3.connect(next(path.glob('*.db3')))
    con.execute('UPDATE messages SET id = id + 1000000 WHERE id > 100')  # a hole in the ids
    con.execute('UPDATE messages SET id = id + 5000000 WHERE id <= 50')  # first rows stored last
    con.commit()
    con.close()
    for bulk in (True, False):
        seg, = read_recording(path, bulk=bulk).segments
        assert np.array_equal(seg.stamp_ns, stamp)
        assert np.array_equal(seg.accel_mps2, accel) and np.array_equal(seg.force_n, force)


def test_bare_storage_file(tmp_path, storage):
    stamp, accel, force = _data(n=30)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, storage=storage)
    rec = read_recording(next(path.glob('*.mcap' if storage == 'mcap' else '*.db3')))
    assert np.array_equal(rec.segments[0].force_n, force) and rec.n_bulk == 8 * 30


def test_many_chunks_and_batches(tmp_path, monkeypatch):
    """Chunks read in many small batches (CRCs one batch ahead) give the same samples."""
    from wheel_force_estimator.bagio import mcap_reader
    from wheel_force_estimator.bagio import mcap_writer
    from wheel_force_estimator.bagio import storage as storage_mod
    n = 1500
    stamp, accel, force = _data(n=n, seed=5)
    accel[4, 1000] = -7.25  # a value in a late chunk, checked below
    # ~8 KiB chunks (about 20 samples of 8 topics each), batches of a few chunks, so chunk
    # and batch boundaries fall everywhere in the record
    monkeypatch.setattr(mcap_writer, 'CHUNK_BYTES', 8 << 10)
    monkeypatch.setattr(mcap_reader, '_BATCH_BYTES', 20 << 10)
    path = write_recording(tmp_path / 'bag', stamp, accel, force, storage='mcap')
    layout = storage_mod.bag_layout(path)
    with layout.files[0].open('rb') as fh:
        size = fh.seek(0, 2)
    assert size > 60 * (20 << 10)  # so well over 60 batches
    fast = read_recording(path)
    slow = read_recording(path, bulk=False)
    imu_only = read_recording(path, require_wft=False)
    assert fast.n_bulk == 8 * n
    for rec in (fast, slow, imu_only):
        seg, = rec.segments
        assert np.array_equal(seg.stamp_ns, stamp)
        assert np.array_equal(seg.accel_mps2.view(np.int64), accel.view(np.int64))
    assert np.array_equal(fast.segments[0].force_n.view(np.int64), force.view(np.int64))
    assert imu_only.segments[0].force_n is None
    assert fast.segments[0].accel_mps2[4, 1000] == -7.25
