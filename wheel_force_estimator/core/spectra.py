# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Welch auto- and cross-spectral densities of multi-channel records.

Conventions (stated once, as in :func:`scipy.signal.csd`): the cross-spectral density of
``a`` and ``b`` is ``E[conj(A) B]``, one-sided, density-scaled (units of ``a`` times units of
``b`` per Hz), the mean over Hann (or other) windowed, detrended, overlapping segments.

One engine serves every public function: the record is cut into windows by a strided view
(no copy), windows are processed in chunks of bounded size (detrend, taper, real FFT), and the
products are accumulated with one batched matrix product per chunk.  Memory therefore grows
with the number of channels and the segment length, never with the record length.

Several recordings or segments are never concatenated: each gets its own
:func:`cross_spectra` and :func:`combine_spectra` averages them weighted by their window
counts, which is exactly Welch over the union of their windows with no window straddling a
join.
"""
from dataclasses import dataclass
from typing import Sequence, Tuple, Union

import numpy as np
import scipy.fft
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import as_signals
from wheel_force_estimator.core.validation import positive_float
from wheel_force_estimator.core.validation import read_only_array

DETRENDS = ('constant', 'linear', 'none')

# Bytes of float64 window data held per chunk: measured fastest at 4 MiB (1 h, 24 channels)
# and it bounds peak memory; per-chunk Python overhead is negligible at that size.
_CHUNK_BYTES = 4 * 2**20
# Windows gathered (across chunks and segments) per batch of products in
# pooled_cross_spectra.  Each batch reads and writes every accumulated spectral matrix once
# (~95 MB at 32768-sample windows and 26 channels), and at long windows a 4 MiB chunk holds
# one window: products window by window paid that traffic per window, 2.9 s of the
# 20-minute bag's fit for 52 windows.  8 measured best (8 segments of 40000 samples, 26
# channels: 32768-sample windows 0.48 -> 0.24 s, 8192 0.32 -> 0.24 s; 4 and 16 slower);
# chunks of short windows hold more than 8 and are used as they come.  Memory: up to 8
# windows' spectra and their concatenation (2 x 54 MB at 32768 samples and 26 channels).
_PRODUCT_WINDOWS = 8


@dataclass(frozen=True)
class WelchConfig:
    """
    Welch averaging parameters.

    Parameters
    ----------
    fs_hz : float
        Sample rate in Hz, > 0.
    segment_length : int
        Samples per segment (window length and FFT length), >= 8.  The frequency resolution
        is ``fs_hz / segment_length``.
    overlap : float
        Fraction of a segment shared with the next one, in [0, 0.95).  The overlap in samples
        is ``round(overlap * segment_length)``.
    window : str or tuple
        Any window specification accepted by :func:`scipy.signal.get_window` (periodic, as
        :func:`scipy.signal.welch` uses), e.g. ``'hann'`` or ``('tukey', 0.25)``.
    detrend : str
        Per-segment detrending before tapering: ``'constant'`` (mean), ``'linear'``
        (least-squares line) or ``'none'``.

    Raises
    ------
    ConfigError
        When a value is out of range or the window is not known to scipy.

    """

    fs_hz: float
    segment_length: int = 1024
    overlap: float = 0.5
    window: Union[str, Tuple] = 'hann'
    detrend: str = 'constant'

    def __post_init__(self):
        object.__setattr__(self, 'fs_hz', positive_float(self.fs_hz, 'WelchConfig.fs_hz'))
        if isinstance(self.segment_length, (bool, np.bool_)) or not isinstance(
                self.segment_length, (int, np.integer)):
            raise ConfigError(
                f'WelchConfig.segment_length must be an integer, got {self.segment_length!r}')
        if self.segment_length < 8:
            raise ConfigError(
                f'WelchConfig.segment_length must be >= 8, got {self.segment_length}')
        object.__setattr__(self, 'segment_length', int(self.segment_length))
        try:
            overlap = float(self.overlap)
        except (TypeError, ValueError) as err:
            raise ConfigError(
                f'WelchConfig.overlap must be a number, got {self.overlap!r}') from err
        if not 0.0 <= overlap < 0.95:
            raise ConfigError(f'WelchConfig.overlap must be in [0, 0.95), got {self.overlap!r}')
        object.__setattr__(self, 'overlap', overlap)
        if isinstance(self.window, list):
            object.__setattr__(self, 'window', tuple(self.window))
        if not isinstance(self.window, (str, tuple)):
            raise ConfigError(
                f'WelchConfig.window must be a window name or (name, parameter...) tuple, '
                f'got {self.window!r}')
        try:
            win = scipy.signal.get_window(self.window, self.segment_length)
        except (ValueError, TypeError) as err:
            raise ConfigError(
                f'WelchConfig.window {self.window!r} is not a scipy window: {err}') from err
        if not np.all(np.isfinite(win)) or not np.any(win != 0.0):
            raise ConfigError(f'WelchConfig.window {self.window!r} is zero or not finite')
        if self.detrend not in DETRENDS:
            raise ConfigError(
                f'WelchConfig.detrend must be one of {DETRENDS}, got {self.detrend!r}')

    @property
    def overlap_samples(self) -> int:
        """Return the number of samples shared by consecutive segments."""
        return int(round(self.overlap * self.segment_length))

    @property
    def step_samples(self) -> int:
        """Return the hop between segment starts in samples (>= 1 as overlap < 0.95)."""
        return self.segment_length - self.overlap_samples

    @property
    def f_hz(self) -> np.ndarray:
        """Return the one-sided frequency axis in Hz, shape ``(segment_length // 2 + 1,)``."""
        return scipy.fft.rfftfreq(self.segment_length, 1.0 / self.fs_hz)

    def window_array(self) -> np.ndarray:
        """Return the periodic window, shape ``(segment_length,)``."""
        return scipy.signal.get_window(self.window, self.segment_length)

    def n_windows(self, n_samples: int) -> int:
        """Return the number of whole segments in ``n_samples`` contiguous samples (may be 0)."""
        if n_samples < self.segment_length:
            return 0
        return (n_samples - self.segment_length) // self.step_samples + 1


@dataclass(frozen=True)
class CrossSpectra:
    """
    Welch spectral matrices of inputs ``x`` and outputs ``y`` (one-sided densities).

    Parameters
    ----------
    f_hz : numpy.ndarray, shape (nf,)
        Frequency axis in Hz.
    sxx : numpy.ndarray, shape (nf, n_in, n_in), complex128
        ``sxx[f, i, j] = E[conj(X_i) X_j]`` in (input unit)²/Hz; Hermitian in ``(i, j)``.
    syx : numpy.ndarray, shape (nf, n_out, n_in), complex128
        ``syx[f, o, i] = E[conj(X_i) Y_o]`` in input unit · output unit / Hz.
    syy : numpy.ndarray, shape (nf, n_out), float64
        ``syy[f, o] = E[|Y_o|²]`` in (output unit)²/Hz.
    n_windows : int
        Number of segments averaged (the weight used by :func:`combine_spectra`).
    config : WelchConfig
        Parameters the spectra were computed with.

    Raises
    ------
    ShapeError
        When the array shapes are inconsistent.
    ConfigError
        When ``n_windows`` < 1 or ``config`` is not a :class:`WelchConfig`.

    """

    f_hz: np.ndarray
    sxx: np.ndarray
    syx: np.ndarray
    syy: np.ndarray
    n_windows: int
    config: WelchConfig

    def __post_init__(self):
        if not isinstance(self.config, WelchConfig):
            raise ConfigError(f'CrossSpectra.config must be a WelchConfig, got {self.config!r}')
        if isinstance(self.n_windows, (bool, np.bool_)) or not isinstance(
                self.n_windows, (int, np.integer)) or self.n_windows < 1:
            raise ConfigError(f'CrossSpectra.n_windows must be an integer >= 1, '
                              f'got {self.n_windows!r}')
        object.__setattr__(self, 'n_windows', int(self.n_windows))
        # Read-only, copied unless already frozen: freezing never touches a caller's array.
        f_hz = read_only_array(self.f_hz, np.float64)
        sxx = read_only_array(self.sxx, np.complex128)
        syx = read_only_array(self.syx, np.complex128)
        syy = read_only_array(self.syy, np.float64)
        nf = f_hz.shape[0] if f_hz.ndim == 1 else -1
        if nf < 1 or sxx.ndim != 3 or sxx.shape[0] != nf or sxx.shape[1] != sxx.shape[2]:
            raise ShapeError(f'CrossSpectra: sxx must be (nf, n_in, n_in) with nf = len(f_hz), '
                             f'got f_hz {f_hz.shape}, sxx {sxx.shape}')
        if syx.ndim != 3 or syx.shape[0] != nf or syx.shape[2] != sxx.shape[1]:
            raise ShapeError(f'CrossSpectra: syx must be (nf, n_out, n_in) = '
                             f'({nf}, n_out, {sxx.shape[1]}), got {syx.shape}')
        if syy.shape != syx.shape[:2]:
            raise ShapeError(f'CrossSpectra: syy must be (nf, n_out) = {syx.shape[:2]}, '
                             f'got {syy.shape}')
        for name, arr in (('f_hz', f_hz), ('sxx', sxx), ('syx', syx), ('syy', syy)):
            object.__setattr__(self, name, arr)

    @property
    def n_inputs(self) -> int:
        """Return the number of input channels."""
        return self.sxx.shape[1]

    @property
    def n_outputs(self) -> int:
        """Return the number of output channels."""
        return self.syx.shape[1]


def _window_spectra(signals: Sequence[np.ndarray], config: WelchConfig):
    """
    Yield the scaled FFTs of chunks of windows of all channels.

    Parameters
    ----------
    signals : sequence of numpy.ndarray, each (n_ch_k, n)
        Validated float64 records of equal length, stacked along channels in this order.
    config : WelchConfig
        Segmenting, window and detrend.

    Yields
    ------
    numpy.ndarray, shape (nf, n_chunk_windows, n_channels), complex128
        FFTs of detrended, tapered segments multiplied by ``sqrt(scale)`` so that the sum of
        ``conj(Z_a) Z_b`` over all windows divided by their count is the one-sided density.

    """
    seg = config.segment_length
    step = config.step_samples
    n = signals[0].shape[1]
    n_win = config.n_windows(n)
    n_ch = sum(s.shape[0] for s in signals)
    win = config.window_array()
    # Density scaling exactly as scipy.signal.csd: 1 / (fs * sum(w²)); the one-sided doubling
    # of every bin except DC (and Nyquist for even lengths) is applied to the products, so the
    # amplitude factor is its square root.
    onesided = np.full(seg // 2 + 1, 2.0)
    onesided[0] = 1.0
    if seg % 2 == 0:
        onesided[-1] = 1.0
    amp = np.sqrt(onesided / (config.fs_hz * np.dot(win, win)))
    views = [np.lib.stride_tricks.sliding_window_view(s, seg, axis=1)[:, ::step] for s in signals]
    if config.detrend == 'linear':
        ramp = np.arange(seg, dtype=np.float64) - 0.5 * (seg - 1)
        ramp /= np.sqrt(np.dot(ramp, ramp))
    chunk = max(1, _CHUNK_BYTES // (8 * seg * n_ch))
    buf = np.empty((min(chunk, n_win), n_ch, seg), dtype=np.float64)
    for w0 in range(0, n_win, chunk):
        w1 = min(n_win, w0 + chunk)
        block = buf[:w1 - w0]
        c0 = 0
        for v in views:
            block[:, c0:c0 + v.shape[0], :] = v[:, w0:w1, :].transpose(1, 0, 2)
            c0 += v.shape[0]
        if config.detrend != 'none':
            block -= block.mean(axis=-1, keepdims=True)
        if config.detrend == 'linear':
            # The centred ramp is orthogonal to the constant, so removing the mean and then
            # the projection on the unit ramp is the least-squares line fit.
            block -= (block @ ramp)[..., np.newaxis] * ramp
        block *= win
        # every core (independent transforms, the same numbers as one; docs/performance.md)
        spec = scipy.fft.rfft(block, axis=-1, workers=-1)
        spec *= amp
        yield np.ascontiguousarray(spec.transpose(2, 0, 1))


def _check_pair(x, y, name: str, config: WelchConfig):
    if not isinstance(config, WelchConfig):
        raise ConfigError(f'{name}: config must be a WelchConfig, got {config!r}')
    x = as_signals(x, f'inputs of {name}')
    y = as_signals(y, f'outputs of {name}')
    if x.shape[0] < 1 or y.shape[0] < 1:
        raise ShapeError(f'{name}: need at least one input and one output channel, '
                         f'got {x.shape[0]} inputs and {y.shape[0]} outputs')
    if x.shape[1] != y.shape[1]:
        raise ShapeError(f'{name}: inputs have {x.shape[1]} samples but outputs have '
                         f'{y.shape[1]}; they must be the same contiguous segment')
    _check_length(x.shape[1], name, config)
    return x, y


def _check_length(n: int, name: str, config: WelchConfig):
    if n < config.segment_length:
        raise InsufficientDataError(
            f'{name}: {n} samples, shorter than one Welch segment of '
            f'{config.segment_length} samples ({config.segment_length / config.fs_hz:g} s)')


def cross_spectra(x, y, config: WelchConfig, name: str = 'recording') -> CrossSpectra:
    """
    Welch spectral matrices of one contiguous segment.

    Parameters
    ----------
    x : array_like, shape (n_in, n)
        Input signals (e.g. accelerations in m/s²), time last, uniformly sampled at
        ``config.fs_hz``.
    y : array_like, shape (n_out, n)
        Output signals (e.g. forces in N), sample-aligned with ``x``.
    config : WelchConfig
        Welch parameters.
    name : str
        What the segment is, used in error messages (file, segment index, ...).

    Returns
    -------
    CrossSpectra
        ``sxx`` in (x unit)²/Hz, ``syx`` in x unit · y unit / Hz, ``syy`` in (y unit)²/Hz.
        Each entry equals :func:`scipy.signal.csd` of the corresponding channel pair with the
        same parameters (``csd(x_i, y_o)`` for ``syx[:, o, i]``).

    Raises
    ------
    ShapeError
        Wrong array dimensions, no channel, or ``x`` and ``y`` of different lengths.
    InsufficientDataError
        Fewer samples than one segment.
    NonFiniteError
        A NaN or infinite sample (channel and sample named).
    ConfigError
        ``config`` is not a :class:`WelchConfig`.

    """
    x, y = _check_pair(x, y, name, config)
    return pooled_cross_spectra([(x, y)], config, name)


def _add_products(spectra: list, s_xx: np.ndarray, s_xy: np.ndarray, syy: np.ndarray) -> None:
    """Add the products of window spectra (each (nf, n_windows, n_channels)) in place."""
    z = np.concatenate(spectra, axis=1) if len(spectra) > 1 else spectra[0]
    n_in = s_xx.shape[1]
    zc = z.conj().transpose(0, 2, 1)[:, :n_in]
    # two batched products instead of one of all channels: the output-output cross terms
    # are not needed, and at long windows their memory is the cost
    s_xx += np.matmul(zc, z[:, :, :n_in])
    s_xy += np.matmul(zc, z[:, :, n_in:])
    zy = z[:, :, n_in:]
    syy += np.einsum('fwc,fwc->fc', zy.real, zy.real)
    syy += np.einsum('fwc,fwc->fc', zy.imag, zy.imag)


def pooled_cross_spectra(pairs: Sequence[Tuple[np.ndarray, np.ndarray]], config: WelchConfig,
                         name: str = 'recording') -> CrossSpectra:
    """
    Welch spectral matrices over the windows of several contiguous segments, as one average.

    Equal to :func:`combine_spectra` of :func:`cross_spectra` of each pair (tested): no
    window straddles two segments.  One set of spectral matrices is accumulated for all the
    segments instead of one per segment: at the scorer's 32768-sample windows a set is
    ~100 MB, and on this machine a fresh page costs more than the products that fill it.

    Parameters
    ----------
    pairs : sequence of (array_like, array_like)
        ``(x, y)`` per segment, as :func:`cross_spectra` takes them (the same channel counts).
    config : WelchConfig
        Welch parameters.
    name : str
        What the segments are, used in error messages.

    Returns
    -------
    CrossSpectra
        As :func:`cross_spectra`, ``n_windows`` the total.

    Raises
    ------
    InsufficientDataError
        No pair, or a pair shorter than one segment.
    ShapeError
        Wrong dimensions, or pairs with different channel counts.
    NonFiniteError, ConfigError
        As :func:`cross_spectra`.

    """
    checked = [_check_pair(x, y, f'{name} (segment {k})' if len(pairs) > 1 else name, config)
               for k, (x, y) in enumerate(pairs)]
    if not checked:
        raise InsufficientDataError(f'{name}: no segment to compute spectra of')
    n_in, n_out = checked[0][0].shape[0], checked[0][1].shape[0]
    for k, (x, y) in enumerate(checked):
        if (x.shape[0], y.shape[0]) != (n_in, n_out):
            raise ShapeError(f'{name}: segment {k} has {x.shape[0]} inputs and {y.shape[0]} '
                             f'outputs, segment 0 {n_in} and {n_out}')
    nf = config.segment_length // 2 + 1
    s_xx = np.zeros((nf, n_in, n_in), dtype=np.complex128)
    s_xy = np.zeros((nf, n_in, n_out), dtype=np.complex128)     # conj(X) Y: Syx transposed
    syy = np.zeros((nf, n_out), dtype=np.float64)
    n_win = 0
    pending: list = []          # window spectra not yet in the products (_PRODUCT_WINDOWS)
    for x, y in checked:
        for z in _window_spectra((x, y), config):
            pending.append(z)
            if sum(p.shape[1] for p in pending) >= _PRODUCT_WINDOWS:
                _add_products(pending, s_xx, s_xy, syy)
                pending = []
        n_win += config.n_windows(x.shape[1])
    if pending:
        _add_products(pending, s_xx, s_xy, syy)
    s_xx /= n_win
    # Exactly Hermitian with a real diagonal, so eigen-solvers downstream see what they expect.
    sxx = 0.5 * (s_xx + s_xx.conj().transpose(0, 2, 1))
    del s_xx
    syx = np.ascontiguousarray(s_xy.transpose(0, 2, 1))
    syx /= n_win
    syy /= n_win
    return CrossSpectra(config.f_hz, sxx, syx, syy, n_win, config)


def combine_spectra(spectra: Sequence[CrossSpectra]) -> CrossSpectra:
    """
    Average spectra of several segments, weighted by their window counts.

    The result is Welch over the union of all segments' windows: no window straddles the
    join between two recordings, so gaps and offsets between segments create no artefact.

    Parameters
    ----------
    spectra : sequence of CrossSpectra
        Spectra computed with the same :class:`WelchConfig` and channel counts.

    Returns
    -------
    CrossSpectra
        With ``n_windows`` the total window count.

    Raises
    ------
    InsufficientDataError
        When ``spectra`` is empty.
    ConfigError
        When an item is not a :class:`CrossSpectra` or the configs or frequency axes differ.
    ShapeError
        When the input or output channel counts differ.

    """
    items = list(spectra)
    if not items:
        raise InsufficientDataError('combine_spectra: no spectra to combine')
    for k, s in enumerate(items):
        if not isinstance(s, CrossSpectra):
            raise ConfigError(f'combine_spectra: item {k} is not a CrossSpectra: {type(s)}')
    first = items[0]
    for k, s in enumerate(items[1:], start=1):
        if s.config != first.config:
            raise ConfigError(
                f'combine_spectra: item {k} was computed with {s.config}, item 0 with '
                f'{first.config}')
        if s.f_hz.shape != first.f_hz.shape or not np.array_equal(s.f_hz, first.f_hz):
            raise ConfigError(f'combine_spectra: item {k} has a different frequency axis')
        if s.sxx.shape != first.sxx.shape or s.syx.shape != first.syx.shape:
            raise ShapeError(
                f'combine_spectra: item {k} has {s.n_inputs} inputs and {s.n_outputs} outputs, '
                f'item 0 has {first.n_inputs} inputs and {first.n_outputs} outputs')
    total = sum(s.n_windows for s in items)
    sxx = sum(s.sxx * (s.n_windows / total) for s in items)
    syx = sum(s.syx * (s.n_windows / total) for s in items)
    syy = sum(s.syy * (s.n_windows / total) for s in items)
    return CrossSpectra(first.f_hz, sxx, syx, syy, total, first.config)


def auto_spectral_density(x, config: WelchConfig,
                          name: str = 'signals') -> Tuple[np.ndarray, np.ndarray]:
    """
    Welch power spectral density of each channel.

    Parameters
    ----------
    x : array_like, shape (n_ch, n) or (n,)
        Signals, time last, sampled at ``config.fs_hz``.
    config : WelchConfig
        Welch parameters.
    name : str
        What ``x`` is, used in error messages.

    Returns
    -------
    f_hz : numpy.ndarray, shape (nf,)
        Frequency axis in Hz.
    psd : numpy.ndarray, shape (n_ch, nf)
        One-sided density in (x unit)²/Hz, equal to :func:`scipy.signal.welch` with the same
        parameters.

    Raises
    ------
    ShapeError
        Wrong array dimensions.
    InsufficientDataError
        Fewer samples than one segment.
    NonFiniteError
        A NaN or infinite sample.
    ConfigError
        ``config`` is not a :class:`WelchConfig`.

    """
    if not isinstance(config, WelchConfig):
        raise ConfigError(f'{name}: config must be a WelchConfig, got {config!r}')
    x = as_signals(x, name)
    _check_length(x.shape[1], name, config)
    psd = np.zeros((config.segment_length // 2 + 1, x.shape[0]), dtype=np.float64)
    for z in _window_spectra((x,), config):
        psd += np.einsum('fwc,fwc->fc', z.real, z.real)
        psd += np.einsum('fwc,fwc->fc', z.imag, z.imag)
    psd /= config.n_windows(x.shape[1])
    return config.f_hz, np.ascontiguousarray(psd.T)


def power_quantile_hz(f_hz: np.ndarray, power: np.ndarray, fraction: float) -> Union[float, None]:
    """
    Return the frequency below which ``fraction`` of the summed ``power`` lies [Hz].

    The first bin of ``f_hz`` whose cumulative power reaches ``fraction`` of the total; None
    when there is no power.  (The one home of the "band holding 99 % of the power" rule the
    diagnosis uses for its load-state and differentiator corners.)
    """
    cum = np.cumsum(power)
    if not cum[-1] > 0.0:
        return None
    return float(f_hz[np.searchsorted(cum, fraction * cum[-1])])
