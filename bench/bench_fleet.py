# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
`wheel-force fleet` throughput: 16 two-minute bags on 1 and 2 Dask worker processes.

Writes ``--bags`` bags of ``--minutes`` each (4 Imu + 4 WrenchStamped topics at 512 Hz, the
known linear system of ``bench_cli.make_bag``; with WFT topics every task also computes RMSE,
the heavier path), fits a model on one of them, then times:

- baseline: a plain loop over the same bags in this one process (``fleet.task.process_bag``,
  no Dask, no store), after one warm-up bag;
- ``run_fleet`` on a LocalCluster of 1 and of 2 worker processes (one thread each), warmed up
  on every worker first (numba compiles once per process); the cluster start is timed apart.

Goals (issue 17): 2 workers >= 1.7x the throughput of 1 on this 2-core machine; 1 worker
within 10 % of the plain loop.  Also printed: each worker's peak RSS (``ru_maxrss`` of the
worker process) and, from the measured per-bag cost, what a 1000-vehicle season costs on N
workers.

Usage: ``python bench/bench_fleet.py [--bags 16] [--minutes 2] [--repeat 2] [--keep DIR]``
"""
import argparse
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

from wheel_force_estimator.fleet.discover import file_sha256
from wheel_force_estimator.fleet.discover import find_bags
from wheel_force_estimator.fleet.run import run_fleet
from wheel_force_estimator.fleet.task import FleetSettings
from wheel_force_estimator.fleet.task import process_bag


def _peak_rss_mb():
    """Return this process's peak RSS [MB] (VmHWM: unlike ru_maxrss, not inherited)."""
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('VmHWM:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


def _make_bag(path, minutes, seed):
    # in a child process, so this process's peak RSS is the plain loop's
    code = ('import sys; from pathlib import Path; sys.path.insert(0, sys.argv[1]); '
            'from bench_cli import make_bag; '
            'make_bag(Path(sys.argv[2]), float(sys.argv[3]), seed=int(sys.argv[4]))')
    subprocess.run([sys.executable, '-c', code, str(Path(__file__).parent), str(path),
                    str(minutes), str(seed)], check=True)


def _warm(path, model, sha):
    ref = find_bags([path])[0]
    return process_bag(ref, FleetSettings(model, sha, 5.0)).status


def timed_cluster(n_workers, fleet_dir, model, sha, warm_bag, out, repeat):
    """Return (start s, best run s, peak RSS MB per worker) on a fresh LocalCluster."""
    from distributed import Client
    from distributed import LocalCluster
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)
    t_start = time.perf_counter() - t0
    try:
        client.run(_warm, str(warm_bag), str(model), sha)
        best = float('inf')
        for i in range(repeat):
            target = out / f'w{n_workers}_{i}'
            t0 = time.perf_counter()
            outcome = run_fleet(model, [fleet_dir], target,
                                scheduler=cluster.scheduler_address)
            best = min(best, time.perf_counter() - t0)
            assert outcome.n_computed == len(outcome.results) and not outcome.failed
        rss = sorted(client.run(_peak_rss_mb).values())
    finally:
        client.close()
        cluster.close()
    return t_start, best, rss


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--bags', type=int, default=16)
    parser.add_argument('--minutes', type=float, default=2.0)
    parser.add_argument('--repeat', type=int, default=2, help='timed runs per setting')
    parser.add_argument('--keep', help='directory to keep the bags in')
    args = parser.parse_args()
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='wf_bench_fleet_'))
    work.mkdir(parents=True, exist_ok=True)
    fleet_dir = work / 'fleet'
    try:
        t0 = time.perf_counter()
        for i in range(args.bags):
            bag = fleet_dir / f'car_{i:03d}'
            if not bag.exists():
                _make_bag(bag, args.minutes, seed=100 + i)
        warm_bag = work / 'warm'
        if not warm_bag.exists():
            _make_bag(warm_bag, min(args.minutes, 0.5), seed=1)
        model = work / 'model.npz'
        if not model.exists():
            subprocess.run([sys.executable, '-m', 'wheel_force_estimator', 'fit',
                            str(fleet_dir / 'car_000'), '-o', str(model)], check=True,
                           stdout=subprocess.DEVNULL)
        print(f'{args.bags} bags x {args.minutes:g} min written, model fitted: '
              f'{time.perf_counter() - t0:.1f} s')
        sha = file_sha256(model)
        refs = find_bags([fleet_dir])
        settings = FleetSettings(str(model), sha, 5.0)
        _warm(str(warm_bag), str(model), sha)
        t_loop = float('inf')
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            for ref in refs:
                assert process_bag(ref, settings).ok
            t_loop = min(t_loop, time.perf_counter() - t0)
        rss_loop = _peak_rss_mb()
        out = work / 'out'
        shutil.rmtree(out, ignore_errors=True)
        start1, t1, rss1 = timed_cluster(1, fleet_dir, model, sha, warm_bag, out, args.repeat)
        start2, t2, rss2 = timed_cluster(2, fleet_dir, model, sha, warm_bag, out, args.repeat)
        data_s = args.bags * args.minutes * 60.0
        print(f'\n{"setting":34s} {"wall s":>7s} {"s/bag":>6s} {"x real time":>11s}  notes')
        print(f'{"plain loop, one process":34s} {t_loop:7.2f} {t_loop / args.bags:6.3f} '
              f'{data_s / t_loop:11.0f}  peak RSS {rss_loop:.0f} MB')
        print(f'{"run_fleet, 1 worker process":34s} {t1:7.2f} {t1 / args.bags:6.3f} '
              f'{data_s / t1:11.0f}  cluster start {start1:.1f} s, worker peak RSS '
              f'{", ".join(f"{r:.0f}" for r in rss1)} MB')
        print(f'{"run_fleet, 2 worker processes":34s} {t2:7.2f} {t2 / args.bags:6.3f} '
              f'{data_s / t2:11.0f}  cluster start {start2:.1f} s, worker peak RSS '
              f'{", ".join(f"{r:.0f}" for r in rss2)} MB')
        print(f'\nspeed-up 2 vs 1 worker: {t1 / t2:.2f}x (goal >= 1.7x)')
        print(f'overhead of 1 worker vs the plain loop: {100 * (t1 / t_loop - 1):+.1f} % '
              f'(goal <= 10 %)')
        per_hour_s = t1 / (data_s / 3600.0)
        season_h = 1000 * 200.0
        print(f'\nper worker: {per_hour_s:.2f} s of compute per hour of recording')
        print(f'1000-vehicle season, 200 h of recording per vehicle = {season_h:.0f} h:')
        for n in (1, 2, 16, 64, 256):
            print(f'  {n:4d} workers: {season_h * per_hour_s / n / 3600.0:8.2f} h '
                  f'(assuming linear scaling and storage keeping up)')
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
