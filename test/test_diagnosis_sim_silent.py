# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Blind diagnosis on simulator pairs: nothing named where nothing is there or nameable.

The pairs, seeds and concealed sizes of ``test_diagnosis_sim.py`` (``support/blind_pairs.py``;
that file's docstring says what is blind).  Null pairs (the nominal car against itself on
other noise or with a drift of 1-3 % in mass, springs and dampers) name nothing.

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
"""
import pytest

from support.blind_pairs import concealment
from support.blind_pairs import diagnosis_of
from support.blind_pairs import FZ
from support.blind_pairs import mean_over
from support.blind_pairs import NOT_NAMEABLE
from support.blind_pairs import SEEDS
from support.blind_pairs import travel_diagnosis

#: About a third of the slow tier's work on one worker: started first (test/conftest.py).
pytestmark = pytest.mark.long_file


@pytest.mark.slow
@pytest.mark.parametrize('seed', SEEDS)
@pytest.mark.parametrize('effect', ['none', 'none_reseeded', 'small_drift'])
def test_null_pairs_give_no_findings(effect, seed):
    # The sim FRF leaves 10-30 % (1 Hz high-passed) of every force unexplained in the
    # simulation itself; the sim contrast must keep that, other roads, and a linear drift of
    # 1-3 % in mass, springs and dampers from being named as physics.
    result = diagnosis_of(effect, seed)
    assert result.findings == (), result.summary


@pytest.mark.slow
@pytest.mark.parametrize('effect', [
    pytest.param(e, marks=pytest.mark.xfail(strict=True, reason=(
        'issue 30, open: measured 2026-11-27 on branch issue30 after the merge with main '
        '(blind seed 5): mass_error named on LF/RF/LR/RR Fx (mass_kg 0.81, explains 4 %); '
        'not yet located whether the fit changes merged from main or this branch cause it')))
    if e == 'backlash' else e for e in NOT_NAMEABLE])
def test_concealed_effects_not_nameable_are_not_misnamed(effect):
    seed = SEEDS[0]
    hidden = concealment(effect, seed)
    assert hidden.concealed, hidden.describe()
    result = diagnosis_of(effect, seed)
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
        assert (mean_over(fit.after, finding.channels)
                <= 1.03 * mean_over(fit.real_linear, finding.channels))


@pytest.mark.slow
def test_concealed_bump_stop_is_named_from_suspension_travel():
    # The same concealed pair as above, but with the compression recorded (a suspension-travel
    # channel) instead of inferred from the spindle accelerations: the stop is then named on
    # the vertical channels with a gap near the simulated 33 mm, and improves the holdout.
    # The bottleneck for the spindle-only diagnosis is the compression state, not the method.
    hidden = concealment('bump_stop', SEEDS[0])
    assert hidden.concealed, hidden.describe()
    result = travel_diagnosis('bump_stop')
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
    assert travel_diagnosis('none').findings == (), travel_diagnosis('none').summary
