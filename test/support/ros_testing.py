# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Helpers for tests and benchmarks of the ROS side: synthetic models, isolated DDS runs.

Not installed with the package: tests import it as ``support.ros_testing`` (``test/`` is on
``sys.path`` under pytest), benchmarks through ``bench/benchutil.ros_testing``, and the message
counter runs as a script (``python test/support/ros_testing.py ...``).

DDS isolation follows DESIGN.md: participants stay on this machine
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and on a domain drawn at random per run, so
parallel runs never talk to each other.
"""
import os
from pathlib import Path
import random
import subprocess
import sys
import time
from typing import Dict, Mapping, Optional, Sequence

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.model import FrfModel

NS_PER_S = 1_000_000_000


def synthetic_model(fs_hz: float = 512.0, n_taps: int = 128, delay_samples: int = 48,
                    seed: int = 0, input_channels: Sequence[str] = INPUT_CHANNELS,
                    output_channels: Sequence[str] = OUTPUT_CHANNELS) -> FrfModel:
    """
    Return a model with random two-sided, decaying, zero-DC FIR taps (no fitting).

    The FRF arrays are the taps' response on a 256-point grid; coherences are 1.  Static
    force about 1-3 kN, static acceleration gravity on z.

    Parameters
    ----------
    fs_hz : float
        Sample rate [Hz].
    n_taps : int
        FIR length [samples].
    delay_samples : int
        Look-ahead (tap index of lag zero) [samples].
    seed : int
        Random seed.
    input_channels, output_channels : sequence of str
        Channel names.

    Returns
    -------
    FrfModel

    """
    rng = np.random.default_rng(seed)
    n_in, n_out = len(input_channels), len(output_channels)
    lag = np.arange(n_taps) - delay_samples
    taps = rng.normal(size=(n_out, n_in, n_taps)) * np.exp(-np.abs(lag) / (n_taps / 10)) * 40.0
    taps -= taps.mean(axis=-1, keepdims=True)
    f_hz = np.fft.rfftfreq(256, 1.0 / fs_hz)
    h = np.einsum('fk,oik->foi', np.exp(-2j * np.pi * np.outer(f_hz, lag) / fs_hz), taps)
    static_accel = np.zeros(n_in)
    static_accel[2::3] = 9.81
    return FrfModel(
        fs_hz=fs_hz, input_channels=tuple(input_channels),
        output_channels=tuple(output_channels), f_hz=f_hz, h=h,
        coherence_ordinary=np.ones(h.shape), coherence_multiple=np.ones(h.shape[:2]),
        cond_sxx=np.ones(f_hz.size), fir_taps=taps, fir_delay_samples=delay_samples,
        static_force_n=rng.uniform(1000.0, 3000.0, n_out), static_accel_mps2=static_accel,
        estimator='h1', fit={'source': 'synthetic_model (tests)'})


def synthetic_accel(n_samples: int, fs_hz: float = 512.0, seed: int = 1) -> np.ndarray:
    """Return ``(12, n_samples)`` spindle accelerations: low-passed noise plus gravity on z."""
    rng = np.random.default_rng(seed)
    white = rng.normal(size=(len(INPUT_CHANNELS), n_samples + 64)) * 3.0
    kernel = np.hanning(9)
    x = np.apply_along_axis(lambda r: np.convolve(r, kernel / kernel.sum(), 'same'), 1, white)
    x = x[:, 64:]
    x[2::3] += 9.81
    return x


def sample_stamps(n_samples: int, fs_hz: float = 512.0,
                  start_ns: int = 1_700_000_000 * NS_PER_S) -> np.ndarray:
    """Return ``n_samples`` stamps on the ideal clock of ``fs_hz`` [ns]."""
    return start_ns + np.round(np.arange(n_samples) * (NS_PER_S / fs_hz)).astype(np.int64)


#: Environment variable naming the DDS domain of test runs (else one is drawn at random).
TEST_DOMAIN_VARIABLE = 'WFT_TEST_DOMAIN_ID'


def isolated_ros_env(base: Optional[Mapping[str, str]] = None) -> Dict[str, str]:
    """
    Return an environment for DDS participants private to this run.

    The domain is ``$WFT_TEST_DOMAIN_ID`` when set (give each of several concurrent test runs
    on one machine its own: two random draws can meet, and then one run counts the other's
    messages), else drawn at random.  Never the user's ``ROS_DOMAIN_ID``: that may be a live
    graph.
    """
    env = dict(os.environ if base is None else base)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    chosen = env.get(TEST_DOMAIN_VARIABLE)
    # Domains 1..100 keep Fast DDS's port mapping clear of the Linux ephemeral port range.
    env['ROS_DOMAIN_ID'] = chosen or str(random.SystemRandom().randint(1, 100))
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    return env


def remove_dead_shared_memory(shm_dir: Path = Path('/dev/shm')) -> int:
    """
    Remove the Fast DDS shared-memory ports and segments no live process holds; return how many.

    Jazzy's rmw_fastrtps (8.4.3) with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` always uses
    shared memory: neither ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` nor an XML profile without
    builtin transports removes it (measured: ``/proc/PID/maps`` lists
    ``/dev/shm/fastrtps_portN``; with the default range, SUBNET, the variable does).  A
    participant killed hard (SIGKILL, ``os._exit``, a SIGSTOPped process killed) leaves its
    ports behind (eProsima/Fast-DDS#1144, #5053).  A later participant with the same
    participant id opens the dead port (of its domain, or port 7000 + id, which every domain
    shares in LOCALHOST mode, measured) and was never discovered: the
    stalled-subscriber test's second message counter waited forever for the node's publishers
    (CI twice, here 1 run in 4).  So a test that kills a participant hard calls this once the
    process is gone, before it starts the next one.

    Each live port or segment holds an ``flock`` on its ``_el`` (or ``_sl``) file; one that
    can be locked has no live owner.  A port being created is not locked yet: call this only
    while no participant on the machine is starting (the ROS tests run one at a time).  This
    is what Fast DDS's ``fastdds shm clean`` does (not in the Jazzy wheels), written here
    because nothing installed does it.
    """
    import fcntl
    import re

    lock_name = re.compile(r'^(fastrtps_(?:port\d{1,5}|[0-9a-z]{16}))_(?:el|sl)$')
    removed = 0
    for lock in sorted(shm_dir.glob('fastrtps_*')):
        match = lock_name.match(lock.name)
        if match is None:
            continue
        try:
            with open(lock, 'ab') as handle:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue                      # held: its owner is alive
        base = match.group(1)
        for name in (base, lock.name, f'sem.{base}_mutex'):
            try:
                (shm_dir / name).unlink()
            except FileNotFoundError:
                pass
        removed += 1
    return removed


def node_command(model_path, params: Mapping[str, object] = (),
                 params_file: Optional[Path] = None, ros_args: Sequence[str] = ()) -> list:
    """Return the command line running ``wheel_force_node`` with parameter overrides."""
    cmd = [sys.executable, '-m', 'wheel_force_estimator.ros.run', '--ros-args', *ros_args]
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    cmd += ['-p', f'model_path:={model_path}']
    for key, value in dict(params).items():
        if isinstance(value, (list, tuple)):
            value = '[' + ', '.join(f'"{v}"' if isinstance(v, str) else repr(v)
                                    for v in value) + ']'
        elif isinstance(value, float):
            value = repr(value)
        elif isinstance(value, bool):
            value = str(value).lower()
        cmd += ['-p', f'{key}:={value}']
    return cmd


def start_node(model_path, env: Mapping[str, str], params: Mapping[str, object] = (),
               log_path: Optional[Path] = None, params_file: Optional[Path] = None,
               ros_args: Sequence[str] = ()) -> subprocess.Popen:
    """Start the node as a subprocess (stdout/stderr to ``log_path`` or discarded)."""
    out = open(log_path, 'w') if log_path is not None else subprocess.DEVNULL
    try:
        proc = subprocess.Popen(node_command(model_path, params, params_file, ros_args),
                                env=dict(env), stdout=out, stderr=subprocess.STDOUT)
        proc.log_path = log_path        # stop_node shows it when the node will not stop
        return proc
    finally:
        if log_path is not None:
            out.close()


def stop_node(proc: subprocess.Popen, timeout_s: float = 10.0) -> int:
    """
    Stop the node (or another ROS process of a test) with SIGINT, like Ctrl-C; return its code.

    A process that does not stop within ``timeout_s`` is killed (-9), and the end of its log is
    printed: pytest shows it under the failing test.
    """
    if proc.poll() is None:
        proc.send_signal(2)
        try:
            return proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            remove_dead_shared_memory()
            log_path = getattr(proc, 'log_path', None)
            if log_path is not None and Path(log_path).exists():
                print(f'node did not stop within {timeout_s} s; end of {log_path}:\n'
                      + Path(log_path).read_text(errors='replace')[-4000:])
            return -9
    return proc.returncode


def wait_until(predicate, timeout_s: float, period_s: float = 0.02) -> bool:
    """Poll ``predicate`` until it is true or ``timeout_s`` passed; return its last value."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return bool(predicate())


class SpinningParticipant:
    """
    A node in its own rclpy context, spun by an EventsExecutor in a background thread.

    Subclasses create their publishers/subscriptions on ``self.node`` and then call
    :meth:`start`.  The executor is spun with a finite timeout (the Jazzy wheels' EventsExecutor
    spins at 100 % CPU and runs nothing without one).
    """

    def __init__(self, name: str):
        import rclpy
        from rclpy.context import Context
        self._rclpy = rclpy
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = None
        self.stop = None
        self.thread = None

    def start(self):
        """Start spinning in a daemon thread."""
        import threading

        from rclpy.experimental import EventsExecutor
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self.stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self):
        """Stop spinning and shut the context down."""
        if self.thread is not None:
            self.stop.set()
            self.thread.join()
            self.executor.shutdown()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)


#: How long the message counter waits for a publisher on every topic [s] (then it says which
#: topics have none and exits 2, so a test fails with that line, not at pytest's timeout).
COUNTER_DISCOVERY_S = 60.0


def count_messages_main(argv: Sequence[str]) -> int:
    """
    Count raw messages on topics in a process of its own, like ``ros2 topic echo``.

    ``python test/support/ros_testing.py [--type imu|wrench] [--source-stamps]
    RELIABILITY DEPTH EXPECTED TIMEOUT_S TOPIC...`` subscribes every TOPIC (KEEP_LAST
    ``DEPTH``), prints ``ready`` once each has a publisher (else, after
    :data:`COUNTER_DISCOVERY_S`, ``not ready: ...`` and exits 2), then one JSON line when every
    topic reached ``EXPECTED`` messages or ``TIMEOUT_S`` passed after the first message:
    ``{"counts": [...]}``, with ``--source-stamps`` also ``"source_ns"``: per topic, the
    writer's source timestamp of every message [ns] (when the publisher *wrote* it: how it
    paced its output, whatever this reader's own scheduling).
    """
    import argparse
    import json

    from geometry_msgs.msg import WrenchStamped
    import rclpy
    from rclpy.qos import HistoryPolicy
    from rclpy.qos import QoSProfile
    from rclpy.qos import ReliabilityPolicy
    from rclpy.task import Future
    from sensor_msgs.msg import Imu

    parser = argparse.ArgumentParser(prog='ros_testing.py')
    parser.add_argument('--type', choices=('wrench', 'imu'), default='wrench')
    parser.add_argument('--source-stamps', action='store_true')
    parser.add_argument('reliability', choices=('reliable', 'best_effort'))
    parser.add_argument('depth', type=int)
    parser.add_argument('expected', type=int)
    parser.add_argument('timeout_s', type=float)
    parser.add_argument('topics', nargs='+')
    args = parser.parse_args(argv)
    topics, expected = args.topics, args.expected
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=args.depth,
                     reliability=(ReliabilityPolicy.RELIABLE if args.reliability == 'reliable'
                                  else ReliabilityPolicy.BEST_EFFORT))
    rclpy.init()
    node = rclpy.create_node('message_counter')
    counts = [0] * len(topics)
    source_ns = [[] for _ in topics]
    first = []
    done = Future()

    def counter(k):
        def count():
            if not first:
                first.append(time.monotonic())
            counts[k] += 1
            if counts[k] == expected and min(counts) >= expected:
                done.set_result(True)

        def on_msg(_raw):
            count()

        def on_msg_with_info(_raw, info):
            source_ns[k].append(info['source_timestamp'])
            count()
        return on_msg_with_info if args.source_stamps else on_msg

    msg_type = {'wrench': WrenchStamped, 'imu': Imu}[args.type]
    subs = [node.create_subscription(msg_type, t, counter(k), qos, raw=True)
            for k, t in enumerate(topics)]
    if args.source_stamps:
        # The Jazzy wheels' EventsExecutor cannot hand message info to a callback
        # ("SystemError: null argument"); a deep reader does not need its speed.
        from rclpy.executors import SingleThreadedExecutor
        executor = SingleThreadedExecutor()
    else:
        # Messages are taken by the executor's own loop, one Python call each, as a
        # subscriber spun by ``rclpy.spin`` would (``ros2 topic echo``): a Python turn per
        # message would cost more than the messages themselves.
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor()
    executor.add_node(node)
    try:
        deadline = time.monotonic() + COUNTER_DISCOVERY_S
        while not all(node.count_publishers(t) for t in topics):
            if time.monotonic() > deadline:
                missing = [t for t in topics if not node.count_publishers(t)]
                print(f'not ready: no publisher on {", ".join(missing)} after '
                      f'{COUNTER_DISCOVERY_S:g} s', flush=True)
                return 2
            executor.spin_once(timeout_sec=0.01)
        print('ready', flush=True)
        while not done.done() and not (first and time.monotonic() - first[0] > args.timeout_s):
            executor.spin_until_future_complete(done, timeout_sec=0.1)
    finally:
        out = {'counts': counts}
        if args.source_stamps:
            out['source_ns'] = source_ns
        print(json.dumps(out), flush=True)
        del subs
        executor.shutdown()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(count_messages_main(sys.argv[1:]))
