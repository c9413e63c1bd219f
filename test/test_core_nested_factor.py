# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""A nested input set's least-squares factor bordered from the smaller set's (block Cholesky)."""
import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.nested_factor import BorderedFactor
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations

FS_HZ = 128.0
DESIGN = LiveDesign(look_aheads_s=(0.1,), history_s=0.3, fine_s=0.05, blocks_per_octave=4,
                    regularisation=1e-4)
D_MAX = 12


def _equations(n_in=5, n_out=2, seed=3):
    """Correlated, low-passed inputs and outputs that depend on every input."""
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 0.4)
    x = signal.lfilter(b, a, rng.normal(size=(n_in, 6000)), axis=1)
    x[1] += 0.6 * x[0]
    y = rng.normal(size=(n_out, n_in)) @ np.roll(x, 2, axis=1) + 0.1 * rng.normal(
        size=(n_out, 6000))
    acc = CorrelationAccumulator(n_in, n_out, DESIGN.max_lag(FS_HZ) + D_MAX)
    acc.add(x, y)
    return NormalEquations(acc.result(FS_HZ), D_MAX, DESIGN)


@pytest.mark.parametrize('ridge', [1e-4, 1e-3])
def test_bordered_factor_solves_the_larger_set_as_its_own_factorisation(ridge):
    # Fails (checked) with the added inputs' unknowns numbered input by input instead of
    # lag by lag: two added inputs then keep each other's future taps at a short look-ahead.
    full = _equations()
    inner = LagOrderedFactor(full.subset((0, 1, 2)), ridge)
    middle = BorderedFactor(inner, full.subset((0, 1, 2, 3)), ridge)
    outer = BorderedFactor(middle, full, ridge)                        # two levels of nesting
    both = BorderedFactor(inner, full, ridge)                          # two inputs added
    for eq, got in ((full.subset((0, 1, 2, 3)), middle), (full, outer), (full, both)):
        want = LagOrderedFactor(eq, ridge)
        for d in (D_MAX, 5, 0):
            a, b = got.estimator(d), want.estimator(d)
            scale = np.abs(b.fine_taps).max()
            np.testing.assert_allclose(a.fine_taps, b.fine_taps, rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(a.coarse_taps, b.coarse_taps, rtol=0, atol=1e-9 * scale)
            np.testing.assert_array_equal(a.coarse_edges, b.coarse_edges)
            assert a.info == b.info and a.n_in == eq.n_in
    # the added inputs carry taps: the comparison is not of two all-zero blocks
    assert np.abs(outer.estimator(5).fine_taps[:, 4]).max() > 0.01
    # a shorter look-ahead asked first: its W is the leading block of the longest one's,
    # formed on the way (the shared W of a lag-ordered inner factor)
    want = LagOrderedFactor(full, ridge).estimator(5)
    got = BorderedFactor(inner, full, ridge).estimator(5)
    scale = np.abs(want.fine_taps).max()
    np.testing.assert_allclose(got.fine_taps, want.fine_taps, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(got.coarse_taps, want.coarse_taps, rtol=0, atol=1e-9 * scale)


def test_bordered_factor_refuses_added_inputs_without_power():
    full = _equations()
    dead = NormalEquations.__new__(NormalEquations)
    dead.__dict__.update(full.__dict__)
    a = full.a.copy()
    n_b = full.edges.size - 1
    a[4 * n_b:, :] = 0.0
    a[:, 4 * n_b:] = 0.0
    dead.__dict__['a'] = a                              # the fifth input: no power, no ridge
    with pytest.raises(InsufficientDataError, match='added inputs are not positive definite'):
        BorderedFactor(LagOrderedFactor(full.subset((0, 1, 2, 3))), dead, 1e-4).estimator(3)


def test_bordered_factor_needs_a_smaller_set_of_the_same_basis():
    full = _equations()
    with pytest.raises(ValueError, match='not a smaller set'):
        BorderedFactor(LagOrderedFactor(full), full, 1e-4)
