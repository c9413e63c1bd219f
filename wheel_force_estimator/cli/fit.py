# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force fit RECORDING… -o MODEL``: fit the MIMO FRF from instrumented recordings.

Recordings are bags (the twelve spindle accelerations to the twelve wheel forces) or generic
DAQ exports with declared channels (``--input``/``--output``/``--fs``; any number of inputs
of one quantity to any number of forces).  Each gap-free bag segment and each generic file
contributes its own Welch windows.

Short generic records: the CLI's default two-resolution fit needs one record of
``long_segment_length`` samples (8192).  Rig and DAQ exports are often shorter (a 7 s
sine test), so when no generic record is that long and the user did not ask for the long
resolution (``--long-segment-length`` or the params file), the fit falls back to one
resolution and says so; nothing is padded.  When the user did ask, the fit is refused
(exit 1) with the lengths named.  Bags keep the refusal: a proving-ground bag without one
16 s gap-free stretch usually means a wrong or broken recording.
"""
import argparse
import dataclasses
import functools
from pathlib import Path
import sys
from typing import Tuple

from wheel_force_estimator.cli.common import add_generic_arguments
from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import explicit_fit_keys
from wheel_force_estimator.cli.common import fit_channels
from wheel_force_estimator.cli.common import generic_request
from wheel_force_estimator.cli.common import load_fit_config
from wheel_force_estimator.cli.common import nominal_fs_hz
from wheel_force_estimator.cli.common import read_recordings
from wheel_force_estimator.cli.common import topic_config


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``fit``."""
    p = subparsers.add_parser(
        'fit', help='fit the acceleration->force FRF from recordings with a WFT',
        description='Read recordings (rosbag2 mcap/sqlite3 directories or ROS 1 .bag files '
                    'with the four spindle Imu and four WFT topics, or generic DAQ exports '
                    'with --input/--output/--fs), fit the MIMO FRF (Welch, per gap-free '
                    'segment, averaged) and save a model file.')
    p.add_argument('recordings', nargs='+', metavar='RECORDING',
                   help='training recordings: bags, or .csv/.txt/.mat/.npz/.json files with '
                        '--input/--output/--fs')
    p.add_argument('-o', '--out-model', dest='out_model', required=True, metavar='MODEL',
                   help='model file (.npz)')
    p.add_argument('--config', metavar='YAML', help='params file (topics, fit settings)')
    add_namespace_argument(p)
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    p.add_argument('--estimator', choices=('h1', 'h1_tikhonov', 'h1_tsvd'))
    p.add_argument('--segment-length', type=int, metavar='N', help='Welch segment [samples]')
    p.add_argument('--regularisation', type=float, metavar='R')
    p.add_argument('--f-min-hz', type=float, metavar='HZ')
    p.add_argument('--long-segment-length', type=int, metavar='N',
                   help='long Welch segment below the crossover (0 = single resolution; '
                        'default 8192, dropped with a note for generic records shorter '
                        'than that)')
    p.add_argument('--live-look-ahead-s', type=float, metavar='S',
                   help='look-ahead of the live (causal) estimator stored in the model [s] '
                        '(default: live_look_ahead_s of the params file, else 0.05); '
                        '0, 25, 50, 100 and 250 ms are designed too, for the reports')
    add_generic_arguments(p)
    return p


@dataclasses.dataclass(frozen=True)
class _TrainingData:
    """What the fit is computed from, whichever kind of recording it came from."""

    segments: list
    n_read: int
    n_recordings: int
    fs_hz: float
    input_channels: Tuple[str, ...]
    output_channels: Tuple[str, ...]
    input_quantity: str
    fit_info: dict


def _bag_data(args) -> _TrainingData:
    from wheel_force_estimator.bagio import available_extras
    from wheel_force_estimator.core.pipeline import TrainingSegment
    from wheel_force_estimator.core.spindle import declared_inputs
    from wheel_force_estimator.core.spindle import declared_outputs

    topics = topic_config(args)
    channels = fit_channels(args.config)
    if channels.inputs is None or channels.moments is None:
        # "auto": what every training recording carries (fit only what is there)
        found = [set(available_extras(b, topics)) for b in args.recordings]
        available = set.intersection(*found) if found else set()
    else:
        available = set()
    extras = channels.extras(available)
    recordings = read_recordings(args.recordings, topics, require_wft=True, extras=extras)
    inputs = declared_inputs('rates' in extras, 'spin' in extras, channels.split,
                             channels.cornering)
    outputs = declared_outputs('moments' in extras)
    fs_hz = nominal_fs_hz(recordings)
    segments = [TrainingSegment(seg.signals(inputs, fs_hz), seg.signals(outputs),
                                f'{rec.path}#{i}')
                for rec in recordings for i, seg in enumerate(rec.segments)]
    return _TrainingData(segments, sum(s.accel_mps2.shape[1] for s in segments),
                         len(recordings), fs_hz, inputs, outputs,
                         'acceleration',
                         {'bags': [str(Path(b)) for b in args.recordings]})


def _generic_data(request, paths) -> _TrainingData:
    from wheel_force_estimator.core.pipeline import TrainingSegment

    recordings = request.read(paths)
    segments = [TrainingSegment(rec.inputs, rec.outputs, rec.path) for rec in recordings]
    info = {'recordings': [str(Path(p)) for p in paths],
            'input_quantity': request.input_quantity,
            'declared_inputs': [s.text for s in request.inputs],
            'declared_outputs': [s.text for s in request.outputs]}
    return _TrainingData(segments, sum(r.n_samples for r in recordings), len(recordings),
                         request.fs_hz, request.input_channels, request.output_channels,
                         request.input_quantity, info)


def command(args: argparse.Namespace) -> int:
    """Run ``fit``; return the exit code."""
    from wheel_force_estimator.core.design import fit_design
    from wheel_force_estimator.core.model import save_model
    from wheel_force_estimator.core.pipeline import coherence_summary

    request = generic_request(args, args.recordings)
    settings = {'estimator': args.estimator, 'segment_length': args.segment_length,
                'regularisation': args.regularisation, 'f_min_hz': args.f_min_hz,
                'long_segment_length': args.long_segment_length}
    config = load_fit_config(args.config, **settings)
    config = _with_live(config, args)
    data = _bag_data(args) if request is None else _generic_data(request, args.recordings)
    # Bags keep the long-segment refusal; generic records fall back unless the user chose it.
    # Too few long windows for the inputs fall back for both, unless the user chose it.
    explicit = explicit_fit_keys(args.config, **settings)
    channels = fit_channels(args.config)      # validated for every recording kind
    if request is None and channels.inputs is not None:
        explicit = explicit | {'inputs'}      # the input groups imposed: not searched
    elif request is not None and (channels.inputs, channels.moments) != (None, None):
        print(f'note: {args.config}: wheel_force_fit.inputs and .moments choose the '
              f'channels of a spindle model; generic recordings take theirs from --input / '
              f'--output (ignored here)', file=sys.stderr)
    default_long = 'long_segment_length' not in explicit
    fallback = request is not None and default_long
    chosen = request is not None and 'segment_length' not in explicit
    fitted = fit_design(data.segments, data.fs_hz, config, data.input_channels,
                        data.output_channels, data.input_quantity, data.fit_info, fallback,
                        chosen, chosen, default_long, imposed=explicit)
    model = fitted.model
    path = save_model(model, args.out_model)
    summary = coherence_summary(model)
    _print_summary(model, summary, fitted, data)
    if args.report:
        from wheel_force_estimator.offline import compare
        from wheel_force_estimator.offline import training_evaluator
        from wheel_force_estimator.report import live
        from wheel_force_estimator.report.builders import write_fit_report
        cmp = compare(model, training_evaluator(model, data.segments),
                      model.live[0].look_ahead_samples)
        print(live.comparison_text(cmp, model.fs_hz))
        extra = functools.partial(live.report_section, cmp=cmp, fs_hz=model.fs_hz,
                                  data='Training data (in-sample: `evaluate --causal` on '
                                       'held-out recordings is the honest figure)')
        report = write_fit_report(args.report, model, summary, extra)
        print(f'report: {report}')
    print(f'model: {path}')
    return 0


def _with_live(config, args):
    """Return ``config`` designing the live estimators (configured look-ahead first)."""
    from wheel_force_estimator.cli.common import configured_look_ahead_s
    from wheel_force_estimator.core.live_estimator import LiveDesign
    from wheel_force_estimator.core.live_estimator import SWEEP_LOOK_AHEADS_S
    from wheel_force_estimator.cli.common import UsageError
    from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
    look = configured_look_ahead_s(args.config, args.live_look_ahead_s)
    if look > LS_LOOK_AHEAD_S:
        where = ('--live-look-ahead-s' if args.live_look_ahead_s is not None
                 else f'{args.config}: live_look_ahead_s')
        raise UsageError(f'{where} = {look:g} s is outside 0 .. {LS_LOOK_AHEAD_S:g} s (the '
                         f'longest look-ahead `fit` designs the live estimator for)')
    return dataclasses.replace(config, live=LiveDesign(look_aheads_s=(look,)
                                                       + SWEEP_LOOK_AHEADS_S))


def _print_bridged(model) -> None:
    """Say which inputs left lines unexcited inside their band (bridged, not fitted)."""
    for key, length in (('bridged_lines', 'segment_length'),
                        ('bridged_lines_long', 'long_segment_length')):
        counts = {k: v for k, v in (model.fit.get(key) or {}).items() if v}
        if counts:
            text = ', '.join(f'{k} {v}' for k, v in counts.items())
            print(f'unexcited lines inside the band, bridged from the excited ones '
                  f'({model.fit.get(length)}-sample segments; unexcited: '
                  f'{model.fit.get("unexcited")}): {text}')


def _print_summary(model, summary, fitted, data: _TrainingData) -> None:
    config, note = fitted.config, fitted.note
    used = sum(s.accel_mps2.shape[1] for s in fitted.used)
    print(f'recordings: {data.n_recordings}   segments used: {len(fitted.used)}   '
          f'samples used: {used} of {data.n_read} ({used / data.fs_hz:.1f} s)   '
          f'sample rate: {data.fs_hz:g} Hz')
    for line in fitted.skipped:
        print(f'  not used (too short for one Welch segment): {line}')
    if note:
        print(note)
    if fitted.warning:
        print(fitted.warning, file=sys.stderr)
    _print_design(model)
    print(f'estimator: {model.estimator}   segment: {config.segment_length}   '
          f'windows averaged: {model.fit["n_windows"]}')
    if config.long_segment_length:
        print(f'below {config.crossover_hz:g} Hz: segment {config.long_segment_length}, '
              f'windows averaged: {model.fit["n_windows_long"]}   FIR taps: {model.n_taps}')
    _print_bridged(model)
    print('multiple coherence (mean 0.5-50 Hz) and bands with coherence < 0.5:')
    for name in model.output_channels:
        bands = summary['low_bands_hz'][name]
        text = ', '.join(f'{a:.1f}-{b:.1f}' for a, b in bands[:6]) or '-'
        more = f' (+{len(bands) - 6} more)' if len(bands) > 6 else ''
        print(f'  {name:6s} {summary["mean_coherence"][name]:.3f}   low: {text}{more}')
    _print_moment_inputs(model, summary)
    worst = ', '.join(f'{c:.3g} @ {f:.2f} Hz' for f, c in summary['worst_cond'][:3])
    print(f'worst condition numbers of Sxx: {worst}')
    if model.live:
        first = model.live[0]
        others = ', '.join(f'{1e3 * e.look_ahead_samples / model.fs_hz:.1f}'
                           for e in model.live[1:])
        print(f'live estimator: look-ahead {first.look_ahead_samples} samples '
              f'({1e3 * first.look_ahead_samples / model.fs_hz:.1f} ms), '
              f'{first.info["method"]}, history {first.history_samples / model.fs_hz:.2f} s; '
              f'also stored: {others or "-"} ms')


def _print_moment_inputs(model, summary) -> None:
    """Say which inputs the moments were given and whether the coherence supports them."""
    from wheel_force_estimator.report.builders import moment_input_lines
    for line in moment_input_lines(model, summary):
        print(line)


def _print_design(model) -> None:
    """Print the design each output was given and its held-out (cross-validated) RMSE."""
    design = model.fit.get('design') or {}
    if design.get('method') != 'blocked_cross_validation':
        return
    imposed = ', '.join(design['imposed']) or 'none'
    print(f'design chosen by blocked cross-validation ({design["n_blocks"]} blocks; imposed '
          f'settings: {imposed}); held-out RMSE % unfiltered / 1 Hz high-passed:')
    for name, row in design['rows'].items():
        detail = ', '.join(f'{k} {v:g}' if isinstance(v, float) else f'{k} {v}'
                           for k, v in row.items()
                           if k not in ('family', 'cv_rmse_pct', 'cv_rmse_hp1_pct',
                                        'input_sets'))
        print(f'  {name:6s} {row["family"]:8s} {row["cv_rmse_pct"]:6.1f} '
              f'{row["cv_rmse_hp1_pct"]:6.1f}   {detail}')
    sets = [s['name'] for s in design.get('input_sets') or ()]
    if len(sets) > 1:
        from wheel_force_estimator.core.search import other_set_folds
        folds = other_set_folds(design)
        where = (f'; on the input-set folds: {folds["n_blocks"]} blocks, '
                 f'{folds["scoring_segment_length"]}-sample segments' if folds else '')
        together = ('; the four corners of a component choose together'
                    if design.get('input_set_groups') else '')
        print(f'held-out RMSE % per input set (best candidate of each set{where}; '
              f'unfiltered / 1 Hz high-passed{together}):')
        print(f'  {"":6s} ' + '  '.join(f'{n:>17s}' for n in sets))
        for name, row in design['rows'].items():
            per = row['input_sets']
            print(f'  {name:6s} ' + '  '.join(
                f'{per[n]["cv_rmse_pct"]:8.1f}/{per[n]["cv_rmse_hp1_pct"]:<8.1f}'
                for n in sets))
