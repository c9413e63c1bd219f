# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live (causal) estimator: a MIMO least-squares FIR designed for a stated look-ahead.

Why this method
---------------
The offline FIR is the two-sided inverse of the FRF; cutting its acausal part to a short
look-ahead throws away what the cut taps did, and nothing else makes up for it.  The causal
Wiener filter instead asks which causal filter (inputs up to ``n + D``, ``D`` the look-ahead)
minimises the mean square error, so the history takes over what the future cannot supply.
Of the ways to get it:

- spectral factorisation of the 12x12 input spectrum (causal Wiener) needs a stable MIMO
  spectral factor of a nearly singular matrix at low frequency (collinear rigid-body
  motion): fragile, and it does not bound the filter length;
- a Kalman observer needs an identified state-space model (order selection, stability), a
  second estimation problem with its own failure modes;
- the least-squares FIR with look-ahead solves linear normal equations (Wiener-Hopf) built
  from the correlation functions of the training data: one Cholesky solve, a filter length
  chosen up front, and the same data ``fit`` already holds in memory.

So the estimator is the least-squares FIR.  Its history must be long (the quasi-static
loads of braking and cornering live in seconds of history: measured z RMSE 22 % with 0.5 s,
12.7 % with 2 s), but a full-rate FIR of seconds has 12 x 1000s of unknowns per output.  The
impulse response far in the past is smooth, so the taps are **multi-rate**: one tap per
sample from ``-D`` to ``fine_s``, then piecewise-constant blocks whose width grows
geometrically (``blocks_per_octave`` per doubling of the lag) up to ``history_s``.  About
310 unknowns per input at the defaults for a car (48 blocks per octave), solved exactly; the
piecewise-constant blocks also give a cheap recursive realisation (a running sum,
:mod:`.causal_filter`).

The coarse blocks must stay narrow far into the past: the rear wheels meet the road the
front wheels met a wheelbase earlier (0.1-2 s at road speeds), with its wheel-hop content.
Measured (2026-11-29, all 14 inputs, 10 min of the course at seed 1, held-out seed 2, 50 ms,
`Fz` mean of the corners, unfiltered / 1 Hz high-passed): 32 blocks per octave at ridge 1e-4
(the default before) 8.4 / 7.5 % on the compact car, 9.9 / 11.3 % on a pickup, 10.6 / 11.1 %
on the van; 48 blocks per octave at ridge 1e-5 6.1 / 5.2, 7.3 / 7.6 and 7.8 / 7.4 %; 64
blocks 5.4 / 4.0, 6.3 / 5.5 and 6.6 / 5.4 % (x and y equal within 0.3 point).  The finest
basis the cost bound allows (:data:`MAX_PAST_UNKNOWNS`) is the default, and the ridge, chosen
by ``fit``'s cross-validation, sets how much of it the data can carry.  48, not 64: every
factorisation of ``fit``'s search costs (n / n32)³ of the 32-block one's, 1.9x at 48 and
3.1x at 64, and at 64 a 60 s bag's `fit` took 49 s against 14 s (48: 32 s) and the fast test
tier 7 minutes against its 5.

Correlations
------------
First tried: the inverse FFT of the Welch cross-spectra ``fit`` computes anyway, divided by
the window's autocorrelation (no second pass).  That estimate is consistent but not a
positive definite sequence; on 2 minutes of data (14 long windows) the normal equations came
out indefinite.  The correlations are therefore accumulated from the segments themselves
(:class:`CorrelationAccumulator`, block FFTs while ``fit`` holds the data anyway: about a
second per 10 minutes): the biased estimate, positive semi-definite by construction, with
no window taper and no lag limit from the Welch segment, and the whole-segment mean removed
(not per window), so quasi-static content keeps its correlation.

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

Defaults (``LiveDesign``), chosen on held-out simulated data (5 min training, 2.5 min
held-out, other seed; mean RMSE % x / y / z at 50 ms; offline two-sided 29.0 / 20.6 / 10.7):
32 blocks per octave 29.3 / 13.7 / 8.2, 16 per octave 29.5 / 13.9 / 12.2 (Fz needs the
resolution); ridge 1e-3 instead of 1e-4 (the FRF's own default) 29.6 / 13.8 / 10.8; history
2 s 30.6 / 14.4 / 9.5, 8 s 28.6 / 13.5 / 8.0 (30 % dearer fit), so 4 s.
"""
import dataclasses
import functools
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np
import scipy.fft
import scipy.linalg

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.validation import read_only_array

# The look-ahead the node and `predict --causal` use when nothing else is configured [s]
# (DESIGN.md `live_look_ahead_s`): 26 samples at 512 Hz.
DEFAULT_LIVE_LOOK_AHEAD_S = 0.05
# Look-aheads `fit` also designs, so reports can show accuracy against look-ahead [s].
SWEEP_LOOK_AHEADS_S = (0.0, 0.025, 0.05, 0.1, 0.25)
METHOD = 'multirate_ls_fir'
#: Coarse-tap resolutions of the default basis, finest first [blocks per octave].
BLOCKS_PER_OCTAVE_CHOICES = (48, 32)
#: Past unknowns (all inputs) the default basis may reach: the finest of
#: :data:`BLOCKS_PER_OCTAVE_CHOICES` within it, else the coarsest.  A cost bound, not a tuned
#: accuracy figure: the Cholesky factor of ``n`` unknowns is ``8 n²`` bytes and ``n³ / 3``
#: flops, and ``fit`` factorises a few per fold.  With the 0.25 s offline look-ahead a car's
#: 12-18 inputs at 512 Hz reach 5300-7900 unknowns (0.2-0.5 GB per factor) at 48 blocks per
#: octave; the 28-30 of six components get 32.
MAX_PAST_UNKNOWNS = 6144


def look_ahead_samples(look_ahead_s: float, fs_hz: float) -> int:
    """Return the look-ahead in samples for ``look_ahead_s`` at ``fs_hz`` (rounded)."""
    return int(round(float(look_ahead_s) * float(fs_hz)))


@dataclasses.dataclass(frozen=True)
class LiveDesign:
    """
    How the live estimators are designed at fit time.

    Parameters
    ----------
    look_aheads_s : tuple of float
        Look-aheads to design, each >= 0 [s]; the first one is the configured one.
    history_s : float
        Longest past lag used [s], > 0.
    fine_s : float
        Past lags up to this are one tap per sample [s], >= 0.
    blocks_per_octave : int or None
        Resolution of the coarse taps beyond ``fine_s``: blocks per doubling of the lag, >= 1.
        None (the default): the finest the cost bound allows for the inputs at hand
        (:meth:`for_inputs`).
    regularisation : float
        Ridge per unit tap relative to each input's power [-], >= 0.

    Raises
    ------
    ConfigError
        On invalid values.

    """

    look_aheads_s: Tuple[float, ...] = (DEFAULT_LIVE_LOOK_AHEAD_S,)
    history_s: float = 4.0
    fine_s: float = 0.125
    blocks_per_octave: Optional[int] = None
    regularisation: float = 1e-4

    def __post_init__(self):
        """Validate the values."""
        try:
            looks = tuple(float(v) for v in self.look_aheads_s)
        except (TypeError, ValueError) as err:
            raise ConfigError(f'live look-aheads must be numbers, got '
                              f'{self.look_aheads_s!r}') from err
        if not looks or not all(np.isfinite(v) and v >= 0.0 for v in looks):
            raise ConfigError(f'live look-aheads must be finite and >= 0 s, got {looks!r}')
        object.__setattr__(self, 'look_aheads_s', looks)
        for name in ('history_s', 'fine_s', 'regularisation'):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ConfigError(f'live {name} must be finite and >= 0, got {value!r}')
        if self.history_s <= 0.0:
            raise ConfigError(f'live history_s must be > 0, got {self.history_s!r}')
        bpo = self.blocks_per_octave
        if bpo is not None and (isinstance(bpo, bool) or not isinstance(
                bpo, (int, np.integer)) or bpo < 1):
            raise ConfigError(f'live blocks_per_octave must be an integer >= 1, '
                              f'got {self.blocks_per_octave!r}')

    def for_inputs(self, n_in: int, fs_hz: float) -> 'LiveDesign':
        """
        Return the design with its coarse resolution fixed for ``n_in`` inputs at ``fs_hz``.

        A resolution already set is kept.  Otherwise the finest of
        :data:`BLOCKS_PER_OCTAVE_CHOICES` whose past lags over all ``n_in`` inputs stay within
        :data:`MAX_PAST_UNKNOWNS`, else the coarsest.  Callers resolve with the model's input
        count, so the nested input sets of one fit share one basis.
        """
        if self.blocks_per_octave is not None:
            return self
        fine = int(round(self.fine_s * fs_hz))
        history = max(1, int(round(self.history_s * fs_hz)))
        for bpo in BLOCKS_PER_OCTAVE_CHOICES:
            if n_in * (lag_edges(0, fine, history, bpo).size - 1) <= MAX_PAST_UNKNOWNS:
                break
        return dataclasses.replace(self, blocks_per_octave=bpo)

    def max_lag(self, fs_hz: float) -> int:
        """Return the longest correlation lag the design needs at ``fs_hz`` [samples]."""
        longest = max(look_ahead_samples(v, fs_hz) for v in self.look_aheads_s)
        return longest + max(1, int(round(self.history_s * fs_hz))) + 2


@dataclasses.dataclass(frozen=True)
class CausalEstimator:
    """
    A fitted live estimator (immutable; arrays read-only).

    Output sample ``n`` is ``sum_k fine_taps[:, :, k] x(n + D - k)`` (tap ``k`` is lag
    ``k - D``, so the fine part covers lags ``-D .. n_fine - D - 1``) plus, for every coarse
    block ``p``, ``coarse_taps[:, :, p]`` times the sum of ``x(n - l)`` over lags
    ``coarse_edges[p] <= l < coarse_edges[p + 1]``.

    Parameters
    ----------
    look_ahead_samples : int
        ``D`` [samples], >= 0.
    fine_taps : numpy.ndarray, shape (n_out, n_in, n_fine)
        Full-rate taps [output unit / input unit], ``n_fine > D``.
    coarse_edges : numpy.ndarray, shape (n_coarse + 1,), int
        Lag block boundaries [samples], increasing, starting at ``n_fine - D``
        (``n_coarse = 0``: one edge, no coarse part).
    coarse_taps : numpy.ndarray, shape (n_out, n_in, n_coarse)
        Tap value of each coarse block [output unit / input unit].
    info : dict
        How it was designed (method, history, regularisation, look-ahead in s).

    Raises
    ------
    ModelFileError
        A field with the wrong type, shape or values (the field is named).

    """

    look_ahead_samples: int
    fine_taps: np.ndarray
    coarse_edges: np.ndarray
    coarse_taps: np.ndarray
    info: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        """Validate shapes and values; store read-only copies."""
        d = self.look_ahead_samples
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 0:
            raise ModelFileError(f'live estimator look_ahead_samples: expected an int >= 0, '
                                 f'got {d!r}')
        object.__setattr__(self, 'look_ahead_samples', int(d))
        fine = _read_only(self.fine_taps, np.float64, 'fine_taps', d)
        if fine.ndim != 3 or fine.shape[2] <= d:
            raise ModelFileError(f'live estimator (look-ahead {d}) fine_taps: expected '
                                 f'(n_out, n_in, > {d}), got {fine.shape}')
        edges = _read_only(self.coarse_edges, np.int64, 'coarse_edges', d)
        coarse = _read_only(self.coarse_taps, np.float64, 'coarse_taps', d)
        n_fine = fine.shape[2]
        if (edges.ndim != 1 or edges.size < 1 or edges[0] != n_fine - d
                or np.any(np.diff(edges) <= 0)):
            raise ModelFileError(f'live estimator (look-ahead {d}) coarse_edges: expected '
                                 f'increasing lags from {n_fine - d}, got {edges.tolist()[:5]}')
        if coarse.shape != fine.shape[:2] + (edges.size - 1,):
            raise ModelFileError(f'live estimator (look-ahead {d}) coarse_taps: expected shape '
                                 f'{fine.shape[:2] + (edges.size - 1,)}, got {coarse.shape}')
        if not isinstance(self.info, Mapping):
            raise ModelFileError(f'live estimator (look-ahead {d}) info: expected an object')
        object.__setattr__(self, 'fine_taps', fine)
        object.__setattr__(self, 'coarse_edges', edges)
        object.__setattr__(self, 'coarse_taps', coarse)
        object.__setattr__(self, 'info', dict(self.info))

    @property
    def n_out(self) -> int:
        """Return the number of outputs."""
        return int(self.fine_taps.shape[0])

    @property
    def n_in(self) -> int:
        """Return the number of inputs."""
        return int(self.fine_taps.shape[1])

    @property
    def history_samples(self) -> int:
        """Return the longest past lag used [samples]."""
        return int(self.coarse_edges[-1]) - 1

    def fir(self, fs_hz: float) -> FirFilter:
        """Return the same filter as one full-rate FIR (lag zero at tap ``D``)."""
        d = self.look_ahead_samples
        taps = np.zeros((self.n_out, self.n_in, d + self.history_samples + 1))
        taps[:, :, :self.fine_taps.shape[2]] = self.fine_taps
        for p in range(self.coarse_taps.shape[2]):
            lo, hi = self.coarse_edges[p] + d, self.coarse_edges[p + 1] + d
            taps[:, :, lo:hi] = self.coarse_taps[:, :, p:p + 1]
        return FirFilter(taps, d, fs_hz)


def _read_only(value, dtype, name: str, d: int) -> np.ndarray:
    try:
        arr = read_only_array(value, dtype)
    except (TypeError, ValueError) as err:
        raise ModelFileError(f'live estimator (look-ahead {d}) {name}: not convertible '
                             f'to {np.dtype(dtype).name}') from err
    if arr.dtype.kind == 'f' and not np.all(np.isfinite(arr)):
        raise ModelFileError(f'live estimator (look-ahead {d}) {name}: NaN or infinity')
    return arr


# -- design -----------------------------------------------------------------------------------

def lag_edges(look_ahead: int, fine: int, history: int, blocks_per_octave: int) -> np.ndarray:
    """
    Return the lag block boundaries of the multi-rate basis [samples].

    One block per lag from ``-look_ahead`` to ``fine - 1``, then blocks whose edges grow by
    ``2 ** (1 / blocks_per_octave)`` (at least one sample) up to lag ``history``.  Block
    ``p`` covers lags ``edges[p] <= l < edges[p + 1]``.
    """
    fine = max(1, min(fine, history + 1))
    edges = list(range(-look_ahead, fine + 1))
    ratio = 2.0 ** (1.0 / blocks_per_octave)
    while edges[-1] < history + 1:
        edges.append(min(history + 1, max(edges[-1] + 1, int(round(edges[-1] * ratio)))))
    return np.asarray(edges, dtype=np.int64)


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


# -- model file section -----------------------------------------------------------------------

def _keys(d: int) -> Tuple[str, str, str]:
    return (f'live{d}_fine_taps', f'live{d}_coarse_edges', f'live{d}_coarse_taps')


def live_arrays(estimators: Sequence[CausalEstimator]) -> Dict[str, np.ndarray]:
    """Return the model-file arrays of ``estimators`` (keys carry the look-ahead)."""
    arrays = {}
    for est in estimators:
        fine, edges, coarse = _keys(est.look_ahead_samples)
        arrays.update({fine: est.fine_taps, edges: est.coarse_edges, coarse: est.coarse_taps})
    return arrays


def live_meta(estimators: Sequence[CausalEstimator]) -> list:
    """Return the ``meta.live_estimators`` list of ``estimators``."""
    return [dict(est.info, look_ahead_samples=est.look_ahead_samples) for est in estimators]


def live_from_contents(meta: Mapping, contents: Mapping[str, np.ndarray]
                       ) -> Tuple[CausalEstimator, ...]:
    """
    Parse the live estimators of a model file (none for schema 1).

    Raises
    ------
    ModelFileError
        A malformed ``meta.live_estimators`` entry or a missing / malformed array (named).

    """
    entries = meta.get('live_estimators', [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise ModelFileError("model field 'meta.live_estimators': expected a list of objects")
    out = []
    for entry in entries:
        d = entry.get('look_ahead_samples')
        if isinstance(d, bool) or not isinstance(d, int) or d < 0:
            raise ModelFileError(f"model field 'meta.live_estimators': look_ahead_samples "
                                 f'must be an int >= 0, got {d!r}')
        arrays = []
        for key in _keys(d):
            if key not in contents:
                raise ModelFileError(f'model field {key!r} is missing (live estimator with '
                                     f'look-ahead {d} samples)')
            arrays.append(contents[key])
        if arrays[1].dtype.kind not in 'iu':
            raise ModelFileError(f'model field {_keys(d)[1]!r}: expected integers')
        info = {k: v for k, v in entry.items() if k != 'look_ahead_samples'}
        out.append(CausalEstimator(d, arrays[0], arrays[1], arrays[2], info))
    return tuple(out)


def check_live(estimators, n_out: int, n_in: int) -> Tuple[CausalEstimator, ...]:
    """
    Validate a model's live estimators against its channel counts.

    Raises
    ------
    ModelFileError
        Not estimators, wrong channel counts or a look-ahead present twice.

    """
    if isinstance(estimators, CausalEstimator) or not all(
            isinstance(e, CausalEstimator) for e in estimators):
        raise ModelFileError("model field 'live': expected a sequence of CausalEstimator")
    looks = [e.look_ahead_samples for e in estimators]
    if len(set(looks)) != len(looks):
        raise ModelFileError(f"model field 'live': look-aheads {looks} repeat")
    for e in estimators:
        if (e.n_out, e.n_in) != (n_out, n_in):
            raise ModelFileError(
                f"model field 'live': estimator with look-ahead {e.look_ahead_samples} has "
                f'{e.n_out} outputs x {e.n_in} inputs, the model {n_out} x {n_in}')
    return tuple(estimators)


def find_live(estimators: Sequence[CausalEstimator], look_ahead: int
              ) -> Optional[CausalEstimator]:
    """Return the estimator for ``look_ahead`` samples, or ``None``."""
    return next((e for e in estimators if e.look_ahead_samples == look_ahead), None)
