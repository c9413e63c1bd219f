# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The spin acceleration (issue 33): hand values, numpy.gradient, and chunked == batch.

The live node differentiates the spin rate as the samples arrive
(:class:`SpinAccelerationStream`); offline ``predict`` differentiates whole segments
(:func:`spin_acceleration`).  Both must give the same numbers, bit for bit, or the node's
wrenches drift from ``predict --causal``.
"""
import numpy as np
import pytest

from wheel_force_estimator.core.derived import spin_acceleration
from wheel_force_estimator.core.derived import SpinAccelerationStream
from wheel_force_estimator.core.errors import ShapeError

PERIOD_NS = 1_953_125
T0_NS = 1_760_000_000 * 10**9


def test_hand_values_central_inside_one_sided_at_the_ends():
    # f = t^2 at t = 0, 1, 3 s (unequal steps): the second-order central difference on
    # unequal steps is exact for a parabola (2 t at t = 1 is 2); the ends are one-sided
    # slopes (1 and 4).  Bug caught: equal-step formula on unequal steps (gives 2.25).
    stamps = np.array([0, 1, 3], dtype=np.int64) * 10**9 + T0_NS
    got = spin_acceleration(np.array([[0.0, 1.0, 9.0]]), stamps)
    np.testing.assert_allclose(got, [[1.0, 2.0, 4.0]], rtol=1e-14)


def test_equals_numpy_gradient_on_jittered_stamps():
    rng = np.random.default_rng(4)
    n = 500
    stamps = T0_NS + np.cumsum(PERIOD_NS + rng.integers(-20_000, 20_000, n))
    spin = 30.0 + np.cumsum(rng.standard_normal((4, n)), axis=1) * 0.01
    expected = np.gradient(spin, (stamps - stamps[0]) * 1e-9, axis=1)
    # numpy steps on float times relative to the first stamp, ours on integer steps: they
    # differ by rounding only (a wrong formula or a one-sample shift is ~1 rad/s^2)
    np.testing.assert_allclose(spin_acceleration(spin, stamps), expected, rtol=0, atol=1e-6)


def _stream_all(stream, stamps, x, cuts):
    out_t, out_x = [], []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        t, v = stream.push(stamps[lo:hi], x[:, lo:hi])
        out_t.append(t)
        out_x.append(v)
        # one sample behind: everything received but the newest is released
        assert stream.held == (1 if hi > 0 else 0)
    t, v = stream.finish()
    out_t.append(t)
    out_x.append(v)
    assert stream.held == 0
    return np.concatenate(out_t), np.concatenate(out_x, axis=1)


@pytest.mark.parametrize('chunks', ['single', 'ones', 'twos', 'random'])
def test_chunked_equals_batch_exactly_with_passenger_rows(chunks):
    rng = np.random.default_rng(7)
    n = 203
    stamps = T0_NS + np.cumsum(PERIOD_NS + rng.integers(-5_000, 5_000, n))
    x = rng.standard_normal((7, n))
    spin_rows = [5, 1, 6]
    cuts = {'single': [0, n], 'ones': list(range(n + 1)), 'twos': list(range(0, n, 2)) + [n],
            'random': sorted({0, n, *rng.integers(1, n, 40).tolist()})}[chunks]
    t, got = _stream_all(SpinAccelerationStream(7, spin_rows), stamps, x, cuts)
    assert np.array_equal(t, stamps)
    expected = x.copy()
    expected[spin_rows] = spin_acceleration(x[spin_rows], stamps)
    # bit for bit: the node must equal predict --causal (bug caught: an off-by-one window,
    # the one-sided end applied inside, a passenger row differentiated or shifted)
    assert np.array_equal(got, expected)


def test_segments_restart_and_a_single_sample_segment_gives_nothing():
    stream = SpinAccelerationStream(2, [0])
    x = np.array([[1.0, 3.0, 6.0, 10.0], [9.0, 8.0, 7.0, 6.0]])
    t = T0_NS + np.arange(4, dtype=np.int64) * 10**9
    first = _stream_all(stream, t[:3], x[:, :3], [0, 1, 3])
    np.testing.assert_array_equal(first[1][0], [2.0, 2.5, 3.0])
    assert stream.push(t[3:], x[:, 3:])[0].size == 0          # a new segment: held
    stamp, value = stream.finish()
    assert stamp.size == 0 and value.shape == (2, 0)          # one sample: no derivative
    assert stream.finish()[0].size == 0                       # nothing held, nothing out


def test_bad_arguments():
    with pytest.raises(ShapeError, match='n >= 2'):
        spin_acceleration(np.zeros((4, 1)), np.zeros(1, dtype=np.int64))
    with pytest.raises(ShapeError, match='spin rows'):
        SpinAccelerationStream(4, [4])
    with pytest.raises(ShapeError, match='spin rows'):
        SpinAccelerationStream(4, [1, 1])
    with pytest.raises(ShapeError, match='expected'):
        SpinAccelerationStream(4, [3]).push(np.zeros(2, dtype=np.int64), np.zeros((3, 2)))


# --- the traction/braking split (issue 29) ---------------------------------------------------

FS_HZ = 512.0


def _accel_with_ax(mean_ax, n, seed=0):
    """12 accelerations whose four ax average to ``mean_ax``, other rows noise."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((12, n))
    ax = x[0::3]
    x[0::3] = ax - ax.mean(axis=0) + mean_ax
    return x


def test_split_of_a_steady_specific_force_is_that_force_from_the_first_sample():
    # the filter starts in the first sample's steady state: a constant f_x comes out as is,
    # with no start transient, on the side of its sign (bugs caught: zero initial state, the
    # parts swapped, ay/az rows taken for ax)
    from wheel_force_estimator.core.derived import traction_braking
    for f_x, expected in ((2.5, [[2.5], [0.0]]), (-4.0, [[0.0], [-4.0]])):
        got = traction_braking(_accel_with_ax(np.full(400, f_x), 400), FS_HZ)
        # the IIR rounds to ~1e-12; a start transient would be O(1)
        np.testing.assert_allclose(got, np.repeat(expected, 400, axis=1), rtol=0, atol=1e-9)


def test_split_passes_driver_inputs_and_stops_road_vibration():
    # 2nd-order Butterworth at fc = 2 Hz: |H| = 1/sqrt(1 + (f/fc)^4); 0.1 Hz passes
    # (1 - 3e-6), 20 Hz is cut to 1/100.  Judged on the second half (the start state is the first
    # sample's, not the sine's)
    from wheel_force_estimator.core.derived import SPLIT_LOW_PASS_HZ
    from wheel_force_estimator.core.derived import traction_braking
    n = int(60 * FS_HZ)
    t = np.arange(n) / FS_HZ
    for f_hz in (0.1, 20.0):
        got = traction_braking(_accel_with_ax(np.sin(2 * np.pi * f_hz * t), n), FS_HZ)
        f_x = got[0] + got[1]
        assert np.all(got[0] >= 0) and np.all(got[1] <= 0)
        gain = np.abs(f_x[n // 2:]).max()
        expected = 1 / np.sqrt(1 + (f_hz / SPLIT_LOW_PASS_HZ) ** 4)
        assert gain == pytest.approx(expected, rel=0.02), f_hz


@pytest.mark.parametrize('chunks', [[1] * 50, [7, 13, 1, 300], [5000]])
def test_split_chunked_equals_batch_exactly(chunks):
    from wheel_force_estimator.core.derived import ACCEL_DERIVED_CHANNELS
    from wheel_force_estimator.core.derived import SpecificForceParts
    from wheel_force_estimator.core.derived import specific_force_parts
    rng = np.random.default_rng(8)
    n = sum(chunks)
    x = np.concatenate([_accel_with_ax(np.cumsum(rng.standard_normal(n)) * 0.05, n),
                        rng.standard_normal((4, n))])       # rows after the 12 ride along
    x[1:12:3] += np.cumsum(rng.standard_normal(n)) * 0.05    # a slow lateral force too
    for names in (ACCEL_DERIVED_CHANNELS, ACCEL_DERIVED_CHANNELS[::-1][:3]):
        stream = SpecificForceParts(FS_HZ, names)
        edges = np.cumsum([0] + chunks)
        got = np.concatenate([stream.push(x[:, a:b]) for a, b in zip(edges, edges[1:])],
                             axis=1)
        np.testing.assert_array_equal(got, specific_force_parts(x, FS_HZ, names))
        stream.reset()      # a new segment starts in its own first sample's steady state
        np.testing.assert_array_equal(stream.push(x[:, 10:]),
                                      specific_force_parts(x[:, 10:], FS_HZ, names))


def test_cornering_split_is_the_lateral_twin_of_the_traction_braking_split():
    # the same filter on the mean ay: swapping the ax and ay rows swaps the two splits,
    # bit for bit (bugs caught: ax rows taken for ay, the parts' order or signs swapped)
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.derived import specific_force_parts
    from wheel_force_estimator.core.derived import traction_braking
    rng = np.random.default_rng(3)
    n = 3000
    x = rng.standard_normal((12, n)) + np.sin(np.arange(n) / 300.0) * 3.0
    swapped = x.copy()
    swapped[0::3], swapped[1::3] = x[1::3], x[0::3]
    both = specific_force_parts(x, FS_HZ, SPLIT_CHANNELS + CORNERING_CHANNELS)
    np.testing.assert_array_equal(both[:2], traction_braking(x, FS_HZ))
    np.testing.assert_array_equal(both[2:], traction_braking(swapped, FS_HZ))
    left, right = both[2:]
    assert np.all(left >= 0) and np.all(right <= 0) and left.max() > 1 and right.min() < -1
    # a steady left turn (f_y = +3 m/s^2, ISO 8855 y left) is all left_turn_ay
    steady = np.zeros((12, 200))
    steady[1::3] = 3.0
    np.testing.assert_allclose(specific_force_parts(steady, FS_HZ, CORNERING_CHANNELS),
                               [[3.0] * 200, [0.0] * 200], rtol=0, atol=1e-9)


def test_accel_derived_count_counts_the_trailing_splits_only():
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.derived import accel_derived_count
    assert accel_derived_count(INPUT_CHANNELS) == 0
    assert accel_derived_count(INPUT_CHANNELS + SPLIT_CHANNELS) == 2
    assert accel_derived_count(INPUT_CHANNELS + SPLIT_CHANNELS + CORNERING_CHANNELS) == 4
    assert accel_derived_count(SPLIT_CHANNELS + INPUT_CHANNELS) == 0


def test_split_bad_arguments():
    from wheel_force_estimator.core.derived import specific_force_parts
    from wheel_force_estimator.core.derived import traction_braking
    from wheel_force_estimator.core.errors import ConfigError
    with pytest.raises(ShapeError, match='12 spindle accelerations'):
        traction_braking(np.zeros((11, 5)), FS_HZ)
    with pytest.raises(ConfigError, match='twice the 2 Hz'):
        traction_braking(np.zeros((12, 5)), 3.5)
    with pytest.raises(ConfigError, match=r"\['up_ay'\]: not among"):
        specific_force_parts(np.zeros((12, 5)), FS_HZ, ('left_turn_ay', 'up_ay'))


def test_the_cli_does_not_import_scipy_signal_to_start():
    """Bug caught: the bag reader importing this module made every CLI start pay ~0.7 s."""
    import subprocess
    import sys
    code = ('import sys, wheel_force_estimator.cli.main as m; m.build_parser(); '
            'print("scipy.signal" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout
    assert out.split() == ['False']
