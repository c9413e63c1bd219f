# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Hand-computed values and rubric edges of the prediction metrics."""
import numpy as np
import pytest

from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.metrics import rubric
from wheel_force_estimator.core.metrics import rubric_counts
from wheel_force_estimator.core.metrics import RUBRIC_LEVELS

FS_HZ = 512.0


def sine(f_hz, amp, n, phase=0.0):
    return amp * np.sin(2.0 * np.pi * f_hz * np.arange(n) / FS_HZ + phase)


def test_rmse_hand_computed():
    # target [1, -1, 1, -1] (mean 0, RMS 1); prediction [1, -1, 1, 1] has mean 0.5, so the
    # mean-removed error is [-0.5, -0.5, -0.5, 1.5]: RMS sqrt(3/4) -> 86.60 %.
    got = rmse_pct([[1.0, -1.0, 1.0, -1.0]], [[1.0, -1.0, 1.0, 1.0]])
    assert got.shape == (1,)
    assert got[0] == pytest.approx(100.0 * np.sqrt(0.75), abs=1e-12)


def test_rmse_scaled_and_offset_predictions():
    # Per channel: 0.9 * target -> exactly 10 %; target + offset -> 0 % (mean removed);
    # -target -> 200 %.  Only rounding (~1e-14 relative) separates these from the exact values.
    rng = np.random.default_rng(1)
    target = rng.standard_normal((3, 1000)) + np.array([[4000.0], [-3.0], [0.0]])
    prediction = np.stack([0.9 * target[0], target[1] + 250.0, -target[2]])
    np.testing.assert_allclose(rmse_pct(target, prediction), [10.0, 0.0, 200.0], atol=1e-9)
    np.testing.assert_allclose(rmse_pct(target, target), 0.0, atol=1e-12)


def test_rmse_of_orthogonal_drift_is_analytic():
    # Over whole periods sines of different frequencies are orthogonal, so a 0.1 Hz drift of
    # amplitude 0.5 added to target sines (5 Hz amp 2, 13 Hz amp 1) gives exactly
    # 100 * (0.5/sqrt 2) / sqrt((4 + 1)/2) % unfiltered; 1e-9 covers rounding over 20480 samples.
    n = int(40 * FS_HZ)
    target = sine(5.0, 2.0, n) + sine(13.0, 1.0, n, 0.3)
    prediction = target + sine(0.1, 0.5, n, 1.0)
    expected = 100.0 * (0.5 / np.sqrt(2.0)) / np.sqrt(2.5)
    assert rmse_pct(target, prediction)[0] == pytest.approx(expected, abs=1e-9)


def test_highpass_removes_low_frequency_drift_and_keeps_road_band_error():
    # The zero-phase 4th-order 1 Hz high-pass has |H|^2 = 1 / (1 + (1/0.1)^8) ~ 1e-8 at 0.1 Hz,
    # so in steady state the drift error vanishes; the odd-extension edge transients of a slow,
    # smooth drift stay below 0.5 % of the target RMS (measured 0.02 %).  A 20 Hz error passes
    # (|H|^2 = 1 - 4e-11) so its high-passed RMSE equals the unfiltered one to 0.1 % relative,
    # which also covers the edge transients at 20 Hz (measured 4e-5).
    n = int(40 * FS_HZ)
    target = sine(5.0, 2.0, n) + sine(13.0, 1.0, n, 0.3)
    drift = target + sine(0.1, 0.5, n, 1.0)
    road = target + sine(20.0, 0.2, n, 0.7)
    both = np.stack([target, target])
    got = rmse_hp_pct(both, np.stack([drift, road]), FS_HZ)
    assert rmse_pct(target, drift)[0] > 20.0
    assert got[0] < 0.5
    assert got[1] == pytest.approx(rmse_pct(target, road)[0], rel=1e-3)


def test_highpass_is_zero_phase_and_shared_with_rmse_hp():
    # Zero phase: a 10 Hz sine comes out unshifted with gain 1 / (1 + 0.1^8) ~ 1 - 1e-8 and
    # the 0.1 Hz part is removed (gain 1e-8).  The slowest pole (zeta 0.38 at 1 Hz) decays
    # with tau = 0.42 s, so 8 s from the ends the edge transients are ~e^-19 of their start
    # and the residual is below 1e-6 of the amplitude (measured 4e-6 at 5 s, 4e-8 at 8 s).
    # rmse_hp_pct is rmse_pct of the high-passed pair.
    n = int(30 * FS_HZ)
    x = np.stack([sine(10.0, 1.0, n) + sine(0.1, 3.0, n, 0.4), sine(10.0, 2.0, n)])
    y = highpass(x, FS_HZ)
    inner = slice(int(8 * FS_HZ), n - int(8 * FS_HZ))
    np.testing.assert_allclose(y[:, inner], np.stack([sine(10.0, 1.0, n), sine(10.0, 2.0, n)])
                               [:, inner], rtol=0, atol=1e-6)
    assert rmse_hp_pct(x[:1], x[1:], FS_HZ, 2.0)[0] == pytest.approx(
        rmse_pct(highpass(x[:1], FS_HZ, 2.0), highpass(x[1:], FS_HZ, 2.0))[0], rel=1e-12)


@pytest.mark.parametrize('n', [16, 17, 100, 4097])
def test_highpass_equals_scipy_sosfiltfilt_exactly(n):
    # highpass runs scipy's forward-backward steps with the filter's zi computed once; bug
    # caught: a wrong odd extension, a zi not scaled by the edge sample, a shifted crop.
    import scipy.signal
    from wheel_force_estimator.core.filter_design import butter_sos
    x = np.random.default_rng(n).standard_normal((3, n)) + 7.0
    for cutoff in (1.0, 20.0):
        ref = scipy.signal.sosfiltfilt(butter_sos(4, cutoff, 'highpass', FS_HZ), x, axis=1,
                                       padlen=15)
        np.testing.assert_array_equal(highpass(x, FS_HZ, cutoff), ref)
        np.testing.assert_array_equal(highpass(x[0], FS_HZ, cutoff), ref[:1])


def test_constant_target_channel_is_named():
    target = np.ones((12, 100)) * 0.1                # 0.1 is not exact in binary: mean != 0.1
    target[:11] += np.random.default_rng(2).standard_normal((11, 100))
    prediction = np.zeros((12, 100))
    with pytest.raises(InsufficientDataError, match='target rr_fz has zero RMS'):
        rmse_pct(target, prediction, channels=OUTPUT_CHANNELS)
    with pytest.raises(InsufficientDataError, match='target channel 11 has zero RMS'):
        rmse_pct(target, prediction)
    with pytest.raises(InsufficientDataError, match='high-pass RMSE: target rr_fz'):
        rmse_hp_pct(target, prediction, FS_HZ, channels=OUTPUT_CHANNELS)


def test_metric_errors():
    x = np.zeros((2, 100))
    x[:, ::2] = 1.0
    with pytest.raises(ShapeError, match=r'prediction shape \(2, 99\) differs'):
        rmse_pct(x, x[:, :99])
    with pytest.raises(ShapeError, match='expected 12 channels'):
        rmse_pct(x, x, channels=OUTPUT_CHANNELS)
    bad = x.copy()
    bad[1, 7] = np.nan
    with pytest.raises(NonFiniteError, match='RMSE prediction: .* channel 1 at sample 7'):
        rmse_pct(x, bad)
    with pytest.raises(InsufficientDataError, match='0 samples'):
        rmse_pct(np.zeros((2, 0)), np.zeros((2, 0)))
    with pytest.raises(InsufficientDataError, match='15 samples, at least 16 required'):
        rmse_hp_pct(x[:, :15], x[:, :15], FS_HZ)
    with pytest.raises(ConfigError, match='cutoff_hz must be below fs/2'):
        rmse_hp_pct(x, x, FS_HZ, cutoff_hz=256.0)
    with pytest.raises(ConfigError, match='fs_hz'):
        rmse_hp_pct(x, x, -1.0)


@pytest.mark.parametrize('pct, level', [
    (0.0, 'perfect'), (24.999, 'perfect'), (25.0, 'great'), (49.999, 'great'),
    (50.0, 'good'), (74.999, 'good'), (75.0, 'bad'), (99.999, 'bad'),
    (100.0, 'not_qualified'), (1e6, 'not_qualified'), (np.inf, 'not_qualified')])
def test_rubric_edges(pct, level):
    assert rubric(pct) == level


def test_rubric_levels_counts_and_errors():
    assert RUBRIC_LEVELS == ('perfect', 'great', 'good', 'bad', 'not_qualified')
    counts = rubric_counts(np.array([[10.0, 30.0], [30.0, 80.0], [150.0, 25.0]]))
    assert counts == {'perfect': 1, 'great': 3, 'good': 0, 'bad': 1, 'not_qualified': 1}
    assert list(counts) == list(RUBRIC_LEVELS)
    assert rubric_counts({'lf_fz': 21.3, 'lf_fx': 60.0})['good'] == 1
    assert rubric_counts([]) == dict.fromkeys(RUBRIC_LEVELS, 0)
    with pytest.raises(NonFiniteError, match='NaN'):
        rubric(float('nan'))
    with pytest.raises(ConfigError, match='>= 0'):
        rubric(-0.1)
    with pytest.raises(ConfigError, match='must be a number'):
        rubric_counts(['great'])
