# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Locating a residual: frequency band, time window, operating regime."""
import numpy as np
import pytest

from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.locate import locate_channel
from wheel_force_estimator.diagnosis.locate import regime
from wheel_force_estimator.diagnosis.locate import residual_bands
from wheel_force_estimator.diagnosis.locate import residual_windows

FS = 256.0


def _ctx(n, seed=0):
    rng = np.random.default_rng(seed)
    disp, vel = rng.standard_normal(n), rng.standard_normal(n)
    return ChannelContext(disp, vel, rng.standard_normal(n), disp, 3000.0 + 100 * disp, None,
                          FS)


def test_band_of_a_sinusoidal_residual():
    rng = np.random.default_rng(1)
    t = np.arange(int(60 * FS)) / FS
    target = rng.standard_normal(t.size) * 10.0
    residual = 5.0 * np.sin(2 * np.pi * 12.0 * t) + 0.1 * rng.standard_normal(t.size)
    bands = residual_bands([target], [residual], FS)
    assert bands
    lo, hi = bands[0]
    assert lo <= 12.0 <= hi
    # Welch lines are 0.25 Hz apart: a pure tone spreads over a few lines of the Hann window.
    assert hi - lo < 2.0


def test_no_band_for_white_residual():
    rng = np.random.default_rng(2)
    n = int(60 * FS)
    assert residual_bands([rng.standard_normal(n)], [0.1 * rng.standard_normal(n)], FS) == ()


def test_time_window_of_a_burst():
    rng = np.random.default_rng(3)
    n = int(60 * FS)
    residual = rng.standard_normal(n)
    burst = slice(int(20.0 * FS), int(20.5 * FS))
    residual[burst] += 20.0 * np.sin(np.arange(burst.stop - burst.start))
    windows = residual_windows([residual], [100.0], FS)
    assert len(windows) == 1
    a, b = windows[0]
    # Window start/end extend by at most the 0.25 s rolling window around the burst.
    assert 119.7 <= a <= 120.0 and 120.5 <= b <= 120.8


def test_no_window_for_stationary_residual():
    rng = np.random.default_rng(4)
    assert residual_windows([rng.standard_normal(int(60 * FS))], [0.0], FS) == ()


def test_regime_of_a_one_sided_residual():
    n = 20000
    ctx = _ctx(n)
    rng = np.random.default_rng(5)
    residual = 0.2 * rng.standard_normal(n) + 5.0 * np.maximum(ctx.disp - 1.8, 0.0)
    assert regime([residual], [ctx]) == 'large compression'
    residual = 0.2 * rng.standard_normal(n) + 5.0 * np.maximum(-ctx.vel - 1.8, 0.0)
    assert regime([residual], [ctx]) == 'fast rebound'
    assert regime([rng.standard_normal(n)], [ctx]) == 'uniform'


def test_locate_channel_rmse_matches_definition():
    n = 5000
    rng = np.random.default_rng(6)
    target = 100.0 + rng.standard_normal(n)
    prediction = target + 0.3 * rng.standard_normal(n)
    m = locate_channel('lf_fz', [target], [prediction], [_ctx(n)], [0.0], FS)
    err = (prediction - prediction.mean()) - (target - target.mean())
    expected = 100.0 * np.sqrt(np.mean(err ** 2)) / np.std(target)
    assert m.rmse_pct == pytest.approx(expected, rel=1e-12)
    assert m.to_dict()['channel'] == 'lf_fz'
