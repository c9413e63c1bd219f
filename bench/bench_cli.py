# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
`wheel-force fit` and `wheel-force predict` on one hour of 4-corner 512 Hz data (rosbag2).

Writes a 1 h mcap bag (4 Imu + 4 WrenchStamped topics, 14.7 M messages) with a known linear
12x12 system, then runs the real CLI in subprocesses and reads their wall time and peak RSS
(``ru_maxrss`` of the child).  Baselines in the same run: rosbags' per-message reading +
deserialisation of the same bag (the floor a naive reader would pay before any numeric work)
and the bag's own duration (real time).  Goals (issue 3): fit <= 60 s and <= 4 GB,
predict >= 2000x real time.  ``predict`` runs ``--repeat`` times with its default zstd chunk
compression and as many times uncompressed (best and median printed).

Usage: ``python bench/bench_cli.py [--minutes 60] [--keep DIR] [--repeat 3]``
"""
import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy import signal

from wheel_force_estimator.bagio import write_recording

FS_HZ = 512.0
PERIOD_NS = 1_953_125


def make_bag(path: Path, minutes: float, seed: int = 0):
    """Write a bag of a known linear system, in 10-minute pieces to bound memory."""
    n = int(minutes * 60 * FS_HZ)
    rng = np.random.default_rng(seed)
    b_in, a_in = signal.butter(2, 40 / (FS_HZ / 2))
    x = signal.lfilter(b_in, a_in, rng.normal(size=(12, n)), axis=1).astype(np.float64)
    mix = rng.normal(size=(12, 12)) * 30 + np.eye(12) * 300
    b, a = signal.butter(2, 15 / (FS_HZ / 2))
    y = signal.lfilter(b, a, mix @ x, axis=1) + 3000.0
    x[2::3] += 9.81
    stamps = 1_700_000_000 * 10**9 + PERIOD_NS * np.arange(n, dtype=np.int64)
    write_recording(path, stamps, x, y, storage='mcap')
    return n


def run_child(args):
    """Run a command; return (wall s, peak RSS bytes of that child alone, stdout)."""
    with tempfile.TemporaryFile('w+') as out, tempfile.TemporaryFile('w+') as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=err, text=True)
        # wait4 reports the rusage of this one child (RUSAGE_CHILDREN would be the max over
        # every child so far, including the one that wrote the bag)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f'{args} failed:\n{err.read()}')
        return wall, usage.ru_maxrss * 1024, out.read()


def naive_read_rate(path: Path, limit: int = 200_000) -> float:
    """Messages/s of rosbags AnyReader + deserialize_cdr on the first ``limit`` messages."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore
    from rosbags.typesys import Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    t0 = time.perf_counter()
    count = 0
    with AnyReader([path], default_typestore=store) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            count += 1
            if count >= limit:
                break
    return count / (time.perf_counter() - t0)


def first_touch_s_per_gb() -> float:
    """Seconds per GB to fault in fresh anonymous memory in a new process (the VM's cost)."""
    code = ('import time, numpy as np\n'
            't = time.perf_counter()\n'
            'a = np.empty(1 << 29, np.uint8)\n'
            'a[::4096] = 1\n'
            'print((time.perf_counter() - t) * 2)')
    return float(subprocess.run([sys.executable, '-c', code], check=True, capture_output=True,
                                text=True).stdout)


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--minutes', type=float, default=60.0)
    parser.add_argument('--keep', help='directory to keep the bags in')
    parser.add_argument('--repeat', type=int, default=3, help='predict runs per mode')
    parser.add_argument('--make-only', metavar='BAG', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.make_only:
        make_bag(Path(args.make_only), args.minutes)
        return 0
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='wf_bench_cli_'))
    work.mkdir(parents=True, exist_ok=True)
    bag = work / 'hour'
    try:
        if bag.exists():
            shutil.rmtree(bag)
        t0 = time.perf_counter()
        # in a child process: the parent must stay small, because a forked child's ru_maxrss
        # starts from the parent's resident set
        subprocess.run([sys.executable, __file__, '--minutes', str(args.minutes),
                        '--make-only', str(bag)], check=True)
        n = int(args.minutes * 60 * FS_HZ)
        t_write = time.perf_counter() - t0
        seconds = n / FS_HZ
        n_msgs = 8 * n
        wf = [sys.executable, '-m', 'wheel_force_estimator']
        model = work / 'model.npz'
        t_fit, rss_fit, _ = run_child(wf + ['fit', str(bag), '-o', str(model)])
        os.sync()  # the bag just written must not be flushed to disk during the timed runs
        runs = {}
        for mode in ('zstd', 'none') * args.repeat:
            out = work / f'pred_{mode}'
            if out.exists():
                shutil.rmtree(out)
            runs.setdefault(mode, []).append(run_child(
                wf + ['predict', str(model), str(bag), '-o', str(out), '--compression', mode]))
        naive = naive_read_rate(bag)
        touch = first_touch_s_per_gb()
        print(f'data: {seconds / 60:.0f} min x 4 corners at {FS_HZ:g} Hz = {n_msgs / 1e6:.1f} M '
              f'messages, bag written in {t_write:.1f} s')
        print(f'{"step":34s} {"wall s":>8s} {"x real time":>12s} {"peak RSS GB":>12s}  goal')
        print(f'{"wheel-force fit":34s} {t_fit:8.1f} {seconds / t_fit:12.0f} '
              f'{rss_fit / 1e9:12.2f}  <= 60 s, <= 4 GB')
        for mode, label in (('zstd', 'predict (default, zstd chunks)'),
                            ('none', 'predict --compression none')):
            walls = sorted(r[0] for r in runs[mode])
            rss = max(r[1] for r in runs[mode])
            print(f'{label:34s} {walls[0]:8.1f} {seconds / walls[0]:12.0f} {rss / 1e9:12.2f}  '
                  f'>= 2000x real time (best of {len(walls)}; median '
                  f'{seconds / walls[len(walls) // 2]:.0f}x)')
        print(f'{"baseline: rosbags per-message read":34s} {n_msgs / naive:8.1f} '
              f'{seconds / (n_msgs / naive):12.0f} {"":12s}  (extrapolated from 200 k msgs)')
        print(f'machine: first touch of fresh memory costs {touch:.2f} s per GB in a new '
              f'process (page cache of a new output file too), so peak RSS and output size '
              f'are time here')
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == '__main__':
    os.environ.setdefault('MPLBACKEND', 'Agg')
    sys.exit(main())
