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


def test_roll_bar_rate_is_recovered_and_carried_as_a_cross_corner_term():
    from scipy import signal

    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.core.physics import apply_physics
    from wheel_force_estimator.diagnosis.coupling import axle_terms
    from wheel_force_estimator.diagnosis.features import FeatureConfig

    rng = np.random.default_rng(4)
    n = 8192
    sos = signal.butter(2, [0.5, 20.0], 'bandpass', fs=FS_HZ, output='sos')
    accel = signal.sosfilt(sos, rng.standard_normal((12, n)), axis=1) * 5.0
    accel[2::3] += 9.81
    base = rng.standard_normal((12, n)) * 500.0 + 3000.0
    rec0 = MotionRecording('real', FS_HZ, accel, base, INPUT_CHANNELS, OUTPUT_CHANNELS)
    true = {'front': 2.0e4, 'rear': -8.0e3}
    terms = [axle_terms([rec0], 'lf_fz', 'rf_fz', true['front'], FeatureConfig()),
             axle_terms([rec0], 'lr_fz', 'rr_fz', true['rear'], FeatureConfig())]
    real_force = apply_physics(terms, FS_HZ, INPUT_CHANNELS, OUTPUT_CHANNELS, accel, base,
                               rest_inputs=accel.mean(axis=1))
    noise = rng.standard_normal((12, n)) * 10.0
    rec = MotionRecording('real', FS_HZ, accel, real_force + noise, INPUT_CHANNELS,
                          OUTPUT_CHANNELS)
    finding = left_right_coupling([rec], _Fixed(base), _Fixed(real_force), OUTPUT_CHANNELS,
                                  256, 1.0)
    assert finding is not None and finding.physics == 'anti_roll_bar'
    assert finding.channels == ('lf_fz', 'rf_fz', 'lr_fz', 'rr_fz')
    front, rear = finding.terms
    # Opposite signs left and right: each side is driven by its own minus the other's motion.
    assert front.sources == ('lf_az', 'rf_az') and front.partners == ('rf_az', 'lf_az')
    # 10 N of force noise against a roll-bar force of ~50-100 N RMS over 8192 samples: the
    # least-squares rate scatters by well under 1 %; 2 % catches a factor or a sign error.
    assert front.parameters['stiffness_n_per_m'] == pytest.approx(true['front'], rel=0.02)
    assert rear.parameters['stiffness_n_per_m'] == pytest.approx(true['rear'], rel=0.02)
    assert finding.parameters['front_stiffness_n_per_m'] == front.parameters[
        'stiffness_n_per_m']
