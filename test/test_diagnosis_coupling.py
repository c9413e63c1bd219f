# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Left-right coupling test (sim FRF vs real-data FRF) on known-answer residuals."""
import numpy as np
import pytest

from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.coupling import left_right_coupling

CHANNELS = ('lf_fz', 'rf_fz', 'lr_fz', 'rr_fz')
FS_HZ = 256.0


class _Fixed:
    """Reference stub returning a fixed prediction."""

    def __init__(self, prediction):
        self.prediction = prediction

    def predict(self, rec):
        return self.prediction


def _case(front_left, front_right, seed=0, n=4096):
    """Targets, sim prediction missing (front_left, front_right) x error, exact refit."""
    rng = np.random.default_rng(seed)
    force = rng.standard_normal((4, n)) * 1000.0
    roll = rng.standard_normal(n) * 100.0
    noise = rng.standard_normal((4, n)) * 10.0
    sim = force.copy()
    sim[0] -= front_left * roll
    sim[1] -= front_right * roll
    rec = MotionRecording('real', FS_HZ, np.zeros((4, n)), force + noise, CHANNELS, CHANNELS)
    return rec, _Fixed(sim), _Fixed(force)


def test_antisymmetric_omission_is_named():
    rec, sim, real = _case(1.0, -1.0)
    finding = left_right_coupling([rec], sim, real, CHANNELS, 0, 0.0)
    assert finding is not None
    assert finding.physics == 'anti_roll_bar'
    # Only the front axle misses anything; the rear pair has no residual to explain.
    assert finding.channels == ('lf_fz', 'rf_fz')
    # Error RMS 141 N (difference) against 14 N noise: the refit removes ~99 %.
    assert finding.explained_fraction > 0.95


@pytest.mark.parametrize('left, right', [(1.0, 1.0), (1.0, 0.0)])
def test_symmetric_or_one_sided_omission_is_not_coupling(left, right):
    # Same-sign error (heave-like) or one corner only (per-corner effect): the refit helps
    # the sum at least a third as much as the difference, so no coupling is named.
    rec, sim, real = _case(left, right)
    assert left_right_coupling([rec], sim, real, CHANNELS, 0, 0.0) is None


def test_identical_references_find_nothing():
    rec, _, real = _case(0.0, 0.0)
    assert left_right_coupling([rec], real, real, CHANNELS, 0, 0.0) is None


def test_without_vehicle_channels_nothing_is_tested():
    rec, sim, real = _case(1.0, -1.0)
    assert left_right_coupling([rec], sim, real, ('a', 'b', 'c', 'd'), 0, 0.0) is None


def test_roll_gain_is_recovered_and_carried_as_a_cross_corner_term():
    from scipy import signal

    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.core.physics import apply_physics
    from wheel_force_estimator.diagnosis.coupling import axle_term

    rng = np.random.default_rng(4)
    n = 8192
    accel = rng.standard_normal((12, n))
    # Predicted loads with a roll-like left-right difference below a few Hz.
    roll = signal.sosfilt(signal.butter(2, 3.0, fs=FS_HZ, output='sos'),
                          rng.standard_normal((2, n)), axis=1) * 2000.0
    base = rng.standard_normal((12, n)) * 300.0 + 3000.0
    for (left, right), r in zip((('lf_fz', 'rf_fz'), ('lr_fz', 'rr_fz')), roll):
        base[OUTPUT_CHANNELS.index(left)] += r
        base[OUTPUT_CHANNELS.index(right)] -= r
    true = {'front': (0.25, 2.0), 'rear': (-0.1, 4.0)}
    terms = [axle_term('lf_fz', 'rf_fz', *true['front']),
             axle_term('lr_fz', 'rr_fz', *true['rear'])]
    real_force = apply_physics(terms, FS_HZ, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, base)
    noise = rng.standard_normal((12, n)) * 10.0
    rec = MotionRecording('real', FS_HZ, accel, real_force + noise, INPUT_CHANNELS,
                          OUTPUT_CHANNELS)
    finding = left_right_coupling([rec], _Fixed(base), _Fixed(real_force), OUTPUT_CHANNELS,
                                  256, 1.0)
    assert finding is not None and finding.physics == 'anti_roll_bar'
    assert finding.channels == ('lf_fz', 'rf_fz', 'lr_fz', 'rr_fz')
    front, rear = finding.terms
    # Opposite signs left and right: each side's partner is the other side's Fz.
    assert front.partners == ('rf_fz', 'lf_fz') and front.state == 'load'
    for term, (gain, corner) in ((front, true['front']), (rear, true['rear'])):
        # The corner is found on the grid; 10 N of noise against a coupling force of ~100 N
        # RMS over 8192 samples leaves the gain within 0.5 %: 2 % catches a factor of 2 (the
        # half per side) or a sign error.
        assert term.state_lowpass_hz == corner
        assert term.parameters['gain'] == pytest.approx(gain, rel=0.02)
    assert finding.parameters['front_roll_gain'] == front.parameters['gain']


def test_roll_coupling_without_a_load_signature_is_named_without_a_term():
    from scipy import signal

    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS

    rng = np.random.default_rng(5)
    n = 8192
    sos = signal.butter(2, [0.5, 20.0], 'bandpass', fs=FS_HZ, output='sos')
    accel = signal.sosfilt(sos, rng.standard_normal((12, n)), axis=1) * 5.0
    base = rng.standard_normal((12, n)) * 500.0 + 3000.0
    # An anti-symmetric front force unrelated to the predicted loads (and wheel motion).
    roll = signal.sosfilt(signal.butter(2, 2.0, fs=FS_HZ, output='sos'),
                          rng.standard_normal(n)) * 300.0
    real_force = base.copy()
    real_force[OUTPUT_CHANNELS.index('lf_fz')] += roll
    real_force[OUTPUT_CHANNELS.index('rf_fz')] -= roll
    noise = rng.standard_normal((12, n)) * 10.0
    rec = MotionRecording('real', FS_HZ, accel, real_force + noise, INPUT_CHANNELS,
                          OUTPUT_CHANNELS)
    finding = left_right_coupling([rec], _Fixed(base), _Fixed(real_force), OUTPUT_CHANNELS,
                                  256, 1.0)
    assert finding is not None and finding.channels == ('lf_fz', 'rf_fz')
    # Bug caught: a rate fitted on noise written into the model (it worsens unseen data).
    assert finding.terms == () and 'no term' in finding.evidence
