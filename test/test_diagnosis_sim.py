# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Blind diagnosis on simulator pairs: hit rates over seeds no rule was calibrated on.

Each case: the nominal car (sim) and a car with one effect (real), same roads and noise, a
holdout on other roads; the diagnosis is not told the effect.  Every effect has its concealed
size (:mod:`sim.concealment`), and each test first checks that the pair really conceals it:
it acts on under 5 % of the samples, or adds less error than the simulation's FRF already
makes on the simulation itself, on every channel.  2-minute records (duration scale 0.2).

Blind: the concealed sizes (:data:`sim.concealment.CONCEALED_PARAMS`), the selection's
thresholds (``SelectionConfig``, e.g. ``linear_tolerance``) and every figure quoted in the
diagnosis modules were measured on the :data:`CALIBRATION_SEEDS` (their holdouts are
``seed + 100``, their reseeded nulls ``seed + 50``).  This test runs :data:`SEEDS`, none of
them, with the rates of issue 14's benchmark targets as the bar (not rates measured here):
``bench/diagnose_blind.py --seed-list`` runs more.
Five simulated effects are concealed but not nameable here, and the test asserts that nothing
else is named for them instead:

- ``tire_lift_off``: the WFT at the hub reads the suspension force plus inboard inertia, which
  do not depend on the tyre contact, so lifting off changes the recorded motion but hardly the
  acceleration-to-force behaviour (it adds 0.2 x the noise floor on the worst channel, on
  0.3 % of the samples).  It is named from the motion instead (:mod:`diagnosis.finders.motion`: the
  free-flight signature ``Fz = -m_o az`` and a tyre that never pulls), without a model term.
- ``bump_stop`` at its concealed size (engaged on 3 % of the samples): the true stop force
  explains 18 % of the Fz residual (coefficient 1.0), but no feature the recordings give
  tracks suspension compression closely (body motion is not measured).  Seed 4 names it on
  LF Fz through the predicted load; halved per road event (the records carry their events,
  as bags do), the gate half keeps the plain fit's row there (7.67 % written = plain fit,
  7.96 % simulation).  The stop is fitted on the dynamic engagements of the 2-minute
  record; a long slalom or figure-8 holds the load above its threshold for seconds, a
  regime the record never showed the term in, and there the term adds force that a stop on
  the body-wheel travel does not add to the wheel (seed 1 of the benchmark, LF Fz, contiguous
  halves: in-sample a driveway 8.6 -> 5.3 %, the record's own slalom 13.0 -> 12.9 %; on the
  holdout the slalom 22.8 -> 36.2 %, the figure-8 30.2 -> 50.6 %).  So only
  "nothing else named" is asserted.  With the compression recorded (a suspension-travel
  channel through the generic path) the same concealed stop is named, and its written
  model beats the plain fit.
- ``stiffness_error`` and ``damping_error`` at their concealed sizes (springs 5 % stiffer,
  dampers 3.2 % softer): concealed under the two-resolution FRF the diagnosis fits means
  0.8-0.85 x its noise floor, and that is a change of the size the drift null carries
  (1-3 %, which must stay silent; ``SelectionConfig.linear_tolerance`` is 4 %).  Measured
  at seed 4: no candidate passes (the best, a cubic stiffness, explains 4-5 % of an Fz
  residual, under the 5 % minimum).
- ``backlash`` at its concealed size (a clearance of +-30 um in the fore-aft hub bushing):
  at seed 4 it explains 4 % of the rear Fx residuals, under the 5 % minimum (seed 0 of the
  benchmark names ``mass_error`` on Fx instead).

The concealed sizes are measured with the FRF the diagnosis fits on the simulation, the
design of ``wheel-force fit`` (:mod:`sim.concealment`).  ``time_delay`` is the exception:
the simulator resolves one integration step (1/2048 s), the smallest delay it makes, and
that adds 1.0-1.1 x the floor of that FRF - marginally visible, kept as the smallest case
there is.
"""
import functools

import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import MotionRecording

#: Seeds the concealed sizes, the selection's thresholds and the figures quoted in the
#: diagnosis modules were measured on (holdouts ``seed + 100``, reseeded nulls ``seed + 50``).
CALIBRATION_SEEDS = (0, 1, 2, 4)
#: Seeds this test runs: never used to calibrate anything.
SEEDS = (5, 6)
#: Smallest fraction of the (effect, seed) cases of :data:`EFFECTS` whose first finding names
#: the effect on its channels.  The calibration seeds reach 20/24 (0.83: ``mass_error`` missed
#: on 2 of 3, one ``rebound_stop`` and one ``cubic_stiffness`` missed); 3 of 4 is the bar.
MIN_HIT_RATE = 0.75
#: Smallest fraction of the named nonlinear cases whose written model beats the plain fit
#: (issue 14's target; 11/12 on the calibration seeds).
MIN_BETTER_RATE = 0.9
SCALE = 0.2
#: Holdout length (duration scale 0.5 = 5 minutes): before/after are reported on its second
#: half (the gate and the choice of the written model see the first), and a stop engaging on
#: 3 % of the samples needs minutes of unseen road to show whether its model generalises.
HOLDOUT_SCALE = 0.5
SMALL_DRIFT = {'mass_error': {'fraction': 0.01}, 'stiffness_error': {'fraction': 0.02},
               'damping_error': {'fraction': -0.03}}
FZ = tuple(c for c in OUTPUT_CHANNELS if c.endswith('fz'))
#: Effect -> channels the first finding must lie in.
EFFECTS = {
    'rebound_stop': FZ,
    'cubic_stiffness': FZ,
    'damper_asymmetry': FZ,
    'coulomb_friction': FZ,
    'anti_roll_bar': FZ,
    'time_delay': OUTPUT_CHANNELS,
    'sensor_saturation': OUTPUT_CHANNELS,
    'mass_error': OUTPUT_CHANNELS,
}
NONLINEAR = ('rebound_stop', 'cubic_stiffness', 'damper_asymmetry', 'coulomb_friction',
             'sensor_saturation')
#: Concealed but not nameable from these recordings (see the module docstring).
NOT_NAMEABLE = ('tire_lift_off', 'bump_stop', 'stiffness_error', 'damping_error', 'backlash')
#: At the simulator's resolution rather than concealed (see the module docstring): the
#: largest ratio to the noise floor allowed for them.
AT_RESOLUTION = {'time_delay': 1.2}
#: About half the slow tier's work on one worker: started first (test/conftest.py).
pytestmark = pytest.mark.long_file


@functools.lru_cache(maxsize=None)
def _simulated(effect, seed, scale=SCALE):
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.concealment import concealed_params
    if effect == 'small_drift':
        return simulate('proving_ground', tuple(SMALL_DRIFT), seed, scale,
                        effect_params=SMALL_DRIFT)
    if effect.startswith('none'):
        return simulate('proving_ground', (), seed, scale)
    return simulate('proving_ground', (effect,), seed, scale,
                    effect_params=concealed_params(effect))


def _events(result):
    """Road-event starts as the bag reader gives them (seconds on the record's clock)."""
    return tuple(((t - int(result.stamp_ns[0])) * 1e-9, e) for t, e in result.events)


def _recording(effect, seed, name, scale=SCALE):
    # With the road events a bag carries: a single holdout bag is halved per event.
    result = _simulated(effect, seed, scale)
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS, events=_events(result))


@functools.lru_cache(maxsize=None)
def _diagnosis(effect, seed):
    real_seed = seed + 50 if effect == 'none_reseeded' else seed
    sim = [_recording('none', seed, 'sim')]
    real = [_recording(effect, real_seed, 'real')]
    holdout = [_recording(effect, seed + 100, 'holdout', HOLDOUT_SCALE)]
    return diagnose(real, sim, holdout)


def _concealment(effect, seed):
    from wheel_force_estimator.sim.concealment import measure_concealment
    from wheel_force_estimator.diagnosis.reference import FrfReference
    model = FrfReference.fit([_recording('none', seed, 'sim')], 'sim').model
    return measure_concealment(effect, _simulated('none', seed), _simulated(effect, seed),
                               model)


def _check_concealed(effect, seed):
    hidden = _concealment(effect, seed)
    if effect in AT_RESOLUTION:
        assert max(hidden.excess_ratio.values()) < AT_RESOLUTION[effect], hidden.describe()
    else:
        assert hidden.concealed, hidden.describe()


def _named_first(effect, seed) -> bool:
    """Return True when the first finding names ``effect`` on channels it acts on."""
    findings = _diagnosis(effect, seed).findings
    return bool(findings) and findings[0].physics == effect and set(
        findings[0].channels) <= set(EFFECTS[effect])


def _mean(values, channels):
    return float(np.mean([values[c] for c in channels]))


@pytest.mark.slow
@pytest.mark.parametrize('seed', SEEDS)
@pytest.mark.parametrize('effect', ['none', 'none_reseeded', 'small_drift'])
def test_null_pairs_give_no_findings(effect, seed):
    # The sim FRF leaves 10-30 % (1 Hz high-passed) of every force unexplained in the
    # simulation itself; the sim contrast must keep that, other roads, and a linear drift of
    # 1-3 % in mass, springs and dampers from being named as physics.
    result = _diagnosis(effect, seed)
    assert result.findings == (), result.summary


@pytest.mark.slow
def test_concealed_effects_are_named_first_across_blind_seeds():
    # Bug caught: a rule tuned until one seed's diagonal passed (the hit rate falls on seeds
    # it never saw), or a selection that names nothing (0 hits).
    cases = [(e, s) for e in EFFECTS for s in SEEDS]
    for effect, seed in cases:
        _check_concealed(effect, seed)
    hits = [(e, s) for e, s in cases if _named_first(e, s)]
    missed = {(e, s): [f.physics for f in _diagnosis(e, s).findings]
              for e, s in cases if (e, s) not in hits}
    assert len(hits) >= MIN_HIT_RATE * len(cases), missed


@pytest.mark.slow
def test_anti_roll_bar_is_carried_as_a_cross_corner_term():
    # A gain on the predicted left-right load difference, the two sides coupled with opposite
    # signs (partners are the other side's Fz), wherever it is named first.
    named = [s for s in SEEDS if _named_first('anti_roll_bar', s)]
    assert named, 'anti_roll_bar named first on no seed'
    for seed in named:
        first = _diagnosis('anti_roll_bar', seed).findings[0]
        assert first.terms and all(t.physics == 'anti_roll_bar' and t.state == 'load'
                                   and set(t.partners) == set(t.channels) for t in first.terms)


@pytest.mark.slow
def test_named_linear_omissions_get_within_3_pct_of_the_plain_fit():
    # A linear omission: the written model (`evaluate` on the report half, mean over the
    # finding's channels) gets within 3 % of a plain fit on the real data and beats the
    # simulation's FRF, in every case where it is named first.
    cases = [(e, s) for e in EFFECTS if e not in NONLINEAR for s in SEEDS
             if _named_first(e, s)]
    assert cases, 'no linear omission named first'
    for effect, seed in cases:
        result = _diagnosis(effect, seed)
        fit, channels = result.fit, result.findings[0].channels
        after = _mean(fit.after, channels)
        assert after <= 1.03 * _mean(fit.real_linear, channels), (effect, seed)
        assert after < _mean(fit.before, channels), (effect, seed)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    'issue 30, open: with the strengths fitted on both figures the terms are written again '
    'where they pay on the gate half, but per channel: on seed 5 (measured before the '
    "diagnosis's linear model took fit's searched design) 0/5 named nonlinear cases had "
    'every named channel from a +physics row (rebound_stop: terms on some Fz, 20.54/10.20 % '
    'vs 20.98/11.43 % for the plain fit; seeds 5-6 with the old strengths: 0/10)'))
def test_named_nonlinear_physics_beat_best_linear_fit_on_real_data():
    # The model --out-model writes (`evaluate` of it on the report half) beats a plain
    # `wheel-force fit` on the real recordings on the named channels: the effect is not
    # something any linear model could fit, and the written model carries it there (whole,
    # or in the rows of the named channels when chosen per channel).
    cases = [(e, s) for e in NONLINEAR for s in SEEDS if _named_first(e, s)]
    assert cases, 'no nonlinear effect named first'
    better = []
    for effect, seed in cases:
        result = _diagnosis(effect, seed)
        fit, channels = result.fit, result.findings[0].channels
        sources = {fit.rows_from.get(c, fit.model) for c in channels}
        if (all(s.endswith('+physics') for s in sources)
                and _mean(fit.after, channels) < _mean(fit.real_linear, channels)):
            better.append((effect, seed))
    assert len(better) >= MIN_BETTER_RATE * len(cases), sorted(set(cases) - set(better))


@pytest.mark.slow
@pytest.mark.parametrize('effect', [
    pytest.param(e, marks=pytest.mark.xfail(strict=True, reason=(
        'issue 30, open: measured 2026-11-27 on branch issue30 after the merge with main '
        '(blind seed 5): mass_error named on LF/RF/LR/RR Fx (mass_kg 0.81, explains 4 %); '
        'not yet located whether the fit changes merged from main or this branch cause it')))
    if e == 'backlash' else e for e in NOT_NAMEABLE])
def test_concealed_effects_not_nameable_are_not_misnamed(effect):
    seed = SEEDS[0]
    hidden = _concealment(effect, seed)
    assert hidden.concealed, hidden.describe()
    result = _diagnosis(effect, seed)
    # nothing else is named (naming nothing is allowed for these)
    assert [f.physics for f in result.findings if f.physics != effect] == [], result.summary
    if effect == 'tire_lift_off':
        # Named from the motion comparison, located in time, with no term (the model written
        # is the linear one).
        assert [f.physics for f in result.findings] == ['tire_lift_off'], result.summary
        finding = result.findings[0]
        assert finding.time_windows_s and finding.terms == ()
        assert set(finding.channels) <= set(FZ)
        # The recorded motion is not the simulated one, so the simulation is not kept as it
        # is: the written model is no worse than a plain fit on the real data there.
        fit = result.fit
        assert (_mean(fit.after, finding.channels)
                <= 1.03 * _mean(fit.real_linear, finding.channels))


def _travel_recording(effect, seed, name, scale=SCALE):
    # What a DAQ export with string potentiometers gives the generic path: suspension travel
    # (compression from static equilibrium, + jounce) in, vertical wheel forces out.
    result = _simulated(effect, seed, scale)
    fz = [OUTPUT_CHANNELS.index(c) for c in FZ]
    travel = tuple(c[:2] + '_travel' for c in FZ)
    return MotionRecording(name, result.fs_hz, result.states['suspension_compression_m'],
                           result.force_n[fz], travel, FZ, input_quantity='displacement')


@functools.lru_cache(maxsize=None)
def _travel_diagnosis(effect, seed=SEEDS[0]):
    return diagnose([_travel_recording(effect, seed, 'real')],
                    [_travel_recording('none', seed, 'sim')],
                    [_travel_recording(effect, seed + 100, 'holdout', HOLDOUT_SCALE)])


@pytest.mark.slow
def test_concealed_bump_stop_is_named_from_suspension_travel():
    # The same concealed pair as above, but with the compression recorded (a suspension-travel
    # channel) instead of inferred from the spindle accelerations: the stop is then named on
    # the vertical channels with a gap near the simulated 33 mm, and improves the holdout.
    # The bottleneck for the spindle-only diagnosis is the compression state, not the method.
    hidden = _concealment('bump_stop', SEEDS[0])
    assert hidden.concealed, hidden.describe()
    result = _travel_diagnosis('bump_stop')
    assert result.findings, result.summary
    assert all(f.physics == 'bump_stop' for f in result.findings), result.summary
    named = {c for f in result.findings for c in f.channels}
    assert len(named) >= 3, named
    for finding in result.findings:
        assert 0.025 < finding.parameters['gap_m'] < 0.036, finding.parameters
    # The static law on the sim travel is not an FRF and cannot be written; the written model is
    # built on the FIR fitted from the real travel, which does far worse here (seed 4: 51.0 %
    # against 21.1 % for the static law, Fz mean): measured, not asserted as a gain.  Bug
    # caught: a candidate built on a reference that has no FRF.
    sources = set(result.fit.rows_from.values()) or {result.fit.model}
    assert not any(s.startswith('sim') for s in sources), sources
    # The matched pair without a stop, through the same travel channels: nothing is named.
    assert _travel_diagnosis('none').findings == (), _travel_diagnosis('none').summary
