# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Live node: throughput, latency and CPU through real DDS, next to a bare rclpy relay.

Prints, from one run (node, relay, publisher, each its own process; this script is the
consumer):

- sustained replay rate without a single lost sample, as a multiple of real time (4 corners
  x 512 Hz in, 4 x 512 Hz out), for ``wheel_force_node`` and for a bare relay (raw
  subscribe -> publish, no computation, same EventsExecutor and QoS).  A trial at rate X
  publishes ``--trial-s`` seconds of wall time; it passes when the target received every input
  message (its own counters) and published every output, and the consumer received every
  output of one corner (consuming all four would cost this 2-core machine more than the
  targets themselves);
- latency (receive time - input stamp) p50 / p99 at 1x real time for block sizes 16 / 64 /
  128, with the node's output pacing on (estimates spread over the next block at the input
  rate), next to the block length and the live look-ahead, and the node's CPU % of one core;
- RMSE cost of a few causal-delay settings against the non-causal offline prediction.

Goals: node >= 80 % of the relay and >= 5x real time; p99 <= 2 blocks (filling + pacing) +
look-ahead + 5 ms; CPU <= 25 % at 1x.  The node's counters come from ``/diagnostics``.

Usage: ``.venv/bin/python bench/bench_node.py [--quick]``.
"""
import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from benchutil import ros_testing
import numpy as np

_support = ros_testing()
SpinningParticipant = _support.SpinningParticipant

FS_HZ = 512.0
CORNERS = ('lf', 'rf', 'lr', 'rr')
PERIOD_NS = 1e9 / FS_HZ
HERE = Path(__file__).resolve()


# -- helper processes ------------------------------------------------------------------------

def _ros():
    """Import rclpy lazily: the helper modes and main need it, the RMSE part does not."""
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    return rclpy, Context, EventsExecutor


def input_qos(depth=200):
    """Node default: sensor data, best effort, KEEP_LAST."""
    from rclpy.qos import HistoryPolicy
    from rclpy.qos import QoSProfile
    from rclpy.qos import ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT)


def reliable_qos(depth):
    """Node outputs / publisher: reliable, KEEP_LAST."""
    from rclpy.qos import HistoryPolicy
    from rclpy.qos import QoSProfile
    from rclpy.qos import ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE)


def run_relay():
    """Bare relay: four raw Imu subscriptions republished unchanged; counts on /relay/status."""
    rclpy, _, EventsExecutor = _ros()
    from sensor_msgs.msg import Imu
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node('bare_relay')
    received = [0] * 4
    published = [0] * 4
    pubs = [node.create_publisher(Imu, f'/relay/{c}/imu', reliable_qos(1024)) for c in CORNERS]

    def relay(c):
        publish = pubs[c].publish

        def on_msg(raw):
            received[c] += 1
            publish(raw)
            published[c] += 1
        return on_msg

    subs = [node.create_subscription(Imu, f'/spindle/{c}/imu', relay(k), input_qos(), raw=True)
            for k, c in enumerate(CORNERS)]
    status = node.create_publisher(String, '/relay/status', 10)
    node.create_timer(0.2, lambda: status.publish(String(data=json.dumps(
        {'received': received, 'published': published}))))
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    del subs
    rclpy.try_shutdown()


def run_publisher():
    """Publish as driven by stdin lines ``{"rate": X, "n": N, "start_ns": S, "live": bool}``."""
    rclpy, _, _ = _ros()
    from sensor_msgs.msg import Imu
    from wheel_force_estimator.bagio.cdr import encode_imu
    synthetic_accel = _support.synthetic_accel
    rclpy.init()
    node = rclpy.create_node('bench_publisher')
    pubs = [node.create_publisher(Imu, f'/spindle/{c}/imu', reliable_qos(1000))
            for c in CORNERS]
    accel = synthetic_accel(8192, FS_HZ, seed=3)
    print(json.dumps({'ready': True}), flush=True)
    for line in sys.stdin:
        cmd = json.loads(line)
        if cmd.get('wait_subscribers'):
            while not all(p.get_subscription_count() > 0 for p in pubs):
                time.sleep(0.02)
            print(json.dumps({'subscribed': True}), flush=True)
            continue
        rate, n = cmd['rate'], cmd['n']
        start = time.monotonic()
        if cmd['live']:
            t0_ns = time.time_ns() + 50_000_000
            start_ns = t0_ns
        else:
            start_ns = cmd['start_ns']
        stamps = start_ns + np.round(np.arange(n) * PERIOD_NS).astype(np.int64)
        behind = 0.0
        for lo in range(0, n, 4096):
            hi = min(lo + 4096, n)
            idx = np.arange(lo, hi) % accel.shape[1]
            blobs = [encode_imu(stamps[lo:hi], accel[3 * c:3 * c + 3, idx],
                                f'{CORNERS[c]}_spindle') for c in range(4)]
            i = lo
            while i < hi:
                if cmd['live']:
                    wait = (stamps[i] - time.time_ns()) * 1e-9
                    burst = 1
                else:
                    wait = (stamps[i] - start_ns) * 1e-9 / rate - (time.monotonic() - start)
                    burst = 16
                if wait > 0:
                    time.sleep(wait)
                else:
                    behind = max(behind, -wait)
                for k in range(i - lo, min(i + burst, hi) - lo):
                    for c in range(4):
                        pubs[c].publish(blobs[c][k])
                i = min(i + burst, hi)
        print(json.dumps({'wall_s': time.monotonic() - start, 'behind_s': behind,
                          'last_ns': int(stamps[-1])}), flush=True)
    rclpy.try_shutdown()


# -- consumer (this process) -----------------------------------------------------------------

class Consumer(SpinningParticipant):
    """Counts one output corner, records its latency, follows the targets' counters."""

    def __init__(self):
        super().__init__('bench_consumer')
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import WrenchStamped
        from sensor_msgs.msg import Imu
        from std_msgs.msg import String
        self.raw = {'node': [], 'relay': []}
        self.rx_ns = {'node': [], 'relay': []}
        self.status = {'node': None, 'relay': None}
        self.subs = [
            self.node.create_subscription(WrenchStamped, '/virtual_wft/lf/wrench',
                                          self._cb('node'), reliable_qos(5000), raw=True),
            self.node.create_subscription(Imu, '/relay/lf/imu', self._cb('relay'),
                                          reliable_qos(5000), raw=True),
            self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                          self._on_health, 10),
            self.node.create_subscription(String, '/relay/status', self._on_relay, 10)]
        self.start()

    def _cb(self, target):
        raws, rx = self.raw[target], self.rx_ns[target]

        def on_msg(raw):
            rx.append(time.time_ns())
            raws.append(raw)
        return on_msg

    def _on_health(self, msg):
        corners = [{kv.key: kv.value for kv in s.values} for s in msg.status
                   if s.name.startswith('/wheel_force_node: ')]
        if len(corners) != 4:
            return
        # The node holds its look-ahead until more data (a pause is not the end of the data):
        # an estimate held counts as delivered, the next trial's first samples release it.
        self.status['node'] = {'received': sum(int(v['received']) for v in corners),
                               'published': 4 * (int(corners[0]['published'])
                                                 + int(corners[0]['in_flight'])),
                               'in_flight': int(corners[0]['in_flight'])}

    def _on_relay(self, msg):
        data = json.loads(msg.data)
        self.status['relay'] = {'received': sum(data['received']),
                                'published': sum(data['published']), 'in_flight': 0}

    def wait_for_target(self, target, timeout_s=30.0):
        """Wait until the target's output and status topics reach this consumer."""
        topic = '/virtual_wft/lf/wrench' if target == 'node' else '/relay/lf/imu'
        self.status[target] = None
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.node.count_publishers(topic) > 0 and self.status[target] is not None:
                break
            time.sleep(0.05)
        time.sleep(0.5)   # the writer's side of the match

    def snapshot(self, target):
        st = self.status[target] or {'received': 0, 'published': 0, 'in_flight': 0}
        return dict(st, outputs=len(self.raw[target]))

    def clear_latency(self, target):
        self.raw[target].clear()
        self.rx_ns[target].clear()

    def latency_ms(self, target, skip_s=1.0, tail_s=2.0):
        """
        Return receive time - stamp [ms] of the outputs received since ``clear_latency``.

        The first ``skip_s`` (discovery) and the last ``tail_s`` seconds of stamps are left
        out: the node holds the look-ahead of a stream's end until more data comes.
        """
        from wheel_force_estimator.bagio.cdr import decode_imu
        from wheel_force_estimator.bagio.cdr import decode_wrench
        raws = list(self.raw[target])
        rx = np.array(self.rx_ns[target][:len(raws)], dtype=np.int64)
        stamps = decode_wrench(raws)[0] if target == 'node' else decode_imu(raws).stamp_ns
        lat = (rx - stamps) * 1e-6
        if stamps.size == 0:
            return lat
        keep = (stamps >= stamps[0] + skip_s * 1e9) & (stamps <= stamps[-1] - tail_s * 1e9)
        return lat[keep]


# -- orchestration ---------------------------------------------------------------------------

class Publisher:
    """The publisher helper process, driven line by line."""

    def __init__(self, env):
        self.proc = subprocess.Popen([sys.executable, str(HERE), '--publisher'], env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self._read()

    def _read(self):
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError('publisher helper died')
        return json.loads(line)

    def wait_subscribers(self):
        self.proc.stdin.write(json.dumps({'wait_subscribers': True}) + '\n')
        self.proc.stdin.flush()
        self._read()
        time.sleep(0.5)   # the subscribers' side of the match (best effort drops before it)

    def play(self, rate, n, start_ns=0, live=False):
        self.proc.stdin.write(json.dumps({'rate': rate, 'n': n, 'start_ns': start_ns,
                                          'live': live}) + '\n')
        self.proc.stdin.flush()
        return self._read()

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(10)


def cpu_seconds(pid):
    """User + system CPU time of a process [s] (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def start_target(target, env, model_path=None, block=16, log=None):
    node_command = _support.node_command
    if target == 'relay':
        cmd = [sys.executable, str(HERE), '--relay']
    else:
        cmd = node_command(model_path, {'block_size': block, 'damage_publish_period_s': 0.2,
                                        'output_qos_depth': max(1024, 4 * block)})
    return subprocess.Popen(cmd, env=env, stdout=log or subprocess.DEVNULL,
                            stderr=subprocess.STDOUT)


def settle(consumer, target, expect_received, timeout_s=5.0):
    """Wait until the target's counters stop moving (or reach what was sent)."""
    last, since = None, time.monotonic()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        snap = consumer.snapshot(target)
        if (snap['received'] >= expect_received and snap['published'] >= expect_received
                and (snap['outputs'] + snap['in_flight']) * 4 >= expect_received):
            break
        key = (snap['received'], snap['published'], snap['outputs'])
        if key != last:
            last, since = key, time.monotonic()
        elif time.monotonic() - since > 1.5:
            break
        time.sleep(0.05)
    time.sleep(0.3)
    return consumer.snapshot(target)


def throughput(target, env, consumer, model_path, rates, trial_s, stamp0, block=16):
    """Return (highest lossless rate, table of trials)."""
    proc = start_target(target, env, model_path, block)
    pub = Publisher(env)
    rows, best = [], 0.0
    try:
        pub.wait_subscribers()
        consumer.wait_for_target(target)
        queue, last_ok, first_fail, bisections = list(rates), 0.0, None, 2
        while True:
            if first_fail is None:
                if not queue:
                    break
                rate = queue.pop(0)
            elif bisections:
                # Refine between the last rate that passed and the first that failed.
                bisections -= 1
                rate = round(0.5 * (last_ok + first_fail), 1)
            else:
                break
            n = int(rate * FS_HZ * trial_s)
            before = settle(consumer, target, 0, timeout_s=0.5)
            t_cpu = cpu_seconds(proc.pid)
            res = pub.play(rate, n, start_ns=stamp0)
            cpu = (cpu_seconds(proc.pid) - t_cpu) / res['wall_s']
            stamp0 = res['last_ns'] + 10 * 10**9      # next trial after a gap
            after = settle(consumer, target, before['received'] + 4 * n)
            got_in = after['received'] - before['received']
            got_pub = after['published'] - before['published']
            # held look-ahead counts as delivered (see Consumer._on_health)
            got_out = (after['outputs'] + after['in_flight']
                       - before['outputs'] - before['in_flight'])
            achieved = n / FS_HZ / res['wall_s']
            ok = got_in == 4 * n and got_pub == 4 * n and got_out == n
            rows.append((rate, achieved, got_in, got_pub, got_out, 4 * n, cpu, ok))
            print(f'  {target:5s} block {block:3d} asked {rate:5.1f}x achieved '
                  f'{achieved:5.1f}x: in {got_in}/{4 * n}, published {got_pub}/{4 * n}, '
                  f'lf received {got_out}/{n}, CPU {100 * cpu:5.1f} % -> {"ok" if ok else "LOSS"}',
                  flush=True)
            if ok:
                best = max(best, achieved)
                last_ok = rate
            else:
                first_fail = rate
    finally:
        pub.close()
        proc.send_signal(2)
        proc.wait(10)
    return best, rows, stamp0


def latency_run(env, consumer, model_path, block, seconds, delay_ms):
    proc = start_target('node', env, model_path, block)
    pub = Publisher(env)
    try:
        pub.wait_subscribers()
        consumer.wait_for_target('node')
        consumer.clear_latency('node')
        t_cpu, t_wall = cpu_seconds(proc.pid), time.monotonic()
        pub.play(1.0, int(seconds * FS_HZ), live=True)
        cpu = (cpu_seconds(proc.pid) - t_cpu) / (time.monotonic() - t_wall)
        time.sleep(1.0 + block / FS_HZ + delay_ms * 1e-3)
        lat = consumer.latency_ms('node')
    finally:
        pub.close()
        proc.send_signal(2)
        proc.wait(10)
    return lat, cpu


def relay_cpu_1x(env, consumer, seconds):
    proc = start_target('relay', env)
    pub = Publisher(env)
    try:
        pub.wait_subscribers()
        consumer.wait_for_target('relay')
        consumer.clear_latency('relay')
        t_cpu, t_wall = cpu_seconds(proc.pid), time.monotonic()
        pub.play(1.0, int(seconds * FS_HZ), live=True)
        cpu = (cpu_seconds(proc.pid) - t_cpu) / (time.monotonic() - t_wall)
        time.sleep(0.5)
        lat = consumer.latency_ms('relay')
    finally:
        pub.close()
        proc.send_signal(2)
        proc.wait(10)
    return lat, cpu


# -- causal delay cost (no ROS) --------------------------------------------------------------

def causal_delay_cost(delays):
    """RMSE % of causal predictions against the non-causal offline one, per look-ahead."""
    from wheel_force_estimator.core.metrics import rmse_pct
    from wheel_force_estimator.core.predict import predict_forces
    model, accel, truth, source = realistic_model()
    reference = predict_forces(model, accel)
    rows = []
    for d in delays:
        if d > model.fir_delay_samples:
            continue
        pred = predict_forces(model, accel, causal_delay_samples=d)
        pct = rmse_pct(reference, pred)
        vs_truth = rmse_pct(truth, pred) if truth is not None else np.full(1, np.nan)
        rows.append((d, d / FS_HZ * 1e3, float(np.median(pct)), float(np.max(pct)),
                     float(np.median(vs_truth))))
    return rows, model, source


def realistic_model():
    """Return a model fitted on simulated proving-ground data, its test data and source."""
    try:
        from wheel_force_estimator import INPUT_CHANNELS
        from wheel_force_estimator import OUTPUT_CHANNELS
        from wheel_force_estimator.core.pipeline import fit_model
        from wheel_force_estimator.core.pipeline import FitConfig
        from wheel_force_estimator.core.pipeline import TrainingSegment
        from wheel_force_estimator.sim import simulate
        train = simulate(seed=11, duration_scale=0.1, fs_hz=FS_HZ)
        test = simulate(seed=12, duration_scale=0.05, fs_hz=FS_HZ)
        seg = TrainingSegment(train.accel_mps2, train.force_n, 'sim seed 11')
        model = fit_model([seg], FS_HZ, FitConfig(), INPUT_CHANNELS, OUTPUT_CHANNELS)
        return (model, test.accel_mps2, test.force_n,
                'fitted on 60 s of simulated proving ground (sim seed 11), tested on seed 12')
    except (ImportError, TypeError) as err:
        synthetic_accel = _support.synthetic_accel
        synthetic_model = _support.synthetic_model
        return (synthetic_model(n_taps=1024, delay_samples=512), synthetic_accel(30000), None,
                f'synthetic model ({err})')


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='short trials, fewer rates')
    parser.add_argument('--relay', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--publisher', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--trial-s', type=float, default=None, help='wall seconds per trial')
    parser.add_argument('--blocks', type=lambda t: [int(v) for v in t.split(',')],
                        default=[16, 128], help='node block sizes of the throughput trials')
    parser.add_argument('--no-delay-cost', action='store_true',
                        help='skip the causal-delay RMSE table (fits a model: slow)')
    args = parser.parse_args()
    if args.relay:
        return run_relay()
    if args.publisher:
        return run_publisher()

    from wheel_force_estimator.core.model import save_model
    isolated_ros_env = _support.isolated_ros_env
    synthetic_model = _support.synthetic_model

    env = isolated_ros_env()
    os.environ.update(env)
    trial_s = args.trial_s or (2.0 if args.quick else 4.0)
    rates = [2, 5, 10, 20, 30] if args.quick else [2, 5, 10, 15, 20, 25, 30, 40, 50, 60]
    tmpdir = tempfile.TemporaryDirectory(prefix='bench_node_')
    # Production-sized filter: 1024 taps (Welch segment 1024); the node keeps its default
    # live_look_ahead_s (0.05 s).
    model_path = save_model(synthetic_model(n_taps=1024, delay_samples=512),
                            Path(tmpdir.name) / 'm.npz')
    delay_ms = 1e3 * round(0.05 * FS_HZ) / FS_HZ
    consumer = Consumer()
    try:
        print(f'== throughput (trials of {trial_s:g} s wall; 1024-tap model)')
        stamp0 = 1_700_000_000 * 10**9
        relay_best, _, stamp0 = throughput('relay', env, consumer, None, rates, trial_s, stamp0)
        for block in args.blocks:
            node_best, _, stamp0 = throughput('node', env, consumer, model_path, rates,
                                              trial_s, stamp0, block)
            ratio = node_best / relay_best if relay_best else float('nan')
            print(f'sustained lossless rate, block {block}: node {node_best:.1f}x real time, '
                  f'bare relay {relay_best:.1f}x -> node = {100 * ratio:.0f} % of relay '
                  f'(goals: >= 80 %, >= 5x)', flush=True)

        seconds = 6.0 if args.quick else 12.0
        print(f'== latency and CPU at 1x real time ({seconds:g} s live stream each)')
        lat_r, cpu_r = relay_cpu_1x(env, consumer, seconds)
        print(f'  bare relay: latency p50 {np.percentile(lat_r, 50):.2f} ms, p99 '
              f'{np.percentile(lat_r, 99):.2f} ms, CPU {100 * cpu_r:.1f} % of one core')
        for block in (16, 64, 128):
            lat, cpu = latency_run(env, consumer, model_path, block, seconds, delay_ms)
            block_ms = block / FS_HZ * 1e3
            p50, p99 = np.percentile(lat, [50, 99]) if lat.size else (np.nan, np.nan)
            bound = 2 * block_ms + delay_ms + 5.0
            print(f'  block {block:3d} ({block_ms:5.1f} ms) + look-ahead {delay_ms:.0f} ms: '
                  f'latency p50 {p50:6.1f} ms, p99 {p99:6.1f} ms (goal <= {bound:.0f} ms: '
                  f'{"ok" if p99 <= bound else "MISSED"}), CPU {100 * cpu:4.1f} % of one core '
                  f'(goal <= 25 %), {lat.size} outputs')
    finally:
        consumer.close()
        tmpdir.cleanup()

    if args.no_delay_cost:
        return 0
    print('== causal delay cost: RMSE % of the live (truncated look-ahead) prediction vs the '
          'non-causal offline one, and vs the measured force')
    rows, model, source = causal_delay_cost([0, 16, 32, 64, 128, 256, 512])
    print(f'  model: {source}; full look-ahead {model.fir_delay_samples} samples '
          f'({model.fir_delay_samples / FS_HZ * 1e3:.0f} ms), {model.n_taps} taps')
    for d, ms, med, worst, truth in rows:
        print(f'  look-ahead {d:4d} samples ({ms:6.1f} ms): vs offline median {med:6.2f} %, '
              f'worst channel {worst:6.2f} %; vs measured median {truth:6.2f} %')
    return 0


if __name__ == '__main__':
    sys.exit(main())
