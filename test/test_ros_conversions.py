# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Bulk CDR codecs checked against rclpy's own serializer, and the damage diagnostics."""
import struct

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu

from wheel_force_estimator.bagio.cdr import decode_imu
from wheel_force_estimator.bagio.cdr import decode_wrench
from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.bagio.cdr import encode_wrench
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.ros.diagnostics import build_damage_array
from wheel_force_estimator.ros.diagnostics import corner_level
from wheel_force_estimator.ros.diagnostics import CornerReport
from wheel_force_estimator.ros.diagnostics import status_values


def imu_msg(sec, nanosec, frame, accel):
    msg = Imu()
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = nanosec
    msg.header.frame_id = frame
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = accel
    msg.angular_velocity.x = 7.0          # other fields must not leak into the result
    msg.orientation.w = 1.0
    return msg


def same_cdr(ours, theirs, frame):
    """Equal bytes except the alignment padding (rclpy leaves it uninitialised)."""
    pad = slice(16 + len(frame) + 1, 4 + (12 + len(frame) + 1 + 7) // 8 * 8)
    a, b = bytearray(ours), bytearray(theirs)
    a[pad] = b[pad] = bytes(pad.stop - pad.start)
    return a == b


def big_endian_imu(sec, nanosec, frame, accel):
    """Hand-built big-endian CDR (allowed by the spec, never written by Fast DDS on x86)."""
    name = frame.encode() + b'\0'
    head = b'\x00\x00\x00\x00' + struct.pack('>iII', sec, nanosec, len(name)) + name
    body = [0.0] * 37
    body[25:28] = accel
    return head + b'\0' * ((-(len(head) - 4)) % 8) + struct.pack('>37d', *body)


def test_decode_imu_matches_rclpy_for_every_padding():
    rng = np.random.default_rng(0)
    # Frame ids of length 0..17 cover every padding before the first double.
    frames = ['x' * k for k in range(18)]
    accel = rng.normal(size=(len(frames), 3)) * 10
    raws = [serialize_message(imu_msg(100 + k, 999_999_999 - k, f, a))
            for k, (f, a) in enumerate(zip(frames, accel))]
    d = decode_imu(raws)
    np.testing.assert_array_equal(d.stamp_ns, [(100 + k) * 10**9 + 999_999_999 - k
                                               for k in range(len(frames))])
    np.testing.assert_array_equal(d.accel_mps2, accel.T)          # bit exact
    assert d.valid.all()


def test_decode_imu_flags_each_fault():
    good = serialize_message(imu_msg(5, 10, 'lf_imu', (1.0, 2.0, 3.0)))
    nan = serialize_message(imu_msg(5, 11, 'lf_imu', (np.nan, 2.0, 3.0)))
    inf = serialize_message(imu_msg(5, 12, 'lf_imu', (1.0, np.inf, 3.0)))
    other = serialize_message(imu_msg(5, 13, 'rf_imu', (1.0, 2.0, 3.0)))
    longer = serialize_message(imu_msg(5, 14, 'lf_imu_2', (1.0, 2.0, 3.0)))
    bad_nsec = bytearray(good)
    bad_nsec[8:12] = struct.pack('<I', 1_000_000_000)
    bad_kind = b'\x00\x03' + good[2:]             # parameter-list encapsulation: not ours
    raws = [good, nan, inf, other, longer, good[:-8], b'', bytes(bad_nsec), bad_kind,
            big_endian_imu(6, 7, 'lf_imu', (4.0, 5.0, 6.0))]
    d = decode_imu(raws, expected_frame_id='lf_imu')
    np.testing.assert_array_equal(d.malformed, [0, 0, 0, 0, 0, 1, 1, 1, 1, 0])
    np.testing.assert_array_equal(d.wrong_frame, [0, 0, 0, 1, 1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(d.nonfinite, [0, 1, 1, 0, 0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(d.valid, [1, 0, 0, 0, 0, 0, 0, 0, 0, 1])
    assert d.stamp_ns[-1] == 6 * 10**9 + 7
    np.testing.assert_array_equal(d.accel_mps2[:, -1], [4.0, 5.0, 6.0])
    # Without an expected frame every well-formed frame id is accepted.
    assert not decode_imu(raws).wrong_frame.any()


def test_encode_imu_is_what_rclpy_reads_and_writes():
    stamps = np.array([0, 5 * 10**9 + 7, 2**31 * 10**9 - 1])
    accel = np.array([[1.0, -2.0, 3.5], [0.0, 9.81, -1e-3], [1e6, -1e6, 0.5]])
    raws = encode_imu(stamps, accel, 'rr_spindle')
    for k, raw in enumerate(raws):
        msg = deserialize_message(raw, Imu)
        assert msg.header.frame_id == 'rr_spindle'
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamps[k]
        assert (msg.linear_acceleration.x, msg.linear_acceleration.y,
                msg.linear_acceleration.z) == tuple(accel[:, k])
        assert msg.orientation_covariance[0] == -1.0        # REP-145: not provided
        assert same_cdr(raw, serialize_message(msg), 'rr_spindle')
    d = decode_imu(raws, 'rr_spindle')
    np.testing.assert_array_equal(d.stamp_ns, stamps)
    np.testing.assert_array_equal(d.accel_mps2, accel)


def test_wrench_round_trip_through_rclpy():
    stamps = np.array([1, 2, 3]) * 10**9 + 5
    force = np.arange(9.0).reshape(3, 3) * 100.0
    torque = -np.arange(9.0).reshape(3, 3)
    raws = encode_wrench(stamps, force, 'lf_wheel', torque)
    msg = deserialize_message(raws[1], WrenchStamped)
    assert msg.header.frame_id == 'lf_wheel' and msg.header.stamp.sec == 2
    assert (msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z) == (100.0, 400.0, 700.0)
    assert msg.wrench.torque.z == -7.0
    assert same_cdr(raws[1], serialize_message(msg), 'lf_wheel')
    s, w, bad = decode_wrench(raws + [serialize_message(WrenchStamped()), b'junk'])
    np.testing.assert_array_equal(s[:3], stamps)
    np.testing.assert_array_equal(w[:, :3], np.concatenate([force, torque]))
    np.testing.assert_array_equal(bad, [0, 0, 0, 0, 1])
    np.testing.assert_array_equal(decode_wrench(encode_wrench(stamps, force, 'f'))[1][3:], 0.0)


def test_encode_rejects_bad_input():
    with pytest.raises(ShapeError, match='negative stamp'):
        encode_wrench(np.array([-1]), np.zeros((3, 1)), 'f')
    with pytest.raises(ShapeError, match='expected \\(3, n\\)'):
        encode_wrench(np.array([1]), np.zeros((2, 1)), 'f')
    with pytest.raises(ShapeError, match='NUL'):
        encode_imu(np.array([1]), np.zeros((3, 1)), 'a\0b')
    with pytest.raises(ShapeError, match='1 messages'):
        encode_imu(np.array([1, 2]), np.zeros((3, 1)), 'f')
    assert decode_imu([]).stamp_ns.size == 0


def test_corner_level_budget_and_stale():
    damage = (('fx', 10.0), ('fy', 50.0), ('fz', 85.0))
    assert corner_level(damage, 0.0, '') == (0, 'ok')                     # budget off
    assert corner_level(damage, 1000.0, '')[0] == 0
    level, text = corner_level(damage, 100.0, '')                         # 85 % of budget
    assert level == 1 and 'fz' in text
    level, text = corner_level(damage, 80.0, 'no message for 2.00 s')
    assert level == 2 and 'exceeded' in text and 'stale' in text
    assert corner_level(damage, 0.0, 'no message yet')[0] == 1


def test_damage_array_layout():
    reports = [CornerReport(c, (('fx', 1.0 / 3.0), ('fy', 2e17), ('fz', 0.0)), 12.5,
                            'no message' if c == 'rr' else '', (('received', 7),))
               for c in ('lf', 'rf', 'lr', 'rr')]
    msg = build_damage_array(reports, 'wheel_force_node', 3 * 10**9 + 4, 1e17)
    assert msg.header.stamp.sec == 3 and msg.header.stamp.nanosec == 4
    assert [s.name for s in msg.status] == [f'virtual_wft/{c}' for c in ('lf', 'rf', 'lr', 'rr')]
    status = msg.status[0]
    assert status.hardware_id == 'wheel_force_node'
    assert status.level == DiagnosticStatus.ERROR           # fy above the 1e17 budget
    values = status_values(status)
    assert list(values)[:5] == ['fx', 'fy', 'fz', 'damage_rate_per_s', 'received']
    assert float(values['fx']) == 1.0 / 3.0                  # repr: exact round trip
    assert values['received'] == '7'
