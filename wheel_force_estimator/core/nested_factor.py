# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The least-squares FIR factorisation of an input set, bordered from a nested smaller set's.

The fit's search scores nested input sets (``accel`` then ``accel+split``, ...:
:func:`.spindle.input_sets`): each set's columns begin with the previous set's.  The
unknowns of the normal equations (:class:`.normal_equations.NormalEquations`) are numbered
input by input, so the smaller set's matrix ``A11`` is a block of the larger set's, and the
block Cholesky factorisation gives the larger factor from the smaller one::

    A = [[A11, A12], [A21, A22]] = L Lᵀ,   L = [[L11, 0], [Wᵀ, L22]],
    W = L11⁻¹ A12,   L22 L22ᵀ = A22 - Wᵀ W.

For the two inputs of the traction/braking split (876 of 6132 unknowns at the defaults) that is
one triangular solve with their columns and an 876-unknown Cholesky per look-ahead, where a
factorisation of the larger set from scratch costs ~1.6 times the smaller set's own
(``bench/bench_nested_factor.py`` at 32 blocks per octave, 706 of 4942 unknowns: both sets at
two look-aheads 1.68 s from scratch, 0.89 s bordered, taps equal to 5e-12). The lag-ordered
factor serves every look-ahead as a leading block; bordered, that holds within each part but
not across them, so ``L22`` is formed per look-ahead (the search needs two: the live one and
the two-sided least-squares FIR's). ``W`` is not, when ``inner`` is lag-ordered: a look-ahead's
inner unknowns are a leading part of the longest look-ahead's, and a forward substitution's
leading rows depend on the leading rows alone, so ``W(d) = L11(d)⁻¹ A12(d)`` is the leading
block of the longest look-ahead's ``W`` (one solve with the added columns per factor instead of
one per look-ahead: the largest cost of bordering at 48 blocks per octave and more). A bordered
``inner`` does not number its unknowns that way, and gets its ``W`` per look-ahead.

Only the factorisation is new: the equations, the ridge and the solution are those of
:class:`.normal_equations.LagOrderedFactor` of the larger set, to rounding (tested).
"""
from typing import Dict, Tuple

import numpy as np
import scipy.linalg

from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.normal_equations import lag_order
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations
from wheel_force_estimator.core.normal_equations import TriangularFactor


class BorderedFactor(TriangularFactor):
    """
    The factor of ``eq`` (a set of inputs) from the factor of its first inputs, ``inner``.

    Parameters
    ----------
    inner : LagOrderedFactor or BorderedFactor
        Factorisation of the equations of ``eq``'s first ``inner.equations.n_in`` inputs, at
        the same ridge and longest look-ahead (:meth:`.NormalEquations.subset` of ``eq``).
    eq : NormalEquations
        Equations of the larger set.
    regularisation : float
        Ridge of the factorisation [-] (``inner``'s).
    parts : dict, optional
        :attr:`parts` of a factor bordered the same way from the same matrix (the same
        inputs' correlations, basis, ridge and ``inner`` chain) with another right-hand
        side: used, and filled, instead of new parts.

    Raises
    ------
    InsufficientDataError
        The added inputs' Schur complement is not positive definite.

    """

    def __init__(self, inner, eq: NormalEquations, regularisation: float, parts=None):
        n_b = eq.edges.size - 1
        d_max = -int(eq.edges[0])
        inner_eq = inner.equations
        if (inner_eq.edges.size - 1 != n_b or -int(inner_eq.edges[0]) != d_max
                or inner_eq.n_in >= eq.n_in):
            raise ValueError('bordered factor: the inner equations are not a smaller set of '
                             'the same basis')
        self._inner, self._eq, self._d_max, self._n_b = inner, eq, d_max, n_b
        self._ridge = float(regularisation)
        # the added inputs' unknowns lag by lag, as the lag-ordered factor numbers its own,
        # so a look-ahead is a leading part
        self._added = lag_order(np.arange(inner_eq.n_in, eq.n_in), n_b, d_max)
        self._parts: Dict[int, Tuple[np.ndarray, np.ndarray, np.ndarray]] = (
            {} if parts is None else parts)
        self._info = dict(eq.info, regularisation=self._ridge)
        #: Input counts from the factorised set up to this one (how the factor was made).
        self.chain = tuple(inner.chain) + (eq.n_in,)

    @property
    def parts(self) -> Dict[int, Tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Return ``{look_ahead: (order, W, L22)}`` formed so far (shared; see ``parts=``)."""
        return self._parts

    def _part(self, look_ahead: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(order, W, L22)`` of look-ahead ``look_ahead`` (formed on first use)."""
        d = int(look_ahead)
        if d not in self._parts:
            inner_order = self._inner.order(d)
            added = self._added[:(self._eq.n_in - self._inner.equations.n_in)
                                * (self._n_b - self._d_max + d)]
            if d != self._d_max and isinstance(self._inner, LagOrderedFactor):
                # the leading block of the longest look-ahead's W (module notes)
                w = self._part(self._d_max)[1][:inner_order.size, :added.size]
            else:
                w = self._inner.solve_lower(d, self._eq.block(inner_order, added))
            schur = self._eq.block(added, added)
            extra = (self._ridge - self._eq.info['regularisation']) * self._eq.ridge_unit[added]
            schur[np.diag_indices_from(schur)] += extra
            schur -= w.T @ w
            try:
                # symmetric: the transpose is factorised in place, no Fortran copy
                l22 = scipy.linalg.cholesky(schur.T, lower=True, overwrite_a=True,
                                            check_finite=False)
            except np.linalg.LinAlgError as err:
                raise InsufficientDataError(
                    f'live estimator (look-ahead {d} samples): the normal equations of the '
                    f'added inputs are not positive definite (inputs without power?)') from err
            self._parts[d] = (np.concatenate([inner_order, added]), w, l22)
        return self._parts[d]

    def order(self, look_ahead: int) -> np.ndarray:
        """Return the equation indices of the ``look_ahead`` unknowns in the factor's sequence."""
        return self._part(look_ahead)[0]

    def solve_lower(self, look_ahead: int, b: np.ndarray) -> np.ndarray:
        """Return ``L⁻¹ b`` for look-ahead ``look_ahead`` (rows of ``b`` in :meth:`order`)."""
        _, w, l22 = self._part(look_ahead)
        m = w.shape[0]
        z1 = self._inner.solve_lower(look_ahead, b[:m])
        z2 = scipy.linalg.solve_triangular(l22, b[m:] - w.T @ z1, lower=True,
                                           check_finite=False)
        return np.concatenate([z1, z2])

    def solve_upper(self, look_ahead: int, z: np.ndarray) -> np.ndarray:
        """Return ``L⁻ᵀ z`` for look-ahead ``look_ahead`` (rows in :meth:`order`)."""
        _, w, l22 = self._part(look_ahead)
        m = w.shape[0]
        x2 = scipy.linalg.solve_triangular(l22, z[m:], lower=True, trans='T',
                                           check_finite=False)
        x1 = self._inner.solve_upper(look_ahead, z[:m] - w @ x2)
        return np.concatenate([x1, x2])
