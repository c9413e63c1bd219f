# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force diagnose``: name the physics a simulation (or model) leaves out."""
import argparse
import sys

from wheel_force_estimator.cli.common import add_generic_arguments
from wheel_force_estimator.cli.common import add_namespace_argument
from wheel_force_estimator.cli.common import topic_config
from wheel_force_estimator.cli.common import UsageError


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``diagnose``."""
    p = subparsers.add_parser(
        'diagnose', help='sim-vs-real diagnosis: locate the mismatch, name the missing physics',
        description="Predict the real forces with the simulation's FRF (--sim), a model "
                    '(--model, any declared input quantity) or - without either - the best '
                    'linear dynamic model fitted on the real data (the MIMO FIR `fit` makes), '
                    'locate the residual (bands, time windows, operating regime), rank '
                    'candidate physics by the residual they explain on held-out data against a '
                    'time-shifted-feature null, and score the reference, the plain fit on the '
                    'real data and the written model on the report half of the holdout (without '
                    '--holdout: on held-out blocks of the real recordings, each model fitted on '
                    'the other blocks) exactly as `evaluate` does, unfiltered and 1 Hz '
                    'high-passed.  Generic recordings (CSV/MAT/NPZ/JSON) are read with '
                    '--input/--output role specs and --fs.  The method: docs/diagnosis.md.')
    p.add_argument('--real', nargs='+', required=True, metavar='FILE',
                   help='real recordings (bags, or generic files with --input/--output)')
    ref = p.add_mutually_exclusive_group()
    ref.add_argument('--sim', nargs='+', metavar='FILE', help='simulation recordings')
    ref.add_argument('--model', metavar='MODEL', help='model file (.npz) as the reference')
    p.add_argument('--holdout', nargs='+', default=[], metavar='FILE',
                   help='real recordings kept out of fitting: with two or more files the 1st, '
                        '3rd, ... decide (gate, written model) and the 2nd, 4th, ... report '
                        '(`evaluate OUT_MODEL` on those reproduces fit.after); one file is '
                        'predicted whole and its samples halved - per gap-free segment, or per '
                        'road event when it has markers (first halves decide, second halves '
                        'report; fit.report_on gives the `evaluate FILE --samples ...` that '
                        'reproduces the figures)')
    p.add_argument('--json', required=True, metavar='FILE', help='write the diagnosis here')
    p.add_argument('--out-model', metavar='MODEL',
                   help='write the best model: reference or real-data FRF + fitted physics '
                        'terms, the reference, or the plain real-data fit, per group of '
                        'channels, as the gate half of the holdout (without one: held-out '
                        'blocks of the real recordings) prefers, never worse than the plain fit '
                        'there in either figure (fit.model in the JSON says which)')
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    p.add_argument('--config', metavar='YAML', help='params file (topic names, fit settings)')
    add_namespace_argument(p)
    add_generic_arguments(p)
    p.add_argument('--no-travel', action='store_true',
                   help='ignore the suspension travel topic: diagnose spindle acceleration -> '
                        'force even when every bag carries travel')
    p.add_argument('--highpass-hz', type=float, metavar='HZ',
                   help='corner of the band-limited integration of the features (default 0.2)')
    p.add_argument('--linear', choices=('auto', 'frf', 'regression'), default='auto',
                   help='linear reference fitted on --sim recordings: the MIMO FRF, a '
                        'per-channel F0 + k x + c v + m a law, or auto (FRF for acceleration '
                        'inputs)')
    return p


def _generic(request, args):
    from wheel_force_estimator.diagnosis.generic import motion_recording

    def load(paths):
        return [motion_recording(rec) for rec in request.read(paths)]
    return load(args.real), (load(args.sim) if args.sim else None), load(args.holdout)


def _bags(args, reference=None):
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.bagio.travel import TRAVEL_CHANNELS
    from wheel_force_estimator.cli.common import read_recordings
    from wheel_force_estimator.core.derived import accel_derived_count
    from wheel_force_estimator.diagnosis.recording import from_bag_recording
    topics = topic_config(args)

    def read_all(paths):  # the travel topic too, unless --no-travel
        return read_recordings(paths, topics, require_wft=True, travel=not args.no_travel)
    read = {name: read_all(paths) if paths else None
            for name, paths in (('real', args.real), ('sim', args.sim),
                                ('holdout', args.holdout))}
    bags = [r for recs in read.values() for r in recs or ()]
    # Suspension travel in every bag (and a simulation to compare with): diagnose it as the
    # generic path does a string-potentiometer export, travel in, vertical forces out.
    travel = bool(args.sim) and not args.no_travel and all(r.travel_topic for r in bags)
    if travel:
        print(f'suspension travel ({topics.travel_topic}) in every bag: diagnosing travel -> '
              'vertical force (--no-travel for the spindle accelerations)')
    elif any(r.travel_topic for r in bags) and not args.no_travel:
        without = [str(r.path) for r in bags if not r.travel_topic]
        print(f'suspension travel not used: {"no --sim reference" if not args.sim else ""}'
              f'{"; " if not args.sim and without else ""}'
              f'{"not in " + ", ".join(without) if without else ""}')
    # the spindle accelerations; with the splits derived from them when the --model declares
    # them (a model of `wheel-force fit`: its inputs are read as predict reads them)
    inputs = INPUT_CHANNELS
    if reference is not None:
        declared = tuple(reference.input_channels)
        n_derived = accel_derived_count(declared)
        if n_derived and declared[:-n_derived] == INPUT_CHANNELS:
            inputs = declared
    channels = ((TRAVEL_CHANNELS, tuple(c for c in OUTPUT_CHANNELS if c.endswith('fz')))
                if travel else (inputs, OUTPUT_CHANNELS))

    def load(recs):
        out = []
        for rec in recs:
            out.extend(from_bag_recording(rec, *channels, travel=travel))
        return out
    return (load(read['real']), load(read['sim']) if args.sim else None,
            load(read['holdout'] or ()))


def command(args: argparse.Namespace) -> int:
    """Run ``diagnose``; return the exit code."""
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.cli.common import generic_request
    request = generic_request(args, args.real, args.sim, args.holdout)

    from wheel_force_estimator.cli.common import explicit_fit_keys
    from wheel_force_estimator.cli.common import load_fit_config
    from wheel_force_estimator.core.model import load_model
    from wheel_force_estimator.core.model import save_model
    from wheel_force_estimator.diagnosis.features import FeatureConfig
    from wheel_force_estimator.diagnosis.pipeline import diagnose
    from wheel_force_estimator.diagnosis.run import DiagnosisConfig

    reference = None
    if args.model:
        reference = load_model(args.model)
        if request is None and len(reference.output_channels) > len(OUTPUT_CHANNELS):
            # a six-component model: the diagnosis (force physics) works on its forces
            from wheel_force_estimator.core.model import select_outputs
            reference = select_outputs(reference, OUTPUT_CHANNELS)
        if request is not None:
            from wheel_force_estimator.cli.evaluate import check_generic_model
            check_generic_model(reference, args.model, request)
    real, sim, holdout = _bags(args, reference) if request is None else _generic(request, args)
    if args.out_model and real and real[0].input_quantity == 'displacement' and (
            request is None):
        raise UsageError('--out-model: the travel diagnosis fits travel -> vertical force, '
                         'which predict cannot apply to spindle accelerations; add --no-travel')
    reference = reference if args.model else sim
    features = FeatureConfig() if args.highpass_hz is None else FeatureConfig(args.highpass_hz)
    # One fit design with `wheel-force fit`: same params file, same short-record rule.
    explicit = explicit_fit_keys(args.config)
    # The plain fit on the real data is `fit`'s: the traction/braking and cornering splits
    # offered to every row of bags unless the params file's `inputs` leaves them out (generic
    # recordings and the suspension travel are fitted on their own channels, as `fit` fits
    # them).
    from wheel_force_estimator.cli.common import fit_channels
    derived = () if request is not None else fit_channels(args.config).derived
    config = DiagnosisConfig(features=features, fit=load_fit_config(args.config),
                             linear=args.linear, derived=derived,
                             fit_fallback=request is not None
                             and 'long_segment_length' not in explicit,
                             long_window_fallback='long_segment_length' not in explicit,
                             segment_fallback=request is not None
                             and 'segment_length' not in explicit,
                             choose_resolution=request is not None
                             and 'segment_length' not in explicit, progress=True)
    result = diagnose(real, reference, holdout, config)
    path = result.write_json(args.json)
    for m in result.mismatch[:4]:
        bands = ', '.join(f'{a:.1f}-{b:.1f} Hz' for a, b in m.bands_hz) or '-'
        print(f'mismatch {m.channel:8s} RMSE {m.rmse_pct:6.1f} %  bands {bands}  '
              f'regime {m.regime}')
    for line in result.summary:
        print(line)
    for line in result.rejected:
        print(f'  not accepted: {line}')
    if result.fit.data == 'too_short':
        for note in result.fit.notes:
            print(f'warning: {note}', file=sys.stderr)
    if args.out_model:
        from wheel_force_estimator.core.errors import DiagnosisError
        if result.model is None:
            raise DiagnosisError('no FRF model to write: the reference is not one and the real '
                                 'recordings could not be fitted (see the notes above)')
        model = result.model
        if not model.live and result.fit.model != 'model':
            # Like `fit`, the written model carries live estimators for the node (the
            # configured look-ahead first).  A model whose linear map is the --model's keeps
            # that model's estimators (or none, when it is written unchanged).
            from wheel_force_estimator.cli.common import configured_look_ahead_s
            from wheel_force_estimator.core.live_estimator import LiveDesign
            from wheel_force_estimator.core.live_estimator import SWEEP_LOOK_AHEADS_S
            from wheel_force_estimator.diagnosis.written import with_live_estimators
            look = configured_look_ahead_s(args.config)
            try:
                model = with_live_estimators(model, real, LiveDesign(
                    look_aheads_s=(look,) + SWEEP_LOOK_AHEADS_S), result.real_fit)
            except DiagnosisError as err:
                print(f'warning: {err}; written without them (a live look-ahead then cuts '
                      f'the offline FIR)', file=sys.stderr)
        print(f'written model ({result.fit.model}): {save_model(model, args.out_model)}')
    if args.report:
        from wheel_force_estimator.diagnosis.plots import write_report
        print(f'report: {write_report(args.report, result, real, holdout)}')
    print(f'diagnosis: {path}')
    return 0
