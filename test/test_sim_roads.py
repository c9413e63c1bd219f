# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of sim.roads (ISO 8608 spectra, left/right coherence, enveloping) and sim.courses."""
import numpy as np
import pytest
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.sim import courses
from wheel_force_estimator.sim import roads

DX_M = 0.01
N_POINTS = 1 << 20  # 10.5 km of road
TRACK_M = 1.47
# The course list of the brief (paper Table 1/2 events), in the default course's order.
PAPER_EVENTS = ('highway', 'belgian_block', 'cobblestone', 'washboard', 'pothole',
                'manhole_cover', 'railway_crossing', 'speed_bump', 'driveway', 'variant_wave',
                'twist', 'braking', 'slalom', 'figure_8', 'city_braking')


@pytest.fixture(scope='module')
def road_pair():
    rng = np.random.default_rng(11)
    return roads.random_road_pair(rng, N_POINTS, DX_M, 'C', TRACK_M)


def _bands(n, values, edges):
    pairs = zip(edges[:-1], edges[1:])
    return np.array([values[(n >= lo) & (n < hi)].mean() for lo, hi in pairs])


def test_random_road_has_the_iso8608_psd(road_pair):
    left, right = road_pair
    edges = np.geomspace(0.1, 4.0, 9)
    for z in (left, right):
        n, psd = scipy.signal.welch(z, fs=1.0 / DX_M, nperseg=1 << 15)
        ratio = _bands(n, psd, edges) / _bands(n, roads.iso8608_psd(n, 'C'), edges)
        # 63 Welch averages and >= 19 lines per band: random error <= 3 % (1 sigma) per band;
        # the Hann window's leakage at the steep n^-2 slope adds ~1 % at the lowest band
        np.testing.assert_allclose(ratio, 1.0, atol=0.1)


def test_left_right_coherence_follows_the_model(road_pair):
    left, right = road_pair
    n, coh = scipy.signal.coherence(left, right, fs=1.0 / DX_M, nperseg=1 << 13)
    edges = np.array([0.03, 0.1, 0.3, 0.6, 1.0, 2.0])
    measured = _bands(n, coh, edges)
    model = _bands(n, roads.coherence_sq(n, TRACK_M), edges)
    # 255 averages: the coherence estimate scatters by ~0.02-0.05 and is biased up by
    # ~1/255 where the true value is 0; the model spans 0.9 -> 0.003 over these bands
    np.testing.assert_allclose(measured, model, atol=0.06)
    assert measured[0] > 0.7 and measured[-1] < 0.05


def test_cross_slope_variance_is_the_gradient_of_the_same_spectrum():
    rng = np.random.default_rng(5)
    slope = roads.random_cross_slope(rng, N_POINTS, DX_M, 'B')
    n = np.fft.rfftfreq(N_POINTS, DX_M)
    band = (n >= roads.N_MIN_CYC_PER_M) & (n <= roads.N_MAX_CYC_PER_M)
    expected = np.sum((2 * np.pi * n[band]) ** 2 * roads.iso8608_psd(n[band], 'B')) * n[1]
    # ~50 000 independent spectral lines: the sample variance is within 2 % (6 sigma)
    assert np.var(slope) == pytest.approx(expected, rel=0.03)


def test_unknown_road_class():
    with pytest.raises(ConfigError, match="road class 'Z'"):
        roads.iso8608_psd(np.ones(3), 'Z')


def test_envelope_averages_over_the_contact_length():
    z = np.zeros(200)
    z[100:] = 0.01  # a 10 mm step
    e = roads.envelope(z, DX_M, 0.18)
    assert e.shape == z.shape
    assert np.all(np.diff(e) >= -1e-15)  # monotonic up to cumulative-sum rounding
    ramp = np.flatnonzero((e > 0.0) & (e < 0.01))
    assert ramp.size == 18  # 19-point window: the step becomes an 18-point ramp
    np.testing.assert_allclose(roads.envelope(np.full(50, 0.3), DX_M, 0.18), 0.3)
    np.testing.assert_array_equal(roads.envelope(z, DX_M, 0.0), z)


def test_block_pavement_is_piecewise_stones():
    rng = np.random.default_rng(2)
    h, c = roads.block_pavement(rng, 100_000, DX_M, 0.18, 0.006, 0.03, 0.0)
    steps = np.flatnonzero(np.diff(c) != 0.0)
    lengths = np.diff(steps) * DX_M
    assert lengths.min() >= 0.8 * 0.18 - 2 * DX_M and lengths.max() <= 1.2 * 0.18 + 2 * DX_M
    # ~5500 stones: sample std within 5 % of the parameter
    assert np.std(h[steps + 1]) == pytest.approx(0.006, rel=0.05)
    assert np.std(c[steps + 1]) == pytest.approx(0.03, rel=0.05)


def test_default_course_is_ten_minutes_of_paper_events():
    specs = courses.course_events('proving_ground')
    assert tuple(s.name for s in specs) == PAPER_EVENTS
    assert sum(s.duration_s for s in specs) == pytest.approx(600.0)


@pytest.fixture(scope='module')
def short_plan():
    return courses.build_course('proving_ground', seed=4, duration_scale=0.1, fs_int_hz=1024.0)


def test_duration_scale_shortens_every_event(short_plan):
    full = np.cumsum([0.0] + [s.duration_s for s in courses.course_events('proving_ground')])
    starts = [t for t, _ in short_plan.events]
    np.testing.assert_allclose(starts, 0.1 * full[:-1], atol=1e-9)
    assert short_plan.duration_s == pytest.approx(60.0)
    assert tuple(n for _, n in short_plan.events) == PAPER_EVENTS


def test_driver_plan_is_physical(short_plan):
    v = short_plan.speed_mps
    assert v.min() >= 0.0 and v.max() <= 100.0 / 3.6 + 1e-9
    # the rate limiter allows 6.5 m/s^2 (braking event); smoothing only lowers it
    assert np.abs(short_plan.accel_x_mps2).max() <= 6.5 + 1e-6
    dxdt = np.diff(short_plan.x_m) * short_plan.fs_int_hz
    # trapezoidal integration; a cumulative sum of 60 000 terms rounds at ~1e-11 relative
    np.testing.assert_allclose(dxdt, 0.5 * (v[1:] + v[:-1]), rtol=1e-9)


def test_course_is_deterministic_for_a_seed(short_plan):
    again = courses.build_course('proving_ground', seed=4, duration_scale=0.1,
                                 fs_int_hz=1024.0)
    other = courses.build_course('proving_ground', seed=5, duration_scale=0.1,
                                 fs_int_hz=1024.0)
    np.testing.assert_array_equal(again.road_raw, short_plan.road_raw)
    np.testing.assert_array_equal(again.speed_mps, short_plan.speed_mps)
    assert not np.array_equal(other.road_raw, short_plan.road_raw)
    np.testing.assert_array_equal(other.speed_mps, short_plan.speed_mps)  # same manoeuvres


def test_figure_8_steers_after_reaching_speed():
    plan = courses.build_course([courses.EventSpec('braking', 5.0, 50.0), ('figure_8', 40.0)],
                                fs_int_hz=1024.0)
    t = np.arange(plan.speed_mps.size) / plan.fs_int_hz
    v = plan.speed_mps
    steady = (t > 15.0) & (t < 40.0)
    expected = v[steady] ** 2 / 20.0  # R = 20 m
    ay = np.abs(plan.accel_y_mps2[steady])
    # away from the 0.6 s smoothed direction changes the demand is v^2 / R
    assert np.median(np.abs(ay - expected)) < 1e-3
    first = t[np.flatnonzero(np.abs(plan.accel_y_mps2) > 0.1)[0]]
    assert first > 5.0  # no steering while still braking from 50 km/h


def test_flat_course_has_a_flat_road():
    plan = courses.build_course('flat', fs_int_hz=1024.0)
    assert np.all(plan.road_raw == 0.0)
    assert plan.speed_mps[0] == 0.0 and plan.speed_mps[-1] == pytest.approx(30.0 / 3.6)


@pytest.mark.parametrize('course, match', [
    ('nurburgring', "unknown course 'nurburgring'"),
    ([('cobbles', 3.0)], "unknown course event 'cobbles'"),
    ([('highway', -1.0)], 'duration_s must be > 0'),
    ([42], 'neither an EventSpec'),
    ([], 'no events'),
])
def test_course_errors(course, match):
    with pytest.raises(ConfigError, match=match):
        courses.build_course(course)


def test_duration_scale_must_be_positive():
    with pytest.raises(ConfigError, match='duration_scale'):
        courses.build_course('highway', duration_scale=0.0)
