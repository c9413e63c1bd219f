# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Blind sim-vs-real diagnosis benchmark: confusion matrix, hit rate, holdout RMSE before/after.

Four parts, each printed with a baseline measured in the same run:

1. Known-answer synthetic pairs (test/support/diagnosis_synthetic.py): one concealed effect
   per case.
2. Simulator pairs (sim.simulate: nominal car vs car with one effect, holdout on another
   seed), diagnosed as ``wheel-force diagnose`` runs on bags (``BAG_CONFIG``: the MIMO FRF
   of ``wheel-force fit`` fitted on the simulation and on the real records alike).  The
   effect is concealed (sim/concealment.py): it acts on under 5 % of the samples, or the
   error it adds is below the error the simulation's FRF already makes on the simulation,
   on every channel (1 Hz high-passed); the measurement is printed for every case.
   ``--car suv`` drives a heavier SUV instead of the default compact car (same effect
   sizes, so smaller relative to that car's forces).  Seed 0 uses the concealed sizes,
   every further seed scales their strength by a draw in 0.6..1.0 (``--sizes default``: the
   simulator's default, visible sizes, drawn x0.7..1.4).  Nulls: the matched pair, the nominal
   car on other roads, and small linear parameter drift.  Per case, `wheel-force evaluate`
   figures (1 Hz high-passed RMSE, mean over the first finding's channels, Fz when nothing is
   named) on the report half of the holdout of: the sim FRF (before), a plain
   `wheel-force fit` on the real recordings (fit), and the model `--out-model` writes (written,
   which one in the last column); a confusion matrix per seed and pooled, hit rates over all
   cases and over the concealed ones, and the targets of issue 14: named nonlinear cases with
   the written model better than the plain fit, named linear ones within 3 % of it and better
   than the simulation, nulls with no finding and the written model no worse than the plain
   fit (issue 30: the best linear model on held-out data, not the reference unchanged).
3. The stop cases again with suspension travel recorded instead of spindle accelerations
   (generic path): what a travel channel adds where the compression cannot be inferred
   (baseline: the spindle-only diagnosis of the same pairs in part 2).
4. The real datasets in ../shared/data (friction damper, MR damper) through the generic path.
5. Lightly damped structures (base-excited modes, one or three inputs) through the generic
   path as ``wheel-force diagnose`` runs it on DAQ files: the Welch segment chosen by
   blocked cross-validation (core/resolution.py), baseline the paper's 1024 samples.  The
   elements inside the loop (hardening, friction between base and an unmeasured mass) are
   named through the structure's response (diagnosis/dynamic.py), also at smaller sizes.
6. Displacement / velocity rigs (one corner of the synthetic law driven by its displacement
   or velocity, 2 x 60 s to fit, 2 x 60 s holdout, 3 seeds) through the generic path as the
   CLI runs it: the differentiator low-pass chosen between fs/8 and the sharper corner by
   the gate half of the holdout (diagnosis/features.py), baseline fs/8 alone.

Baseline ("naive"): the same candidates ranked by held-out gain alone - no sim contrast, no
time-shifted-feature null, no practical thresholds - naming the best one.  A good diagnosis
names the true effect as often and "none" far more often when nothing is there.

Usage: ``.venv/bin/python bench/diagnose_blind.py [--seeds N] [--sim-seeds N]
[--duration-scale X] [--holdout-scale X] [--sizes concealed|default] [--car compact|suv]
[--skip-sim | --only-sim] [--effects a,b]`` (defaults: 3 synthetic seeds, 3 simulator
seeds at duration scale 0.2 = 2-minute recordings with 5-minute holdouts, ~35 min on a
2-core machine).
"""
import argparse
from collections import Counter
from dataclasses import replace
from pathlib import Path
import sys
import time

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.cli.heap import keep_freed_memory
from wheel_force_estimator.core.design import product_fit_config
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.reference import FrfReference
from wheel_force_estimator.diagnosis.reference import RegressionReference
from wheel_force_estimator.diagnosis.selection import SelectionConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from benchutil import test_support  # noqa: E402,I100

#: The known-answer pairs and structures (test fixtures, not shipped in the package).
FIXTURES = test_support('diagnosis_synthetic')

SYNTHETIC = ('none', 'offset_drift', 'bump_stop', 'rebound_stop', 'cubic_stiffness',
             'damper_asymmetry', 'coulomb_friction', 'backlash', 'tire_lift_off',
             'anti_roll_bar', 'time_delay', 'sensor_saturation', 'mass_error',
             'stiffness_error', 'damping_error')
NAIVE = SelectionConfig(n_null=1, null_factor=1e-9, min_gain=1e-9, min_improvement_pct=0.0,
                        max_terms=1)
NULLS = ('none', 'none_reseeded', 'small_drift')
#: Small linear parameter drift (a null: no finding expected).
SMALL_DRIFT = {'mass_error': {'fraction': 0.01}, 'stiffness_error': {'fraction': 0.02},
               'damping_error': {'fraction': -0.03}}
#: Magnitude parameters scaled by the per-seed draw (gaps and thresholds kept).
DRAWN = {'bump_stop': ('stiffness_n_per_m', 'progressive_n_per_m3'),
         'rebound_stop': ('stiffness_n_per_m',), 'cubic_stiffness': ('coefficient_n_per_m3',),
         'coulomb_friction': ('force_n',), 'backlash': ('gap_m',),
         'anti_roll_bar': ('front_n_per_m', 'rear_n_per_m'), 'time_delay': ('delay_s',),
         'mass_error': ('fraction',), 'stiffness_error': ('fraction',),
         'damping_error': ('fraction',)}
SHARED = Path(__file__).resolve().parents[1].parent / 'shared' / 'data'


#: A second car for ``--car suv``: heavier, taller, stiffer, all-wheel drive - what "other
#: cars" means for a diagnosis whose rules were developed on the compact default.
SUV = {'name': 'suv_awd_2160kg', 'sprung_mass_kg': 2050.0, 'pitch_inertia_kgm2': 3800.0,
       'roll_inertia_kgm2': 900.0, 'unsprung_mass_front_kg': 58.0,
       'unsprung_mass_rear_kg': 52.0, 'outboard_mass_front_kg': 30.0,
       'outboard_mass_rear_kg': 28.0, 'wheel_spin_inertia_front_kgm2': 1.7,
       'wheel_spin_inertia_rear_kgm2': 1.5, 'wheelbase_m': 2.90, 'cg_to_front_axle_m': 1.38,
       'cg_height_m': 0.72, 'track_front_m': 1.64, 'track_rear_m': 1.64,
       'wheel_radius_m': 0.37, 'spring_rate_front_n_per_m': 42000.0,
       'spring_rate_rear_n_per_m': 47000.0, 'damping_front_ns_per_m': 3400.0,
       'damping_rear_ns_per_m': 3600.0, 'tyre_stiffness_n_per_m': 290000.0,
       'tyre_contact_length_m': 0.22, 'drive_front_fraction': 0.4, 'drag_area_m2': 1.05}
#: The car of the simulator parts (None: the simulator's default compact car).
CAR = None


#: What ``wheel-force diagnose`` runs on bags (cli/diagnose.py): the fit design of
#: ``wheel-force fit`` without a params file (two resolutions) for the simulation's FRF and
#: every real-data fit, no short-record or segment fallbacks, no cross-validated segment.
BAG_CONFIG = DiagnosisConfig(fit=product_fit_config(), fit_fallback=False,
                             long_window_fallback=True, segment_fallback=False)


def named(result) -> str:
    """First finding's physics, or 'none'."""
    return result.findings[0].physics if result.findings else 'none'


def truth_of(effect: str) -> str:
    return 'none' if effect in NULLS + ('offset_drift',) else effect


def simulated_physics(effect: str) -> tuple:
    """Effects the 'real' car of a case is simulated with (nulls: none, or the small drift)."""
    if effect == 'small_drift':
        return tuple(SMALL_DRIFT)
    return () if effect in NULLS else (effect,)


def draw_params(effect: str, seed: int, sizes: str):
    """
    Effect parameters of one simulator case and the strength factor drawn for it.

    Seed 0: factor 1 (the concealed or default sizes); further seeds draw it from 0.6..1.0
    (concealed: smaller is still concealed) or 0.7..1.4 (default sizes).
    """
    import numpy as np
    from wheel_force_estimator.sim.concealment import concealed_params
    from wheel_force_estimator.sim.effects import EFFECT_DEFAULTS
    if effect == 'small_drift':
        return SMALL_DRIFT, 1.0
    if effect not in EFFECT_DEFAULTS:
        return None, 1.0
    low, high = (0.6, 1.0) if sizes == 'concealed' else (0.7, 1.4)
    factor = 1.0 if seed == 0 else float(
        np.random.default_rng([seed, len(effect)]).uniform(low, high))
    if sizes == 'concealed':
        return concealed_params(effect, factor), factor
    params = {k: v * factor for k, v in EFFECT_DEFAULTS[effect].items()
              if k in DRAWN.get(effect, ())}
    if effect == 'damper_asymmetry':
        params = {'rebound_to_compression_ratio': 1.0 + 2.0 * factor}
    if effect == 'sensor_saturation':
        params = {'limit_mps2': EFFECT_DEFAULTS[effect]['limit_mps2'] / factor}
    return {effect: params}, factor


def print_confusion(title, rows):
    """rows: (true, named_by_method, named_by_naive, before, after, ..., concealed at [7])."""
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
    hidden = [r for r in rows if len(r) > 7 and r[7]]
    for k, name in ((1, 'diagnosis'), (2, 'naive baseline')):
        hits = sum(r[0] == r[k] for r in rows)
        effect_rows = [r for r in rows if r[0] != 'none']
        null_rows = [r for r in rows if r[0] == 'none']
        print(f'{name:15s} hit rate {hits}/{len(rows)} = {hits / len(rows):.0%}   '
              f'effects named right {sum(r[0] == r[k] for r in effect_rows)}/'
              f'{len(effect_rows)}   false alarms on nulls '
              f'{sum(r[k] != "none" for r in null_rows)}/{len(null_rows)}')
        if hidden:
            print(f'{"":15s} concealed effects named right '
                  f'{sum(r[0] == r[k] for r in hidden)}/{len(hidden)}')


def run_synthetic(seeds, effects):
    rows = []
    config = DiagnosisConfig(linear='regression')
    print('\n== synthetic known-answer pairs (2 corners, 60 s real x2, holdout 60 s)')
    print(f'{"effect":18s} seed  named             naive             lf_fz RMSE % before -> '
          f'written (plain fit on real; written model)')
    for effect in effects:
        for seed in seeds:
            sim, real, holdout, _ = FIXTURES.synthetic_pair(effect, seed=seed)
            result = diagnose(real, sim, holdout, config)
            naive = diagnose(real, RegressionReference.fit(sim, config.features, 'sim'),
                             holdout, replace(config, selection=NAIVE))
            fit = result.fit
            rows.append((truth_of(effect), named(result), named(naive), fit.before['lf_fz'],
                         fit.after['lf_fz'], fit.real_linear['lf_fz'], fit.model))
            print(f'{effect:18s} {seed:4d}  {named(result):17s} {named(naive):17s} '
                  f'{fit.before["lf_fz"]:6.1f} -> {fit.after["lf_fz"]:6.1f} '
                  f'({fit.real_linear["lf_fz"]:.1f}; {fit.model})', flush=True)
    print_confusion('synthetic', rows)
    print_targets(rows, 'synthetic pairs, lf_fz: ')


def _events(result):
    """Road-event starts as the bag reader gives them: seconds on the record's own clock."""
    t0 = int(result.stamp_ns[0])
    return tuple(((t - t0) * 1e-9, e) for t, e in result.events)


def _rec(result, name):
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS, events=_events(result))


def run_sim(seeds, duration_scale, effects, sizes, holdout_scale):
    import numpy as np
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.concealment import measure_concealment
    from wheel_force_estimator.sim.effects import EFFECT_NAMES
    rows = []
    no_holdout_rows = []
    config = BAG_CONFIG
    print(f'\n== simulator pairs ({sizes} sizes, proving ground x {duration_scale:g}, holdout x '
          f'{holdout_scale:g}, MIMO FRF on the sim, holdout RMSE % with 1 Hz high-pass over the '
          f'named channels)')
    print(f'{"effect":18s} seed  draw  named             naive             before written '
          f'     fit  written model    all named')
    for seed in seeds:
        seed_rows = []
        nominal = simulate('proving_ground', (), seed, duration_scale, vehicle=CAR)
        sim = [_rec(nominal, 'sim')]
        ref = FrfReference.fit(sim, 'sim', config.fit)  # as the diagnosis fits the sim
        for effect in effects:
            if effect not in NULLS and effect not in EFFECT_NAMES:
                continue
            params, factor = draw_params(effect, seed, sizes)
            physics = simulated_physics(effect)
            t0 = time.time()
            # 'none' is the matched pair (real == sim); 'none_reseeded' drives the nominal car
            # over other roads, so the sim FRF meets data it was not fitted on.
            real_seed = seed + 50 if effect == 'none_reseeded' else seed
            real_run = simulate('proving_ground', physics, real_seed, duration_scale,
                                vehicle=CAR, effect_params=params)
            real = [_rec(real_run, 'real')]
            holdout = [_rec(simulate('proving_ground', physics, seed + 100, holdout_scale,
                                     vehicle=CAR,
                                     effect_params=params), 'holdout')]
            hidden = None
            if effect not in NULLS:
                hidden = measure_concealment(effect, nominal, real_run, ref.model)
                print(f'  {effect} seed {seed}: {hidden.describe()}', flush=True)
            result = diagnose(real, sim, () if NO_HOLDOUT else holdout, config)
            # the naive baseline is the with-holdout benchmark's (it costs a second diagnosis)
            naive = (result if NO_HOLDOUT or NO_NAIVE
                     else diagnose(real, ref, holdout, replace(config, selection=NAIVE)))
            fit = result.fit
            chans = (result.findings[0].channels if result.findings
                     else [c for c in OUTPUT_CHANNELS if c.endswith('fz')])
            if NO_HOLDOUT:
                figures = _unseen_figures(result, real, ref, holdout, chans, config)
                no_holdout_rows.append((truth_of(effect), named(result), seed) + figures)
                figures = [figures[0], figures[2], figures[4]]
            else:
                figures = [float(np.mean([getattr(fit, k)[c] for c in chans])) for k in (
                    'before', 'after', 'real_linear')]
            row = ((truth_of(effect), named(result), named(naive)) + tuple(figures)
                   + (fit.model, hidden is not None and hidden.concealed))
            seed_rows.append(row)
            everything = ', '.join(dict.fromkeys(f.physics for f in result.findings)) or '-'
            print(f'{effect:18s} {seed:4d}  {factor:4.2f}  {named(result):17s} '
                  f'{named(naive):17s} {figures[0]:6.1f} {figures[1]:7.1f} {figures[2]:8.1f}  '
                  f'{fit.model:16s} {everything} ({time.time() - t0:.0f} s)', flush=True)
        print_confusion(f'simulator seed {seed}', seed_rows)
        rows += seed_rows
    if len(seeds) > 1:
        print_confusion(f'simulator, {len(seeds)} seeds pooled', rows)
    print_targets(rows)
    if NO_HOLDOUT:
        print_no_holdout(no_holdout_rows)


#: Skip the naive baseline of the simulator pairs (``--no-naive``: its column repeats the
#: diagnosis).
NO_NAIVE = False
#: Diagnose the simulator pairs without ``--holdout`` (``--no-holdout``): the written model
#: and the plain fit are then scored on the whole holdout recording, which nothing saw.
NO_HOLDOUT = False


def holdout_figures(model, holdout):
    """Return per-channel RMSE % of ``model`` on ``holdout``: (unfiltered, 1 Hz HP) arrays."""
    import numpy as np
    from wheel_force_estimator.core.evaluation import rmse_figures
    from wheel_force_estimator.core.predict import predict_forces
    preds = [predict_forces(model, r.inputs) for r in holdout]
    raw, hp = rmse_figures([np.asarray(r.outputs) for r in holdout], preds, holdout[0].fs_hz,
                           holdout[0].output_channels)
    return np.asarray(raw), np.asarray(hp)


def _unseen_figures(result, real, ref, holdout, chans, config):
    """
    Mean RMSE % over ``chans`` on the whole ``holdout`` (nothing saw it), both figures.

    Returns ``(before, before_hp, written, written_hp, plain, plain_hp)``: the simulation's
    FRF, the model the diagnosis writes, a plain ``wheel-force fit`` on ``real`` (its design).
    """
    import numpy as np
    from wheel_force_estimator.diagnosis.run import real_linear_fit
    plain = real_linear_fit(real, config).model  # fit's design: the search included
    out = []
    for model in (ref.model, result.model, plain):
        raw, hp = holdout_figures(model, holdout)
        index = [holdout[0].output_channels.index(c) for c in chans]
        out += [float(np.mean(raw[index])), float(np.mean(hp[index]))]
    return tuple(out)


def print_no_holdout(rows):
    """Issue 30's targets without a holdout: rows (true, named, seed, 6 figures)."""
    print('\n== without --holdout: whole holdout recording, mean over the first finding of '
          'its channels (Fz when none): unfiltered | 1 Hz high-passed')
    print(f'{"effect":18s} seed  {"named":17s}  sim    written  plain   |  sim    written  '
          f'plain')
    within = better = nonlinear = 0
    for true, name, seed, b, b_hp, w, w_hp, p, p_hp in rows:
        print(f'{true:18s} {seed:4d}  {name:17s} {b:6.1f} {w:7.1f} {p:7.1f}   | {b_hp:6.1f} '
              f'{w_hp:7.1f} {p_hp:7.1f}', flush=True)
        within += w <= 1.005 * p and w_hp <= 1.005 * p_hp
        if true == name and true != 'none' and true not in LINEAR_EFFECTS:
            nonlinear += 1
            better += ((w <= 0.95 * p and w_hp <= 1.03 * p_hp)
                       or (w_hp <= 0.95 * p_hp and w <= 1.03 * p))
    print(f'written within 0.5 % of the plain fit or better in both figures: {within}/{len(rows)}'
          f' (target 100 %)')
    print(f'named nonlinear cases, written >= 5 % better than the plain fit in one figure and '
          f'at most 3 % worse in the other: {better}/{nonlinear} (target >= 80 %)')


#: Linear omissions (a linear model can represent them): the written model must get within
#: 3 % of the plain fit on the real data and beat the simulation.
LINEAR_EFFECTS = ('mass_error', 'stiffness_error', 'damping_error', 'anti_roll_bar',
                  'time_delay')


#: Physics that change the recorded motion (issue 14 item 4): the written model must be no
#: worse than the plain fit on the real data.
MOTION_EFFECTS = ('sensor_saturation', 'tire_lift_off')


#: Two figures closer than this [points of %] are the same model's rows scored twice (a row
#: the per-channel choice took from the plain fit differs from it by rounding, ~1e-12).
SAME_PCT = 1e-6


def print_targets(rows, label=''):
    """Issue 14's targets over rows (true, named, naive, before, written, fit, model, hidden)."""
    nonlinear = [r for r in rows if r[0] != 'none' and r[0] not in LINEAR_EFFECTS
                 and r[0] not in MOTION_EFFECTS and r[0] == r[1]]
    motion = [r for r in rows if r[0] in MOTION_EFFECTS and r[0] == r[1]]
    linear = [r for r in rows if r[0] in LINEAR_EFFECTS and r[0] == r[1]]
    nulls = [r for r in rows if r[0] == 'none']
    print(f'{label}named nonlinear cases, written model better than a plain fit on the real '
          f'data: {sum(r[4] < r[5] for r in nonlinear)}/{len(nonlinear)} (target >= 90 %)')
    print(f'{label}named motion cases (clip, tyre in the air), written model no worse than the '
          f'plain fit: {sum(r[4] <= r[5] + SAME_PCT for r in motion)}/{len(motion)}')
    print(f'{label}named linear cases, written model within 3 % of the plain fit and better than '
          f'the simulation: {sum(r[4] <= 1.03 * r[5] and r[4] < r[3] for r in linear)}/'
          f'{len(linear)}')
    # issue 30: with nothing named, the written model is the best linear one on held-out
    # data (no worse than the plain fit), no longer the reference unchanged
    print(f'{label}null cases with no finding and the written model no worse than the plain '
          f'fit: {sum(r[1] == "none" and r[4] <= r[5] + SAME_PCT for r in nulls)}/{len(nulls)}')
    missed = [r for r in rows if r[0] != 'none' and r[0] != r[1]]
    print(f'{label}effect cases not named first (written model vs plain fit): ' + (', '.join(
        f'{r[0]} {r[4]:.1f} vs {r[5]:.1f} % ({r[6]})' for r in missed) or '-'))


#: Effects diagnosed again with the compression recorded (suspension travel, generic path).
TRAVEL_CASES = ('none', 'small_drift', 'bump_stop')


def _travel_rec(result, name):
    fz = [OUTPUT_CHANNELS.index(c) for c in OUTPUT_CHANNELS if c.endswith('fz')]
    outputs = tuple(OUTPUT_CHANNELS[i] for i in fz)
    return MotionRecording(name, result.fs_hz, result.states['suspension_compression_m'],
                           result.force_n[fz], tuple(c[:2] + '_travel' for c in outputs),
                           outputs, input_quantity='displacement', events=_events(result))


def run_travel(seeds, duration_scale, sizes, holdout_scale):
    """
    Diagnose the stop cases from suspension travel instead of spindle accelerations.

    The spindle-only diagnosis cannot tell when a rarely engaged bump stop is in contact (the
    compression has to be inferred); with the compression recorded (string potentiometers in a
    DAQ export) the generic path fits a linear law on the sim and seeks the physics it misses.
    """
    import numpy as np
    from wheel_force_estimator.sim.api import simulate
    print(f'\n== suspension travel in, Fz out (generic path, {sizes} sizes, linear law on the sim;'
          f' holdout RMSE % with 1 Hz high-pass over the named channels, Fz when none)')
    print(f'{"effect":18s} seed  draw  named             before written    fit  written model'
          f'    findings')
    rows = []
    for seed in seeds:
        sim = [_travel_rec(simulate('proving_ground', (), seed, duration_scale, vehicle=CAR),
                           'sim')]
        for effect in TRAVEL_CASES:
            params, factor = draw_params(effect, seed, sizes)
            physics = simulated_physics(effect)
            real = [_travel_rec(simulate('proving_ground', physics, seed, duration_scale,
                                         vehicle=CAR, effect_params=params), 'real')]
            holdout = [_travel_rec(simulate('proving_ground', physics, seed + 100,
                                            holdout_scale, vehicle=CAR, effect_params=params),
                                   'holdout')]
            result = diagnose(real, sim, holdout, BAG_CONFIG)
            chans = (result.findings[0].channels if result.findings
                     else real[0].output_channels)
            before, after, fit = (float(np.mean([getattr(result.fit, k)[c] for c in chans]))
                                  for k in ('before', 'after', 'real_linear'))
            rows.append((truth_of(effect), named(result)))
            detail = '; '.join(f'{f.physics} {",".join(f.channels)} gap '
                               f'{f.parameters.get("gap_m", float("nan")) * 1e3:.1f} mm'
                               for f in result.findings) or '-'
            print(f'{effect:18s} {seed:4d}  {factor:4.2f}  {named(result):17s} {before:6.1f} '
                  f'{after:7.1f} {fit:6.1f}  {result.fit.model:16s} {detail}', flush=True)
    hits = sum(t == n for t, n in rows if t != 'none')
    alarms = sum(n != 'none' for t, n in rows if t == 'none')
    print(f'travel: stops named {hits}/{sum(t != "none" for t, _ in rows)}, false alarms on '
          f'nulls {alarms}/{sum(t == "none" for t, _ in rows)}')


def real_datasets():
    """Yield ``(title, real, holdout)`` of the real datasets present in ../shared/data."""
    from wheel_force_estimator.diagnosis.generic import load_generic
    from wheel_force_estimator.diagnosis.generic import parse_spec
    friction = SHARED / 'friction_damper'
    if friction.is_dir():
        inp = [parse_spec('data[1]:displacement:in', 'input')]
        out = [parse_spec('data[2]:force:kip', 'output')]

        def load(names):
            return [load_generic(friction / f, inp, out, 1024.0) for f in names]
        yield ('friction damper (Coble et al. 2022, CC BY-SA 4.0)',
               load(('1Hz30lbtension0.5amplitude.json', '1Hz30lbtension1.5amplitude.json',
                     '2Hz30lbtension0.5amplitude.json')),
               load(('1Hz30lbtension1amplitude.json', '0.5Hz30lbtension1amplitude.json')))
    else:
        print(f'friction damper: skipped, {friction} absent')
    mr = SHARED / 'mr_damper'
    if mr.is_dir():
        inp = [parse_spec('x_F[0]:displacement:mm', 'input')]
        out = [parse_spec('x_F[2]:force:N', 'output')]
        yield ('MR damper (labcontrol-data/mr-damper, MIT)',
               [load_generic(mr / 'data_simulation_4.2_MRdamper.mat', inp, out, 100.0)],
               [load_generic(mr / 'data_simulation_4.4_MRdamper.mat', inp, out, 100.0)])
    else:
        print(f'MR damper: skipped, {mr} absent')


def run_real():
    print('\n== real datasets (generic path, the FIR `fit` makes on the real data = reference)')
    for title, real, hold in real_datasets():
        _report_real(title, real, hold)


def _short(report_on):
    """Return a ``fit.report_on`` entry with the file's name only (and no sample list)."""
    from wheel_force_estimator.diagnosis.holdout import evaluate_arguments
    args = evaluate_arguments(report_on)
    return Path(args[0]).name + (f' (report samples, {args[-1].count("..")} ranges)'
                                 if len(args) > 1 else '')


def _report_real(title, real, hold):
    import dataclasses
    from wheel_force_estimator.core.design import product_fit_config
    from wheel_force_estimator.core.errors import DiagnosisError
    ch = real[0].output_channels[0]
    for segment in (None, 256):
        # As the CLI runs it: the segment chosen by cross-validation unless set.
        config = DiagnosisConfig(choose_resolution=True) if segment is None else (
            DiagnosisConfig(fit=dataclasses.replace(product_fit_config(),
                                                    segment_length=segment)))
        how = 'fit defaults' if segment is None else f'segment_length {segment}'
        try:
            result = diagnose(real, None, hold, config)
        except DiagnosisError as err:
            print(f'{title} ({how}): refused: {err}')
            continue
        print(f'{title} ({how}): named {[f.physics for f in result.findings]}; RMSE % on '
              f'{", ".join(_short(p) for p in result.fit.report_on)}: plain fit on the real '
              f'data {result.fit.real_linear[ch]:.1f} -> written {result.fit.after[ch]:.1f} '
              f'({result.fit.model})')
        for line in result.rejected:
            print(f'   not kept: {line}')


RIG_EFFECTS = ('none', 'coulomb_friction', 'damper_asymmetry', 'cubic_stiffness', 'backlash',
               'bump_stop')


def _rig_record(effect, seed, quantity, seconds=60.0, fs_hz=256.0):
    """One corner of the synthetic law driven by its displacement or velocity, 5 % noise."""
    import numpy as np
    sy = FIXTURES
    rng = np.random.default_rng(seed)
    m = sy.random_motion(rng, int(seconds * fs_hz), fs_hz)
    lin = sy.linear_force(m)
    force = lin + sy.effect_force(effect, m, lin, fs_hz)
    force = force[:1] + 0.05 * np.std(lin[:1]) * rng.standard_normal((1, lin.shape[1]))
    motion = {'displacement': m.x, 'velocity': m.v}[quantity][:1]
    return MotionRecording(f'{effect} {quantity} run {seed}', fs_hz, motion, force, ('x',),
                           ('f',), input_quantity=quantity)


def run_rigs(seeds=range(3)):
    from wheel_force_estimator.diagnosis.features import FeatureConfig
    print('\n== displacement / velocity rigs (generic path, segment chosen by cross-validation; '
          'RMSE % on the report half: plain fit -> written; differentiator low-pass fs/8 alone '
          'vs chosen by the gate)')
    print(f'{"input":13s} {"effect":17s} seed  {"fs/8 alone: named":26s} {"fit":>6s} '
          f'{"written":>8s}   {"chosen: named":26s} {"written":>8s}  corner')
    hits = {'alone': 0, 'chosen': 0}
    better = {'alone': 0, 'chosen': 0}
    total = false = 0
    for quantity in ('displacement', 'velocity'):
        for effect in RIG_EFFECTS:
            for seed in seeds:
                real = [_rig_record(effect, 10 * seed + k, quantity) for k in (1, 2)]
                hold = [_rig_record(effect, 10 * seed + k, quantity) for k in (3, 4)]
                alone = diagnose(real, None, hold, DiagnosisConfig(
                    choose_resolution=True, features=FeatureConfig(lowpass_hz=256.0 / 8)))
                chosen = diagnose(real, None, hold, DiagnosisConfig(choose_resolution=True))
                corner = [n.split(':')[1].split(' kept')[0].strip() for n in chosen.fit.notes
                          if n.startswith('Differentiator low-pass')]
                cells = []
                for key, res in (('alone', alone), ('chosen', chosen)):
                    if effect != 'none':
                        hits[key] += named(res) == effect
                        better[key] += res.fit.after['f'] < res.fit.real_linear['f']
                    cells.append(f'{named(res):26s}')
                if effect == 'none':
                    false += bool(chosen.findings)
                else:
                    total += 1
                print(f'{quantity:13s} {effect:17s} {seed:4d}  {cells[0]} '
                      f'{alone.fit.real_linear["f"]:6.2f} {alone.fit.after["f"]:8.2f}   '
                      f'{cells[1]} {chosen.fit.after["f"]:8.2f}  {"".join(corner)}', flush=True)
    print(f'rigs: effect named right: fs/8 alone {hits["alone"]}/{total}, chosen '
          f'{hits["chosen"]}/{total}; written model better than the plain fit: fs/8 alone '
          f'{better["alone"]}/{total}, chosen {better["chosen"]}/{total}; findings on linear '
          f'rigs (chosen): {false}/{2 * len(seeds)}')


def run_structures():
    import numpy as np
    structure_recording = FIXTURES.structure_recording
    STRUCTURES = FIXTURES.STRUCTURES
    print('\n== lightly damped structures (base-excited 5-13 Hz modes, 2-5 % damping; 2 x 60 s '
          'to fit, 60 s holdout; RMSE %, 1 Hz high-pass, mean over outputs, report half)')
    print(f'{"case":24s} {"paper segment: named":28s} {"fit":>6s} {"written":>8s}   '
          f'{"segment chosen: named":28s} {"fit":>6s} {"written":>8s}')
    # The elements inside the loop also at a fifth / a third of their size (2 % / 3.3 % of the
    # spring force at the RMS deflection), where the plain FIR's load is still a usable state.
    cases = [(c, 1.0) for c in STRUCTURES]
    cases += [('hardening in the loop', 0.2), ('friction in the loop', 0.33)]
    for case, strength in cases:
        real = [structure_recording(case, s, strength=strength) for s in (1, 2)]
        hold = [structure_recording(case, 3, strength=strength)]
        cells = []
        for choose in (False, True):
            result = diagnose(real, None, hold, DiagnosisConfig(choose_resolution=choose))
            chans = real[0].output_channels
            fit, after = (float(np.mean([getattr(result.fit, k)[c] for c in chans]))
                          for k in ('real_linear', 'after'))
            cells.append(f'{named(result):28s} {fit:6.1f} {after:8.1f}')
        label = case if strength == 1.0 else f'{case} x{strength:g}'
        print(f'{label:24s} {cells[0]}   {cells[1]}', flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seeds', type=int, default=3, help='synthetic seeds per effect')
    parser.add_argument('--sim-seeds', type=int, default=3, help='simulator seeds per effect')
    parser.add_argument('--duration-scale', type=float, default=0.2,
                        help='proving-ground duration scale (1 = ~10 min per recording)')
    parser.add_argument('--holdout-scale', type=float, default=0.5,
                        help='holdout duration scale (0.5 = ~5 min; half of it reports)')
    parser.add_argument('--sizes', choices=('concealed', 'default'), default='concealed',
                        help='simulator effect sizes: concealed (sim/concealment.py) or the '
                             "simulator's default, visible sizes")
    parser.add_argument('--car', choices=('compact', 'suv'), default='compact',
                        help='simulator car: the default compact or a heavier SUV (SUV)')
    parser.add_argument('--skip-sim', action='store_true')
    parser.add_argument('--only-sim', action='store_true',
                        help='run the simulator parts alone (no synthetic, real, rig parts)')
    parser.add_argument('--effects', help='comma-separated subset')
    parser.add_argument('--seed-list', help='comma-separated simulator seeds (instead of '
                        '--sim-seeds N = 0..N-1); seeds 0-2 and 4 are calibration seeds')
    parser.add_argument('--no-naive', action='store_true',
                        help='skip the naive baseline of the simulator pairs (half the time)')
    parser.add_argument('--no-holdout', action='store_true',
                        help='diagnose the simulator pairs without --holdout and score the '
                             'written model and the plain fit on the whole holdout recording')
    args = parser.parse_args(argv)
    keep_freed_memory()              # as `wheel-force diagnose` does (cli/heap.py)
    chosen = args.effects.split(',') if args.effects else None
    global CAR, NO_HOLDOUT, NO_NAIVE
    NO_HOLDOUT, NO_NAIVE = args.no_holdout, args.no_naive
    if args.car == 'suv':
        from wheel_force_estimator.sim.vehicle import VehicleParams
        CAR = VehicleParams(**SUV)
    t0 = time.time()
    if args.seeds > 0 and not args.only_sim:
        run_synthetic(range(args.seeds), [e for e in chosen or SYNTHETIC if e in SYNTHETIC])
    if not args.skip_sim:
        from wheel_force_estimator.sim.effects import EFFECT_NAMES
        sim_seeds = ([int(s) for s in args.seed_list.split(',')] if args.seed_list
                     else range(args.sim_seeds))
        run_sim(sim_seeds, args.duration_scale,
                chosen or NULLS + tuple(EFFECT_NAMES), args.sizes, args.holdout_scale)
        if not chosen or 'bump_stop' in chosen:
            run_travel(sim_seeds, args.duration_scale, args.sizes,
                       args.holdout_scale)
    if not args.only_sim:
        run_real()
        run_structures()
        run_rigs()
    print(f'\ntotal {time.time() - t0:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
