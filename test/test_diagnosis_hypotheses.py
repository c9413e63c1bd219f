# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Candidate rules: sign of load-driven terms, lift-off, roll pairs, linear-rate tolerance."""
import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis.blocks import Piece
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.selection import SelectionConfig
from wheel_force_estimator.diagnosis.selection import Selector

FS_HZ = 256.0


def _context(load):
    zeros = np.zeros(load.size)
    return ChannelContext(zeros, zeros, zeros, zeros, load, None, FS_HZ)


def _selector(load, residual):
    piece = Piece(_context(load), residual, load, 0, 'lf_fx')
    return Selector([piece], SelectionConfig())


def _load(seed=0, n=8192):
    rng = np.random.default_rng(seed)
    return 1000.0 * np.sin(2 * np.pi * 1.3 * np.arange(n) / FS_HZ) + rng.normal(0, 50, n)


def test_load_backlash_explains_a_lost_force_but_not_its_opposite():
    hyp = BY_KEY['backlash:load']
    load = _load()
    ctx = _context(load)
    shape = hyp.grid([ctx])[5]
    lost = hyp.basis(ctx, shape)
    noise = np.random.default_rng(1).normal(0.0, 0.05 * np.std(lost), load.size)
    forward = _selector(load, lost + noise)
    # The exact law with 5 % noise: the held-out gain is close to 1 - 0.05**2.
    assert forward.gain(hyp, shape, forward._sse()) > 0.9
    backward = _selector(load, -lost + noise)
    # A force gained (not lost) around the unloaded point is not a clearance.
    assert backward.gain(hyp, shape, backward._sse()) == 0.0


def test_lift_off_is_only_tried_on_a_preloaded_load():
    hyp = BY_KEY['tire_lift_off']
    swinging = _load()
    assert hyp.grid([_context(swinging)]) == []
    preloaded = 3000.0 + swinging
    preloaded[::500] = -100.0
    assert hyp.grid([_context(preloaded)]) != []


def test_only_vertical_channels_get_a_roll_partner():
    sources, partners = pairing(OUTPUT_CHANNELS, INPUT_CHANNELS)
    for out, src, partner in zip(OUTPUT_CHANNELS, sources, partners):
        assert src in INPUT_CHANNELS
        if out.endswith('fz'):
            assert partner == {'lf': 'rf', 'rf': 'lf', 'lr': 'rr', 'rr': 'lr'}[out[:2]] + '_az'
        else:
            assert partner is None


def _linear_motion(n=60 * 256, seed=3):
    """Wheel motion with exact derivatives: 24 sines, 1.5-15 Hz, random phases."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    w = 2 * np.pi * rng.uniform(1.5, 15.0, 24)
    amp = 2e-3 / (w / w.min())
    phase = rng.uniform(0.0, 2 * np.pi, 24)
    arg = np.outer(w, t) + phase[:, np.newaxis]
    disp = amp @ np.sin(arg)
    vel = (amp * w) @ np.cos(arg)
    acc = -(amp * w * w) @ np.sin(arg)
    return disp, vel, acc


def test_a_damping_change_inside_the_tolerance_is_drift_and_outside_it_is_named():
    stiffness, damping, mass = 20000.0, 2000.0, 15.0
    disp, vel, acc = _linear_motion()
    load = stiffness * disp + damping * vel + mass * acc
    noise = np.random.default_rng(4).normal(0.0, 0.005 * np.std(damping * vel), disp.size)
    config = SelectionConfig(linear_tolerance=0.04)

    def select(change):
        ctx = ChannelContext(disp, vel, acc, acc, load, None, FS_HZ)
        residual = change * damping * vel + noise
        selector = Selector([Piece(ctx, residual, load + residual, 0, 'lf_fz')], config)
        return selector, selector.run([BY_KEY['damping_error']])

    selector, drift = select(-0.02)
    rates = selector.apparent_rates()
    # The reference's own rates are read back from its prediction (exact linear law).
    assert abs(rates['damping_error'] / damping - 1.0) < 1e-3
    assert abs(rates['stiffness_error'] / stiffness - 1.0) < 1e-3
    assert abs(rates['mass_error'] / mass - 1.0) < 1e-3
    # 2 % is far above the noise (the change explains most of the residual) but within the
    # 4 % tolerance: drift, not a finding.
    assert drift.accepted == ()
    choice, _, reason = drift.rejected
    assert choice.hypothesis.physics == 'damping_error' and choice.gain > 0.9
    assert 'tolerance' in reason and '-2.0%' in reason
    _, error = select(-0.08)
    assert [a.hypothesis.physics for a in error.accepted] == ['damping_error']
    assert abs(error.accepted[0].coefficient / (-0.08 * damping) - 1.0) < 0.02
    ctx = ChannelContext(disp, vel, acc, acc, load, None, FS_HZ)
    residual = -0.02 * damping * vel + noise
    strict = Selector([Piece(ctx, residual, load + residual, 0, 'lf_fz')],
                      SelectionConfig(linear_tolerance=0.0)).run([BY_KEY['damping_error']])
    assert [a.hypothesis.physics for a in strict.accepted] == ['damping_error']


def test_known_mass_error_and_time_delay_become_term_parameters():
    from wheel_force_estimator.core.physics import PhysicsTerm
    from wheel_force_estimator.diagnosis.candidates import term_parameters
    from wheel_force_estimator.diagnosis.grids import shift_signal
    stiffness, damping, mass = 20000.0, 2000.0, 15.0
    disp, vel, acc = _linear_motion()
    load = stiffness * disp + damping * vel + mass * acc
    rng = np.random.default_rng(5)
    ctx = ChannelContext(disp, vel, acc, acc, load, None, FS_HZ)

    def accepted(residual, key):
        piece = Piece(ctx, residual, load + residual, 0, 'lf_fz')
        found = Selector([piece], SelectionConfig()).run([BY_KEY[key]]).accepted
        assert [a.hypothesis.key for a in found] == [key]
        a = found[0]
        params = term_parameters(a.hypothesis, a.shape, a.coefficient, FS_HZ)
        PhysicsTerm(key, ('lf_fz',), params)  # a valid term of the registry
        return params

    # 1.2 kg missing (8 % of the reference's 15 kg), noise at 1 % of that force: the
    # least-squares mass scatters by ~1e-4 relative; 1 % catches a unit or factor error.
    extra = 1.2 * acc
    params = accepted(extra + rng.normal(0.0, 0.01 * np.std(extra), acc.size), 'mass_error')
    assert params['mass_kg'] == pytest.approx(1.2, rel=0.01)
    # Force stream 3 samples late (a grid point): the delay is read back exactly, in s.
    late = shift_signal(load, 3.0) - load
    params = accepted(late + rng.normal(0.0, 0.01 * np.std(late), acc.size), 'time_delay')
    assert params == {'delay_s': 3.0 / FS_HZ}


def test_every_candidate_is_a_registered_term_kind():
    from wheel_force_estimator.core.physics import TERM_KINDS
    from wheel_force_estimator.diagnosis.candidates import HYPOTHESES
    from wheel_force_estimator.diagnosis.candidates import LOAD_LINEAR
    # One registry: every candidate the diagnosis ranks can be written as a model term.
    assert {h.key for h in HYPOTHESES + (LOAD_LINEAR,)} <= set(TERM_KINDS)


def test_short_records_get_shorter_cross_validation_blocks_down_to_the_floor():
    from wheel_force_estimator.core.errors import DiagnosisError
    from wheel_force_estimator.diagnosis.blocks import CvData
    config = SelectionConfig()                       # 5 folds of 2 s blocks (512 samples)

    def pieces(*sizes):
        return [Piece(_context(np.ones(n)), np.ones(n), np.ones(n), k, 'f')
                for k, n in enumerate(sizes)]
    long = CvData(pieces(8192), config)
    assert np.array_equal(long.starts[0], np.arange(16) * 512)
    # 1000 samples: 5 blocks of 200 (one per fold) instead of a refusal.
    short = CvData(pieces(1000), config)
    assert np.array_equal(short.starts[0], np.arange(5) * 200)
    assert sorted(short.fold) == [0, 1, 2, 3, 4]
    # Two recordings: every one keeps at least one block.
    two = CvData(pieces(900, 150), config)
    assert all(s.size >= 1 for s in two.starts) and np.unique(two.fold).size == 5
    # Below min_block_samples (64) per fold: one fold per 64-sample block (4 here) ...
    fewer = CvData(pieces(300), config)
    assert fewer.n_folds == 4 and sorted(fewer.fold) == [0, 1, 2, 3]
    assert np.array_equal(fewer.starts[0], np.arange(4) * 64)
    # ... and below 2 such blocks it is refused, with the reason.
    with pytest.raises(DiagnosisError, match='too little data to cross-validate f: .* '
                       r'100 samples .* fewer than 2 time blocks of 64'):
        CvData(pieces(100), config)


def test_null_lags_of_a_periodic_feature_are_where_it_is_unlike_itself():
    from wheel_force_estimator.diagnosis.blocks import null_lags
    n, period = 8192, 256
    phase = 2 * np.pi * np.arange(n) / period
    # A sine, its square wave (odd harmonics) and its rectified form (even harmonics): a
    # shift by a whole period reproduces each, so the null must avoid those lags.
    for feature in (np.sin(phase), np.sign(np.sin(phase)), np.abs(np.sin(phase))):
        lags = np.array(null_lags(feature, 8))
        assert lags.size == 8
        assert lags.min() >= n // 4 and lags.max() < 3 * n // 4
        assert np.all(np.diff(lags) >= n // 32)
        x = feature - feature.mean()
        rho = [abs(np.dot(x, np.roll(x, int(k)))) / np.dot(x, x) for k in lags]
        assert max(rho) < 0.05, rho
    # A constant feature has no autocorrelation to go by: evenly spread lags.
    assert null_lags(np.ones(n), 3) == (n // 4, n // 2, 3 * n // 4)


def test_a_short_sine_test_gets_fewer_null_lags_rather_than_related_ones():
    # 6 whole periods of 1024 samples: within the middle half only the 6 quarter-period
    # offsets put the feature out of phase; a lag the spacing (n / 32 = 192 samples) away
    # from one keeps (1 + cos(0.25 pi)) / 2 = 85 % of the energy in phase - the feature
    # itself, as far as a null can tell (bug caught: filling the null with such lags, which
    # explained 27 % of the friction damper's residual against 49 % for the true backlash).
    from wheel_force_estimator.diagnosis.blocks import null_lags
    n, period = 6144, 1024
    for feature in (np.sin(2 * np.pi * np.arange(n) / period),
                    np.clip(np.sin(2 * np.pi * np.arange(n) / period), -0.3, 0.3)):
        lags = np.array(null_lags(feature, 8))
        assert lags.size == 6
        np.testing.assert_array_equal(lags % (period // 2), period // 4)


def test_the_null_of_a_sine_test_is_not_the_feature_shifted_by_whole_periods():
    from wheel_force_estimator.diagnosis.blocks import NullShift
    hyp = BY_KEY['backlash:load']
    n = 8192
    # A sine test at a period that divides the record: the old fixed quarter-record shift
    # (2048 samples = 8 periods) handed the null the true feature itself.
    load = 1000.0 * np.sin(2 * np.pi * np.arange(n) / 256) + np.random.default_rng(2).normal(
        0, 50, n)
    ctx = _context(load)
    shape = hyp.grid([ctx])[5]
    lost = hyp.basis(ctx, shape)
    noise = np.random.default_rng(3).normal(0.0, 0.3 * np.std(lost), n)
    sel = _selector(load, lost + noise)
    base = sel._sse()
    true_gain = sel.gain(hyp, shape, base)
    assert true_gain > 0.8
    assert sel.gain(hyp, shape, base, NullShift((n // 4,))) > 0.8 * true_gain
    nulls = sel.null_gains(hyp, shape=shape)
    assert max(nulls) < 0.25 * true_gain, nulls
