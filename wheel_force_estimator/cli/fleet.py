# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force fleet MODEL PATH… --out DIR``: fleet damage on a Dask cluster.

One task per bag (read -> predict -> pseudo damage, damage per hour, relative damage
spectrum; RMSE % when the bag has WFT topics), on a LocalCluster of worker processes or an
existing cluster (``--scheduler``).  Writes ``fleet.csv`` and ``fleet.json`` (percentiles of
damage per hour; with ``--reference``, repeats of the proving-ground schedule for the P-th
percentile customer over ``--target-hours``).  Exit 1 when any bag failed (its row says why).
"""
import argparse


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``fleet``."""
    p = subparsers.add_parser(
        'fleet', help='damage of many bags on a Dask cluster: customer percentiles vs a '
                      'proving-ground schedule',
        description='Predict the wheel forces of every bag under PATH (rosbag2 directories '
                    'and ROS 1 .bag files, searched recursively) on a Dask cluster, one task '
                    'per bag, and tabulate pseudo damage and damage per hour per channel, '
                    'with fleet percentiles and the proving-ground correlation.  A rerun '
                    'skips bags whose result is already in --out.')
    p.add_argument('model', metavar='MODEL', help='model file (.npz)')
    p.add_argument('paths', nargs='+', metavar='PATH', help='bag or directory of bags')
    p.add_argument('--out', required=True, metavar='DIR',
                   help='output directory: fleet.csv, fleet.json, results/ (resume), forces/')
    p.add_argument('--reference', nargs='+', default=[], metavar='BAG',
                   help='bags of the proving-ground schedule (one pass)')
    p.add_argument('--target-hours', type=float, metavar='H', default=None,
                   help='customer usage the reference must represent (default 6000 h: '
                        '240 000 km at 40 km/h)')
    p.add_argument('--scheduler', metavar='ADDRESS',
                   help='running Dask scheduler, e.g. tcp://host:8786 (default: a local '
                        'cluster of worker processes)')
    p.add_argument('--workers', type=int, metavar='N',
                   help='worker processes of the local cluster (default: the usable cores)')
    p.add_argument('--write-forces', action='store_true',
                   help="write each bag's predicted forces to DIR/forces/<bag id> as "
                        '`predict` does')
    p.add_argument('--config', metavar='YAML', help='params file (topic names)')
    p.add_argument('--sn-slope', type=float, default=5.0, help='Basquin exponent k')
    p.add_argument('--sn-slope-moment', type=float, default=None, metavar='K',
                   help='Basquin exponent of the wheel moments (torsion; default: --sn-slope)')
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    return p


def _check_args(args) -> None:
    import math

    from wheel_force_estimator.cli.common import UsageError
    if args.workers is not None and args.scheduler:
        raise UsageError('--workers sizes the local cluster; with --scheduler the cluster '
                         'has its own workers')
    if args.workers is not None and args.workers < 1:
        raise UsageError(f'--workers must be >= 1, got {args.workers}')
    if not (math.isfinite(args.sn_slope) and args.sn_slope > 0):
        raise UsageError(f'--sn-slope must be a finite number > 0, got {args.sn_slope:g}')
    if args.target_hours is not None:
        if not args.reference:
            raise UsageError('--target-hours needs --reference')
        if not (math.isfinite(args.target_hours) and args.target_hours > 0):
            raise UsageError(f'--target-hours must be a finite number > 0, '
                             f'got {args.target_hours:g}')


def _progress():
    """Return an ``on_result`` callback drawing a bar when stderr is a terminal, or None."""
    import sys
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm
    bar = {}

    def update(result, n_done, n_total):
        if 'bar' not in bar:
            bar['bar'] = tqdm(total=n_total, desc='fleet', unit='bag', leave=False)
        bar['bar'].update(1)
        if n_done == n_total:
            bar['bar'].close()
    return update


def command(args: argparse.Namespace) -> int:
    """Run ``fleet``; return the exit code."""
    import logging

    from wheel_force_estimator.fleet import DEFAULT_TARGET_HOURS
    from wheel_force_estimator.fleet import run_fleet
    from wheel_force_estimator.fleet.errors import FleetError
    from wheel_force_estimator.report.fleet import fleet_text

    _check_args(args)
    # Dask logs worker restarts and slow shutdowns as warnings; a failed bag is reported in
    # its row instead.  (Importing distributed configures its loggers, so quiet them after.)
    import distributed  # noqa: F401
    logging.getLogger('distributed').setLevel(logging.ERROR)
    outcome = run_fleet(
        args.model, args.paths, args.out, reference_paths=args.reference,
        scheduler=args.scheduler, workers=args.workers, write_forces=args.write_forces,
        config_path=args.config, sn_slope=args.sn_slope, sn_slope_moment=args.sn_slope_moment,
        target_hours=(DEFAULT_TARGET_HOURS if args.target_hours is None
                      else args.target_hours),
        on_result=_progress())
    print(fleet_text(outcome))
    print(f'tables: {outcome.csv_path}, {outcome.json_path} ({outcome.n_computed} bag(s) '
          f'processed, {outcome.n_cached} taken from earlier runs)')
    if args.report:
        from wheel_force_estimator.report.fleet import write_fleet_report
        print(f'report: {write_fleet_report(args.report, outcome)}')
    failed = outcome.failed
    if failed:
        total = len(outcome.results) + len(outcome.reference_results)
        raise FleetError(f'{len(failed)} of {total} bag(s) failed (status "failed" in '
                         f'{outcome.csv_path}), e.g. {failed[0].error}')
    return 0
