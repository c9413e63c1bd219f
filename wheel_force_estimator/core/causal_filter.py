# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Streaming realisation of a :class:`~.live_estimator.CausalEstimator` at any block length.

A 16-sample block must cost about what its 16 samples are worth, so nothing here transforms
the whole history per call:

- the full-rate taps (``-D`` .. ``fine_s``, ~100 taps) run through the overlap-add engine
  (:class:`.overlap_add.OverlapAddFilter`); at that length one call of ``m`` samples costs an
  FFT of about ``m + 100`` points, so short blocks stay cheap and long ones fast;
- each coarse block ``p`` (taps constant over lags ``[e_p, e_{p+1})``) contributes
  ``θ_p (S(n - e_p) - S(n - e_{p+1}))`` with ``S`` the running sum of the input (a recursive
  integrator), so the whole multi-second history costs one multiply-add per block edge per
  sample (~40 edges), whatever the history length.  Adjacent blocks share their edges, so
  the coefficient of ``S(n - e_q)`` is ``θ_q - θ_{q-1}``; they sum to zero, so a constant
  offset of ``S`` (where the sum starts) cancels exactly.

Both parts give, for any chunking, the direct convolution of the stream (to rounding), so a
node fed 16-sample blocks equals the offline prediction; the stream before the first call
(and after :meth:`CausalFilter.reset`) counts as zeros, as in the overlap-add engine.
"""
import numpy as np

from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.overlap_add import OverlapAddFilter
from wheel_force_estimator.core.validation import as_signals

# Samples per gather of the running sum in one call: bounds memory to about
# 8 B x n_in x edges x this (32 MB for 12 inputs and 160 edges).
_GATHER_SAMPLES = 2048


class CausalFilter:
    """
    Stream filter of one live estimator; output lags input by the look-ahead.

    Parameters
    ----------
    estimator : CausalEstimator
        The estimator.
    fs_hz : float
        Sample rate [Hz].

    """

    def __init__(self, estimator: CausalEstimator, fs_hz: float):
        self._est = estimator
        d = estimator.look_ahead_samples
        self._fine = OverlapAddFilter(FirFilter(estimator.fine_taps, d, fs_hz))
        theta = estimator.coarse_taps
        n_b = theta.shape[2]
        coef = np.zeros(theta.shape[:2] + (n_b + 1,))
        if n_b:
            coef[:, :, :n_b] += theta
            coef[:, :, 1:] -= theta
        self._coef = coef                                    # (o, i, edges)
        # Stream lag of S(n - e_q) behind the newest input: the output is D samples late.
        self._lags = d + np.asarray(estimator.coarse_edges) if n_b else np.zeros(0, np.int64)
        self._span = int(self._lags.max()) if n_b else 0
        self.reset()

    @property
    def delay_samples(self) -> int:
        """Return the lag of the output stream behind the input stream [samples]."""
        return self._est.look_ahead_samples

    @property
    def efficient_block(self) -> int:
        """Return a long block length [samples] that keeps memory bounded and calls few."""
        return _GATHER_SAMPLES

    @property
    def n_in(self) -> int:
        """Return the number of input channels."""
        return self._est.n_in

    @property
    def n_out(self) -> int:
        """Return the number of output channels."""
        return self._est.n_out

    def reset(self) -> None:
        """Forget the stream: the next call starts from an all-zero history."""
        self._fine.reset()
        self._sum_hist = np.zeros((self.n_in, self._span))
        self._carry = np.zeros(self.n_in)

    def process(self, x_block) -> np.ndarray:
        """
        Filter the next block of the input stream.

        Parameters
        ----------
        x_block : array_like, shape (n_in, m)
            Next ``m >= 0`` input samples [input unit].

        Returns
        -------
        numpy.ndarray, shape (n_out, m)
            Next ``m`` output samples [output unit], lagged by :attr:`delay_samples`.

        Raises
        ------
        ShapeError
            Wrong shape.
        NonFiniteError
            NaN or infinity (the state is left unchanged).

        """
        x = np.asarray(x_block, dtype=np.float64)
        if x.ndim != 2 or x.shape[0] != self.n_in:
            raise ShapeError(f'causal filter input: expected shape ({self.n_in}, m), '
                             f'got {x.shape}')
        x = as_signals(x, 'causal filter input', min_samples=0)
        y = self._fine.process(x)
        m = x.shape[1]
        if not self._span or m == 0:
            return y
        running = np.cumsum(x, axis=1)
        running += self._carry[:, None]
        buf = np.concatenate([self._sum_hist, running], axis=1)
        for t0 in range(0, m, _GATHER_SAMPLES):
            t = np.arange(t0, min(m, t0 + _GATHER_SAMPLES)) + self._span
            gathered = buf[:, t[:, None] - self._lags[None, :]]             # (i, t, q)
            y[:, t0:t0 + t.size] += np.tensordot(self._coef, gathered, axes=([1, 2], [0, 2]))
        self._carry = running[:, -1].copy()
        self._sum_hist = buf[:, -self._span:].copy()
        return y
