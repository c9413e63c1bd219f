# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
FIR realisation of a MIMO FRF: the filter type and its design from an FRF.

Convention (stated once, used everywhere): a :class:`FirFilter` with taps ``g[o, i, k]`` and
look-ahead ``delay`` computes

    y[o, n] = sum_i sum_k g[o, i, k] * x[i, n + delay - k],

so tap index ``delay`` is lag zero, indices below ``delay`` are the acausal look-ahead and the
frequency response relative to lag zero is ``H(f) = sum_k g[k] exp(-2j pi f (k - delay) / fs)``.

:func:`fir_from_frf` design choices, in order:

1. Bins below ``f_min_hz`` and above ``f_max_hz`` are set to zero, and the DC bin always is:
   the DC gain of an acceleration-to-force FRF is unobservable from Welch estimates with mean
   detrending, and the accelerometers measure specific force, so their gravity offset must not
   reach the dynamic force.  Inside the band the gain rises from 0 at ``f_min_hz`` to 1 at
   ``f_min_hz + transition_hz`` along a raised cosine (and falls likewise towards ``f_max_hz``
   when that is below Nyquist).  Hard edges would be smeared by the taper of step 3 into a
   ripple decaying only like 1/f: measured for a unit FRF with 1024 taps at 512 Hz, the error
   at 2 Hz is 7 % with a hard DC notch and 0.8 % with the default 2-bin (1 Hz) transition.
   This transition is zero-phase, so even a causal system gets a two-sided FIR; cutting its
   look-ahead (:func:`with_delay`) trades latency against accuracy below ~10 Hz.
2. ``irfft`` of the one-sided FRF gives the (circular) two-sided impulse response over
   ``n_fft = fs / df`` lags; it is rotated so lag zero sits at tap ``delay``.  Lags that do not
   fit (beyond the look-ahead or the causal length) wrap around, so a short look-ahead is best
   obtained with :func:`with_delay`, which discards them instead.
3. A cosine taper (a Tukey window split at lag zero: flat near lag zero, the outer
   ``taper_fraction`` of each side rolled off to zero just outside the taps) reduces truncation
   ripple and wrap-around, at the cost of smoothing the response by the window's transform.
4. The DC gain of every (out, in) pair is forced to zero (to rounding) by subtracting the
   taper-weighted mean, ``g -= w * sum(g) / sum(w)``: the correction is smooth at both ends, so
   it adds no new truncation ripple, and a constant input gives exactly zero output once the
   filter is filled.

Applying a :class:`FirFilter` to signals (streaming and batch overlap-add) is the job of
:mod:`wheel_force_estimator.core.overlap_add`.
"""
from dataclasses import dataclass
import operator
from typing import Optional

import numpy as np
import scipy.fft

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import positive_float
from wheel_force_estimator.core.validation import read_only_array

#: Fraction of each side (look-ahead, causal) of the impulse response that is cosine-tapered.
DEFAULT_TAPER_FRACTION = 0.25


def as_index(value, name: str) -> int:
    try:
        return operator.index(value)
    except TypeError as err:
        raise ConfigError(f'{name} must be an integer, got {value!r}') from err


def _taper_fraction(value) -> float:
    try:
        fraction = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'taper_fraction must be a number, got {value!r}') from err
    if not 0.0 <= fraction <= 1.0:
        raise ConfigError(f'taper_fraction must be in [0, 1], got {value!r}')
    return fraction


@dataclass(frozen=True, eq=False)
class FirFilter:
    """
    MIMO FIR filter with an acausal look-ahead.

    Parameters
    ----------
    taps : numpy.ndarray, shape (n_out, n_in, n_taps), float64
        Impulse response [output unit / input unit]; tap ``delay_samples`` is lag zero.
        Stored as a read-only copy.
    delay_samples : int
        Look-ahead in samples, ``0 <= delay_samples < n_taps``.  A streaming filter's output
        lags its input by this many samples.
    fs_hz : float
        Sample rate [Hz].

    Raises
    ------
    ShapeError
        ``taps`` is not 3-D or has an empty axis.
    NonFiniteError
        ``taps`` holds NaN or infinity.
    ConfigError
        ``delay_samples`` or ``fs_hz`` out of range.

    """

    taps: np.ndarray
    delay_samples: int
    fs_hz: float

    def __post_init__(self):
        # Shared when already frozen (a model's taps), so its tap spectra are cached once.
        taps = read_only_array(self.taps, np.float64)
        if taps.ndim != 3 or min(taps.shape) == 0:
            raise ShapeError(
                f'FIR taps: expected shape (n_out, n_in, n_taps) with no empty axis, '
                f'got {taps.shape}')
        if not np.isfinite(taps).all():
            o, i, k = np.argwhere(~np.isfinite(taps))[0]
            raise NonFiniteError(f'FIR taps: non-finite value at output {o}, input {i}, tap {k}')
        delay = as_index(self.delay_samples, 'delay_samples')
        if not 0 <= delay < taps.shape[2]:
            raise ConfigError(
                f'delay_samples must be in [0, {taps.shape[2]}) for {taps.shape[2]} taps, '
                f'got {delay}')
        object.__setattr__(self, 'taps', taps)
        object.__setattr__(self, 'delay_samples', delay)
        object.__setattr__(self, 'fs_hz', positive_float(self.fs_hz, 'fs_hz'))

    @property
    def n_out(self) -> int:
        """Return the number of output channels."""
        return self.taps.shape[0]

    @property
    def n_in(self) -> int:
        """Return the number of input channels."""
        return self.taps.shape[1]

    @property
    def n_taps(self) -> int:
        """Return the number of taps (look-ahead + lag zero + causal part)."""
        return self.taps.shape[2]

    def frequency_response(self, f_hz) -> np.ndarray:
        """
        Evaluate the response relative to lag zero at arbitrary frequencies.

        Parameters
        ----------
        f_hz : array_like, shape (nf,)
            Frequencies [Hz].

        Returns
        -------
        numpy.ndarray, shape (nf, n_out, n_in), complex128
            ``H(f) = sum_k taps[:, :, k] exp(-2j pi f (k - delay) / fs)`` [output/input unit].

        """
        f = np.atleast_1d(np.asarray(f_hz, dtype=np.float64))
        lag = np.arange(self.n_taps) - self.delay_samples
        phasor = np.exp(-2j * np.pi * np.outer(f, lag) / self.fs_hz)
        return np.einsum('fk,oik->foi', phasor, self.taps)


def response_on_grid(taps: np.ndarray, delay: int, n_fft: int) -> np.ndarray:
    """
    Return the exact response of FIR taps on the ``n_fft`` grid, shape (nf, n_out, n_in).

    Taps longer than ``n_fft`` are wrapped (sampling the DTFT at ``k fs / n_fft``).
    ``taps[:, :, k]`` is lag ``k - delay``.

    The result is C-contiguous, each line's ``(n_out, n_in)`` matrix in one piece: the
    transform runs along the first axis.  The transposed view of a transform along the last
    axis (lines last in memory) made every product of :class:`BlendScorer` stride across the
    whole array: scoring a 16385-line response took 160 ms, 43 ms contiguous
    (docs/performance.md).  The overlap-add and live filters' tap spectra are this
    response too (``delay`` 0 on a grid at least as long as the taps: no wrapping).
    """
    n_taps = taps.shape[2]
    index = (np.arange(n_taps) - delay) % n_fft          # lag k - delay, modulo the grid
    wrapped = np.zeros((n_fft,) + taps.shape[:2])
    for start in range(0, n_taps, n_fft):                # one period of taps at a time
        wrapped[index[start:start + n_fft]] += taps[:, :, start:start + n_fft].transpose(2, 0, 1)
    # every core: independent transforms, the same numbers as one (2.3x faster on two)
    return scipy.fft.rfft(wrapped, axis=0, workers=-1)


def _taper(n_taps: int, delay: int, fraction: float) -> np.ndarray:
    """
    Tukey window split at lag zero: each side's outer ``fraction`` rolled off by a cosine.

    The cosine reaches zero one sample beyond the last tap, so no tap is wasted on a zero.
    """
    w = np.ones(n_taps)
    for side_len, sign in ((delay, -1), (n_taps - 1 - delay, 1)):
        n_roll = int(round(fraction * side_len))
        if n_roll == 0:
            continue
        dist = np.arange(side_len - n_roll + 1, side_len + 1)  # distance from lag zero
        roll = 0.5 * (1.0 + np.cos(np.pi * (dist - (side_len - n_roll)) / (n_roll + 1)))
        w[delay + sign * dist] = roll
    return w


def _zero_dc(taps: np.ndarray, weights: np.ndarray, delay: int,
             dc_gain: Optional[np.ndarray] = None) -> np.ndarray:
    """
    Shift the taps (weighted) so every (out, in) pair has the DC gain ``dc_gain`` (default 0).

    The result is exact to rounding: the last few ulps are placed on lag zero.
    """
    target = np.zeros(taps.shape[:2]) if dc_gain is None else np.asarray(dc_gain, float)
    taps = taps - ((taps.sum(axis=-1) - target)[..., None] / weights.sum()) * weights
    taps[:, :, delay] -= taps.sum(axis=-1) - target
    return taps


def _band_gain(f_hz: np.ndarray, f_min_hz: float, f_max_hz: Optional[float],
               transition_hz: float) -> np.ndarray:
    """Band gain: 0 outside [f_min, f_max] and at DC, raised-cosine edges, 1 inside."""
    gain = ((f_hz >= f_min_hz) & (f_hz > 0.0)).astype(np.float64)
    edges = [f_hz - f_min_hz]
    if f_max_hz is not None:
        gain[f_hz > f_max_hz] = 0.0
        edges.append(f_max_hz - f_hz)
    if transition_hz > 0.0:
        for dist in edges:
            ramp = dist < transition_hz
            gain[ramp] *= 0.5 * (1.0 - np.cos(np.pi * np.clip(dist[ramp], 0.0, None)
                                              / transition_hz))
    return gain


def fir_from_frf(f_hz, h, fs_hz, delay_samples: Optional[int] = None, f_min_hz=0.0,
                 f_max_hz=None, taper_fraction=DEFAULT_TAPER_FRACTION,
                 transition_hz=None, keep_dc: bool = False) -> FirFilter:
    """
    Design the two-sided FIR realisation of a one-sided FRF (see the module notes).

    Parameters
    ----------
    f_hz : array_like, shape (nf,)
        Frequency grid [Hz], uniform from 0 with ``nf = n_fft // 2 + 1`` points, ``df = fs/n_fft``
        (ends at ``fs/2`` for even ``n_fft``).
    h : array_like, shape (nf, n_out, n_in), complex
        FRF ``h[f, out, in]`` [output unit / input unit].  For even ``n_fft`` only the real part
        of the Nyquist bin is used (a real filter has a real Nyquist gain).
    fs_hz : float
        Sample rate [Hz].
    delay_samples : int, optional
        Tap index of lag zero (look-ahead), ``0 <= delay < n_fft``; default ``n_fft // 2``.
    f_min_hz : float
        Bins below this frequency are zeroed (drift control) [Hz]; DC is always zeroed.
    f_max_hz : float, optional
        Bins above this frequency are zeroed [Hz]; default ``fs_hz / 2``.
    taper_fraction : float
        Fraction of each side of the impulse response rolled off by the cosine taper, in [0, 1].
    transition_hz : float, optional
        Width of the raised-cosine band edges [Hz], >= 0; default two bins (``2 fs / n_fft``).
        0 gives hard edges (pure frequency sampling).
    keep_dc : bool
        Instead of zeroing DC, give every pair the DC gain ``Re h[1]`` (the lowest resolved
        line, extrapolated flat: Welch's per-window detrend leaves ``h[0]`` meaningless).
        Only with ``f_min_hz == 0``.  Used when the caller removes the static input itself and
        quasi-static loads (braking, cornering) must pass.

    Returns
    -------
    FirFilter
        ``n_taps = n_fft`` taps [output unit / input unit] with zero DC gain (or ``Re h[1]``
        with ``keep_dc``).

    Raises
    ------
    ShapeError
        ``f_hz`` not 1-D with >= 2 points, or ``h`` not of shape (nf, n_out, n_in).
    NonFiniteError
        ``h`` or ``f_hz`` holds NaN or infinity.
    ConfigError
        Non-uniform grid, grid not starting at 0 or not matching ``fs_hz``, bad band limits,
        an empty pass band, or ``delay_samples`` out of range.

    """
    fs = positive_float(fs_hz, 'fs_hz')
    f = np.asarray(f_hz, dtype=np.float64)
    if f.ndim != 1 or f.size < 2:
        raise ShapeError(f'FRF frequency vector: expected 1-D with >= 2 points, got {f.shape}')
    if not np.isfinite(f).all():
        raise NonFiniteError('FRF frequency vector: non-finite value')
    df = f[1] - f[0]
    n_fft = int(round(fs / df)) if df > 0 else 0
    if (n_fft < 2 or abs(f[0]) > 1e-9 * fs or f.size != n_fft // 2 + 1
            or not np.allclose(f, np.arange(f.size) * (fs / n_fft), rtol=0.0, atol=1e-9 * fs)):
        raise ConfigError(
            f'FRF frequency vector must be uniform from 0 Hz with n_fft//2 + 1 points for '
            f'fs = {fs} Hz; got {f.size} points from {f[0]} to {f[-1]} Hz')
    h = np.asarray(h)
    if h.ndim != 3 or h.shape[0] != f.size or min(h.shape) == 0:
        raise ShapeError(f'FRF h: expected shape ({f.size}, n_out, n_in), got {h.shape}')
    if not np.isfinite(h).all():
        b, o, i = np.argwhere(~np.isfinite(h))[0]
        raise NonFiniteError(
            f'FRF h: non-finite value at {f[b]:g} Hz (bin {b}), output {o}, input {i}')
    f_max = fs / 2.0 if f_max_hz is None else float(f_max_hz)
    f_min = float(f_min_hz)
    if not (0.0 <= f_min < f_max <= fs / 2.0):
        raise ConfigError(
            f'band limits must satisfy 0 <= f_min_hz < f_max_hz <= fs/2 = {fs / 2.0}, '
            f'got f_min_hz={f_min_hz!r}, f_max_hz={f_max_hz!r}')
    transition = 2.0 * fs / n_fft if transition_hz is None else float(transition_hz)
    if not (np.isfinite(transition) and transition >= 0.0):
        raise ConfigError(f'transition_hz must be finite and >= 0, got {transition_hz!r}')
    gain = _band_gain(f, f_min, f_max if f_max < fs / 2.0 else None, transition)
    if not gain.any():
        raise ConfigError(
            f'pass band [{f_min}, {f_max}] Hz with {transition} Hz edges contains no FRF bin '
            f'other than DC (df = {df:g} Hz)')
    delay = n_fft // 2 if delay_samples is None else as_index(delay_samples, 'delay_samples')
    if not 0 <= delay < n_fft:
        raise ConfigError(f'delay_samples must be in [0, {n_fft}), got {delay}')
    fraction = _taper_fraction(taper_fraction)

    dc_gain = None
    if keep_dc:
        if f_min > 0.0:
            raise ConfigError(f'keep_dc needs f_min_hz == 0, got {f_min_hz!r}')
        dc_gain = h[1].real
        h = np.concatenate([dc_gain[None].astype(h.dtype), h[1:]], axis=0)
        gain[0] = 1.0
        if transition > 0.0:
            gain[f < transition] = 1.0
    h_band = h * gain[:, None, None]
    impulse = scipy.fft.irfft(h_band, n=n_fft, axis=0)             # lag-major, circular
    impulse = np.roll(impulse, delay, axis=0).transpose(1, 2, 0)    # lag 0 -> tap `delay`
    weights = _taper(n_fft, delay, fraction)
    taps = _zero_dc(impulse * weights, weights, delay, dc_gain)
    return FirFilter(taps, delay, fs)


def acausal_energy_fraction(fir: FirFilter, delay_samples: int) -> float:
    """
    Energy fraction of taps more than ``delay_samples`` before lag zero (all pairs summed).

    Parameters
    ----------
    fir : FirFilter
        The filter.
    delay_samples : int
        Look-ahead that would be kept, >= 0 [samples].

    Returns
    -------
    float
        Discarded energy over total energy; 0.0 for an all-zero filter or when
        ``delay_samples >= fir.delay_samples``.

    Raises
    ------
    ConfigError
        ``delay_samples`` negative or not an integer.

    """
    keep = as_index(delay_samples, 'delay_samples')
    if keep < 0:
        raise ConfigError(f'delay_samples must be >= 0, got {keep}')
    energy = np.square(fir.taps).sum(axis=(0, 1))
    total = energy.sum()
    n_drop = max(fir.delay_samples - keep, 0)
    return float(energy[:n_drop].sum() / total) if total > 0.0 else 0.0


def with_delay(fir: FirFilter, delay_samples: int,
               taper_fraction=DEFAULT_TAPER_FRACTION) -> FirFilter:
    """
    Return ``fir`` with its look-ahead truncated to ``delay_samples`` (for the live node).

    Taps more than ``delay_samples`` before lag zero are discarded, the remaining look-ahead is
    re-tapered (the causal side keeps its taper) and the DC gain restored to that of ``fir`` as in
    :func:`fir_from_frf`.  ``delay_samples == fir.delay_samples`` returns ``fir`` unchanged.

    Parameters
    ----------
    fir : FirFilter
        The filter to truncate.
    delay_samples : int
        New look-ahead, ``0 <= delay_samples <= fir.delay_samples`` [samples].
    taper_fraction : float
        Fraction of the new look-ahead rolled off by the cosine taper, in [0, 1].

    Returns
    -------
    FirFilter
        ``fir.n_taps - (fir.delay_samples - delay_samples)`` taps.

    Raises
    ------
    ConfigError
        ``delay_samples`` outside ``[0, fir.delay_samples]``.

    """
    delay = as_index(delay_samples, 'delay_samples')
    if not 0 <= delay <= fir.delay_samples:
        raise ConfigError(
            f"delay_samples must be in [0, {fir.delay_samples}] (the filter's look-ahead), "
            f'got {delay}')
    fraction = _taper_fraction(taper_fraction)
    if delay == fir.delay_samples:
        return fir
    taps = fir.taps[:, :, fir.delay_samples - delay:]
    weights = _taper(taps.shape[2], delay, fraction)
    retaper = np.where(np.arange(taps.shape[2]) < delay, weights, 1.0)
    # keep the DC gain of the filter being truncated (zero for a zero-DC design)
    return FirFilter(_zero_dc(taps * retaper, weights, delay, fir.taps.sum(axis=-1)), delay,
                     fir.fs_hz)
