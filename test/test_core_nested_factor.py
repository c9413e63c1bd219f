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


def _correlations(n_in=5, n_out=2, seed=3, max_lag=80):
    """Correlated, low-passed inputs and outputs that depend on every input."""
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 0.4)
    x = signal.lfilter(b, a, rng.normal(size=(n_in, 6000)), axis=1)
    x[1] += 0.6 * x[0]
    y = rng.normal(size=(n_out, n_in)) @ np.roll(x, 2, axis=1) + 0.1 * rng.normal(
        size=(n_out, 6000))
    acc = CorrelationAccumulator(n_in, n_out, max_lag)
    acc.add(x, y)
    return acc.result(FS_HZ)


def _equations(n_in=5, n_out=2, seed=3):
    """Return the normal equations of :func:`_correlations` at the design's look-ahead."""
    corr = _correlations(n_in, n_out, seed, DESIGN.max_lag(FS_HZ) + D_MAX)
    return NormalEquations(corr, D_MAX, DESIGN)


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


def _assert_bordered_where_an_inner_set_has_the_ridge(got, want, ridges, inner_sets):
    """Assert ``got``'s factors bordered iff an inner set has the ridge, taps as ``want``'s."""
    from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
    from wheel_force_estimator.core.live_estimator import look_ahead_samples
    d = look_ahead_samples(LS_LOOK_AHEAD_S, FS_HZ)
    for i, rs in ridges.items():
        for r in rs:
            bordered = isinstance(got[i].factors[r], BorderedFactor)
            assert bordered == any(r in ridges.get(j, ()) for j in inner_sets[i]), (i, r)
            assert not isinstance(want[i].factors[r], BorderedFactor)
            for look in (d, 3):
                a, b = got[i].estimator(r, look), want[i].estimator(r, look)
                scale = np.abs(b.fine_taps).max()
                np.testing.assert_allclose(a.fine_taps, b.fine_taps, rtol=0,
                                           atol=1e-9 * scale)
                np.testing.assert_allclose(a.coarse_taps, b.coarse_taps, rtol=0,
                                           atol=1e-9 * scale)


@pytest.mark.parametrize('ridges', [
    {0: {1e-3, 1e-4}, 1: {1e-3, 1e-4}, 2: {1e-4}},     # a refit's rows (search.py notes)
    {0: {1e-3}, 2: {1e-3, 1e-4}},                      # the middle set carries 1e-3 across
])
def test_refit_factors_bordered_along_nested_sets_solve_as_their_own(ridges):
    # Bug caught: a bordered chain that skips a set between two that use a ridge, or borders
    # a ridge its inner set was not factorised at (KeyError or another ridge's taps).
    from wheel_force_estimator.core.search import _ls_solutions
    corr = _correlations()
    sets = (('a', (0, 1, 2)), ('a+b', (0, 1, 2, 3)), ('a+b+c', (0, 1, 2, 3, 4)))
    got = _ls_solutions(corr, sets, ridges, DESIGN, bordered=True)
    want = _ls_solutions(corr, sets, ridges, DESIGN)
    assert set(got[1].factors) >= {1e-3}                 # the middle set carries 1e-3
    _assert_bordered_where_an_inner_set_has_the_ridge(got, want, ridges,
                                                      {i: range(i) for i in range(3)})
    # sets that are not nested are factorised each from scratch
    apart = (('a', (0, 1, 2)), ('b', (3, 4)))
    alone = _ls_solutions(corr, apart, {0: {1e-3}, 1: {1e-3}}, DESIGN, bordered=True)
    assert not any(isinstance(f, BorderedFactor) for s in alone.values()
                   for f in s.factors.values())


@pytest.mark.parametrize('ridges', [
    {0: {1e-3}, 1: {1e-3}, 3: {1e-3, 1e-4}},   # 3 borders 1e-3 through 2 (carried), not 1
    {1: {1e-3}, 3: {1e-3}, 0: {1e-4}},         # no ancestor has 1e-3: each from scratch
])
def test_refit_factors_bordered_along_a_tree_of_sets_solve_as_their_own(ridges):
    # The sets of a model with a measured group before the derived ones (spindle.input_sets):
    # two branches from the first set.  A set borders from its parent (the earlier set its
    # columns begin with), never from the set listed before it on another branch.  Bugs
    # caught: a factor bordered from a set that is not its leading block (wrong taps), a
    # ridge carried down the wrong branch (KeyError or a needless factorisation).
    from wheel_force_estimator.core.search import _ls_solutions
    from wheel_force_estimator.core.spindle import parents
    corr = _correlations()
    sets = (('a', (0, 1, 2)), ('a+d', (0, 1, 2, 4)), ('a+b', (0, 1, 2, 3)),
            ('a+b+d', (0, 1, 2, 3, 4)))
    assert parents(sets) == (None, 0, 0, 2)
    got = _ls_solutions(corr, sets, ridges, DESIGN, bordered=True)
    want = _ls_solutions(corr, sets, ridges, DESIGN)
    _assert_bordered_where_an_inner_set_has_the_ridge(
        got, want, ridges, {0: (), 1: (0,), 2: (0,), 3: (2, 0)})
    if 3 in ridges and 1e-3 in ridges.get(0, ()):
        assert isinstance(got[2].factors[1e-3], BorderedFactor)     # carried through 2


@pytest.mark.parametrize('ridges', [{0: {1e-3}, 1: {1e-3}, 2: {1e-3}}, {0: {1e-4}, 2: {1e-4}}])
def test_a_set_on_a_coarser_basis_is_factorised_afresh_on_its_own_basis(ridges, monkeypatch):
    # The live basis left to the default is each set's own (candidates.set_design): with a
    # cost bound that gives 3 and 4 inputs 4 blocks per octave and 5 inputs 2, the largest
    # set cannot border from the others.  Bug caught: a set given the basis of all the
    # model's inputs (the coarser one for the 12 accelerations of a model with the spin).
    from wheel_force_estimator.core import live_estimator
    from wheel_force_estimator.core.candidates import LsSolutions
    from wheel_force_estimator.core.candidates import set_parents
    from wheel_force_estimator.core.candidates import subset_correlations
    from wheel_force_estimator.core.search import _ls_solutions
    monkeypatch.setattr(live_estimator, 'BLOCKS_PER_OCTAVE_CHOICES', (4, 2))
    monkeypatch.setattr(live_estimator, 'MAX_PAST_UNKNOWNS', 70)
    design = LiveDesign(look_aheads_s=(0.1,), history_s=0.3, fine_s=0.05, regularisation=1e-4)
    corr = _correlations()
    sets = (('a', (0, 1, 2)), ('a+b', (0, 1, 2, 3)), ('a+b+c', (0, 1, 2, 3, 4)))
    assert set_parents(sets, design, FS_HZ) == (None, 0, None)
    got = _ls_solutions(corr, sets, ridges, design, bordered=True)
    want = _ls_solutions(corr, sets, ridges, design)
    _assert_bordered_where_an_inner_set_has_the_ridge(got, want, ridges,
                                                      {0: (), 1: (0,), 2: ()})
    for i, rs in ridges.items():
        own = LsSolutions(subset_correlations(corr, sets[i][1]), design, sorted(rs),
                          cache=False)
        for r in rs:
            a, b = got[i].estimator(r, 3), own.estimator(r, 3)
            np.testing.assert_array_equal(a.coarse_edges, b.coarse_edges)
            assert a.info['blocks_per_octave'] == (2 if i == 2 else 4)
            np.testing.assert_allclose(a.coarse_taps, b.coarse_taps, rtol=0,
                                       atol=1e-9 * np.abs(b.fine_taps).max())
    # a model whose rows take sets of both bases: one estimator, each row the same filter
    from wheel_force_estimator.core.candidates import embedded_estimator
    from wheel_force_estimator.core.search import _rows_of
    rows = [embedded_estimator(got[i].estimator(min(ridges[i]), 3), sets[i][1], 5)
            for i in (0, 2)]
    assert rows[0].fine_taps.shape[2] != rows[1].fine_taps.shape[2]
    composed = _rows_of(rows)
    for o, row in enumerate(rows):
        np.testing.assert_array_equal(composed.fir(FS_HZ).taps[o], row.fir(FS_HZ).taps[o])


def test_cache_serves_bordered_parts_to_other_outputs_within_its_byte_budget(monkeypatch):
    # Bugs caught: a refit on the same inputs with other outputs (the diagnosis's backfit)
    # forming its bordered parts again, or served another set's or chain's factor; a cache
    # bounded by entries, which evicted every factor before its reuse once a refit needed
    # more than four.
    from wheel_force_estimator.core import candidates as cand
    from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
    from wheel_force_estimator.core.live_estimator import look_ahead_samples
    from wheel_force_estimator.core.search import _ls_solutions
    cache = cand._RecentFactors()
    monkeypatch.setattr(cand, '_FACTORS', cache)
    sets = (('a', (0, 1, 2)), ('a+b', (0, 1, 2, 3)), ('a+b+c', (0, 1, 2, 3, 4)))
    ridges = {0: {1e-3, 1e-4}, 1: {1e-3, 1e-4}, 2: {1e-4}}
    d = look_ahead_samples(LS_LOOK_AHEAD_S, FS_HZ)
    first = _ls_solutions(_correlations(seed=3), sets, ridges, DESIGN, bordered=True)
    first[2].estimator(1e-4, d)
    other = _correlations(seed=3, n_out=3)             # the same inputs, other outputs
    other = type(other)(other.rxx, other.rxy * 2.0 + 1e-3, other.fs_hz, other.n_samples)
    again = _ls_solutions(other, sets, ridges, DESIGN, bordered=True)
    assert again[2].factors[1e-4].parts is first[2].factors[1e-4].parts
    assert again[2].factors[1e-4].chain == (3, 4, 5)
    want = _ls_solutions(other, sets, ridges, DESIGN)  # each set factorised: not cached alike
    assert want[2].factors[1e-4].chain == (5,)
    for i, rs in ridges.items():
        for r in rs:
            a, b = again[i].estimator(r, d), want[i].estimator(r, d)
            scale = np.abs(b.fine_taps).max()
            np.testing.assert_allclose(a.fine_taps, b.fine_taps, rtol=0, atol=1e-9 * scale)
    # five factors of one refit (two factorised, three bordered) and the three of `want`
    assert len(cache._items) == 8
    # the budget: bytes, the oldest out first, the newest always kept
    held = cache.nbytes()
    small = cand._RecentFactors(max_bytes=held // 8)
    monkeypatch.setattr(cand, '_FACTORS', small)
    _ls_solutions(_correlations(seed=4), sets, {2: {1e-4}}, DESIGN)
    _ls_solutions(_correlations(seed=5), sets, {2: {1e-4}}, DESIGN)
    assert len(small._items) == 1 and 0 < small.nbytes() <= held
