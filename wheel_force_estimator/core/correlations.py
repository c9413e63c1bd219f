# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Correlation functions of the training data, the live estimator's sufficient statistics.

Why accumulated, not taken from the spectra
-------------------------------------------
First tried: the inverse FFT of the Welch cross-spectra ``fit`` computes anyway, divided by
the window's autocorrelation (no second pass).  That estimate is consistent but not a
positive definite sequence; on 2 minutes of data (14 long windows) the normal equations came
out indefinite.  The correlations are therefore accumulated from the segments themselves
(:class:`CorrelationAccumulator`, block FFTs while ``fit`` holds the data anyway: about a
second per 10 minutes): the biased estimate, positive semi-definite by construction, with
no window taper and no lag limit from the Welch segment, and the whole-segment mean removed
(not per window), so quasi-static content keeps its correlation.

The normal equations built from them are :mod:`.normal_equations`.
"""
import dataclasses
from typing import Optional, Tuple

import numpy as np
import scipy.fft

from wheel_force_estimator.core.errors import InsufficientDataError


@dataclasses.dataclass(frozen=True)
class Correlations:
    """
    Input and input-output correlation functions of the training data.

    Parameters
    ----------
    rxx : numpy.ndarray, shape (n_in, n_in, 2 T + 1)
        ``rxx[i, j, T + τ] = E[x_i(n) x_j(n + τ)]`` [input unit²].
    rxy : numpy.ndarray, shape (n_in, n_out, 2 T + 1)
        ``rxy[i, o, T + τ] = E[x_i(n) y_o(n + τ)]`` [input unit · output unit].
    fs_hz : float
        Sample rate [Hz].
    n_samples : int
        Samples the estimate is averaged over.

    """

    rxx: np.ndarray
    rxy: np.ndarray
    fs_hz: float
    n_samples: int

    @property
    def max_lag(self) -> int:
        """Return ``T``, the largest lag held [samples]."""
        return (self.rxx.shape[2] - 1) // 2


class CorrelationAccumulator:
    """
    Accumulate correlations of gap-free segments, lags ``-T .. T``, in blocks.

    Each segment has its own mean removed (the predictor removes the static input too) and
    contributes ``sum_n z_a(n) z_b(n + τ)`` over the pairs inside it (no pair straddles two
    segments); the sum is divided by the total sample count.  This is the standard biased
    correlation estimate, a positive semi-definite sequence, so the normal equations built
    from it are too (the window-corrected Welch correlogram is not: with a few minutes of
    data it gave indefinite equations).  Cost: FFTs of blocks of ~4 T samples, memory
    ~(n_in + n_out)² x 2 T complex values.

    Parameters
    ----------
    n_in, n_out : int
        Channel counts.
    max_lag : int
        ``T`` [samples], >= 1.

    """

    def __init__(self, n_in: int, n_out: int, max_lag: int):
        self._n_in, self._n_out, self._t = int(n_in), int(n_out), int(max_lag)
        self._n_fft = scipy.fft.next_fast_len(max(4 * self._t, 4096), real=True)
        self._block = self._n_fft - self._t
        nz = self._n_in + self._n_out
        self._acc = np.zeros((nz, nz, self._n_fft // 2 + 1), dtype=np.complex128)
        self._n = 0

    def add(self, x: np.ndarray, y: np.ndarray, mean: Optional[np.ndarray] = None) -> None:
        """
        Add one segment: ``x`` (n_in, n) inputs, ``y`` (n_out, n) outputs (validated).

        ``mean`` (n_in + n_out,): the offsets removed instead of the segment's own mean (a
        piece of a longer segment keeps that segment's mean, as the whole-segment fit
        removes it: a piece's own mean would take away the quasi-static band below
        ~1 / piece length).
        """
        z = np.concatenate([x, y], axis=0)
        z = z - (z.mean(axis=1, keepdims=True) if mean is None
                 else np.asarray(mean, dtype=np.float64)[:, None])
        n = z.shape[1]
        for s in range(0, n, self._block):
            u = scipy.fft.rfft(z[:, s:s + self._block], n=self._n_fft, axis=1)
            v = scipy.fft.rfft(z[:, s:s + self._block + self._t], n=self._n_fft, axis=1)
            self._acc += u.conj()[:, None, :] * v[None, :, :]
        self._n += n

    def lag_sums(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return the summed (not averaged) products as :class:`Correlations` holds them."""
        return _lag_layout(scipy.fft.irfft(self._acc, n=self._n_fft, axis=2), self._t,
                           self._n_in)

    def result(self, fs_hz: float) -> Correlations:
        """
        Return the correlations averaged over every sample added.

        Raises
        ------
        InsufficientDataError
            Nothing was added.

        """
        if self._n == 0:
            raise InsufficientDataError('live estimator: no training samples')
        rxx, rxy = self.lag_sums()
        return Correlations(rxx / self._n, rxy / self._n, float(fs_hz), self._n)


def _lag_layout(c: np.ndarray, t: int, n_in: int) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(rxx, rxy)`` at lags -T .. T from ``c[a, b, τ] = sum z_a(n) z_b(n + τ)``."""
    c = c[:, :, :t + 1]
    full = np.concatenate([c.transpose(1, 0, 2)[:, :, :0:-1], c], axis=2)   # -T .. T
    return np.ascontiguousarray(full[:n_in, :n_in]), np.ascontiguousarray(full[:n_in, n_in:])


def straddling_products(z_first: np.ndarray, z_second: np.ndarray, gap: int, n_in: int,
                        max_lag: int) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the summed products of the pairs that straddle two pieces of one segment.

    ``z_first`` is the end of the earlier piece and ``z_second`` the start of the later one
    (inputs then outputs stacked, shape (n_in + n_out, n), with the mean removed that
    :meth:`CorrelationAccumulator.add` removes from them), ``gap`` samples apart (0: adjacent).
    Returns ``sum z_a(n) z_b(n + τ)`` over ``n`` in the first and ``n + τ`` in the second
    (lags up to ``max_lag``; none within one piece), laid out as :meth:`CorrelationAccumulator
    .lag_sums`.  Pieces added to an accumulator one by one, plus these, give the correlations
    of the pieces as one signal (:func:`.candidates.straddling_sums`).

    Raises
    ------
    ValueError
        The pieces' ends are longer than the lags they can pair over.

    """
    n1, n2 = z_first.shape[1], z_second.shape[1]
    if gap < 0 or n1 > max_lag or gap + n2 > max_lag:
        raise ValueError(f'straddling pairs: {n1} + {gap} + {n2} samples do not fit lags '
                         f'up to {max_lag}')
    n_fft = scipy.fft.next_fast_len(2 * max_lag + 1, real=True)
    u = scipy.fft.rfft(z_first, n=n_fft, axis=1)
    second = np.zeros((z_second.shape[0], n1 + gap + n2))
    second[:, n1 + gap:] = z_second
    v = scipy.fft.rfft(second, n=n_fft, axis=1)
    # the pairs' lags run from gap + 1 to n1 + gap + n2 - 1 < n_fft: no circular wrap
    return _lag_layout(scipy.fft.irfft(u.conj()[:, None, :] * v[None, :, :], n=n_fft,
                                       axis=2), max_lag, n_in)
