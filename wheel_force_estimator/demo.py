# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``make demo``: the main job end to end on the embedded default vehicle and course.

1. simulate a training and a validation proving-ground session (rosbag2, mcap),
2. ``wheel-force fit`` the 12x12 FRF (report with coherence / FRF plots),
3. ``wheel-force evaluate`` on the validation session (RMSE table, damage, report + JSON),
4. replay the validation bag through the live ROS 2 node and print the live output's RMSE
   table next to the offline one,
5. ``wheel-force diagnose`` a simulation against a "real" car with concealed strut friction
   (it adds less error than the simulation's FRF already makes): the diagnosis is not told the
   effect, names it, writes the augmented model and shows the holdout RMSE before/after;
   ``wheel-force evaluate`` of that model on the report samples (``fit.report_on``)
   reproduces the reported "after",
6. six components (issue 33): a session with the wheel moments, spindle angular rates and
   wheel spin recorded (``simulate --six``), a 24-output fit (forces and moments, from the
   accelerations and the spin rates), its held-out RMSE per component and a time history of
   one moment (``six_components/moment_lf_my.png``),
7. ``wheel-force fleet``: five simulated customer cars on public roads, milder per hour than
   the proving ground (spindle accelerometers only; other
   roads, other drivers' speeds) against the proving-ground validation session as the
   reference schedule: damage per hour per channel, fleet percentiles, how many repeats of
   the schedule equal the 95th-percentile customer, ranked cars and plots.
"""
import argparse
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time
from typing import List

import numpy as np

from wheel_force_estimator.cli.main import main as wheel_force
import yaml


def _run(argv: List[str]):
    print(f'\n$ wheel-force {" ".join(argv)}', flush=True)
    t0 = time.perf_counter()
    rc = wheel_force(argv)
    print(f'  ({time.perf_counter() - t0:.1f} s)', flush=True)
    if rc != 0:
        raise SystemExit(f'demo step failed: wheel-force {argv[0]} exited {rc}')


def _live_rmse(out: Path, validation: Path, live_bag: Path) -> dict:
    """Compare the node's recorded output with the WFT of the validation bag."""
    from wheel_force_estimator.bagio import load_topic_config
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.bagio import read_wrench_topics
    from wheel_force_estimator.core.metrics import rmse_pct

    topics = load_topic_config(None)
    rec = read_recording(validation, topics, require_wft=True)
    stamps = np.concatenate([s.stamp_ns for s in rec.segments])
    target = np.concatenate([s.force_n for s in rec.segments], axis=1)
    live_stamps, live = read_wrench_topics(live_bag, topics.output_topics)
    common, i_t, i_l = np.intersect1d(stamps, live_stamps, return_indices=True)
    from wheel_force_estimator import OUTPUT_CHANNELS
    return {'n_target': int(stamps.size), 'n_live': int(live_stamps.size),
            'n_matched': int(common.size),
            'rmse_pct': dict(zip(OUTPUT_CHANNELS,
                                 rmse_pct(target[:, i_t], live[:, i_l]).tolist()))}


def _replay_through_node(out: Path, model: Path, validation: Path, rate: float) -> Path:
    live_bag = out / 'live_output'
    if live_bag.exists():
        shutil.rmtree(live_bag)
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.setdefault('ROS_DOMAIN_ID', str(40 + os.getpid() % 50))
    node = subprocess.Popen([sys.executable, '-m', 'wheel_force_estimator', 'node',
                             '--model', str(model)], env=env)
    try:
        time.sleep(3.0)
        if node.poll() is not None:
            raise SystemExit(f'demo: the node exited early with {node.returncode}')
        cmd = [sys.executable, '-m', 'wheel_force_estimator', 'replay', str(validation),
               '--rate', str(rate), '--record', str(live_bag)]
        print(f'\n$ wheel-force {" ".join(cmd[3:])}', flush=True)
        subprocess.run(cmd, env=env, check=True)
    finally:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=20)
        except subprocess.TimeoutExpired:
            node.kill()
    return live_bag


def _six_components(out: Path, scale: float) -> None:
    """Fit forces and moments from the accelerations and spin rates; plot one moment."""
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.core.model import load_model
    from wheel_force_estimator.core.predict import predict_forces
    from wheel_force_estimator.report.evaluation_plots import plot_time_overlay

    six = out / 'six_components'
    six.mkdir()
    train, val, model = six / 'training', six / 'validation', six / 'model.npz'
    # a shorter session: 16 inputs x 24 outputs cost more than the 12 x 12 fit
    _run(['simulate', str(train), '--six', '--seed', '1', '--duration-scale',
          str(0.4 * scale)])
    _run(['simulate', str(val), '--six', '--seed', '2', '--duration-scale', str(0.2 * scale)])
    config = six / 'fit.yaml'
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    inputs: ["spin"]\n'
                      '    moments: true\n')
    _run(['fit', str(train), '-o', str(model), '--config', str(config)])
    _run(['evaluate', str(model), str(val), '--json', str(six / 'evaluation.json'),
          '--report', str(six / 'evaluation_report')])
    doc = json.loads((six / 'evaluation.json').read_text())['channels']
    print('\nsix components, held out: RMSE % per component (mean of the 4 corners)')
    for comp in ('fx', 'fy', 'fz', 'mx', 'my', 'mz'):
        values = [v['rmse_pct'] for k, v in doc.items() if k.endswith('_' + comp)]
        print(f'  {comp}: {np.mean(values):6.1f}')
    fitted = load_model(model)
    seg = max(read_recording(val, require_wft=True, extras=('moments', 'spin')).segments,
              key=lambda s: s.n_samples)
    pred = predict_forces(fitted, seg.signals(fitted.input_channels, fitted.fs_hz))
    row = fitted.output_channels.index('lf_my')
    t_s = (seg.stamp_ns - seg.stamp_ns[0]) * 1e-9
    mid = 0.5 * t_s[-1]
    png = plot_time_overlay(six / 'moment_lf_my.png', t_s, seg.moment_nm[1:2], pred[row:row + 1],
                            ['lf_my'], window_s=(mid, min(mid + 5.0, t_s[-1])),
                            title='lf_my: drive/brake moment, held out (5 s)')
    print(f'moment time history: {png}')


def _diagnose(out: Path, scale: float) -> None:
    """Simulate a sim/real/holdout trio with concealed friction and diagnose it blind."""
    from wheel_force_estimator.sim.concealment import concealed_params
    pair = out / 'diagnosis_pair'
    effect = out / 'friction.yaml'
    effect.write_text(yaml.safe_dump(concealed_params('coulomb_friction')))
    _run(['simulate', str(pair), '--pair', '--physics', 'coulomb_friction', '--effect-params',
          str(effect), '--seed', '4', '--holdout-seed', '104', '--duration-scale',
          str(0.3 * scale)])
    _run(['diagnose', '--real', str(pair / 'real'), '--sim', str(pair / 'sim'), '--holdout',
          str(pair / 'holdout'), '--json', str(out / 'diagnosis.json'), '--out-model',
          str(out / 'augmented_model.npz'), '--report', str(out / 'diagnosis_report')])
    # The reported "after" is what evaluate gives on the report half of the holdout: one bag
    # with road events, so fit.report_on names the bag and its report samples.
    fit = json.loads((out / 'diagnosis.json').read_text())['fit']
    from wheel_force_estimator.diagnosis.holdout import evaluate_arguments
    (report_on,) = fit['report_on']
    check = out / 'diagnosis_after.json'
    _run(['evaluate', str(out / 'augmented_model.npz')] + evaluate_arguments(report_on)
         + ['--json', str(check)])
    evaluated = json.loads(check.read_text())['channels']
    diff = max(abs(evaluated[c][fit['metric']] - v) for c, v in fit['after'].items())
    print(f'evaluate of the written model on the report samples reproduces fit.after: largest '
          f'difference {diff:.2g} percentage points over {len(fit["after"])} channels')
    if diff > 0.1:
        raise SystemExit('demo step failed: evaluate does not reproduce fit.after')


# Customer cars of the fleet step: (name, [(road event, duration s, speed km/h), ...]).
# Public roads: mostly city and highway, with the rough stretches short and slow.  A proving
# ground exists to be harsher per hour than the customers it stands for: its schedule packs a
# vehicle life into a few hundred hours, an acceleration factor of about 10 over a severe
# (95th-percentile) customer.  So the cars aim at a front Fz damage per hour of about 1/10 of
# the proving-ground session's for the P95 car (about 1/15 for the median), and none above 1/2
# on any force channel (city braking makes Fx the customers' harshest axis).
FLEET_SEVERITY_AIM = 0.1
FLEET_CARS = (
    ('commuter_calm', (('city_braking', 60.0, 35.0), ('highway', 120.0, 90.0))),
    ('commuter_brisk', (('city_braking', 60.0, 45.0), ('speed_bump', 10.0, 15.0),
                        ('highway', 120.0, 115.0))),
    ('rural', (('highway', 100.0, 80.0), ('railway_crossing', 15.0, 40.0),
               ('variant_wave', 30.0, 40.0), ('manhole_cover', 15.0, 30.0))),
    ('rural_rough', (('highway', 60.0, 70.0), ('cobblestone', 30.0, 20.0),
                     ('washboard', 30.0, 20.0), ('pothole', 20.0, 15.0))),
    ('delivery', (('city_braking', 90.0, 35.0), ('driveway', 20.0, 10.0),
                  ('speed_bump', 20.0, 15.0), ('manhole_cover', 20.0, 30.0))),
)


def _fleet(out: Path, model: Path, reference: Path, scale: float) -> None:
    """Simulate customer cars (accelerometers only) and run ``wheel-force fleet`` on them."""
    from wheel_force_estimator.bagio import write_recording
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.courses import EventSpec
    fleet = out / 'fleet'
    t0 = time.perf_counter()
    for seed, (name, events) in enumerate(FLEET_CARS, start=10):
        course = [EventSpec(event, duration_s, speed_kph)
                  for event, duration_s, speed_kph in events]
        sim = simulate(course, seed=seed, duration_scale=scale)
        # a customer car has no wheel force transducer: spindle Imu topics and events only
        write_recording(fleet / name / 'day_1', sim.stamp_ns, sim.accel_mps2, None,
                        events=sim.events)
    print(f'\nsimulated {len(FLEET_CARS)} customer cars ({time.perf_counter() - t0:.1f} s): '
          f'{", ".join(name for name, _ in FLEET_CARS)}')
    print(f'aimed severity: the P95 customer does about {FLEET_SEVERITY_AIM:g}x the '
          "proving-ground session's front Fz damage per hour\n(a proving ground is harsher "
          'per hour than the roads it stands for: its schedule packs a life into a\nfew '
          'hundred hours, an acceleration factor of about 10 over a severe customer)')
    _run(['fleet', str(model), str(fleet), '--out', str(out / 'fleet_out'), '--reference',
          str(reference), '--workers', '2', '--report', str(out / 'fleet_report')])
    doc = json.loads((out / 'fleet_out' / 'fleet.json').read_text())
    ratios = severity_ratios(doc)
    print('measured severity, customer damage per hour / proving-ground damage per hour: '
          + ', '.join(f'{c} P50 {ratios["50"][c]:.2g} P95 {ratios["95"][c]:.2g}'
                      for c in ('lf_fz', 'rf_fz', 'lf_fx')))
    print('How to read it: "P95 dmg/h" is the pseudo damage per hour that 95 % of the cars do '
          'not exceed;\n"P95 repeats" is how many passes of the proving-ground session do '
          'the damage such a car does\nin the target life (6000 h), channel by channel: '
          'the channels needing the most passes are the\nones the proving ground '
          'under-tests for these customers.')


def severity_ratios(doc: dict) -> dict:
    """Return, per percentile and channel, fleet damage per hour / reference damage per hour."""
    ref = doc['reference']
    per_hour = {c: d * 3600.0 / ref['duration_s'] for c, d in ref['damage'].items()}
    return {p: {c: rate / per_hour[c] if per_hour[c] > 0 else float('inf')
                for c, rate in rates.items()}
            for p, rates in doc['percentiles'].items()}


def main(argv=None) -> int:
    """Run the demo; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', default='demo_out', help='output directory')
    parser.add_argument('--duration-scale', type=float, default=1.0,
                        help='shorten the simulated sessions (1.0 = ~10 min training)')
    parser.add_argument('--replay-rate', type=float, default=5.0,
                        help='replay speed through the live node (x real time)')
    parser.add_argument('--no-node', action='store_true', help='skip the live node step')
    parser.add_argument('--no-diagnosis', action='store_true', help='skip the diagnosis step')
    parser.add_argument('--no-fleet', action='store_true', help='skip the fleet step')
    parser.add_argument('--no-six', action='store_true', help='skip the six-component step')
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    train, val = out / 'training', out / 'validation'
    model = out / 'model.npz'
    scale = str(args.duration_scale)
    _run(['simulate', str(train), '--seed', '1', '--duration-scale', scale])
    _run(['simulate', str(val), '--seed', '2', '--duration-scale', str(0.5 * args.duration_scale)])
    _run(['fit', str(train), '-o', str(model), '--report', str(out / 'fit_report')])
    _run(['evaluate', str(model), str(val), '--json', str(out / 'evaluation.json'),
          '--report', str(out / 'evaluation_report')])
    offline = json.loads((out / 'evaluation.json').read_text())
    if not args.no_node:
        live_bag = _replay_through_node(out, model, val, args.replay_rate)
        live = _live_rmse(out, val, live_bag)
        (out / 'live_rmse.json').write_text(json.dumps(live, indent=1))
        print(f'\nlive node: {live["n_live"]} output samples per corner for '
              f'{live["n_target"]} input samples ({live["n_matched"]} matched by stamp)')
        print(f'{"channel":8s} {"offline RMSE %":>15s} {"live RMSE %":>12s}')
        for name, figures in offline['channels'].items():
            print(f'{name:8s} {figures["rmse_pct"]:15.1f} {live["rmse_pct"][name]:12.1f}')
    if not args.no_six:
        _six_components(out, args.duration_scale)
    if not args.no_diagnosis:
        _diagnose(out, args.duration_scale)
    if not args.no_fleet:
        _fleet(out, model, val, args.duration_scale)
    reports = (['fit_report', 'evaluation_report']
               + ([] if args.no_six else ['six_components/evaluation_report'])
               + ([] if args.no_diagnosis else ['diagnosis_report'])
               + ([] if args.no_fleet else ['fleet_report']))
    print('\nreports: ' + ', '.join(str(out / r / 'report.md') for r in reports))
    return 0


if __name__ == '__main__':
    sys.exit(main())
