# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live estimator's design: the normal equations of its multi-rate basis, and their factors.

The basis and the estimator they solve for are :mod:`.live_estimator`; the correlations they
are built from, :mod:`.correlations`.

Normal equations
----------------
Output ``o`` is ``y_o(n) ~ sum_i sum_l g_oi(l) x_i(n - l)`` for lags ``l`` in ``[-D, H]``,
``g_oi = sum_p θ_oip b_p`` with ``b_p`` the indicator of lag block ``p``.  Then
``A[(i,p),(j,q)] = sum_{l in p} sum_{m in q} r_ij(l - m)`` and
``B[(j,q), o] = sum_{m in q} r_{x_j y_o}(m)``, built from cumulative sums of ``r``.  A ridge
``λ_i = regularisation * r_ii(0)`` per unit tap (times the block width) is added for each
input ``i``: relative to that input's power like the FRF's Tikhonov term, so the result does
not depend on the units or gains of the channels, and it keeps collinear inputs (left and
right on a symmetric road) from trading huge opposite taps.

Factorisation
-------------
One Cholesky factorisation serves every stored look-ahead (:class:`LagOrderedFactor`): with
the unknowns ordered lag by lag, the future lags last and nearest first, each look-ahead's
equations are a leading principal submatrix, whose factor is the leading block of the full
one.  :mod:`.nested_factor` extends a factor to a larger input set by bordering.
"""
import functools
from typing import Optional, Sequence, Tuple

import numpy as np
import scipy.linalg

from wheel_force_estimator.core.correlations import Correlations
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.live_estimator import lag_edges
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.live_estimator import METHOD


def design_causal(corr: Correlations, look_ahead: int, design: LiveDesign) -> CausalEstimator:
    """
    Solve the multi-rate Wiener-Hopf normal equations for one look-ahead.

    Parameters
    ----------
    corr : Correlations
        Correlations of the training data, lags up to ``design.max_lag(fs)`` at least.
    look_ahead : int
        ``D`` [samples], >= 0.
    design : LiveDesign
        History, resolution and ridge.

    Returns
    -------
    CausalEstimator

    Raises
    ------
    ConfigError
        ``corr`` does not reach lag ``look_ahead + history + 2``.
    InsufficientDataError
        The regularised normal equations are not positive definite (no input power).

    """
    return LagOrderedFactor(NormalEquations(corr, look_ahead, design)).estimator(look_ahead)


class NormalEquations:
    """The regularised normal equations of the basis for look-ahead ``D`` (see notes)."""

    def __init__(self, corr: Correlations, look_ahead: int, design: LiveDesign):
        fs = corr.fs_hz
        design = design.for_inputs(corr.rxx.shape[0], fs)
        history = max(1, int(round(design.history_s * fs)))
        t_max = look_ahead + history + 2
        if t_max > corr.max_lag:
            raise ConfigError(f'live estimator: look-ahead {look_ahead} + history {history} '
                              f'samples need correlations to lag {t_max}, have {corr.max_lag}')
        edges = lag_edges(look_ahead, int(round(design.fine_s * fs)), history,
                          design.blocks_per_octave)
        lo_t = corr.max_lag - t_max
        rxx = corr.rxx[:, :, lo_t:corr.rxx.shape[2] - lo_t]
        rxy = corr.rxy[:, :, lo_t:corr.rxy.shape[2] - lo_t]
        n_in, n_out = rxx.shape[0], rxy.shape[1]
        n_b = edges.size - 1
        c1 = np.cumsum(rxy, axis=-1)                                          # (j, o, τ)
        b = c1[:, :, edges[1:] - 1 + t_max] - c1[:, :, edges[:-1] - 1 + t_max]  # (j, o, q)
        width = np.diff(edges).astype(np.float64)
        power = rxx[np.arange(n_in), np.arange(n_in), t_max]
        # the ridge per unit of regularisation (so another ridge needs no second build)
        self.ridge_unit = (power[:, None] * width[None, :]).ravel()
        self.rhs = b.transpose(0, 2, 1).reshape(n_in * n_b, n_out)
        self.edges, self.n_in, self.n_out = edges, n_in, n_out
        self.info = {'method': METHOD, 'history_s': history / fs, 'fine_s': design.fine_s,
                     'blocks_per_octave': design.blocks_per_octave,
                     'regularisation': design.regularisation,
                     'n_training_samples': int(corr.n_samples)}
        self.fs_hz = fs
        self._rxx, self._t_max = rxx, t_max
        self._parent: Optional['NormalEquations'] = None
        self._index: Optional[np.ndarray] = None

    def subset(self, columns: Sequence[int]) -> 'NormalEquations':
        """
        Return the equations of the inputs ``columns`` only (the other inputs' taps dropped).

        The unknowns are ordered input by input, and entry ``((i, p), (j, q))`` of the matrix
        depends on ``r_ij`` alone, so the subset's matrix is a sub-block of this one: the same
        values its own build from the subset's correlations gives (tested), for the cost of a
        copy.  Taken on first use from this matrix (built then if it was not).
        """
        cols = np.asarray(columns, dtype=np.int64)
        n_b = self.edges.size - 1
        index = (cols[:, None] * n_b + np.arange(n_b)[None, :]).ravel()
        sub = object.__new__(NormalEquations)
        sub.__dict__.update({k: v for k, v in self.__dict__.items() if k != 'a'})
        sub.ridge_unit = self.ridge_unit[index]
        sub.rhs = self.rhs[index]
        sub.n_in = int(cols.size)
        sub._rxx = self._rxx[cols[:, None], cols[None, :]]
        sub._parent, sub._index = self, index
        return sub

    def block(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """
        Return the block ``a[rows][:, cols]`` of the regularised matrix (a new array).

        A subset's block is taken from its parent's matrix: no copy of the subset's whole
        matrix (~140 MB for the accelerations at the defaults) just to cut a block from it.
        """
        if self._parent is not None and 'a' not in self.__dict__:
            return self._parent.block(self._index[rows], self._index[cols])
        return gather(self.a, rows, cols)

    @functools.cached_property
    def a(self) -> np.ndarray:
        """
        Return the regularised normal matrix, shape (n_in n_basis, n_in n_basis).

        Built on first use: a caller holding the Cholesky factor of the same matrix (the same
        inputs, another output) needs only :attr:`rhs`, and the build costs about as much as
        the factorisation.
        """
        if self._parent is not None:
            return gather(self._parent.a, self._index, self._index)
        rxx, t_max, edges, n_in = self._rxx, self._t_max, self.edges, self.n_in
        n_b = edges.size - 1
        # sum_{l in p} sum_{m in q} r(l - m) from C2, the double cumulative sum of r:
        # with C1(t) = sum_{τ <= t} r(τ), sum_{m in q} r(l - m) = C1(l - a_q) - C1(l - e_q),
        # and summing that over l in [a_p, e_p) gives four values of C2 (index 0 = lag
        # -2 t_max - 1, an empty sum).  Rounding: ~eps (2 t_max)² max|r|, far below the ridge.
        start, end = edges[:-1], edges[1:]

        def c2_at(t):
            return t + 2 * t_max + 1

        pp = (c2_at(end[:, None] - 1 - start[None, :]), c2_at(start[:, None] - 1 - start[None, :]),
              c2_at(end[:, None] - 1 - end[None, :]), c2_at(start[:, None] - 1 - end[None, :]))
        a = np.empty((n_in, n_b, n_in, n_b))
        for i in range(n_in):
            # r_ij(τ) for j >= i and τ in -2 t_max .. 2 t_max (0 beyond t_max: never reached)
            r = np.zeros((n_in - i, 4 * t_max + 1))
            r[:, t_max:3 * t_max + 1] = rxx[i, i:]
            c2 = np.concatenate([np.zeros((n_in - i, 1)),
                                 np.cumsum(np.cumsum(r, axis=-1), axis=-1)], axis=-1)
            # A[(i,p),(j,q)] uses r_ij(l - m) summed over l in p and m in q
            # np.take: twice as fast as the fancy index here, the same sums in the same order
            row = np.take(c2, pp[0], axis=1)
            row -= np.take(c2, pp[1], axis=1)
            row -= np.take(c2, pp[2], axis=1)
            row += np.take(c2, pp[3], axis=1)
            row = row.transpose(1, 0, 2)
            # the (i, i) block symmetrised against rounding; A[(j,q),(i,p)] = A[(i,p),(j,q)]
            # for j > i: the symmetric matrix from half the gathers, no full-size temporaries
            row[:, 0, :] = 0.5 * (row[:, 0, :] + row[:, 0, :].T)
            a[i, :, i:, :] = row
            a[i + 1:, :, i, :] = row[:, 1:, :].transpose(1, 2, 0)
        a = a.reshape(n_in * n_b, n_in * n_b)
        a[np.diag_indices_from(a)] += self.info['regularisation'] * self.ridge_unit
        return a


def gather(a: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """
    Return ``a[np.ix_(rows, cols)]`` (a new C-ordered array).

    numpy's two-index fancy indexing computes every element's offset from both index arrays.
    When most of the columns are taken, copying 64 whole rows and taking the columns from
    them while they are in cache is about twice as fast (5256 of 6132 unknowns in `fit`:
    212 -> 100 ms, measured 2026-12-06; docs/performance.md); for a narrow block the copied
    rows are mostly waste (876 of 6132 columns: 26 -> 21 ms the other way), and the fancy
    index is kept.
    """
    rows = np.asarray(rows, dtype=np.intp)
    cols = np.asarray(cols, dtype=np.intp)
    if 2 * cols.size < a.shape[1]:
        return a[np.ix_(rows, cols)]
    out = np.empty((rows.size, cols.size), dtype=a.dtype)
    for lo in range(0, rows.size, 64):
        np.take(a[rows[lo:lo + 64]], cols, axis=1, out=out[lo:lo + 64])
    return out


def _fine_count(edges: np.ndarray) -> int:
    """Return the number of leading one-sample blocks (the full-rate taps)."""
    width = np.diff(edges)
    wide = np.flatnonzero(width > 1)
    return int(wide[0]) if wide.size else int(width.size)


def design_live(corr: Correlations, design: LiveDesign) -> Tuple[CausalEstimator, ...]:
    """Design one estimator per distinct look-ahead of ``design`` (configured one first)."""
    looks = list(dict.fromkeys(look_ahead_samples(v, corr.fs_hz) for v in design.look_aheads_s))
    # One factorisation of the longest look-ahead's equations serves every look-ahead.
    factor = LagOrderedFactor(NormalEquations(corr, max(looks), design))
    return tuple(factor.estimator(d) for d in looks)


def lag_order(inputs: np.ndarray, n_b: int, d_max: int) -> np.ndarray:
    """
    Return the equation indices of ``inputs``' unknowns, lag by lag.

    The past first, then the future lags nearest first, all the inputs of one lag together,
    so each look-ahead's unknowns are a leading part.  ``n_b`` basis blocks per input,
    ``d_max`` future lags.
    """
    blocks = np.concatenate([np.arange(d_max, n_b), np.arange(d_max - 1, -1, -1)])
    return (np.asarray(inputs)[None, :] * n_b + blocks[:, None]).ravel()


class TriangularFactor:
    """
    The solution and live estimators of a lower-triangular factorisation of the equations.

    A subclass sets ``_eq`` (:class:`NormalEquations`) and ``_info`` and provides
    ``order(look_ahead)``, ``solve_lower(look_ahead, b)`` and ``solve_upper(look_ahead, z)``
    (rows in ``order``): :class:`LagOrderedFactor` and :class:`.nested_factor.BorderedFactor`.
    """

    _eq: 'NormalEquations'
    _info: dict

    @property
    def equations(self) -> 'NormalEquations':
        """Return the normal equations factorised (longest look-ahead)."""
        return self._eq

    def theta(self, look_ahead: int) -> np.ndarray:
        """
        Return the coefficients for ``look_ahead`` samples, shape (n_out, n_in, n_basis).

        Basis block ``p`` of the result is block ``p + D - look_ahead`` of the longest
        look-ahead's basis.
        """
        d = int(look_ahead)
        eq = self._eq
        order = self.order(d)
        solution = self.solve_upper(d, self.solve_lower(d, eq.rhs[order]))
        n_b = eq.edges.size - 1
        shift = -int(eq.edges[0]) - d
        inputs, blocks = np.divmod(order, n_b)
        theta = np.zeros((eq.n_out, eq.n_in, n_b - shift))
        theta[:, inputs, blocks - shift] = solution.T
        return theta

    def estimator(self, look_ahead: int) -> CausalEstimator:
        """Return the live estimator for ``look_ahead`` samples."""
        d = int(look_ahead)
        theta = self.theta(d)
        edges = self._eq.edges[-int(self._eq.edges[0]) - d:]
        n_fine = _fine_count(edges)
        info = dict(self._info, look_ahead_s=d / self._eq.fs_hz,
                    n_basis_per_input=int(edges.size - 1))
        return CausalEstimator(d, theta[:, :, :n_fine], edges[n_fine:], theta[:, :, n_fine:],
                               info)


class LagOrderedFactor(TriangularFactor):
    """
    One Cholesky factorisation that serves every look-ahead up to the longest.

    The look-ahead ``d`` equations are those of the longest look-ahead ``D`` without the
    future lags ``-D .. -d-1`` (:meth:`NormalEquations.sub`).  Ordering the unknowns lag by
    lag with the past first and the future lags last, nearest first (all inputs of one lag
    together), makes each look-ahead's equations a *leading* principal submatrix, and the
    Cholesky factor of a leading principal submatrix is the leading block of the full factor.
    So a shorter look-ahead costs two triangular solves, not a factorisation.

    Parameters
    ----------
    eq : NormalEquations
        Equations of the longest look-ahead (its future lags one sample each).
    regularisation : float, optional
        Ridge to use instead of the one ``eq`` was built with [-].
    cholesky : numpy.ndarray, optional
        The lower Cholesky factor of these regularised equations in lag order, from
        :attr:`cholesky` of a factorisation of equations with the same matrix (the same
        inputs' correlations, look-ahead, design and ridge) and another right-hand side:
        only the right-hand side of ``eq`` is new (two triangular solves, no factorisation).

    Raises
    ------
    InsufficientDataError
        The regularised equations are not positive definite.
    ShapeError
        ``cholesky`` does not have the shape of the equations.

    """

    def __init__(self, eq: 'NormalEquations', regularisation: Optional[float] = None,
                 cholesky: Optional[np.ndarray] = None):
        n_b = eq.edges.size - 1
        d_max = -int(eq.edges[0])
        self._perm = lag_order(np.arange(eq.n_in), n_b, d_max)
        if cholesky is not None:
            if cholesky.shape != (self._perm.size,) * 2:
                raise ShapeError(f'Cholesky factor {cholesky.shape} for {self._perm.size} '
                                 'unknowns')
            self._l = cholesky
        else:
            a = eq.block(self._perm, self._perm)
            if regularisation is not None:
                ridge = (regularisation - eq.info['regularisation']) * eq.ridge_unit[self._perm]
                a[np.diag_indices_from(a)] += ridge
            try:
                # a is symmetric: its transpose is the Fortran-ordered array LAPACK
                # factorises in place, where a C-ordered one is first copied (220 MB at
                # 5256 unknowns; bench/bench_normal_equations.py)
                self._l = scipy.linalg.cholesky(a.T, lower=True, overwrite_a=True,
                                                check_finite=False)
            except np.linalg.LinAlgError as err:
                raise InsufficientDataError(
                    f'live estimator (look-ahead {d_max} samples): the normal equations are '
                    f'not positive definite (inputs without power?)') from err
        self._eq, self._d_max, self._n_b = eq, d_max, n_b
        #: Input counts from the factorised set up (:class:`.nested_factor.BorderedFactor`).
        self.chain = (eq.n_in,)
        reg = eq.info['regularisation'] if regularisation is None else regularisation
        self._info = dict(eq.info, regularisation=float(reg))

    @property
    def cholesky(self) -> np.ndarray:
        """Return the lower Cholesky factor in lag order (read-only; see ``cholesky=``)."""
        view = self._l.view()
        view.flags.writeable = False
        return view

    def order(self, look_ahead: int) -> np.ndarray:
        """Return the equation indices of the ``look_ahead`` unknowns in the factor's sequence."""
        d = int(look_ahead)
        if not 0 <= d <= self._d_max:
            raise ConfigError(f'look-ahead {d} is not within 0 .. {self._d_max}')
        return self._perm[:self._eq.n_in * (self._n_b - self._d_max + d)]

    def solve_lower(self, look_ahead: int, b: np.ndarray) -> np.ndarray:
        """Return ``L⁻¹ b`` for look-ahead ``look_ahead`` (rows of ``b`` in :meth:`order`)."""
        return solve_leading(self._l, self.order(look_ahead).size, b, transposed=False)

    def solve_upper(self, look_ahead: int, z: np.ndarray) -> np.ndarray:
        """Return ``L⁻ᵀ z`` for look-ahead ``look_ahead`` (rows in :meth:`order`)."""
        return solve_leading(self._l, self.order(look_ahead).size, z, transposed=True)


def solve_leading(lower: np.ndarray, m: int, b: np.ndarray, transposed: bool) -> np.ndarray:
    """
    Return ``L₁₁⁻¹ b`` (or ``L₁₁⁻ᵀ b``), ``L₁₁`` the leading ``m × m`` block of ``lower``.

    scipy's LAPACK wrappers copy a block that is not contiguous, and with the copy of a large
    factor's leading block (3720 of 5256 unknowns: 110 MB) the solve with 12 right-hand sides
    took 4-6 times as long (``bench/bench_normal_equations.py``).  The whole factor needs no
    copy, and zero padding gives the block's solution from it: a forward substitution's first
    ``m`` rows depend on the first ``m`` rows alone, and a back substitution with ``Lᵀ`` of a
    right-hand side that is zero below row ``m`` is zero there and the block's solution above.
    The padded solve costs ``k (n² - m²)`` more multiply-adds for ``k`` right-hand sides; it is
    used while that is below the copy's cost, about 64 multiply-adds per element copied
    (measured).
    """
    n = lower.shape[0]
    k = int(np.prod(b.shape[1:], dtype=np.int64))
    trans = 'T' if transposed else 'N'
    if m < n and k * (n * n - m * m) > 64 * m * m:
        return scipy.linalg.solve_triangular(lower[:m, :m], b, lower=True, trans=trans,
                                             check_finite=False)
    if m < n:
        padded = np.zeros((n,) + b.shape[1:])
        padded[:m] = b
        b = padded
    return scipy.linalg.solve_triangular(lower, b, lower=True, trans=trans,
                                         check_finite=False)[:m]
