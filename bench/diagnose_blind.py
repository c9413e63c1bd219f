# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Blind sim-vs-real diagnosis benchmark: confusion matrix, hit rate, holdout RMSE before/after.

Three parts, each printed with a baseline measured in the same run:

1. Known-answer synthetic pairs (diagnosis/synthetic.py): one concealed effect per case.
2. Simulator pairs (sim.simulate: nominal car vs car with one effect, holdout on another
   seed), linear MIMO FRF fitted on the simulation.
3. The real datasets in ../shared/data (friction damper, MR damper) through the generic path.

Baseline ("naive"): the same candidates ranked by held-out gain alone - no sim contrast, no
time-shifted-feature null, no practical thresholds - naming the best one.  A good diagnosis
names the true effect as often and "none" far more often when nothing is there.

Usage: ``.venv/bin/python bench/diagnose_blind.py [--seeds N] [--sim-seeds N]
[--duration-scale X] [--skip-sim] [--effects a,b]``
"""
import argparse
from collections import Counter
from dataclasses import replace
from pathlib import Path
import sys
import time

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.reference import FrfReference
from wheel_force_estimator.diagnosis.reference import RegressionReference
from wheel_force_estimator.diagnosis.selection import SelectionConfig
from wheel_force_estimator.diagnosis.synthetic import synthetic_pair

SYNTHETIC = ('none', 'offset_drift', 'bump_stop', 'rebound_stop', 'cubic_stiffness',
             'damper_asymmetry', 'coulomb_friction', 'backlash', 'tire_lift_off',
             'anti_roll_bar', 'time_delay', 'sensor_saturation', 'mass_error',
             'stiffness_error', 'damping_error')
NAIVE = SelectionConfig(n_null=1, null_factor=1e-9, min_gain=1e-9, min_improvement_pct=0.0,
                        max_terms=1)
NULLS = ('none', 'none_reseeded')
SHARED = Path(__file__).resolve().parents[1].parent / 'shared' / 'data'


def named(result) -> str:
    """First finding's physics, or 'none'."""
    return result.findings[0].physics if result.findings else 'none'


def truth_of(effect: str) -> str:
    return 'none' if effect in NULLS + ('offset_drift',) else effect


def print_confusion(title, rows):
    """rows: list of (true, named_by_method, named_by_naive, before, after)."""
    labels = sorted({r[0] for r in rows} | {r[1] for r in rows} | {r[2] for r in rows},
                    key=lambda x: (x != 'none', x))
    print(f'\n== {title}: confusion (rows true, columns named first; diagnosis)')
    width = max(len(x) for x in labels) + 1
    short = {x: x[:6] for x in labels}
    print(' ' * width + ' '.join(f'{short[x]:>6s}' for x in labels))
    counts = Counter((r[0], r[1]) for r in rows)
    for t in labels:
        if any(r[0] == t for r in rows):
            print(f'{t:{width}s}' + ' '.join(f'{counts[(t, x)] or "":>6}' for x in labels))
    for k, name in ((1, 'diagnosis'), (2, 'naive baseline')):
        hits = sum(r[0] == r[k] for r in rows)
        effect_rows = [r for r in rows if r[0] != 'none']
        null_rows = [r for r in rows if r[0] == 'none']
        print(f'{name:15s} hit rate {hits}/{len(rows)} = {hits / len(rows):.0%}   '
              f'effects named right {sum(r[0] == r[k] for r in effect_rows)}/'
              f'{len(effect_rows)}   false alarms on nulls '
              f'{sum(r[k] != "none" for r in null_rows)}/{len(null_rows)}')


def run_synthetic(seeds, effects):
    rows = []
    config = DiagnosisConfig(linear='regression')
    print('\n== synthetic known-answer pairs (2 corners, 60 s real x2, holdout 60 s)')
    print(f'{"effect":18s} seed  named             naive             lf_fz RMSE % before -> '
          f'after (best linear on real)')
    for effect in effects:
        for seed in seeds:
            sim, real, holdout, _ = synthetic_pair(effect, seed=seed)
            result = diagnose(real, sim, holdout, config)
            naive = diagnose(real, RegressionReference.fit(sim, config.features, 'sim'),
                             holdout, replace(config, selection=NAIVE))
            fit = result.fit
            rows.append((truth_of(effect), named(result), named(naive), fit.before['lf_fz'],
                         fit.after['lf_fz']))
            print(f'{effect:18s} {seed:4d}  {named(result):17s} {named(naive):17s} '
                  f'{fit.before["lf_fz"]:6.1f} -> {fit.after["lf_fz"]:6.1f} '
                  f'({fit.linear_real["lf_fz"]:.1f})', flush=True)
    print_confusion('synthetic', rows)


def _rec(result, name):
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS)


def run_sim(seeds, duration_scale, effects):
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.effects import EFFECT_NAMES
    rows = []
    config = DiagnosisConfig()
    print(f'\n== simulator pairs (proving ground x {duration_scale:g}, MIMO FRF on the sim, '
          f'RMSE % with 1 Hz high-pass)')
    print(f'{"effect":18s} seed  named             naive             all named; Fz RMSE '
          f'before -> after (mean of 4)')
    for seed in seeds:
        sim = [_rec(simulate('proving_ground', (), seed, duration_scale), 'sim')]
        ref = FrfReference.fit(sim, 'sim', None)
        for effect in effects:
            if effect not in NULLS and effect not in EFFECT_NAMES:
                continue
            physics = () if effect in NULLS else (effect,)
            t0 = time.time()
            # 'none' is the matched pair (real == sim); 'none_reseeded' drives the nominal car
            # over other roads, so the sim FRF meets data it was not fitted on.
            real_seed = seed + 50 if effect == 'none_reseeded' else seed
            real = [_rec(simulate('proving_ground', physics, real_seed, duration_scale),
                         'real')]
            holdout = [_rec(simulate('proving_ground', physics, seed + 100, duration_scale),
                            'holdout')]
            result = diagnose(real, sim, holdout, config)
            naive = diagnose(real, ref, holdout, replace(config, selection=NAIVE))
            fz = [c for c in OUTPUT_CHANNELS if c.endswith('fz')]
            before = sum(result.fit.before[c] for c in fz) / 4
            after = sum(result.fit.after[c] for c in fz) / 4
            rows.append((truth_of(effect), named(result), named(naive), before, after))
            everything = ', '.join(dict.fromkeys(f.physics for f in result.findings)) or '-'
            print(f'{effect:18s} {seed:4d}  {named(result):17s} {named(naive):17s} '
                  f'{everything}; {before:.1f} -> {after:.1f}  ({time.time() - t0:.0f} s)',
                  flush=True)
    print_confusion('simulator', rows)


def run_real():
    from wheel_force_estimator.diagnosis.generic import load_generic
    from wheel_force_estimator.diagnosis.generic import parse_spec
    print('\n== real datasets (generic path, linear law fitted on the real data = baseline)')
    friction = SHARED / 'friction_damper'
    if friction.is_dir():
        inp = [parse_spec('data[1]:displacement:in', 'input')]
        out = [parse_spec('data[2]:force:kip', 'output')]
        real = [load_generic(friction / f, inp, out, 1024.0) for f in (
            '1Hz30lbtension0.5amplitude.json', '1Hz30lbtension1.5amplitude.json',
            '2Hz30lbtension0.5amplitude.json')]
        hold = [load_generic(friction / f, inp, out, 1024.0) for f in (
            '1Hz30lbtension1amplitude.json', '0.5Hz30lbtension1amplitude.json')]
        _report_real('friction damper (Coble et al. 2022, CC BY-SA 4.0)', real, hold)
    else:
        print(f'friction damper: skipped, {friction} absent')
    mr = SHARED / 'mr_damper'
    if mr.is_dir():
        inp = [parse_spec('x_F[0]:displacement:mm', 'input')]
        out = [parse_spec('x_F[2]:force:N', 'output')]
        real = [load_generic(mr / 'data_simulation_4.2_MRdamper.mat', inp, out, 100.0)]
        hold = [load_generic(mr / 'data_simulation_4.4_MRdamper.mat', inp, out, 100.0)]
        _report_real('MR damper (labcontrol-data/mr-damper, MIT)', real, hold)
    else:
        print(f'MR damper: skipped, {mr} absent')


def _report_real(title, real, hold):
    result = diagnose(real, None, hold)
    ch = real[0].output_channels[0]
    print(f'{title}: named {[f.physics for f in result.findings]}; holdout RMSE '
          f'{result.fit.before[ch]:.1f} % (best linear law) -> {result.fit.after[ch]:.1f} %')
    for line in result.rejected:
        print(f'   not kept: {line}')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seeds', type=int, default=3, help='synthetic seeds per effect')
    parser.add_argument('--sim-seeds', type=int, default=1, help='simulator seeds per effect')
    parser.add_argument('--duration-scale', type=float, default=0.2,
                        help='proving-ground duration scale (1 = ~10 min per recording)')
    parser.add_argument('--skip-sim', action='store_true')
    parser.add_argument('--effects', help='comma-separated subset')
    args = parser.parse_args(argv)
    chosen = args.effects.split(',') if args.effects else None
    t0 = time.time()
    if args.seeds > 0:
        run_synthetic(range(args.seeds), [e for e in chosen or SYNTHETIC if e in SYNTHETIC])
    if not args.skip_sim:
        from wheel_force_estimator.sim.effects import EFFECT_NAMES
        run_sim(range(args.sim_seeds), args.duration_scale,
                chosen or NULLS + tuple(EFFECT_NAMES))
    run_real()
    print(f'\ntotal {time.time() - t0:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
