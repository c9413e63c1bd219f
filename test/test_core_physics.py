# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Physics terms: hand-checked force laws, feature filters, term validation, streaming stage."""
import dataclasses
import json

import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core import physics as ph
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError

FS = 512.0


def test_force_laws_hand_values():
    x = np.array([-0.05, -0.01, 0.0, 0.02, 0.04])
    # 10 mm beyond a 30 mm gap is the reference depth: secant stiffness 1e5 N/m -> 1000 N.
    np.testing.assert_allclose(ph.bump_stop_force(x, 0.03, 1e5, 2.0), [0, 0, 0, 0, 1000.0])
    np.testing.assert_allclose(ph.bump_stop_force(x, 0.0, 1e5, 1.0), [0, 0, 0, 2000, 4000])
    np.testing.assert_allclose(ph.rebound_stop_force(x, 0.04, 1e5, 2.0), [-1000.0, 0, 0, 0, 0])
    np.testing.assert_allclose(ph.cubic_stiffness_force(x, 1e6), 1e6 * x ** 3)
    v = np.array([-2.0, 0.0, 1.0])
    np.testing.assert_allclose(ph.damper_asymmetry_force(v, 100.0), [100.0, 0.0, 50.0])
    np.testing.assert_allclose(ph.coulomb_friction_force(v, 50.0, 1e-9), [-50.0, 0.0, 50.0])
    np.testing.assert_allclose(ph.backlash_force(np.clip(x, -0.01, 0.01), 1e4),
                               [100.0, 100.0, 0.0, -100.0, -100.0])
    np.testing.assert_allclose(ph.tire_lift_off_force([-200.0, 0.0, 500.0], 0.0, 1.0),
                               [200.0, 0.0, 0.0])
    np.testing.assert_allclose(ph.anti_roll_bar_force(x, -x, 10.0), 20.0 * x)
    np.testing.assert_allclose(ph.time_delay_force([1.0, 2.0], [0.5, 1.0]), [-0.5, -1.0])
    np.testing.assert_allclose(ph.clip_indicator([-70.0, 10.0, 60.0], 60.0), [-1.0, 0.0, 1.0])
    np.testing.assert_allclose(ph.mass_error_force(v, 2.0), 2.0 * v)
    np.testing.assert_allclose(ph.stiffness_error_force(x, 3.0), 3.0 * x)
    np.testing.assert_allclose(ph.damping_error_force(v, 4.0), 4.0 * v)


def _play_loop(x, b, y0):
    out, y = np.empty_like(x), y0
    for i, xi in enumerate(x):
        y = min(max(y, xi - b), xi + b)
        out[i] = y
    return out


def test_play_operator_matches_loop_and_splits_exactly():
    x = np.random.default_rng(0).standard_normal(1000).cumsum()
    ref = _play_loop(x, 1.5, x[0])
    # The scan only selects values (no arithmetic), so it is exact.
    assert np.array_equal(ph.play_operator(x, 1.5, x[0]), ref)
    first = ph.play_operator(x[:333], 1.5, x[0])
    second = ph.play_operator(x[333:], 1.5, first[-1])
    assert np.array_equal(np.concatenate([first, second]), ref)
    assert ph.play_operator(np.zeros(0), 1.0, 0.0).size == 0


@pytest.mark.parametrize('f_hz', [2.0, 10.0])
def test_feature_filters_integrate_a_sine(f_hz):
    t = np.arange(int(30 * FS)) / FS
    w = 2 * np.pi * f_hz
    disp = 0.01 * np.sin(w * t)
    accel = -w ** 2 * disp + 9.81
    feats = ph.FeatureBank(FS, 'acceleration', 0.2, 0.0, 1).process(accel[np.newaxis])
    tail = slice(-int(5 * FS), None)
    # Amplitude: the 0.2 Hz high-pass passes >= 2 Hz to within 0.1 % and the bilinear
    # integrator's warping at 10 Hz / 512 Hz is 0.1 %; allow 1 %.
    assert np.std(feats['displacement'][0, tail]) == pytest.approx(0.01 / np.sqrt(2), rel=0.01)
    assert np.std(feats['velocity'][0, tail]) == pytest.approx(0.01 * w / np.sqrt(2), rel=0.01)
    # Phase: HP3 at 0.2 Hz leads by 11.5 deg at 2 Hz (known), 2.3 deg at 10 Hz; correlation
    # with the true displacement is cos(phase) > 0.97.
    assert np.corrcoef(feats['displacement'][0, tail], disp[tail])[0, 1] > 0.97


def test_feature_filters_reject_constant_gravity_exactly():
    accel = np.full((2, 4000), 9.81)
    feats = ph.FeatureBank(FS, 'acceleration', 0.2, 0.0, 2).process(accel)
    # Started in steady state, a constant input stays at the DC gain (zero) up to rounding.
    assert np.abs(feats['displacement']).max() < 1e-9
    assert np.abs(feats['velocity']).max() < 1e-9


def test_feature_filters_differentiate_displacement():
    t = np.arange(int(10 * FS)) / FS
    w = 2 * np.pi * 1.0
    feats = ph.FeatureBank(FS, 'displacement', 0.0, 64.0, 1).process(
        0.02 * np.sin(w * t)[np.newaxis])
    tail = slice(-int(4 * FS), None)
    # The 64 Hz low-pass changes a 1 Hz derivative by < 0.1 % in amplitude.
    assert np.std(feats['velocity'][0, tail]) == pytest.approx(0.02 * w / np.sqrt(2), rel=0.005)
    expected = 0.02 * w ** 2 / np.sqrt(2)
    assert np.std(feats['acceleration'][0, tail]) == pytest.approx(expected, rel=0.005)


def test_feature_filter_errors():
    with pytest.raises(ConfigError, match='highpass_hz'):
        ph.feature_filters(FS, 'acceleration', 0.0, 0.0)
    with pytest.raises(ConfigError, match='lowpass_hz'):
        ph.feature_filters(FS, 'displacement', 0.0, FS)
    with pytest.raises(ConfigError, match='input_quantity'):
        ph.feature_filters(FS, 'jerk', 0.2, 0.0)


def _terms():
    return [
        ph.PhysicsTerm('bump_stop', ('lf_fz', 'rf_fz'),
                       {'gap_m': 0.002, 'stiffness_n_per_m': 1e5, 'exponent': 2.0}),
        ph.PhysicsTerm('rebound_stop', ('lr_fz',),
                       {'gap_m': 0.002, 'stiffness_n_per_m': 1e5, 'exponent': 1.0}),
        ph.PhysicsTerm('cubic_stiffness', ('rr_fz',), {'stiffness_n_per_m3': 1e7}),
        ph.PhysicsTerm('damper_asymmetry', ('lf_fz',),
                       {'compression_minus_rebound_n_s_per_m': 300.0}),
        ph.PhysicsTerm('coulomb_friction', ('rf_fz',),
                       {'friction_n': 50.0, 'velocity_scale_mps': 0.01}),
        ph.PhysicsTerm('backlash', ('lf_fx',),
                       {'gap_m': 0.0005, 'stiffness_n_per_m': 1e4, 'hysteretic': 1.0}),
        ph.PhysicsTerm('backlash', ('rf_fx',),
                       {'gap_m': 0.0005, 'stiffness_n_per_m': 1e4, 'hysteretic': 0.0}),
        ph.PhysicsTerm('tire_lift_off', ('lr_fz',), {'threshold_n': 0.0, 'gain': 1.0}),
        ph.PhysicsTerm('anti_roll_bar', ('lf_fz', 'rf_fz'), {'stiffness_n_per_m': 2e4},
                       partners=('rf_az', 'lf_az')),
        ph.PhysicsTerm('anti_roll_bar', ('lr_fz', 'rr_fz'), {'gain': 0.2},
                       partners=('rr_fz', 'lr_fz'), state='load', state_lowpass_hz=2.0),
        ph.PhysicsTerm('time_delay', ('lf_fy', 'rr_fz'), {'delay_s': 3.3 / FS}),
        ph.PhysicsTerm('sensor_saturation', ('lf_fz',),
                       {'limit': 25.0, 'force_n': 40.0, 'integration': 2.0}),
        ph.PhysicsTerm('mass_error', ('rr_fx',), {'mass_kg': 2.0}),
        ph.PhysicsTerm('stiffness_error', ('rr_fy',), {'stiffness_n_per_m': 1e3}),
        ph.PhysicsTerm('damping_error', ('lr_fy',), {'damping_n_s_per_m': 1e2}),
    ]


def _signals(n=6000, seed=1):
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 30.0, fs=FS)
    accel = signal.lfilter(b, a, rng.standard_normal((12, n)), axis=1) * 20.0 + 9.81
    force = rng.standard_normal((12, n)) * 800.0 + 3000.0
    return accel, force


def test_every_vocabulary_entry_has_a_term_and_round_trips_through_json():
    terms = _terms()
    assert {t.physics for t in terms} == set(ph.VOCABULARY)
    for term in terms:
        back = ph.PhysicsTerm.from_dict(json.loads(json.dumps(term.to_dict())))
        assert back == term


def test_stage_chunked_equals_batch_bit_for_bit():
    accel, force = _signals()
    terms = _terms()
    batch = ph.apply_physics(terms, FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    stage = ph.PhysicsStage(terms, FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    parts, i = [], 0
    for m in (1, 2, 127, 0, 1000, 3, 4000, 867):
        parts.append(stage.process(accel[:, i:i + m], force[:, i:i + m]))
        i += m
    assert i == accel.shape[1]
    assert np.array_equal(np.concatenate(parts, axis=1), batch)
    stage.reset()
    assert np.array_equal(stage.process(accel, force), batch)
    # Every term acts: each channel named by a term differs from the linear force.
    touched = {OUTPUT_CHANNELS.index(c) for t in terms for c in t.channels}
    for o in touched:
        assert not np.array_equal(batch[o], force[o])
    for o in set(range(12)) - touched:
        assert np.array_equal(batch[o], force[o])


def test_stage_time_delay_is_an_exact_shift():
    accel, force = _signals(n=500)
    term = ph.PhysicsTerm('time_delay', OUTPUT_CHANNELS, {'delay_s': 7.0 / FS})
    out = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    # F + (F_delayed - F) is F_delayed up to one rounding.
    np.testing.assert_allclose(out[:, 7:], force[:, :-7], rtol=1e-13)
    np.testing.assert_allclose(out[:, :7], np.repeat(force[:, :1], 7, axis=1), rtol=1e-13)
    half = ph.PhysicsTerm('time_delay', ('lf_fx',), {'delay_s': 0.5 / FS})
    out = ph.apply_physics([half], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    np.testing.assert_allclose(out[0, 1:], 0.5 * (force[0, 1:] + force[0, :-1]), rtol=1e-12)


def test_stage_without_terms_is_identity_and_checks_shapes():
    accel, force = _signals(n=100)
    stage = ph.PhysicsStage([], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    assert np.array_equal(stage.process(accel, force), force)
    stage = ph.PhysicsStage(_terms(), FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    with pytest.raises(ShapeError, match='samples'):
        stage.process(accel[:, :10], force[:, :11])
    with pytest.raises(ShapeError, match='channels'):
        stage.process(accel[:3], force)


def test_stage_rest_inputs_start_the_filters_at_rest():
    accel = np.full((12, 300), 9.81)
    force = np.full((12, 300), 1000.0)
    term = ph.PhysicsTerm('stiffness_error', ('lf_fz',), {'stiffness_n_per_m': 1e6})
    out = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force,
                           rest_inputs=np.full(12, 9.81))
    # Constant input at the rest level: zero displacement, no added force (rounding only).
    np.testing.assert_allclose(out, force, atol=1e-6)


def _term(physics, channels=('lf_fz',), **parameters):
    return {'physics': physics, 'channels': channels, 'parameters': parameters}


@pytest.mark.parametrize('kwargs, match', [
    (_term('spring'), 'not one of'),
    (_term('bump_stop', gap_m=0.01), 'parameters'),
    (_term('bump_stop', gap_m=-0.01, stiffness_n_per_m=1.0, exponent=2.0), 'gap_m'),
    (_term('coulomb_friction', friction_n=1.0, velocity_scale_mps=0.0), 'velocity_scale'),
    (_term('stiffness_error', (), stiffness_n_per_m=1.0), 'channels'),
    (_term('stiffness_error', ('lf_fz', 'lf_fz'), stiffness_n_per_m=1.0), 'unique'),
    (_term('stiffness_error', stiffness_n_per_m=float('nan')), 'finite'),
    (_term('anti_roll_bar', stiffness_n_per_m=1.0), 'partner'),
    (_term('backlash', ('lf_fx',), gap_m=0.1, stiffness_n_per_m=1.0, hysteretic=0.5),
     'hysteretic'),
    (_term('sensor_saturation', limit=1.0, force_n=1.0, integration=3.0), 'integration'),
    (_term('stiffness_error', ('force',), stiffness_n_per_m=1.0), 'source'),
    (dict(_term('mass_error', mass_kg=1.0), response_taps=(1.0, float('nan'))),
     r'mass_error\.response_taps\[1\] must be finite'),
    (dict(_term('mass_error', mass_kg=1.0), response_taps='1.0'), 'list of numbers'),
    (dict(_term('mass_error', mass_kg=1.0), response_taps=np.zeros(ph.MAX_RESPONSE_TAPS + 1)),
     'at most'),
    (dict(_term('mass_error', mass_kg=1.0), force_range_n=((0.0, 1.0), (0.0, 1.0))),
     '2 pairs for 1 channels'),
    (dict(_term('mass_error', mass_kg=1.0), force_range_n=((2.0, 1.0),)),
     'least 2 N is above its greatest 1 N'),
    (dict(_term('mass_error', mass_kg=1.0), force_range_n=((0.0, float('inf')),)),
     r'mass_error\.force_range_n\[0\] must be finite'),
    (dict(_term('mass_error', mass_kg=1.0), force_range_n=(1.0,)), 'least, greatest'),
    (dict(_term('mass_error', mass_kg=1.0), force_range_n='0 1'), 'pairs'),
])
def test_term_validation(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        ph.PhysicsTerm(**kwargs)


def test_from_dict_rejects_unknown_and_missing_keys():
    with pytest.raises(ConfigError, match='unknown keys'):
        ph.PhysicsTerm.from_dict({'physics': 'mass_error', 'channels': ['lf_fz'],
                                  'parameters': {'mass_kg': 1.0}, 'colour': 'red'})
    with pytest.raises(ConfigError, match='missing keys'):
        ph.PhysicsTerm.from_dict({'physics': 'mass_error', 'channels': ['lf_fz']})


def test_stage_rejects_unknown_channels_and_negative_delay():
    term = ph.PhysicsTerm('mass_error', ('xx_fz',), {'mass_kg': 1.0}, sources=('lf_az',))
    with pytest.raises(ConfigError, match='xx_fz'):
        ph.PhysicsStage([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    # A force that leads the acceleration needs look-ahead: refused when the term is built.
    with pytest.raises(ConfigError, match='time_delay.delay_s.*look-ahead'):
        ph.PhysicsTerm('time_delay', ('lf_fz',), {'delay_s': -0.01})


def test_predictor_applies_physics_like_the_batch_stage():
    from wheel_force_estimator.core.model import FrfModel
    from wheel_force_estimator.core.predict import predict_forces
    nf, nt = 65, 128
    taps = np.zeros((12, 12, nt))
    taps[np.arange(12), np.arange(12), 10] = 30.0
    model = FrfModel(fs_hz=FS, input_channels=INPUT_CHANNELS, output_channels=OUTPUT_CHANNELS,
                     f_hz=np.linspace(0.0, FS / 2, nf), h=np.zeros((nf, 12, 12), complex),
                     coherence_ordinary=np.zeros((nf, 12, 12)),
                     coherence_multiple=np.zeros((nf, 12)), cond_sxx=np.ones(nf),
                     fir_taps=taps, fir_delay_samples=10, static_force_n=np.full(12, 3000.0),
                     static_accel_mps2=np.full(12, 9.81), estimator='h1')
    accel, _ = _signals(n=3000)
    # Without the delay line and the load state, which start from the first force sample the
    # stage sees (the predictor's stage sees its look-ahead of held rest first); both are
    # covered by test_predictor_streams_every_term_like_one_block.
    terms = [t for t in _terms() if t.physics != 'time_delay' and t.state == 'motion']
    linear = predict_forces(model, accel)
    augmented = predict_forces(model.with_physics([t.to_dict() for t in terms]), accel)
    expected = ph.apply_physics(terms, FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, linear,
                                rest_inputs=model.static_accel_mps2)
    # Same filters and state: the predictor starts its physics stage at the fit-time rest
    # (static acceleration), like the batch stage given that rest.  The predictor's stage
    # first runs through the 10 look-ahead samples of held rest, where the third-order
    # integrators hold their steady state only to rounding: <= 2e-3 N (measured) on terms of
    # 1e4 N in the first samples, 1e-7 N after 1 s; 1e-2 N bounds that.
    np.testing.assert_allclose(augmented, expected, rtol=1e-9, atol=1e-2)


def test_predictor_streams_every_term_like_one_block():
    from wheel_force_estimator.core.model import FrfModel
    from wheel_force_estimator.core.predict import predict_forces
    nf, nt = 65, 128
    taps = np.zeros((12, 12, nt))
    taps[np.arange(12), np.arange(12), 10] = 30.0
    model = FrfModel(fs_hz=FS, input_channels=INPUT_CHANNELS, output_channels=OUTPUT_CHANNELS,
                     f_hz=np.linspace(0.0, FS / 2, nf), h=np.zeros((nf, 12, 12), complex),
                     coherence_ordinary=np.zeros((nf, 12, 12)),
                     coherence_multiple=np.zeros((nf, 12)), cond_sxx=np.ones(nf),
                     fir_taps=taps, fir_delay_samples=10, static_force_n=np.full(12, 3000.0),
                     static_accel_mps2=np.full(12, 9.81), estimator='h1')
    accel, _ = _signals(n=3000)
    # Every kind, including the cross-corner roll bar and the delay line of time_delay,
    # through the Predictor that predict, evaluate and the node share.
    augmented = model.with_physics(_terms())
    whole = predict_forces(augmented, accel, block_size=3000)
    # Bug caught: state (delay line, play operator, filters) lost between blocks.
    for block in (1, 37, 256):
        np.testing.assert_allclose(predict_forces(augmented, accel, block_size=block), whole,
                                   rtol=0.0, atol=1e-6)
    assert not np.allclose(whole, predict_forces(model, accel))


def test_load_driven_roll_coupling_is_antisymmetric_and_streams():
    np.testing.assert_allclose(ph.load_roll_force([1000.0, 0.0], [0.0, 1000.0], 0.2),
                               [100.0, -100.0])
    term = ph.PhysicsTerm('anti_roll_bar', ('lf_fz', 'rf_fz'), {'gain': 0.3},
                          partners=('rf_fz', 'lf_fz'), state='load', state_lowpass_hz=2.0)
    accel, force = _signals()
    batch = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    lf, rf = OUTPUT_CHANNELS.index('lf_fz'), OUTPUT_CHANNELS.index('rf_fz')
    b, a = signal.butter(1, 2.0, fs=FS)

    def low(x):
        return signal.lfilter(b, a, x, zi=signal.lfilter_zi(b, a) * x[0])[0]
    added = batch - force
    # Known answer: half the gain times the low-passed left-right load difference, with
    # opposite signs (bug caught: both sides pushed the same way, or the partner's input read).
    np.testing.assert_allclose(added[lf], 0.15 * (low(force[lf]) - low(force[rf])), atol=1e-9)
    np.testing.assert_allclose(added[rf], -added[lf], atol=1e-9)
    assert np.count_nonzero(np.delete(added, [lf, rf], 0)) == 0
    stage = ph.PhysicsStage([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    parts = [stage.process(accel[:, i:i + 333], force[:, i:i + 333]) for i in range(0, 6000, 333)]
    assert np.array_equal(np.concatenate(parts, axis=1), batch)
    assert ph.PhysicsTerm.from_dict(json.loads(json.dumps(term.to_dict()))) == term
    with pytest.raises(ConfigError, match="partner channel 'rf_az'"):
        ph.PhysicsStage([ph.PhysicsTerm('anti_roll_bar', ('lf_fz',), {'gain': 0.3},
                                        partners=('rf_az',), state='load',
                                        state_lowpass_hz=2.0)],
                        FS, INPUT_CHANNELS, OUTPUT_CHANNELS)


def test_load_driven_backlash_hand_values_and_stage():
    np.testing.assert_allclose(ph.load_backlash_force([-500.0, 90.0, 100.0, 150.0, 900.0],
                                                      100.0, 200.0, 0.5),
                               [100.0, 5.0, 0.0, -25.0, -100.0])
    term = ph.PhysicsTerm('backlash', ('lf_fx',),
                          {'center_n': 3000.0, 'threshold_n': 300.0, 'gain': 0.8},
                          state='load', state_lowpass_hz=5.0)
    accel, force = _signals()
    batch = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    # Known answer: first-order low-pass of the channel's force started at its first value.
    b, a = signal.butter(1, 5.0, fs=FS)
    o = OUTPUT_CHANNELS.index('lf_fx')
    state = signal.lfilter(b, a, force[o], zi=signal.lfilter_zi(b, a) * force[o, 0])[0]
    expected = force[o] - 0.8 * np.clip(state - 3000.0, -300.0, 300.0)
    # Same filter and law evaluated in another order: only rounding differs (1e-9 N on kN).
    np.testing.assert_allclose(batch[o], expected, rtol=0.0, atol=1e-9)
    assert np.array_equal(np.delete(batch, o, 0), np.delete(force, o, 0))
    stage = ph.PhysicsStage([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    parts = [stage.process(accel[:, i:i + 700], force[:, i:i + 700]) for i in range(0, 6000, 700)]
    assert np.array_equal(np.concatenate(parts, axis=1), batch)
    back = ph.PhysicsTerm.from_dict(json.loads(json.dumps(term.to_dict())))
    assert back == term


@pytest.mark.parametrize('physics', ['mass_error', 'stiffness_error'])
def test_load_driven_linear_omission_hand_values_and_stage(physics):
    np.testing.assert_allclose(ph.load_linear_force([900.0, 1000.0, 1500.0], 1000.0, 0.1),
                               [-10.0, 0.0, 50.0])
    term = ph.PhysicsTerm(physics, ('lf_fz', 'rf_fz'), {'center_n': 2500.0, 'gain': 0.07},
                          state='load', state_lowpass_hz=1.0)
    accel, force = _signals()
    batch = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    b, a = signal.butter(1, 1.0, fs=FS)
    for channel in ('lf_fz', 'rf_fz'):
        o = OUTPUT_CHANNELS.index(channel)
        state = signal.lfilter(b, a, force[o], zi=signal.lfilter_zi(b, a) * force[o, 0])[0]
        # Same filter and law in another order: only rounding differs (1e-9 N on kN).
        np.testing.assert_allclose(batch[o], force[o] + 0.07 * (state - 2500.0), rtol=0.0,
                                   atol=1e-9)
    stage = ph.PhysicsStage([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    parts = [stage.process(accel[:, i:i + 500], force[:, i:i + 500]) for i in range(0, 6000, 500)]
    assert np.array_equal(np.concatenate(parts, axis=1), batch)
    assert ph.PhysicsTerm.from_dict(json.loads(json.dumps(term.to_dict()))) == term
    with pytest.raises(ConfigError, match='parameters must be'):
        ph.PhysicsTerm(physics, ('lf_fz',), {'gain': 0.1}, state='load', state_lowpass_hz=1.0)


def _load_terms():
    return [ph.PhysicsTerm(physics, ('lf_fz',), params, state='load', state_lowpass_hz=2.0)
            for physics, params in (
                ('bump_stop', {'threshold_n': 3010.0, 'gain': 2.0, 'exponent': 2.0}),
                ('rebound_stop', {'threshold_n': 2990.0, 'gain': 2.0, 'exponent': 1.0}),
                ('cubic_stiffness', {'center_n': 3000.0, 'gain': 0.2}),
                ('backlash', {'center_n': 3000.0, 'threshold_n': 10.0, 'gain': 0.8}),
                ('mass_error', {'center_n': 3000.0, 'gain': 0.1}),
                ('stiffness_error', {'center_n': 3000.0, 'gain': 0.1}),
                ('coulomb_friction', {'friction_n': 30.0, 'rate_scale_n_per_s': 1e4}))]


def test_every_registered_strength_scales_the_force_and_nothing_else():
    # The diagnosis carries a jointly fitted strength factor into the written model by scaling
    # the kind's strength parameter: that must scale the added force exactly (bug caught: a
    # table kept beside the registry naming a parameter the force is not proportional to).
    accel, force = _signals()
    terms = _terms() + _load_terms()
    assert {t.key for t in terms} == set(ph.TERM_KINDS)
    for term in terms:
        if term.kind.strength is None:
            assert term.physics == 'time_delay'
            with pytest.raises(ConfigError, match='no strength parameter'):
                term.scaled(2.0)
            continue
        one = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force) - force
        two = ph.apply_physics([term.scaled(-1.5)], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel,
                               force) - force
        assert np.abs(one).max() > 1e-3, term.key
        np.testing.assert_allclose(two, -1.5 * one, rtol=1e-9, atol=1e-9, err_msg=term.key)
        changed = {k for k in term.parameters
                   if term.scaled(-1.5).parameters[k] != term.parameters[k]}
        assert changed == {term.kind.strength}, term.key


def test_a_strength_that_is_not_a_parameter_is_refused():
    from wheel_force_estimator.core.physics_terms import TermKind
    with pytest.raises(ConfigError, match="strength parameter 'gain'"):
        TermKind('cubic_stiffness', 'motion', ph.TERM_KINDS['cubic_stiffness'].params,
                 ph.TERM_KINDS['cubic_stiffness'].force, 'gain')


def test_feature_terms_fade_in_while_the_filters_settle_and_force_terms_do_not():
    # A term read from integrated features must not add the filters' start-up transient (the
    # motion before the first sample is unknown): silent for half the settle time, faded in
    # over the other half.  Terms that read the force prediction start at once.
    accel, force = _signals(n=12000)
    cubic = ph.PhysicsTerm('cubic_stiffness', ('rr_fz',), {'stiffness_n_per_m3': 1e7})
    delay = ph.PhysicsTerm('time_delay', ('lf_fy',), {'delay_s': 3.3 / FS})
    n_settle = ph.settle_samples(FS, cubic.highpass_hz, cubic.lowpass_hz)
    assert n_settle == int(np.ceil(3.0 / cubic.highpass_hz * FS))
    lead = 1000
    stage = ph.PhysicsStage([cubic, delay], FS, INPUT_CHANNELS, OUTPUT_CHANNELS,
                            lead_samples=lead)
    added = stage.process(accel, force) - force
    o, d = OUTPUT_CHANNELS.index('rr_fz'), OUTPUT_CHANNELS.index('lf_fy')
    start = lead + n_settle // 2
    assert not added[o, :start].any() and np.abs(added[o, start + 10:]).max() > 1e-3
    weight = ph.settle_weight(-lead, 12000, n_settle)
    unfaded = ph.PhysicsStage([cubic], FS, INPUT_CHANNELS, OUTPUT_CHANNELS,
                              lead_samples=-10 ** 9).process(accel, force) - force
    np.testing.assert_allclose(added[o], weight * unfaded[o], rtol=1e-12, atol=1e-12)
    assert np.all(np.diff(weight) >= 0.0) and weight[lead + n_settle:].min() == 1.0
    assert np.abs(added[d, :10]).max() > 1.0      # the delay term reads the force: no fade
    # the fade restarts with the filters, and a split record gives the same numbers
    stage.reset()
    parts = [stage.process(accel[:, i:i + 777], force[:, i:i + 777])
             for i in range(0, 12000, 777)]
    assert np.array_equal(np.concatenate(parts, axis=1) - force, added)


def test_load_friction_through_a_response_hand_values_and_stage():
    # Known answer: the load state (first-order low-pass started at the first sample), its
    # backward-difference rate, the regularised friction law, then the causal response FIR.
    taps = (0.0, 0.5, -0.25)
    term = ph.PhysicsTerm('coulomb_friction', ('lf_fx',),
                          {'friction_n': 40.0, 'rate_scale_n_per_s': 5e3},
                          state='load', state_lowpass_hz=20.0, response_taps=taps)
    accel, force = _signals()
    batch = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    b, a = signal.butter(1, 20.0, fs=FS)
    o = OUTPUT_CHANNELS.index('lf_fx')
    state = signal.lfilter(b, a, force[o], zi=signal.lfilter_zi(b, a) * force[o, 0])[0]
    rate = np.diff(state, prepend=state[0]) * FS
    friction = 40.0 * np.tanh(rate / 5e3)
    expected = force[o] + np.convolve(friction, taps)[:friction.size]
    np.testing.assert_allclose(batch[o], expected, rtol=0.0, atol=1e-9)
    assert np.array_equal(np.delete(batch, o, 0), np.delete(force, o, 0))
    stage = ph.PhysicsStage([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS)
    parts = [stage.process(accel[:, i:i + m], force[:, i:i + m])
             for i, m in ((0, 1), (1, 2), (3, 997), (1000, 5000))]
    assert np.array_equal(np.concatenate(parts, axis=1), batch)
    back = ph.PhysicsTerm.from_dict(json.loads(json.dumps(term.to_dict())))
    assert back == term and back.response_taps == taps


def test_a_unit_response_is_the_static_term_and_a_delayed_one_shifts_it():
    accel, force = _signals(n=800)
    static = ph.PhysicsTerm('cubic_stiffness', ('rr_fz',), {'stiffness_n_per_m3': 1e7})
    args = (FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force)
    added = ph.apply_physics([static], *args) - force
    unit = dataclasses.replace(static, response_taps=(1.0,))
    assert np.array_equal(ph.apply_physics([unit], *args), ph.apply_physics([static], *args))
    shifted = dataclasses.replace(static, response_taps=(0.0, 0.0, 2.0))
    out = ph.apply_physics([shifted], *args) - force
    o = OUTPUT_CHANNELS.index('rr_fz')
    np.testing.assert_allclose(out[o, 2:], 2.0 * added[o, :-2], rtol=1e-12, atol=1e-9)
    assert np.all(out[o, :2] == 0.0)
    assert 'response_taps' not in static.to_dict()


def test_a_bounded_term_holds_the_edges_of_its_range_per_channel():
    # Known answer: the stage adds clip(the term's force, least, greatest) on each of the
    # term's channels and nothing elsewhere; the bounds survive JSON and scale with the
    # strength (a negative factor swaps the edges); an unbounded term writes no bounds.
    accel, force = _signals()
    term = ph.PhysicsTerm('rebound_stop', ('lf_fz', 'rf_fz'),
                          {'threshold_n': 2990.0, 'gain': 2.0, 'exponent': 2.0},
                          state='load', state_lowpass_hz=20.0)
    free = ph.apply_physics([term], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force) - force
    rows = [OUTPUT_CHANNELS.index(c) for c in term.channels]
    bounds = tuple((float(np.quantile(free[o], 0.02)), 0.0) for o in rows)
    assert all(lo < -1.0 for lo, _ in bounds)
    bounded = dataclasses.replace(term, force_range_n=bounds)
    out = ph.apply_physics([bounded], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force) - force
    for o, (lo, hi) in zip(rows, bounds):
        assert (free[o] < lo).sum() > 10
        np.testing.assert_allclose(out[o], np.clip(free[o], lo, hi), rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(np.delete(out, rows, 0), 0.0)
    back = ph.PhysicsTerm.from_dict(json.loads(json.dumps(bounded.to_dict())))
    assert back == bounded and back.force_range_n == bounds
    with pytest.raises(ConfigError, match='force_range_n must be a list of'):
        ph.PhysicsTerm.from_dict(dict(bounded.to_dict(), force_range_n='-5 0'))
    assert 'force_range_n' not in term.to_dict()
    flipped = bounded.scaled(-2.0)
    assert flipped.force_range_n == tuple((-2.0 * hi, -2.0 * lo) for lo, hi in bounds)
    two = ph.apply_physics([flipped], FS, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, force) - force
    np.testing.assert_allclose(two, -2.0 * out, rtol=1e-12, atol=1e-9)
