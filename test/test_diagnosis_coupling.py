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
