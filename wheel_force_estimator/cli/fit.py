# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force fit BAG… -o MODEL``: fit the MIMO FRF from instrumented recordings."""
import argparse
from pathlib import Path

from wheel_force_estimator.cli.common import load_fit_config
from wheel_force_estimator.cli.common import nominal_fs_hz
from wheel_force_estimator.cli.common import read_recordings


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``fit``."""
    p = subparsers.add_parser(
        'fit', help='fit the acceleration->force FRF from recordings with a WFT',
        description='Read recordings (rosbag2 mcap/sqlite3 directories or ROS 1 .bag files) '
                    'with the four spindle Imu and four WFT topics, fit the 12x12 MIMO FRF '
                    '(Welch, per gap-free segment, averaged) and save a model file.')
    p.add_argument('bags', nargs='+', metavar='BAG', help='training recordings')
    p.add_argument('-o', '--output', required=True, metavar='MODEL', help='model file (.npz)')
    p.add_argument('--config', metavar='YAML', help='params file (topics, fit settings)')
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    p.add_argument('--estimator', choices=('h1', 'h1_tikhonov', 'h1_tsvd'))
    p.add_argument('--segment-length', type=int, metavar='N', help='Welch segment [samples]')
    p.add_argument('--regularisation', type=float, metavar='R')
    p.add_argument('--f-min-hz', type=float, metavar='HZ')
    p.add_argument('--long-segment-length', type=int, metavar='N',
                   help='long Welch segment below the crossover (0 = single resolution)')
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``fit``; return the exit code."""
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.bagio import load_topic_config
    from wheel_force_estimator.core.model import save_model
    from wheel_force_estimator.core.pipeline import coherence_summary
    from wheel_force_estimator.core.pipeline import fit_model
    from wheel_force_estimator.core.pipeline import TrainingSegment

    config = load_fit_config(args.config, estimator=args.estimator,
                             segment_length=args.segment_length,
                             regularisation=args.regularisation, f_min_hz=args.f_min_hz,
                             long_segment_length=args.long_segment_length)
    topics = load_topic_config(args.config)
    recordings = read_recordings(args.bags, topics, require_wft=True)
    fs_hz = nominal_fs_hz(recordings)
    segments, skipped = [], []
    n_read = 0
    for rec in recordings:
        for i, seg in enumerate(rec.segments):
            n = seg.stamp_ns.size
            n_read += n
            source = f'{rec.path}#{i}'
            if n < config.segment_length:
                skipped.append(f'{source}: {n} samples < segment length '
                               f'{config.segment_length}')
                continue
            segments.append(TrainingSegment(seg.accel_mps2, seg.force_n, source))
    model = fit_model(segments, fs_hz, config, INPUT_CHANNELS, OUTPUT_CHANNELS,
                      fit_info={'bags': [str(Path(b)) for b in args.bags]})
    path = save_model(model, args.output)
    summary = coherence_summary(model)
    used = sum(s.accel_mps2.shape[1] for s in segments)
    print(f'recordings: {len(recordings)}   segments used: {len(segments)}   '
          f'samples used: {used} of {n_read} ({used / fs_hz:.1f} s)   '
          f'sample rate: {fs_hz:g} Hz')
    for line in skipped:
        print(f'  not used (too short for one Welch segment): {line}')
    print(f'estimator: {model.estimator}   segment: {config.segment_length}   '
          f'windows averaged: {model.fit["n_windows"]}')
    if config.long_segment_length:
        print(f'below {config.crossover_hz:g} Hz: segment {config.long_segment_length}, '
              f'windows averaged: {model.fit["n_windows_long"]}   FIR taps: {model.n_taps}')
    print('multiple coherence (mean 0.5-50 Hz) and bands with coherence < 0.5:')
    for name in model.output_channels:
        bands = summary['low_bands_hz'][name]
        text = ', '.join(f'{a:.1f}-{b:.1f}' for a, b in bands[:6]) or '-'
        more = f' (+{len(bands) - 6} more)' if len(bands) > 6 else ''
        print(f'  {name:6s} {summary["mean_coherence"][name]:.3f}   low: {text}{more}')
    worst = ', '.join(f'{c:.3g} @ {f:.2f} Hz' for f, c in summary['worst_cond'][:3])
    print(f'worst condition numbers of Sxx: {worst}')
    if args.report:
        from wheel_force_estimator.report.builders import write_fit_report
        report = write_fit_report(args.report, model, summary)
        print(f'report: {report}')
    print(f'model: {path}')
    return 0
