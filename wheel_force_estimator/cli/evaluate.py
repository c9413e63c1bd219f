# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force evaluate MODEL RECORDING…``: compare the prediction with the recorded force.

Recordings are bags (spindle accelerations and WFT) or generic DAQ exports with declared
channels (``--input``/``--output``/``--fs``).  A generic file is one gap-free segment with
sample times from 0 at ``--fs`` and no road events.  The model must have been fitted on the
same channels (names, input quantity) at the same rate; nothing is renamed or resampled.

``--samples A..B[,C..D…]`` (one recording) judges only those samples of the whole-record
prediction, each range as a gap-free segment of its own (``core.evaluation.select_samples``):
the form ``diagnose`` prints in ``fit.report_on`` for a single holdout file, so its figures
are reproducible.
"""
import argparse
import functools
import json
from pathlib import Path

from wheel_force_estimator.cli.common import add_generic_arguments
from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import topic_config


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``evaluate``."""
    p = subparsers.add_parser(
        'evaluate', help='RMSE %%, pseudo damage and spectra of the prediction vs the WFT',
        description='Predict the forces of each recording and judge them against the '
                    'recorded WFT: RMSE % (unfiltered and 1 Hz high-passed) per channel and '
                    "per road event with the paper's rubric, pseudo damage ratio, relative "
                    'damage spectrum and ASD.  Generic DAQ exports are read with '
                    '--input/--output/--fs.')
    p.add_argument('model', metavar='MODEL', help='model file (.npz)')
    p.add_argument('recordings', nargs='+', metavar='RECORDING',
                   help='validation recordings with measured force: bags, or '
                        '.csv/.txt/.mat/.npz/.json files with --input/--output/--fs')
    p.add_argument('--json', metavar='FILE', help='write the figures as JSON')
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    p.add_argument('--config', metavar='YAML', help='params file (topic names, sn_slope)')
    add_namespace_argument(p)
    p.add_argument('--sn-slope', type=float, default=5.0, help='Basquin exponent k')
    p.add_argument('--sn-slope-moment', type=float, default=None, metavar='K',
                   help='Basquin exponent of the wheel moments (torsion; default: --sn-slope)')
    p.add_argument('--samples', metavar='A..B[,C..D...]',
                   help='judge only these samples of the one RECORDING (0-based, half-open, '
                        'counted over its gap-free segments in order) on the prediction of '
                        'the whole record; each range is judged as a segment of its own. '
                        'diagnose prints this for a single holdout file in fit.report_on')
    from wheel_force_estimator.cli.common import add_causal_arguments
    add_causal_arguments(p, 'evaluate')
    add_generic_arguments(p)
    return p


def sample_ranges(args):
    """
    Return the parsed ``--samples`` (None when not given).

    Raises
    ------
    UsageError
        Malformed ranges, or ``--samples`` with more than one recording.

    """
    if args.samples is None:
        return None
    from wheel_force_estimator.cli.common import UsageError
    from wheel_force_estimator.core.sample_ranges import parse_ranges
    if len(args.recordings) != 1:
        raise UsageError(f'--samples selects samples of one recording; '
                         f'{len(args.recordings)} were given')
    try:
        return parse_ranges(args.samples)
    except ValueError as err:
        raise UsageError(f'--samples: {err}') from err


def check_generic_model(model, model_path, request) -> None:
    """
    Refuse a model whose channels, input quantity or rate differ from the declared ones.

    Raises
    ------
    ModelFileError
        Naming the model file and the first channel (or the rate / quantity) that differs.

    """
    from wheel_force_estimator.core.errors import ModelFileError
    from wheel_force_estimator.daqio import quantity_of_unit
    for option, declared, fitted in (('--input', request.input_channels, model.input_channels),
                                     ('--output', request.output_channels,
                                      model.output_channels)):
        if declared == fitted:
            continue
        k = next((k for k, (a, b) in enumerate(zip(declared, fitted)) if a != b),
                 min(len(declared), len(fitted)))
        got = repr(declared[k]) if k < len(declared) else 'nothing'
        want = repr(fitted[k]) if k < len(fitted) else 'nothing'
        raise ModelFileError(
            f'{model_path}: model channel {k} is {want} but {option} declares {got} '
            f'(model: {list(fitted)}, declared: {list(declared)}); nothing is renamed')
    if abs(model.fs_hz - request.fs_hz) > 1e-6 * model.fs_hz:
        raise ModelFileError(f'{model_path}: model fitted at {model.fs_hz:g} Hz but --fs is '
                             f'{request.fs_hz:g} Hz; nothing is resampled')
    unit = model.units.get('input', 'm/s^2')
    quantity = quantity_of_unit(unit)
    if quantity != request.input_quantity:
        raise ModelFileError(f'{model_path}: model inputs are {quantity or "unknown"} '
                             f'({unit}) but --input declares {request.input_quantity}')


def command(args: argparse.Namespace) -> int:
    """Run ``evaluate``; return the exit code."""
    from wheel_force_estimator.cli.common import generic_request
    from wheel_force_estimator.cli.common import announce
    from wheel_force_estimator.cli.common import causal_delay
    from wheel_force_estimator.core.model import load_model
    from wheel_force_estimator.offline import evaluate_generic
    from wheel_force_estimator.offline import evaluate_recordings
    from wheel_force_estimator.report.builders import evaluation_text

    request = generic_request(args, args.recordings)
    ranges = sample_ranges(args)
    model = load_model(args.model)
    delay = causal_delay(args, model.fs_hz)
    announce(model, args.model, delay)
    if request is None:
        from wheel_force_estimator.cli.common import check_bag_model
        from wheel_force_estimator.cli.common import read_recordings
        from wheel_force_estimator.offline import bag_extras
        check_bag_model(model, args.model)
        recordings = read_recordings(args.recordings, topic_config(args),
                                     require_wft=True, expected_fs_hz=model.fs_hz,
                                     extras=bag_extras(model, args.model))

        def run(d):
            return evaluate_recordings(model, recordings, args.sn_slope, d, ranges,
                                       args.sn_slope_moment)
    else:
        check_generic_model(model, args.model, request)
        generic = request.read(args.recordings)

        def run(d):
            return evaluate_generic(model, generic, args.sn_slope, d, ranges)
    evaluation, segments = run(delay)
    print(evaluation_text(evaluation))
    doc = evaluation.to_json()
    extra = None
    if delay is not None and delay != model.fir_delay_samples:
        # The live estimate side by side with the offline one, and against look-ahead.
        from wheel_force_estimator.offline import compare
        from wheel_force_estimator.report import live
        cmp = compare(model, lambda d: evaluation if d == delay else run(d)[0], delay)
        print('\n' + live.comparison_text(cmp, model.fs_hz))
        doc.update(live.comparison_json(cmp, model.fs_hz))
        doc['offline'] = {'channels': cmp.offline.to_json()['channels']}
        extra = functools.partial(live.report_section, cmp=cmp, fs_hz=model.fs_hz,
                                  data=f'{len(segments)} evaluated segment(s)')
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(doc, indent=1))
        print(f'json: {args.json}')
    if args.report:
        from wheel_force_estimator.report.builders import write_evaluation_report
        report = write_evaluation_report(args.report, model, evaluation, segments, extra)
        print(f'report: {report}')
    return 0
