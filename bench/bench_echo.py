# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Keep-last-5 readers (like ``ros2 topic echo``) of the live node's output at 1x, under CPU load.

Prints, per number of busy loops beside the graph (``--loads``, default 0 / 2 / 3 on this
2-core machine), over ``--runs`` runs each: the messages lost by a reliable and a best-effort
keep-last-5 reader (each its own process) of the node's four wrench topics, next to the same two
readers of the feeder's four Imu topics (baseline: a plain steady 512 Hz publisher).  The node
runs in both, so the load is the same; only what the readers read differs.  Losses on both lines
are the readers' own scheduling (a Python reader must get the CPU every ~10 ms); losses on the
node's line only would be the node's output.  ``test_ros_graph.py`` checks what the node
controls, the pacing of its writes, from their source timestamps.

Usage: ``.venv/bin/python bench/bench_echo.py [--runs 3] [--loads 0,2,3]``.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from benchutil import ros_testing
from benchutil import ROS_TESTING_SCRIPT
import numpy as np

from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.core.model import save_model

_support = ros_testing()
isolated_ros_env = _support.isolated_ros_env
sample_stamps = _support.sample_stamps
SpinningParticipant = _support.SpinningParticipant
start_node = _support.start_node
stop_node = _support.stop_node
synthetic_accel = _support.synthetic_accel
synthetic_model = _support.synthetic_model
wait_until = _support.wait_until

FS_HZ = 512.0
CORNERS = ('lf', 'rf', 'lr', 'rr')
N_SAMPLES = 1536                                  # 3 s at 1x, as the graph tests


class Feeder(SpinningParticipant):
    """Four reliable Imu publishers at the sample rate, one sample per corner at a time."""

    def __init__(self):
        from rclpy.qos import HistoryPolicy
        from rclpy.qos import QoSProfile
        from rclpy.qos import ReliabilityPolicy
        from sensor_msgs.msg import Imu
        super().__init__('echo_bench_feeder')
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                         reliability=ReliabilityPolicy.RELIABLE)
        self.pubs = [self.node.create_publisher(Imu, f'/spindle/{c}/imu', qos)
                     for c in CORNERS]
        self.start()

    def publish(self, stamps, accel):
        """Publish at 1x real time."""
        msgs = [encode_imu(stamps, accel[3 * c:3 * c + 3], f'{corner}_spindle')
                for c, corner in enumerate(CORNERS)]
        start = time.monotonic()
        for k in range(stamps.size):
            time.sleep(max(0.0, (stamps[k] - stamps[0]) * 1e-9 - (time.monotonic() - start)))
            for c, pub in enumerate(self.pubs):
                pub.publish(msgs[c][k])


def one_run(env, model_path, topics, kind, seed):
    """Return ``[reliable lost, best-effort lost]`` (summed over the four topics) of one run."""
    node = start_node(model_path, env, {'input_reliability': 'reliable'})
    feeder = Feeder()
    readers = []
    try:
        assert wait_until(lambda: all(p.get_subscription_count() for p in feeder.pubs), 60.0)
        readers = [subprocess.Popen(
            [sys.executable, str(ROS_TESTING_SCRIPT), '--type', kind,
             reliability, '5', str(N_SAMPLES), '20', *topics],
            env=env, stdout=subprocess.PIPE, text=True)
            for reliability in ('reliable', 'best_effort')]
        for reader in readers:
            assert reader.stdout.readline().strip() == 'ready'
        time.sleep(1.0)
        stamps = sample_stamps(N_SAMPLES)
        feeder.publish(stamps, synthetic_accel(N_SAMPLES, FS_HZ, seed=seed))
        counts = [json.loads(reader.stdout.readline())['counts'] for reader in readers]
    finally:
        feeder.close()
        for reader in readers:
            if reader.poll() is None:
                reader.kill()
            reader.wait()
        stop_node(node)
    return [4 * N_SAMPLES - sum(c) for c in counts]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--runs', type=int, default=3, help='runs per load and target')
    parser.add_argument('--loads', type=lambda t: [int(v) for v in t.split(',')],
                        default=[0, 2, 3], help='busy loops beside the graph, comma-separated')
    args = parser.parse_args()
    env = isolated_ros_env()
    os.environ.update(env)                        # the feeder runs in this process
    targets = (('node wrench', 'wrench', [f'/virtual_wft/{c}/wrench' for c in CORNERS]),
               ('baseline: feeder Imu', 'imu', [f'/spindle/{c}/imu' for c in CORNERS]))
    with tempfile.TemporaryDirectory() as tmp:
        model_path = save_model(synthetic_model(fs_hz=FS_HZ, n_taps=96, delay_samples=40),
                                f'{tmp}/model.npz')
        print(f'{"busy loops":>10s}  {"readers of":22s} {"runs lossless":>14s} '
              f'{"lost per run, reliable | best effort (of 4 x 1536)":>52s}')
        for load in args.loads:
            loops = [subprocess.Popen([sys.executable, '-c', 'while True: pass'])
                     for _ in range(load)]
            try:
                for name, kind, topics in targets:
                    lost = np.array([one_run(env, model_path, topics, kind, seed)
                                     for seed in range(args.runs)])
                    print(f'{load:10d}  {name:22s} {int((lost.sum(1) == 0).sum()):>8d} of '
                          f'{args.runs:<3d} {" ".join(map(str, lost[:, 0])):>24s} | '
                          f'{" ".join(map(str, lost[:, 1]))}', flush=True)
            finally:
                for loop in loops:
                    loop.kill()
                    loop.wait()


if __name__ == '__main__':
    main()
