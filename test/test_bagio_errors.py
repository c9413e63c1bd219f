# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Every documented read error, on real bags written with rosbags' own Writer.

The faulty bags are written here with ``rosbags.rosbag2.Writer`` and the Jazzy serialiser
directly (not with our writer, which refuses bad data), so the reader is checked against the
reference serialisation.  Each case runs on mcap and sqlite3 and on both decoding paths.
"""
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import CompressionFormat
from rosbags.rosbag2 import CompressionMode
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer
from rosbags.typesys import get_typestore
from rosbags.typesys import Stores

from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError

STORE = get_typestore(Stores.ROS2_JAZZY)
TOPICS = TopicConfig()
IMU = 'sensor_msgs/msg/Imu'
WRENCH = 'geometry_msgs/msg/WrenchStamped'
PERIOD_NS = 1_953_125  # 512 Hz, exact in ns
T0_NS = 5_000_000_000
N = 200


def _msg(msgtype, stamp_ns, xyz, frame_id='frame'):
    t = STORE.types
    header = t['std_msgs/msg/Header'](
        stamp=t['builtin_interfaces/msg/Time'](sec=int(stamp_ns // 10**9),
                                               nanosec=int(stamp_ns % 10**9)),
        frame_id=frame_id)
    vec = t['geometry_msgs/msg/Vector3']
    v = vec(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))
    if msgtype == IMU:
        cov = np.zeros(9)
        return t[IMU](header=header, orientation=t['geometry_msgs/msg/Quaternion'](
            x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=cov,
            angular_velocity=vec(x=0.0, y=0.0, z=0.0), angular_velocity_covariance=cov,
            linear_acceleration=v, linear_acceleration_covariance=cov)
    return t[WRENCH](header=header, wrench=t['geometry_msgs/msg/Wrench'](
        force=v, torque=vec(x=0.0, y=0.0, z=0.0)))


def _streams(n=N, seed=0):
    """Eight valid (topic, type, stamps, values) streams on one 512 Hz clock."""
    rng = np.random.default_rng(seed)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    out = [[t, IMU, stamp.copy(), rng.standard_normal((n, 3))] for t in TOPICS.imu_topics]
    out += [[t, WRENCH, stamp.copy(), 1e3 * rng.standard_normal((n, 3))]
            for t in TOPICS.wft_topics]
    return out


def write_raw(path, streams, storage='mcap', compression=None, big_endian=(), vary_frames=(),
              log_times=None):
    """
    Write streams message by message with rosbags (any content, faults included).

    Bag timestamps equal header stamps unless ``log_times`` maps a topic to its own.
    """
    writer = Writer(path, version=8, storage_plugin=(
        StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3))
    if compression is not None:
        writer.set_compression(compression, CompressionFormat.ZSTD)
    msgs = []
    with writer:
        for topic, msgtype, stamps, values in streams:
            conn = writer.add_connection(topic, msgtype, typestore=STORE)
            times = (log_times or {}).get(topic, stamps)
            for i, (s, v) in enumerate(zip(stamps, values)):
                frame = 'f' + 'x' * (i % 11) if topic in vary_frames else 'f'
                data = STORE.serialize_cdr(_msg(msgtype, int(s), v, frame), msgtype,
                                           little_endian=topic not in big_endian)
                msgs.append((int(times[i]), len(msgs), conn, bytes(data)))
        for stamp, _, conn, data in sorted(msgs, key=lambda m: (m[0], m[1])):
            writer.write(conn, stamp, data)
    return Path(path)


@pytest.fixture(params=['mcap', 'sqlite3'])
def storage(request):
    return request.param


@pytest.fixture(params=[True, False], ids=['bulk', 'generic'])
def bulk(request):
    return request.param


def test_valid_raw_bag_reads_back_exactly(tmp_path, storage, bulk):
    streams = _streams()
    rec = read_recording(write_raw(tmp_path / 'b', streams, storage), bulk=bulk)
    seg, = rec.segments
    assert np.array_equal(seg.stamp_ns, streams[0][2])
    for k, (_, _, _, values) in enumerate(streams):
        target = seg.accel_mps2 if k < 4 else seg.force_n
        assert np.array_equal(target[3 * (k % 4):3 * (k % 4) + 3], values.T)
    assert rec.n_bulk == (8 * N if bulk else 0)


def test_missing_topic_lists_topics_present(tmp_path, storage, bulk):
    path = write_raw(tmp_path / 'b', _streams()[:7], storage)
    with pytest.raises(BagError, match=r'topic /wft/rr/wrench .*not found; topics present: '
                                       r'/spindle/lf/imu .*/wft/lr/wrench'):
        read_recording(path, bulk=bulk)


def test_wrong_type_is_named(tmp_path, storage):
    streams = _streams()
    streams[1][1] = WRENCH
    with pytest.raises(BagError, match=r'/spindle/rf/imu has type geometry_msgs/msg/Wrench'):
        read_recording(write_raw(tmp_path / 'b', streams, storage))


def test_unequal_counts_name_topic_and_first_stamp(tmp_path, storage, bulk):
    streams = _streams()
    missing = streams[0][2][50]
    streams[6][2] = np.delete(streams[6][2], 50)
    streams[6][3] = np.delete(streams[6][3], 50, axis=0)
    with pytest.raises(BagError, match=rf'/wft/lr/wrench is not on the sample clock .*'
                                       rf'{N} messages, /wft/lr/wrench has {N - 1}.*'
                                       rf'stamp {missing} ns .* not in /wft/lr/wrench'):
        read_recording(write_raw(tmp_path / 'b', streams, storage), bulk=bulk)


def test_stamp_only_in_one_topic(tmp_path, storage):
    streams = _streams()
    extra = streams[2][2][10] + PERIOD_NS // 2
    streams[2][2][10] = extra  # same count, one stamp moved off the common clock
    with pytest.raises(BagError, match=rf'stamp {extra} ns .* is in /spindle/lr/imu but not '
                                       r'in /spindle/lf/imu'):
        read_recording(write_raw(tmp_path / 'b', streams, storage))


def test_duplicate_stamp(tmp_path, storage, bulk):
    streams = _streams()
    streams[3][2][20] = streams[3][2][19]
    with pytest.raises(BagError, match=r'/spindle/rr/imu: duplicate stamp at message 20'):
        read_recording(write_raw(tmp_path / 'b', streams, storage), bulk=bulk)


def test_stamps_out_of_bag_order_are_put_in_stamp_order(tmp_path, storage, bulk):
    # Delivery reordered two samples (header stamps swapped, bag order kept): the reader
    # puts them back by stamp (issue #18) and counts the late one; a reader that kept bag
    # order (or refused) fails here.
    streams = _streams()
    clock = streams[5][2].copy()
    s, v = streams[5][2], streams[5][3]
    s[30], s[31] = s[31], s[30]
    expected = v.copy()
    v[[30, 31]] = v[[31, 30]]  # each value travels with its stamp
    path = write_raw(tmp_path / 'b', streams, storage, log_times={streams[5][0]: clock})
    rec = read_recording(path, bulk=bulk)
    assert np.array_equal(rec.segments[0].force_n[3:6], expected.T)
    assert rec.n_reordered == {'/wft/rf/wrench': 1}
    assert '/wft/rf/wrench 1' in rec.summary()


def test_jump_back_beyond_delivery_is_refused(tmp_path, storage, bulk):
    # A looped/restarted recording: stamps jump back by more than delivery reorders (1 s).
    streams = _streams()
    clock = streams[5][2].copy()
    streams[5][2][100:] -= 2 * 10**9
    path = write_raw(tmp_path / 'b', streams, storage, log_times={streams[5][0]: clock})
    with pytest.raises(BagError, match=r'/wft/rf/wrench: stamp goes backwards at message 100 '
                                       r'\(bag order\) by 1\.998 s'):
        read_recording(path, bulk=bulk)


def test_header_stamp_not_bag_time_is_used(tmp_path, storage):
    streams = _streams()
    late = {name: stamps + 12_345 for name, _, stamps, _ in streams}  # receive latency
    rec = read_recording(write_raw(tmp_path / 'b', streams, storage, log_times=late))
    assert np.array_equal(rec.segments[0].stamp_ns, streams[0][2])


def test_nan_names_topic_channel_and_stamp(tmp_path, storage, bulk):
    streams = _streams()
    streams[1][3][7, 1] = np.nan
    stamp = streams[1][2][7]
    with pytest.raises(NonFiniteError, match=rf'/spindle/rf/imu: non-finite value nan in '
                                             rf'channel rf_ay at message 7, stamp {stamp} ns'):
        read_recording(write_raw(tmp_path / 'b', streams, storage), bulk=bulk)


def test_inf_in_force(tmp_path, storage):
    streams = _streams()
    streams[7][3][3, 2] = -np.inf
    with pytest.raises(NonFiniteError, match=r'/wft/rr/wrench: .* -inf in channel rr_fz'):
        read_recording(write_raw(tmp_path / 'b', streams, storage))


def test_corner_rate_mismatch(tmp_path, storage):
    streams = _streams()
    streams[1][2] = streams[1][2][::2]  # rf runs at 256 Hz
    streams[1][3] = streams[1][3][::2]
    with pytest.raises(BagError, match=r'sample rate of /spindle/rf/imu is 256 Hz but '
                                       r'/spindle/lf/imu runs at 512 Hz'):
        read_recording(write_raw(tmp_path / 'b', streams, storage))


def test_expected_rate_mismatch(tmp_path):
    path = write_raw(tmp_path / 'b', _streams())
    # 512 Hz vs 513 Hz is 0.2 %, above the 0.1 % tolerance; 512.4 Hz (0.08 %) passes.
    with pytest.raises(BagError, match=r'sampled at 512 Hz, expected 513 Hz'):
        read_recording(path, expected_fs_hz=513.0)
    assert read_recording(path, expected_fs_hz=512.4).fs_hz == 512.0
    with pytest.raises(ConfigError, match='expected_fs_hz'):
        read_recording(path, expected_fs_hz=-1.0)


def test_irregular_step_rejected(tmp_path, storage):
    streams = _streams()
    for s in streams:
        s[2][40:] -= PERIOD_NS * 3 // 5  # one step of 0.4 periods, same on every topic
    with pytest.raises(BagError, match=r'irregular sample clock: step of 781250 ns'):
        read_recording(write_raw(tmp_path / 'b', streams, storage))


def test_big_endian_and_varying_frame_ids(tmp_path, storage):
    streams = _streams()
    path = write_raw(tmp_path / 'b', streams, storage, big_endian={TOPICS.imu_topics[2]},
                     vary_frames={TOPICS.imu_topics[0], TOPICS.wft_topics[1]})
    rec = read_recording(path)
    ref = read_recording(path, bulk=False)
    for a, b in ((rec.segments[0].accel_mps2, ref.segments[0].accel_mps2),
                 (rec.segments[0].force_n, ref.segments[0].force_n)):
        assert np.array_equal(a, b)
    assert np.array_equal(rec.segments[0].accel_mps2[0:3], streams[0][3].T)
    assert np.array_equal(rec.segments[0].accel_mps2[6:9], streams[2][3].T)
    # frame ids of 2..12 bytes give several payload lengths, each decoded in bulk; only the
    # big-endian topic goes through the generic deserialiser
    assert rec.n_bulk == 7 * N


@pytest.mark.parametrize('mode', [CompressionMode.STORAGE, CompressionMode.MESSAGE,
                                  CompressionMode.FILE], ids=['chunk', 'message', 'file'])
def test_compressed_mcap(tmp_path, mode):
    streams = _streams(n=50)
    rec = read_recording(write_raw(tmp_path / 'b', streams, 'mcap', compression=mode))
    assert np.array_equal(rec.segments[0].force_n[9:12], streams[7][3].T)
    # every compression mode is read in bulk (payloads decompressed first)
    assert rec.n_bulk == 8 * 50


def _written(tmp_path, storage):
    rng = np.random.default_rng(3)
    stamp = T0_NS + PERIOD_NS * np.arange(3000, dtype=np.int64)
    return write_recording(tmp_path / 'w', stamp, rng.standard_normal((12, 3000)),
                           rng.standard_normal((12, 3000)), storage=storage)


def test_truncated_bag_names_path(tmp_path, storage, bulk):
    path = _written(tmp_path, storage)
    data_file = next(path.glob('*.mcap' if storage == 'mcap' else '*.db3'))
    with data_file.open('r+b') as fh:
        fh.truncate(data_file.stat().st_size // 2)
    with pytest.raises(BagError, match=rf'{path}'):
        read_recording(path, bulk=bulk)


def test_corrupt_bytes_name_path(tmp_path, storage, bulk):
    path = _written(tmp_path, storage)
    data_file = next(path.glob('*.mcap' if storage == 'mcap' else '*.db3'))
    raw = bytearray(data_file.read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 4096] = bytes(range(256)) * 16
    data_file.write_bytes(bytes(raw))
    with pytest.raises(BagError, match=rf'{path}'):
        read_recording(path, bulk=bulk)


def test_missing_storage_file(tmp_path, storage):
    path = _written(tmp_path, storage)
    next(path.glob('*.mcap' if storage == 'mcap' else '*.db3')).unlink()
    with pytest.raises(BagError, match=rf'{path}'):
        read_recording(path)


def test_nonexistent_path(tmp_path):
    with pytest.raises(BagError, match=r'nope\.bag: no such bag'):
        read_recording(tmp_path / 'nope.bag')
    (tmp_path / 'x.txt').write_text('hi')
    with pytest.raises(BagError, match=r'x\.txt: not a bag'):
        read_recording(tmp_path / 'x.txt')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match=r'empty: cannot read'):
        read_recording(tmp_path / 'empty')


@pytest.mark.parametrize('require_wft', [True, False], ids=['all_topics', 'imu_only'])
def test_flipped_value_bit_caught_by_chunk_crc(tmp_path, monkeypatch, require_wft):
    """
    A flipped mantissa bit leaves a valid-looking message: only the chunk CRC sees it.

    The damaged value is a force, so the Imu-only read must verify the whole chunk too.
    """
    from wheel_force_estimator.bagio import mcap_reader
    from wheel_force_estimator.bagio import mcap_writer
    monkeypatch.setattr(mcap_writer, 'CHUNK_BYTES', 8 << 10)  # many chunks and batches
    monkeypatch.setattr(mcap_reader, '_BATCH_BYTES', 20 << 10)
    rng = np.random.default_rng(4)
    stamp = T0_NS + PERIOD_NS * np.arange(2000, dtype=np.int64)
    force = rng.standard_normal((12, 2000))
    force[7, 1500] = 1234.5678  # a unique bit pattern in a late chunk
    path = write_recording(tmp_path / 'w', stamp, rng.standard_normal((12, 2000)), force,
                           storage='mcap')
    data_file = next(path.glob('*.mcap'))
    raw = bytearray(data_file.read_bytes())
    pos = raw.find(np.float64(1234.5678).tobytes())
    assert pos > len(raw) // 2 and raw.count(np.float64(1234.5678).tobytes()) == 1
    raw[pos] ^= 1  # lowest mantissa bit: 1234.5678000000001, finite and plausible
    data_file.write_bytes(bytes(raw))
    with pytest.raises(BagError, match=rf'{data_file}: corrupt or truncated mcap: chunk CRC '
                                       r'mismatch at offset \d+'):
        read_recording(path, require_wft=require_wft)
