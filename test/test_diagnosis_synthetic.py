# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Blind diagnosis on known-answer sim/real pairs: one concealed effect each, or none."""
import json

import numpy as np
import pytest
from support.diagnosis_synthetic import synthetic_pair

from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig

# The synthetic law is a static force-from-motion law, so the per-channel linear law is the
# exact "simulation" model (an FRF of acceleration cannot represent its displacement term).
CONFIG = DiagnosisConfig(linear='regression')

EFFECTS = ('bump_stop', 'rebound_stop', 'cubic_stiffness', 'damper_asymmetry',
           'coulomb_friction', 'backlash', 'tire_lift_off', 'anti_roll_bar', 'time_delay',
           'sensor_saturation', 'mass_error', 'stiffness_error', 'damping_error')


@pytest.fixture(scope='module')
def results():
    out = {}
    for effect in ('none', 'offset_drift') + EFFECTS:
        sim, real, holdout, info = synthetic_pair(effect, seed=7)
        out[effect] = (diagnose(real, sim, holdout, CONFIG), info)
    return out


@pytest.mark.slow
@pytest.mark.parametrize('effect', EFFECTS)
def test_concealed_effect_is_named_first(results, effect):
    result, info = results[effect]
    # Concealed: on < 5 % of the samples, or weaker than the force noise (measured).
    assert info['active_fraction'] < 0.05 or info['effect_to_noise'] < 1.0
    assert result.findings, result.summary
    first = result.findings[0]
    assert first.physics == effect, [f.physics for f in result.findings]
    assert 'lf_fz' in first.channels
    # Significance is part of acceptance; re-check the recorded figures.
    assert first.explained_fraction > 2.0 * max(first.null_fraction, 0.0)
    assert result.fit.data == 'holdout'


@pytest.mark.slow
def test_only_writable_models_are_scored_as_after(results):
    # The reference here is a static law (not an FRF): it cannot be written, so the written
    # model is built on the FIR fitted on the real data, and `after` is that model's figure.
    # (A static displacement law seen through acceleration inputs is no FIR's business: the
    # before/after gain of the physics is tested on FIR-identifiable rigs in
    # test_diagnosis_written.py.)
    for effect in EFFECTS:
        result, _ = results[effect]
        assert result.fit.model in ('real_frf+physics', 'real_linear', 'per_channel'), effect
        assert set(result.fit.rows_from.values()) <= {'real_frf+physics', 'real_linear'}
        if result.fit.model == 'real_linear':
            assert result.fit.after == result.fit.real_linear


@pytest.mark.slow
@pytest.mark.parametrize('effect', ['none', 'offset_drift'])
def test_nothing_beyond_noise_gives_no_findings(results, effect):
    result, _ = results[effect]
    assert result.findings == ()
    assert result.terms == ()
    assert 'No physics beyond noise' in result.summary[0]
    # Nothing to add: the written model is the plain fit on the real data.
    assert result.fit.model == 'real_linear'
    assert result.fit.after == result.fit.real_linear


@pytest.mark.slow
def test_unaffected_channel_gets_no_term(results):
    for effect in EFFECTS:
        if effect == 'anti_roll_bar':
            continue
        result, _ = results[effect]
        assert all('rf_fz' not in f.channels for f in result.findings), effect


@pytest.mark.slow
def test_bump_stop_parameters_and_json(results):
    result, _ = results['bump_stop']
    finding = result.findings[0]
    # The synthetic stop engages at the 97th percentile of the true displacement (~19 mm);
    # the fitted gap sits on the grid of feature quantiles, within a factor of two.
    assert 0.009 < finding.parameters['gap_m'] < 0.04
    assert finding.parameters['stiffness_n_per_m'] > 0.0
    doc = json.loads(json.dumps(result.to_json()))
    assert set(doc) >= {'mismatch', 'findings', 'fit'}
    assert doc['fit']['data'] == 'holdout'
    entry = doc['findings'][0]
    assert set(entry) >= {'physics', 'channels', 'parameters', 'explained_fraction', 'evidence'}
    worst = doc['mismatch'][0]
    assert worst['channel'] == 'lf_fz'
    assert worst['regime'] == 'large compression'
    assert 'compression' in result.summary[0]


@pytest.mark.slow
def test_anti_roll_bar_is_one_shared_finding(results):
    result, _ = results['anti_roll_bar']
    finding = result.findings[0]
    assert set(finding.channels) == {'lf_fz', 'rf_fz'}
    assert finding.terms[0].partners == ('rf_az', 'lf_az')
    # 4000 N/m synthetic coupling, estimated on band-limited displacement features.
    assert finding.parameters['stiffness_n_per_m'] == pytest.approx(4000.0, rel=0.3)


@pytest.mark.slow
def test_time_delay_is_estimated(results):
    result, _ = results['time_delay']
    # 0.1 sample at 256 Hz; the grid starts at 0.1 sample.
    assert result.findings[0].parameters['delay_s'] == pytest.approx(0.1 / 256.0, rel=0.5)


@pytest.mark.slow
def test_terms_reproduce_the_reported_after_fit(results):
    result, _ = results['damper_asymmetry']
    sim, real, holdout, _ = synthetic_pair('damper_asymmetry', seed=7)
    rec = holdout[0]
    before = result.baseline.predict(rec)
    after = apply_physics(result.terms, rec.fs_hz, rec.input_channels, rec.output_channels,
                          rec.inputs, before, rest_inputs=rec.inputs.mean(axis=1))
    terms = [PhysicsTerm.from_dict(t.to_dict()) for t in result.terms]
    again = apply_physics(terms, rec.fs_hz, rec.input_channels, rec.output_channels,
                          rec.inputs, before, rest_inputs=rec.inputs.mean(axis=1))
    assert np.array_equal(after, again)
    assert not np.array_equal(after[0], before[0])
    np.testing.assert_array_equal(after[1], before[1])


def test_cross_validation_fit_without_holdout():
    sim, real, _, _ = synthetic_pair('mass_error', seed=3, duration_s=40.0)
    result = diagnose(real, sim, (), CONFIG)
    assert result.fit.data == 'cross_validation'
    assert result.findings[0].physics == 'mass_error'
    assert result.fit.after['lf_fz'] < result.fit.before['lf_fz']
