# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Bulk CDR layout against rosbags' serialiser (the reference), and its fallbacks."""
import numpy as np
import pytest
from support.cdr_rows import encode_rows

from wheel_force_estimator.bagio.cdr import payload_length
from wheel_force_estimator.bagio.fastcdr import decode_records
from wheel_force_estimator.bagio.fastcdr import decode_rows
from wheel_force_estimator.bagio.fastcdr import IMU
from wheel_force_estimator.bagio.fastcdr import TopicDecoder
from wheel_force_estimator.bagio.fastcdr import WRENCH
from wheel_force_estimator.bagio.plan import make_imu
from wheel_force_estimator.bagio.plan import make_wrench
from wheel_force_estimator.bagio.reader import jazzy_typestore

STORE = jazzy_typestore()
LAYOUTS = [(IMU, make_imu), (WRENCH, make_wrench)]


def _serialize(layout):
    def ser(msg):
        return bytes(STORE.serialize_cdr(msg, layout.msgtype))
    return ser


def _deserialize(layout):
    def deser(data):
        return STORE.deserialize_cdr(data, layout.msgtype)
    return deser


@pytest.mark.parametrize('layout,make', LAYOUTS, ids=['imu', 'wrench'])
@pytest.mark.parametrize('frame', ['', 'a', 'lf_spindle', 'x' * 3, 'x' * 4, 'x' * 11, 'x' * 12,
                                   'rr_wheel_frame_with_a_long_name'])
def test_layout_matches_rosbags(layout, make, frame):
    """Payload length and value offsets agree with rosbags for frame ids across alignments."""
    rng = np.random.default_rng(len(frame))
    # nanosec 0, 1 and 1e9 - 1; the last stamp has the largest int32 sec
    stamp = np.array([10**9, 10**9 + 1, 2 * 10**9 - 1, 2**31 * 10**9 - 1], np.int64)
    values = rng.standard_normal((4, 3))
    rows = encode_rows(layout, stamp, values, make(STORE, frame), _serialize(layout))
    assert rows.shape[1] == payload_length(layout, len(frame) + 1)
    for i in range(4):  # every row equals the reference serialisation
        ref = _serialize(layout)(make(STORE, frame)(int(stamp[i]), tuple(values[i])))
        assert rows[i].tobytes() == ref
    got_stamp, got_values, n_fast = decode_rows(layout, rows, _deserialize(layout))
    assert n_fast == 4
    assert np.array_equal(got_stamp, stamp) and np.array_equal(got_values, values)


def test_disagreement_with_generic_falls_back():
    """If the bulk view ever disagrees with the deserialiser, the deserialiser wins."""
    stamp = 10**9 + np.arange(5, dtype=np.int64)
    values = np.arange(15, dtype=float).reshape(5, 3)
    rows = encode_rows(WRENCH, stamp, values, make_wrench(STORE, 'f'), _serialize(WRENCH))
    other = make_wrench(STORE, 'f')(42, (1.0, 2.0, 3.0))
    got_stamp, got_values, n_fast = decode_rows(WRENCH, rows, lambda data: other)
    assert n_fast == 0
    assert np.all(got_stamp == 42) and np.all(got_values == [1.0, 2.0, 3.0])


def test_unrecognised_rows_use_generic():
    """Big-endian payloads and foreign lengths are decoded by the deserialiser only."""
    msg = make_imu(STORE, 'lf_spindle')(5 * 10**9 + 7, (1.5, -2.5, 9.81))
    big = bytes(STORE.serialize_cdr(msg, IMU.msgtype, little_endian=False))
    calls = []

    def deser(data):
        calls.append(data)
        return STORE.deserialize_cdr(data, IMU.msgtype)

    rows = np.frombuffer(big * 3, np.uint8).reshape(3, -1)
    stamp, values, n_fast = decode_rows(IMU, rows, deser)
    assert n_fast == 0 and len(calls) == 3
    assert np.all(stamp == 5 * 10**9 + 7) and np.all(values == [1.5, -2.5, 9.81])


def test_records_decoded_in_place_at_any_offset():
    """
    Payloads scattered at odd offsets of one buffer decode like stacked rows.

    Two frame ids give two payload lengths in one batch (the grouped path) and the odd
    offsets make every field unaligned; the generic deserialiser sees only the first
    N_VALIDATE messages of each layout.
    """
    rng = np.random.default_rng(12)
    n = 50
    stamp = 10**9 + 1_953_125 * np.arange(n, dtype=np.int64)
    values = rng.standard_normal((n, 3))
    short = encode_rows(IMU, stamp, values, make_imu(STORE, 'lf'), _serialize(IMU))
    long = encode_rows(IMU, stamp, values, make_imu(STORE, 'lf_spindle_frame'),
                       _serialize(IMU))
    rows = [short[i] if i % 3 else long[i] for i in range(n)]
    gaps = rng.integers(1, 40, n)  # junk bytes between payloads
    buf, starts = bytearray(), []
    for row, gap in zip(rows, gaps):
        buf += rng.integers(0, 256, gap, dtype=np.uint8).tobytes()
        starts.append(len(buf))
        buf += row.tobytes()
    buf = np.frombuffer(bytes(buf), np.uint8)
    starts = np.array(starts, np.int64)
    lengths = np.array([len(r) for r in rows], np.int64)
    calls = []

    def deser(data):
        calls.append(data)
        return STORE.deserialize_cdr(data, IMU.msgtype)

    sink = TopicDecoder(IMU, deser)
    sink.add(stamp, lengths, buf, starts)
    got = sink.finish()
    assert got.n_fast == n and len(calls) == 2 * 3
    assert np.array_equal(got.stamp_ns, stamp) and np.array_equal(got.values, values)
    one = lengths == lengths[1]
    st, vals, n_fast = decode_records(IMU, buf, starts[one], int(lengths[1]), deser)
    assert n_fast == one.sum()
    assert np.array_equal(st, stamp[one]) and np.array_equal(vals, values[one])


@pytest.mark.parametrize('reserved', [None, 0, 7, 30, 31, 100])
def test_reserved_decoder_equals_joined_batches(reserved):
    """Decoding into a reserved result gives the same topic for any (even wrong) count."""
    rng = np.random.default_rng(5)
    n = 30
    stamp = 10**9 + 1_953_125 * np.arange(n, dtype=np.int64)
    values = rng.standard_normal((n, 3))
    rows = encode_rows(IMU, stamp, values, make_imu(STORE, 'lf'), _serialize(IMU))
    log_time = stamp + 5
    log_time[[12, 13]] = log_time[[13, 12]]  # out of bag order: finish() sorts stably
    sink = TopicDecoder(IMU, _deserialize(IMU))
    if reserved is not None:
        sink.reserve(reserved)
    for lo, hi in ((0, 10), (10, 11), (11, 25), (25, 30)):  # batches of varied size
        part = rows[lo:hi]
        sink.add(log_time[lo:hi], np.full(hi - lo, part.shape[1]), part.reshape(-1),
                 np.arange(hi - lo, dtype=np.int64) * part.shape[1])
    got = sink.finish()
    order = np.argsort(log_time, kind='stable')
    assert np.array_equal(got.log_time_ns, log_time[order])
    assert np.array_equal(got.stamp_ns, stamp[order])
    assert np.array_equal(got.values, values[order]) and got.n_fast == n
