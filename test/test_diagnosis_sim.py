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

The effects concealed but not nameable here, and the null pairs, are in
``test_diagnosis_sim_silent.py`` (nothing else named for them); the pairs are
``support/blind_pairs.py``.

The concealed sizes are measured with the FRF the diagnosis fits on the simulation, the
design of ``wheel-force fit`` (:mod:`sim.concealment`).  ``time_delay`` is the exception:
the simulator resolves one integration step (1/2048 s), the smallest delay it makes, and
that adds 1.0-1.1 x the floor of that FRF - marginally visible, kept as the smallest case
there is.
"""
import pytest

from support.blind_pairs import check_concealed
from support.blind_pairs import diagnosis_of
from support.blind_pairs import EFFECTS
from support.blind_pairs import mean_over
from support.blind_pairs import MIN_BETTER_RATE
from support.blind_pairs import MIN_HIT_RATE
from support.blind_pairs import named_first
from support.blind_pairs import NONLINEAR
from support.blind_pairs import SEEDS

#: About half the slow tier's work on one worker: started first (test/conftest.py).
pytestmark = pytest.mark.long_file


@pytest.mark.slow
def test_concealed_effects_are_named_first_across_blind_seeds():
    # Bug caught: a rule tuned until one seed's diagonal passed (the hit rate falls on seeds
    # it never saw), or a selection that names nothing (0 hits).
    cases = [(e, s) for e in EFFECTS for s in SEEDS]
    for effect, seed in cases:
        check_concealed(effect, seed)
    hits = [(e, s) for e, s in cases if named_first(e, s)]
    missed = {(e, s): [f.physics for f in diagnosis_of(e, s).findings]
              for e, s in cases if (e, s) not in hits}
    assert len(hits) >= MIN_HIT_RATE * len(cases), missed


@pytest.mark.slow
def test_anti_roll_bar_is_carried_as_a_cross_corner_term():
    # A gain on the predicted left-right load difference, the two sides coupled with opposite
    # signs (partners are the other side's Fz), wherever it is named first.
    named = [s for s in SEEDS if named_first('anti_roll_bar', s)]
    assert named, 'anti_roll_bar named first on no seed'
    for seed in named:
        first = diagnosis_of('anti_roll_bar', seed).findings[0]
        assert first.terms and all(t.physics == 'anti_roll_bar' and t.state == 'load'
                                   and set(t.partners) == set(t.channels) for t in first.terms)


@pytest.mark.slow
def test_named_linear_omissions_get_within_3_pct_of_the_plain_fit():
    # A linear omission: the written model (`evaluate` on the report half, mean over the
    # finding's channels) gets within 3 % of a plain fit on the real data and beats the
    # simulation's FRF, in every case where it is named first.
    cases = [(e, s) for e in EFFECTS if e not in NONLINEAR for s in SEEDS
             if named_first(e, s)]
    assert cases, 'no linear omission named first'
    for effect, seed in cases:
        result = diagnosis_of(effect, seed)
        fit, channels = result.fit, result.findings[0].channels
        after = mean_over(fit.after, channels)
        assert after <= 1.03 * mean_over(fit.real_linear, channels), (effect, seed)
        assert after < mean_over(fit.before, channels), (effect, seed)


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
    cases = [(e, s) for e in NONLINEAR for s in SEEDS if named_first(e, s)]
    assert cases, 'no nonlinear effect named first'
    better = []
    for effect, seed in cases:
        result = diagnosis_of(effect, seed)
        fit, channels = result.fit, result.findings[0].channels
        sources = {fit.rows_from.get(c, fit.model) for c in channels}
        if (all(s.endswith('+physics') for s in sources)
                and mean_over(fit.after, channels) < mean_over(fit.real_linear, channels)):
            better.append((effect, seed))
    assert len(better) >= MIN_BETTER_RATE * len(cases), sorted(set(cases) - set(better))
