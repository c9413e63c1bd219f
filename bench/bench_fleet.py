# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
`wheel-force fleet` throughput: 16 two-minute bags on 1 and 2 Dask worker processes.

Writes ``--bags`` bags of ``--minutes`` each (4 Imu + 4 WrenchStamped topics at 512 Hz, the
known linear system of ``bench_cli.make_bag``; with WFT topics every task also computes RMSE,
the heavier path), fits a model on one of them, then times:

- baseline: a plain loop over the same bags in this one process (``fleet.task.process_bag``,
  no Dask, no store), after one warm-up bag;
- ``run_fleet`` on the LocalCluster it starts itself (``fleet.engine.dask_client``) with 1 and
  with 2 worker processes (one thread each), warmed up
  on every worker first (numba compiles once per process); the cluster start is timed apart.

The settings are timed in interleaved rounds (best wall time of ``--repeat`` each), with the
CPU time they used (workers + the client process, which hosts the LocalCluster's scheduler)
and the load average around each run, because on a shared machine the wall-time ratios
measure the other users as much as this code.

Goals (issue 17): 2 workers >= 1.7x the throughput of 1 on this 2-core machine; 1 worker
within 10 % of the plain loop.  Also printed: each worker's peak RSS (``ru_maxrss`` of the
worker process) and, from the measured per-bag cost, what a 1000-vehicle season costs on N
workers.

Usage: ``python bench/bench_fleet.py [--bags 16] [--minutes 2] [--repeat 2] [--keep DIR]``
"""
import argparse
import contextlib
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

from wheel_force_estimator.fleet.discover import file_sha256
from wheel_force_estimator.fleet.discover import find_bags
from wheel_force_estimator.fleet.engine import dask_client
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


def _cpu_s():
    """Return this process's CPU time, user + system [s]."""
    t = os.times()
    return t.user + t.system


class Setting:
    """One way of running the fleet, timed in rounds interleaved with the others."""

    def __init__(self, name, run, cpu):
        self.name, self._run, self._cpu = name, run, cpu
        self.walls, self.cpus, self.loads = [], [], []

    def measure(self):
        load0 = os.getloadavg()[0]
        c0 = self._cpu()
        t0 = time.perf_counter()
        self._run()
        self.walls.append(time.perf_counter() - t0)
        self.cpus.append(self._cpu() - c0)
        self.loads.append((load0 + os.getloadavg()[0]) / 2)

    @property
    def best(self):
        return min(self.walls)


def start_cluster(stack, n_workers, model, sha, warm_bag):
    """Return (client, start s) of the LocalCluster ``run_fleet`` starts, workers warmed up."""
    t0 = time.perf_counter()
    client = stack.enter_context(dask_client(None, n_workers))
    t_start = time.perf_counter() - t0
    client.run(_warm, str(warm_bag), str(model), sha)
    return client, t_start


def cluster_setting(name, client, fleet_dir, model, out):
    """Return the Setting running ``run_fleet`` on ``cluster`` (into a fresh --out)."""
    count = [0]

    def run():
        count[0] += 1
        outcome = run_fleet(model, [fleet_dir], out / f'{name}_{count[0]}',
                            scheduler=client.scheduler.address)
        assert outcome.n_computed == len(outcome.results) and not outcome.failed

    def cpu():
        # workers + this process (the LocalCluster's scheduler runs in it)
        return sum(client.run(_cpu_s).values()) + _cpu_s()
    return Setting(name, run, cpu)


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

        def loop():
            for ref in refs:
                assert process_bag(ref, settings).ok
        out = work / 'out'
        shutil.rmtree(out, ignore_errors=True)
        plain = Setting('plain loop, one process', loop, _cpu_s)
        plain.measure()
        rss_loop = _peak_rss_mb()
        with contextlib.ExitStack() as stack:
            client1, start1 = start_cluster(stack, 1, model, sha, warm_bag)
            client2, start2 = start_cluster(stack, 2, model, sha, warm_bag)
            one = cluster_setting('w1', client1, fleet_dir, model, out)
            two = cluster_setting('w2', client2, fleet_dir, model, out)
            # interleaved rounds: a change of the machine's load hits every setting alike
            for i in range(args.repeat):
                for setting in ((one, two) if i == 0 else (plain, one, two)):
                    setting.measure()
            rss1 = sorted(client1.run(_peak_rss_mb).values())
            rss2 = sorted(client2.run(_peak_rss_mb).values())
        t_loop, t1, t2 = plain.best, one.best, two.best
        data_s = args.bags * args.minutes * 60.0
        print(f'\n{"setting":30s} {"best wall s":>11s} {"s/bag":>6s} {"x real time":>11s} '
              f'{"CPU s/bag":>9s} {"load avg":>8s}  notes')
        notes = {plain: f'peak RSS {rss_loop:.0f} MB',
                 one: f'cluster start {start1:.1f} s, worker peak RSS '
                      f'{", ".join(f"{r:.0f}" for r in rss1)} MB',
                 two: f'cluster start {start2:.1f} s, worker peak RSS '
                      f'{", ".join(f"{r:.0f}" for r in rss2)} MB'}
        names = {plain: 'plain loop, one process', one: 'run_fleet, 1 worker process',
                 two: 'run_fleet, 2 worker processes'}
        for setting in (plain, one, two):
            print(f'{names[setting]:30s} {setting.best:11.2f} {setting.best / args.bags:6.3f} '
                  f'{data_s / setting.best:11.0f} {min(setting.cpus) / args.bags:9.3f} '
                  f'{setting.loads[setting.walls.index(setting.best)]:8.1f}  '
                  f'{notes[setting]}')
        print(f'\nspeed-up 2 vs 1 worker (best wall): {t1 / t2:.2f}x (goal >= 1.7x)')
        print(f'overhead of 1 worker vs the plain loop: wall {100 * (t1 / t_loop - 1):+.1f} %, '
              f'CPU {100 * (min(one.cpus) / min(plain.cpus) - 1):+.1f} % (goal <= 10 %)')
        print(f'machine: {os.cpu_count()} cores, load average during the runs '
              f'{min(min(s.loads) for s in (plain, one, two)):.1f}-'
              f'{max(max(s.loads) for s in (plain, one, two)):.1f}')
        cpu1, cpu2 = min(one.cpus), min(two.cpus)
        print(f'CPU per bag 2 vs 1 worker: {cpu2 / cpu1:.2f}x; projected speed-up with a free '
              f'core per worker: {2 * cpu1 / cpu2:.2f}x')
        per_hour_s = cpu1 / (data_s / 3600.0)
        season_h = 1000 * 200.0
        print(f'\nper worker: {per_hour_s:.1f} s of CPU per hour of recording (1 worker, a '
              f'dedicated core assumed)')
        print(f'1000-vehicle season, 200 h of recording per vehicle = {season_h:.0f} h:')
        for n in (1, 16, 64, 256):
            print(f'  {n:4d} workers: {season_h * per_hour_s / n / 3600.0:8.2f} h '
                  f'(linear scaling, storage keeping up)')
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
