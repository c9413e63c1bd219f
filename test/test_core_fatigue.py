# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of core.rainflow and core.fatigue: turning points, rainflow, pseudo damage, RDS."""
from collections import Counter

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.fatigue import damage_bands_hz
from wheel_force_estimator.core.fatigue import PAPER_BANDS_HZ
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.fatigue import relative_damage_spectrum
from wheel_force_estimator.core.fatigue import StreamingDamage
from wheel_force_estimator.core.rainflow import rainflow
from wheel_force_estimator.core.rainflow import RainflowCycles
from wheel_force_estimator.core.rainflow import turning_points

ASTM_HISTORY = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]


def _histogram(cycles: RainflowCycles, with_means=False) -> dict:
    """Sum the counts per range (and mean): order-free comparison of two counts."""
    hist = Counter()
    for r, m, c in zip(cycles.ranges, cycles.means, cycles.counts):
        hist[(r, m) if with_means else r] += c
    return dict(hist)


def _astm_three_point(x) -> dict:
    """
    Literal transcription of ASTM E1049-85 5.4.4 (independent oracle, plain Python).

    Returns {(range, mean): count}.  Turning points by a separate loop; like the module, a
    history without a reversal has none.
    """
    points = []
    for v in x:
        if points and v == points[-1]:
            continue
        if len(points) >= 2 and (points[-1] - points[-2]) * (v - points[-1]) > 0:
            points[-1] = v
        else:
            points.append(v)
    if len(points) < 3:
        return {}
    hist = Counter()
    stack = []
    for p in points:
        stack.append(p)
        while len(stack) >= 3:
            x_rng = abs(stack[-1] - stack[-2])
            y_rng = abs(stack[-2] - stack[-3])
            if x_rng < y_rng:
                break
            key = (y_rng, 0.5 * (stack[-2] + stack[-3]))
            if len(stack) == 3:
                # Y contains the starting point: half cycle, drop the start point.
                hist[key] += 0.5
                stack.pop(0)
            else:
                hist[key] += 1.0
                del stack[-3:-1]
    for a, b in zip(stack[:-1], stack[1:]):
        hist[(abs(b - a), 0.5 * (a + b))] += 0.5
    return dict(hist)


def test_astm_worked_example():
    # ASTM E1049-85 Fig. 6 / Table 4, traced by hand with the standard's three-point rules
    # (points A..I = -2, 1, -3, 5, -1, 3, -4, 4, -2; S = start point):
    #   A,B,C: X=|C-B|=4 >= Y=|B-A|=3, Y holds S -> half cycle 3, drop A, S=B.
    #   B,C,D: X=8 >= Y=4, Y holds S          -> half cycle 4, drop B, S=C.
    #   C,D,E: X=6 < Y=8.  D,E,F: X=4 < Y=6.
    #   E,F,G: X=|G-F|=7 >= Y=|F-E|=4, Y free of S -> full cycle 4 (-1..3), drop E, F.
    #   C,D,G: X=9 >= Y=8, Y holds S          -> half cycle 8, drop C, S=D.
    #   D,G,H: X=8 < Y=9.  G,H,I: X=6 < Y=8.  End: residue D-G 9, G-H 8, H-I 6 half each.
    # Totals: 3 -> 0.5, 4 -> 1.5, 6 -> 0.5, 8 -> 1.0, 9 -> 0.5.  Integer data: exact.
    cycles = rainflow(ASTM_HISTORY)
    assert _histogram(cycles) == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    # Means from the same trace: closed (4, 1); halves (3,-0.5) (4,-1) (8,1) (9,0.5) (8,0) (6,1).
    assert _histogram(cycles, with_means=True) == {
        (4.0, 1.0): 1.0, (3.0, -0.5): 0.5, (4.0, -1.0): 0.5, (8.0, 1.0): 0.5,
        (9.0, 0.5): 0.5, (8.0, 0.0): 0.5, (6.0, 1.0): 0.5}
    # The closed cycle comes first, then the four-point residue in time order.
    np.testing.assert_array_equal(cycles.counts, [1.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5])
    np.testing.assert_array_equal(cycles.ranges, [4.0, 3.0, 4.0, 8.0, 9.0, 8.0, 6.0])
    # Pseudo damage with k = 1 is the count-weighted range sum: 1.5 + 6 + 3 + 8 + 4.5 = 23.
    assert pseudo_damage(ASTM_HISTORY, sn_slope=1.0)[0] == 23.0


def test_four_point_matches_astm_three_point_with_ties_and_plateaus():
    # Small integers make equal ranges, equal levels and plateaus frequent: the cases where
    # a four-point implementation could drift from the standard.  Exact integer arithmetic.
    rng = np.random.default_rng(20260101)
    for _ in range(300):
        x = rng.integers(0, 6, size=rng.integers(0, 60)).astype(float)
        assert _histogram(rainflow(x), with_means=True) == _astm_three_point(list(x))


def test_turning_points_hand_example():
    # 1,1 (start) up to 3,3,3 (peak), down to 2,2,2 (valley), up to 5,5 (peak), down to 1,1.
    x = [1, 1, 2, 3, 3, 3, 2, 2, 2, 4, 5, 5, 1, 1]
    np.testing.assert_array_equal(turning_points(x), [1, 3, 2, 5, 1])
    # 1 lies on the way from 0 to 2: not a reversal.
    np.testing.assert_array_equal(turning_points([0, 1, 2, 1]), [0, 2, 1])
    # No reversal at all: no turning points.
    assert turning_points([0, 0, 1, 1, 2]).size == 0


@pytest.mark.parametrize('n_periods', [1, 2, 7])
def test_sine_gives_n_cycles_of_range_two_amplitude(n_periods):
    # -A cos sampled 32 times per period: the extremes fall on samples and are exactly +-A
    # (cos is flat there, so rounding of the angle cannot move the value off +-1).
    amplitude = 3.0
    x = -amplitude * np.cos(2.0 * np.pi * np.arange(32 * n_periods + 1) / 32.0)
    expected_points = np.tile([-amplitude, amplitude], n_periods + 1)[:2 * n_periods + 1]
    np.testing.assert_array_equal(turning_points(x), expected_points)
    # Four-point stack: each rise after the first is closed by the next, larger-or-equal fall,
    # so n - 1 closed cycles; the residue -A, A, -A gives two half cycles: n cycles in total.
    half = rainflow(x, residue='half')
    assert _histogram(half) == {2.0 * amplitude: float(n_periods)}
    np.testing.assert_array_equal(half.counts, [1.0] * (n_periods - 1) + [0.5, 0.5])
    none = rainflow(x, residue='none')
    np.testing.assert_array_equal(none.counts, np.ones(n_periods - 1))
    k = 5.0
    assert pseudo_damage(x, k)[0] == n_periods * (2.0 * amplitude) ** k
    assert pseudo_damage(x, k, residue='none')[0] == (n_periods - 1) * (2.0 * amplitude) ** k


@pytest.mark.parametrize('x', [[], [4.2], [1.0, 2.0], [3.0] * 10, np.arange(50.0),
                               [5, 5, 4, 4, 4, 1, 0, 0], -np.arange(1e4)])
@pytest.mark.parametrize('residue', ['half', 'none'])
def test_no_reversal_no_cycles_zero_damage(x, residue):
    cycles = rainflow(x, residue=residue)
    assert cycles.ranges.size == cycles.means.size == cycles.counts.size == 0
    np.testing.assert_array_equal(pseudo_damage(x, residue=residue), [0.0])
    stream = StreamingDamage(1, residue=residue)
    stream.update(np.asarray(x, dtype=float)[np.newaxis, :])
    np.testing.assert_array_equal(stream.damage(), [0.0])
    np.testing.assert_array_equal(relative_damage_spectrum(np.zeros((2, 0)), 512.0),
                                  np.zeros((2, 5)))


def _road_like(rng, n_ch, n):
    """Seeded random load: integrated noise plus white noise, quantised to create plateaus."""
    x = np.cumsum(rng.standard_normal((n_ch, n)), axis=1) + 3.0 * rng.standard_normal((n_ch, n))
    return np.round(x * 4.0) / 4.0


def test_damage_equals_rainflow_sum_and_per_channel():
    rng = np.random.default_rng(7)
    x = _road_like(rng, 3, 4000)
    k = 4.3
    batch = pseudo_damage(x, k)
    for ch in range(3):
        cycles = rainflow(x[ch])
        # Same cycles, summed in a different order (sequential vs numpy pairwise): rounding
        # of ~1e3 positive terms stays far below 1e-12 relative.
        np.testing.assert_allclose(batch[ch], np.sum(cycles.counts * cycles.ranges ** k),
                                   rtol=1e-12)
        # All-channel estimate == per-channel estimate: channels do not interact.
        assert pseudo_damage(x[ch], k)[0] == batch[ch]


@pytest.mark.parametrize('k', [5.0, 3.2])
def test_damage_scales_as_gain_to_the_k(k):
    rng = np.random.default_rng(11)
    x = rng.standard_normal((2, 5000)).cumsum(axis=1) + rng.standard_normal((2, 5000))
    gain = 3.7
    # Scaling by gain > 0 keeps every comparison (continuous data, no exact ties) so the
    # cycles are the same; each range picks up ~1 ulp, its k-th power ~k ulps: 1e-12 is
    # three orders above that rounding.
    np.testing.assert_allclose(pseudo_damage(gain * x, k), gain ** k * pseudo_damage(x, k),
                               rtol=1e-12)


def test_residue_policies_differ_by_the_residue_half_cycles():
    rng = np.random.default_rng(3)
    x = _road_like(rng, 1, 3000)[0]
    k = 5.0
    half = rainflow(x, residue='half')
    none = rainflow(x, residue='none')
    closed = half.counts == 1.0
    np.testing.assert_array_equal(none.ranges, half.ranges[closed])
    np.testing.assert_array_equal(none.means, half.means[closed])
    assert np.count_nonzero(~closed) >= 2  # a random record leaves a residue
    residue_damage = 0.5 * np.sum(half.ranges[~closed] ** k)
    # Summation-order rounding only (see test_damage_equals_rainflow_sum_and_per_channel).
    np.testing.assert_allclose(pseudo_damage(x, k, 'half') - pseudo_damage(x, k, 'none'),
                               residue_damage, rtol=1e-12)


@pytest.mark.parametrize('residue', ['half', 'none'])
def test_streaming_equals_batch_for_random_chunkings(residue):
    rng = np.random.default_rng(1234)
    x = _road_like(rng, 4, 6000)
    x[2, 1000:1500] = 7.0  # a long plateau across chunk boundaries
    k = 5.0
    stream = StreamingDamage(4, k, residue)
    for trial in range(5):
        stream.reset()
        assert stream.n_samples == 0
        pos = 0
        while pos < x.shape[1]:
            m = int(rng.choice([0, 1, 1, 2, 3, 17, 64, 511, 2000]))
            stream.update(x[:, pos:pos + m])
            pos = min(pos + m, x.shape[1])
            assert stream.n_samples == pos
            if rng.random() < 0.05:
                # Mid-stream damage is the batch damage of the prefix received so far.
                np.testing.assert_allclose(stream.damage(),
                                           pseudo_damage(x[:, :pos], k, residue), rtol=1e-12)
        # Same cycles closing in the same order, so the sums are even bitwise equal today;
        # 1e-12 relative leaves room for a reordered (but equally valid) summation.
        np.testing.assert_allclose(stream.damage(), pseudo_damage(x, k, residue), rtol=1e-12)
    # One sample at a time through the ASTM history, a single channel as 1-D blocks.
    one = StreamingDamage(1, 1.0, residue)
    for v in ASTM_HISTORY:
        one.update([v])
    assert one.damage()[0] == pseudo_damage(ASTM_HISTORY, 1.0, residue)[0]


def test_streaming_error_leaves_state_unchanged():
    stream = StreamingDamage(2, 5.0)
    stream.update(np.array([[0.0, 1.0, -1.0], [0.0, 2.0, 0.0]]))
    before = stream.damage()
    bad = np.array([[0.5, 0.2], [0.1, np.nan]])
    with pytest.raises(NonFiniteError, match=r'sample 3.*channel 1 at sample 1'):
        stream.update(bad)
    with pytest.raises(ShapeError, match='expected 2 channels, got 3'):
        stream.update(np.zeros((3, 4)))
    assert stream.n_samples == 3
    np.testing.assert_array_equal(stream.damage(), before)


def test_relative_damage_spectrum_of_10hz_sine():
    fs_hz = 500.0  # 50 samples per 10 Hz period: extremes fall exactly on samples
    t_s = np.arange(int(60 * fs_hz)) / fs_hz
    force_n = 100.0 * np.cos(2.0 * np.pi * 10.0 * t_s)
    rds = relative_damage_spectrum(force_n, fs_hz, sn_slope=5.0)
    assert rds.shape == (1, 5)
    total = pseudo_damage(force_n, 5.0)[0]
    # Steady state: Butterworth prototype |H|^2 = 1 / (1 + W^8), W the band-pass-mapped
    # frequency, applied twice by filtfilt; damage goes as gain^5.  At 10 Hz: 7.2-17.6 band
    # W = 0.26, gain 0.99998 -> damage ratio 0.9999; 3.6-8.8 band W = 1.31, gain 0.10 -> 1e-5
    # of the damage; the other bands are below 1e-12.  On top of that the zero-phase filters
    # ring for ~0.1 s (1-2 cycles) at each end of the record: measured 0.2 % lost in the
    # 7.2-17.6 band and 3e-4 of the total leaking into the others for this 600-cycle record.
    # Tolerances: leak < 1e-3 (3x the measured edge effect), band damage within 1 % of the
    # unfiltered damage (a few edge cycles out of 600, each at most ~1.5 nominal cycles).
    assert rds[0, [0, 1, 2, 4]].sum() < 1e-3 * rds[0, 3]
    np.testing.assert_allclose(rds[0, 3] / total, 1.0, rtol=0.0, atol=1e-2)


def test_damage_bands():
    assert damage_bands_hz(512.0) is PAPER_BANDS_HZ
    # 0.8 x Nyquist = 20 Hz at 50 Hz: every edge scaled by 20 / 32 = 0.625.
    bands = damage_bands_hz(50.0)
    expected = ((0.0, 1.375), (1.125, 2.75), (2.25, 5.5), (4.5, 11.0), (9.0, 20.0))
    # The paper edges (2.2, 1.8, ...) are not binary fractions: 1 ulp of rounding allowed.
    np.testing.assert_allclose(np.array(bands), np.array(expected), rtol=1e-15, atol=0.0)
    for fs_hz in (10.0, 50.0, 80.0, 80.1, 1000.0):
        top = max(hi for _, hi in damage_bands_hz(fs_hz))
        assert top <= 0.8 * fs_hz / 2.0 + 1e-12
    # Usable at low rates: a 20 Hz record still gets its five bands.
    rng = np.random.default_rng(5)
    rds = relative_damage_spectrum(rng.standard_normal((2, 2000)), 20.0)
    assert rds.shape == (2, 5) and np.all(rds > 0.0)


def test_errors():
    with pytest.raises(NonFiniteError, match='channel 1 at sample 3'):
        pseudo_damage([[0.0, 1.0, 0.0, 1.0], [0.0, 1.0, 0.0, np.inf]])
    with pytest.raises(NonFiniteError, match='sample 2'):
        rainflow([0.0, 1.0, np.nan])
    with pytest.raises(ShapeError, match='expected one channel'):
        rainflow(np.zeros((2, 5)))
    with pytest.raises(ShapeError, match='expected shape'):
        pseudo_damage(np.zeros((2, 2, 2)))
    for bad in (0.0, -1.0, np.nan, 'five'):
        with pytest.raises(ConfigError, match='sn_slope'):
            pseudo_damage([0.0, 1.0, 0.0], sn_slope=bad)
    with pytest.raises(ConfigError, match='residue must be one of'):
        rainflow([0.0, 1.0, 0.0], residue='full')
    with pytest.raises(ConfigError, match='n_channels'):
        StreamingDamage(0)
    with pytest.raises(ConfigError, match='sn_slope'):
        StreamingDamage(3, sn_slope=-5.0)
    x = np.zeros((1, 1000))
    with pytest.raises(ConfigError, match=r'band \(5.0, 3.0\) Hz'):
        relative_damage_spectrum(x, 100.0, bands_hz=[(5.0, 3.0)])
    with pytest.raises(ConfigError, match='Nyquist 50.0 Hz'):
        relative_damage_spectrum(x, 100.0, bands_hz=[(0.0, 50.0)])
    with pytest.raises(ConfigError, match='pairs'):
        relative_damage_spectrum(x, 100.0, bands_hz=[1.0, 2.0])
    with pytest.raises(ConfigError, match='fs_hz'):
        relative_damage_spectrum(x, 0.0)
    with pytest.raises(InsufficientDataError, match='10 samples, at least'):
        relative_damage_spectrum(np.zeros((1, 10)), 100.0)
    with pytest.raises(ShapeError, match='equal length'):
        RainflowCycles(np.zeros(2), np.zeros(2), np.zeros(3))
