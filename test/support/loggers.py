# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""A vehicle logger graph for node tests: four Imu drivers and a recorder of the outputs."""
import signal
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import String
from support.ros_testing import SpinningParticipant
from support.ros_testing import wait_until

from wheel_force_estimator.bagio.cdr import decode_wrench
from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.ros.diagnostics import status_values

FS_HZ = 512.0
CORNERS = ('lf', 'rf', 'lr', 'rr')
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                      reliability=ReliabilityPolicy.RELIABLE)


#: Wait after a service appears before its first call [s] (:meth:`Loggers.call`).
DISCOVERY_GRACE_S = 0.5
#: Period of resending an unanswered idempotent request [s] (:meth:`Loggers.call`).
RESEND_S = 4.0


class Loggers(SpinningParticipant):
    """Four Imu drivers (one publisher each) and a recorder of the node's outputs."""

    def __init__(self, name):
        super().__init__(name)
        self.pubs = [self.node.create_publisher(Imu, f'/spindle/{c}/imu', RELIABLE)
                     for c in CORNERS]
        self.raw = {c: [] for c in CORNERS}
        self.subs = [self.node.create_subscription(
            WrenchStamped, f'/virtual_wft/{c}/wrench', self.raw[c].append, RELIABLE,
            raw=True) for c in CORNERS]
        self.health, self.damage = [], []
        self.subs.append(self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                                       self.health.append, 50))
        self.subs.append(self.node.create_subscription(
            DiagnosticArray, '/virtual_wft/damage', self.damage.append, 100))
        self.event_pub = self.node.create_publisher(String, '/proving_ground/event', RELIABLE)
        self._clients = {}
        self.start()

    def call(self, srv_type, name, request=None, timeout_s=20.0, resend=False):
        """
        Call service ``name`` and return its response (fails the test on a timeout).

        Fast DDS sends a response only to a client whose response reader the service has
        discovered, and gives up after a short wait: the node logs "failed to send response
        (timeout): client will not receive response" and the call never returns (seen once
        in CI, on the first ``get_state`` of a freshly created client).  ``wait_for_service``
        sees only the request side.  So each service gets one client, kept for the
        participant's life, with :data:`DISCOVERY_GRACE_S` after the service appears; and
        an idempotent request (``resend``: a query) is sent again every
        :data:`RESEND_S` until answered.  A state-changing request is sent once.
        """
        client = self._clients.get(name)
        if client is None:
            client = self.node.create_client(srv_type, name)
            assert client.wait_for_service(timeout_sec=timeout_s), f'no service {name}'
            time.sleep(DISCOVERY_GRACE_S)
            self._clients[name] = client
        request = request if request is not None else srv_type.Request()
        deadline = time.monotonic() + timeout_s
        while True:
            future = client.call_async(request)
            if wait_until(future.done, min(RESEND_S, timeout_s) if resend else timeout_s):
                return future.result()
            assert resend and time.monotonic() < deadline, f'{name}: no answer'

    def publish_event(self, name):
        """Publish a proving-ground event (after the node's subscription matched)."""
        assert wait_until(lambda: self.event_pub.get_subscription_count() > 0, 10.0)
        msg = String()
        msg.data = name
        self.event_pub.publish(msg)

    def wait_for_node(self, timeout_s=60.0):
        ok = wait_until(lambda: all(p.get_subscription_count() for p in self.pubs)
                        and all(s.get_publisher_count() for s in self.subs[:4]), timeout_s)
        time.sleep(0.5)                 # the node's readers see us a little after we see them
        return ok

    def publish(self, corner_stamps, accel, rate, burst=4):
        """Publish sample k of every corner at its grid time / ``rate``, corner by corner."""
        msgs = [encode_imu(corner_stamps[c], accel[3 * c:3 * c + 3], f'{corner}_spindle')
                for c, corner in enumerate(CORNERS)]
        n = corner_stamps[0].size
        start = time.monotonic()
        for lo in range(0, n, burst):
            time.sleep(max(0.0, lo / FS_HZ / rate - (time.monotonic() - start)))
            for c in range(len(CORNERS)):
                for k in range(lo, min(lo + burst, n)):
                    self.pubs[c].publish(msgs[c][k])

    def forces(self, corner):
        stamps, wrench, bad = decode_wrench(list(self.raw[corner]))
        assert not bad.any()
        return stamps, wrench


def received(peer):
    """Return the Imu messages the node reports received per corner (last /diagnostics)."""
    if not peer.health:
        return []
    values = {s.name.rsplit(': ', 1)[-1]: status_values(s) for s in peer.health[-1].status}
    return [int(values[c]['received']) for c in CORNERS if c in values]


def stop_and_collect(proc, peer, n):
    """Stop the node (it completes its look-ahead), wait for ``n`` outputs per corner."""
    # Stop once the node has taken every input (what DDS still holds at a stop is not read).
    assert wait_until(lambda: received(peer) == [n] * 4, 10.0), received(peer)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(20) == 0
    assert wait_until(lambda: all(len(r) == n for r in peer.raw.values()), 5.0), \
        [len(r) for r in peer.raw.values()]
