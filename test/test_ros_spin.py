# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The node's wheel spin input (issue 33): the JointState ``{corner}_wheel`` velocities.

The decoding of real ``sensor_msgs/JointState`` messages (matched by name; malformed and
non-finite ones flagged), and the running node fed bad JointState messages through real
rclpy/DDS: each is counted and dropped, the node keeps running and says which topic.
That the node's wrenches equal ``predict --causal`` is ``test_ros_end_to_end``'s.
"""
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import Imu
from sensor_msgs.msg import JointState
from support.ros_testing import sample_stamps
from support.ros_testing import SpinningParticipant
from support.ros_testing import start_node
from support.ros_testing import stop_node
from support.ros_testing import synthetic_accel
from support.ros_testing import synthetic_model
from support.ros_testing import wait_until

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.ros.diagnostics import status_values
from wheel_force_estimator.ros.joints import decode_wheel_spin

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

FS_HZ = 512.0
DELAY = 48
CORNERS = ('lf', 'rf', 'lr', 'rr')
WHEELS = [f'{c}_wheel' for c in CORNERS]


def joint_state(stamp_ns, names, velocity):
    msg = JointState(name=list(names), velocity=[float(v) for v in velocity])
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return msg


def test_wheel_spin_is_read_by_name_and_bad_messages_are_flagged():
    suspension = [f'{c}_suspension' for c in CORNERS]
    msgs = [
        # any order, other joints with NaN velocities (a logger leaves them so): fine
        joint_state(10, suspension + WHEELS[::-1], [np.nan] * 4 + [4.0, 3.0, 2.0, 1.0]),
        joint_state(20, WHEELS, [1.0, 2.0, 3.0, 4.0]),
        joint_state(30, WHEELS[:3], [1.0, 2.0, 3.0]),               # rr_wheel missing
        joint_state(40, WHEELS, [1.0, 2.0, 3.0]),                   # a velocity missing
        joint_state(50, WHEELS + ['lf_wheel'], [1.0] * 5),           # a name twice
        joint_state(60, WHEELS, [1.0, np.inf, 3.0, 4.0]),           # not finite
        joint_state(70, WHEELS, []),                                # no velocities at all
    ]
    d = decode_wheel_spin(msgs)
    assert d.stamp_ns.tolist() == [10, 20, 30, 40, 50, 60, 70]
    assert d.malformed.tolist() == [False, False, True, True, True, False, True]
    assert d.nonfinite.tolist() == [False, False, False, False, False, True, False]
    assert d.valid.tolist() == [True, True, False, False, False, False, False]
    # bug caught: velocities taken in message order instead of by joint name
    assert np.array_equal(d.values()[:, :2], [[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0]])
    assert decode_wheel_spin([]).values().shape == (4, 0)


class SpinInjector(SpinningParticipant):
    """Publishes raw Imu messages and JointState messages; collects /diagnostics."""

    def __init__(self):
        super().__init__('spin_injector')
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.pubs = [self.node.create_publisher(Imu, f'/spindle/{c}/imu', qos) for c in CORNERS]
        self.joints = self.node.create_publisher(JointState, '/suspension/joint_states', qos)
        self.health = []
        self.sub = self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                                 self.health.append, 50)
        self.start()

    def publish(self, stamps, accel, joint_msgs, rate=4.0, burst=16):
        imu = [encode_imu(stamps, accel[3 * c:3 * c + 3], f'{CORNERS[c]}_spindle')
               for c in range(4)]
        start = time.monotonic()
        for lo in range(0, stamps.size, burst):
            due = (stamps[lo] - stamps[0]) * 1e-9 / rate
            time.sleep(max(0.0, due - (time.monotonic() - start)))
            for k in range(lo, min(lo + burst, stamps.size)):
                for c in range(4):
                    self.pubs[c].publish(imu[c][k])
                self.joints.publish(joint_msgs[k])


def node_values(msg):
    return next(status_values(s) for s in msg.status if s.name == '/wheel_force_node')


def test_bad_joint_state_messages_are_counted_dropped_and_the_node_keeps_running(
        ros_env, tmp_path):
    model = synthetic_model(fs_hz=FS_HZ, n_taps=160, delay_samples=DELAY, seed=22,
                            input_channels=INPUT_CHANNELS + SPIN_ACCEL_CHANNELS)
    path = save_model(model, tmp_path / 'spin.npz')
    n = 1198     # the last segment, 701 ..., fills whole blocks of 16 but its held sample
    stamps = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=7)
    spin = 30.0 + np.cumsum(np.random.default_rng(8).standard_normal((4, n)), axis=1) * 0.01
    msgs = [joint_state(t, WHEELS, spin[:, k]) for k, t in enumerate(stamps)]
    msgs[300] = joint_state(stamps[300], WHEELS[1:], spin[1:, 300])       # lf_wheel missing
    msgs[301] = joint_state(stamps[301], WHEELS, spin[:3, 301])           # too few velocities
    msgs[700] = joint_state(stamps[700], WHEELS, [np.nan, 1.0, 1.0, 1.0])  # not finite
    log = tmp_path / 'node.log'
    proc = start_node(path, ros_env, {'live_look_ahead_s': DELAY / FS_HZ,
                                      'input_reliability': 'reliable',
                                      'input_qos_depth': 5000}, log_path=log)
    try:
        peer = SpinInjector()
        try:
            assert wait_until(lambda: all(p.get_subscription_count() for p in peer.pubs)
                              and peer.joints.get_subscription_count(), 30.0), log.read_text()
            time.sleep(0.5)                            # let the node's readers see us too
            peer.publish(stamps, accel, msgs)
            # three samples without spin: dropped on every stream, two gaps, three segments;
            # the look-ahead and the held spin sample of the last stay in flight (a pause;
            # bug caught: the spin's extra sample not counted in flight, or lost)
            expected = n - 3 - (DELAY + 1)

            def settled():
                return bool(peer.health) and (
                    node_values(peer.health[-1])['published'] == str(expected))
            assert wait_until(settled, 20.0), (str(node_values(peer.health[-1]))
                                               if peer.health else log.read_text()[-2000:])
            values = node_values(peer.health[-1])
            corner = next(status_values(s) for s in peer.health[-1].status
                          if s.name.endswith(': rf'))
        finally:
            peer.close()
        assert values['joint_states_topic'] == '/suspension/joint_states'
        assert values['joint_states_received'] == str(n)
        assert values['joint_states_dropped_malformed'] == '2'
        assert values['joint_states_dropped_nonfinite'] == '1'
        assert values['joint_states_dropped'] == '3' and values['single_samples'] == '0'
        assert values['gaps'] == '2' and values['look_ahead_samples'] == str(DELAY + 1)
        assert corner['in_flight'] == str(DELAY + 1) and corner['dropped_incomplete'] == '3'
        assert proc.poll() is None                     # still running after all of it
        assert stop_node(proc) == 0
    finally:
        stop_node(proc)
    text = log.read_text()
    assert '/suspension/joint_states: dropped 2 malformed message(s)' in text, text[-3000:]
    # (the warnings are throttled: the NaN one, 0.4 s later, is in the counters only)
    assert 'JointState received=1198, dropped=3' in text, text[-3000:]
