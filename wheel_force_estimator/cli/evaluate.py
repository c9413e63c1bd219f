# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force evaluate MODEL BAG…``: compare the prediction with the recorded WFT."""
import argparse
import json
from pathlib import Path


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``evaluate``."""
    p = subparsers.add_parser(
        'evaluate', help='RMSE %%, pseudo damage and spectra of the prediction vs the WFT',
        description='Predict the forces of each recording and judge them against the '
                    'recorded WFT: RMSE % (unfiltered and 1 Hz high-passed) per channel and '
                    "per road event with the paper's rubric, pseudo damage ratio, relative "
                    'damage spectrum and ASD.')
    p.add_argument('model', metavar='MODEL', help='model file (.npz)')
    p.add_argument('bags', nargs='+', metavar='BAG', help='validation recordings with WFT')
    p.add_argument('--json', metavar='FILE', help='write the figures as JSON')
    p.add_argument('--report', metavar='DIR', help='write report.md and plots here')
    p.add_argument('--config', metavar='YAML', help='params file (topic names, sn_slope)')
    p.add_argument('--sn-slope', type=float, default=5.0, help='Basquin exponent k')
    p.add_argument('--causal-delay-samples', type=int, metavar='N',
                   help='evaluate the live filter with this look-ahead instead of the full one')
    return p


def evaluate_recordings(model, recordings, sn_slope, causal_delay_samples=None):
    """Predict and evaluate; return ``(Evaluation, segments)``."""
    from wheel_force_estimator.cli.predict import predict_recording
    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments

    segments, events = [], []
    for rec in recordings:
        for i, ((stamps, pred), seg) in enumerate(
                zip(predict_recording(model, rec, causal_delay_samples), rec.segments)):
            segments.append(EvalSegment(seg.force_n, pred, stamps, f'{rec.path}#{i}'))
        events.extend(rec.events)
    events.sort()
    evaluation = evaluate_segments(segments, model.fs_hz, model.output_channels, sn_slope,
                                   events=events)
    return evaluation, segments


def command(args: argparse.Namespace) -> int:
    """Run ``evaluate``; return the exit code."""
    from wheel_force_estimator.bagio import load_topic_config
    from wheel_force_estimator.cli.common import read_recordings
    from wheel_force_estimator.core.model import load_model
    from wheel_force_estimator.report.builders import evaluation_text

    model = load_model(args.model)
    topics = load_topic_config(args.config)
    recordings = read_recordings(args.bags, topics, require_wft=True,
                                 expected_fs_hz=model.fs_hz)
    evaluation, segments = evaluate_recordings(model, recordings, args.sn_slope,
                                               args.causal_delay_samples)
    print(evaluation_text(evaluation))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(evaluation.to_json(), indent=1))
        print(f'json: {args.json}')
    if args.report:
        from wheel_force_estimator.report.builders import write_evaluation_report
        report = write_evaluation_report(args.report, model, evaluation, segments)
        print(f'report: {report}')
    return 0
