# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Pseudo damage (S-N / Miner) of load histories, batch, streaming and per frequency band.

Cycles are counted by :mod:`wheel_force_estimator.core.rainflow` (turning point, rainflow and
residue conventions are stated there).  Convention (stated once, used everywhere here):

* **Pseudo damage.**  Palmgren-Miner sum over cycles of ``count * range**k`` with the Basquin
  S-N curve ``N(dS) = (dS / 1 N)**-k``: a reference range of 1 N fails at one cycle.  The
  reference is arbitrary, so the absolute value has no physical meaning; only ratios of
  damages computed with the same ``k`` (prediction / target, band / band) are meaningful.
  Units: force_n**k when the input is in N.

Batch damage is computed by the streaming engine fed with large blocks, so chunked and batch
results are the same arithmetic in the same order.
"""
import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filter_design import butter_sos
from wheel_force_estimator.core.rainflow import BLOCK_SAMPLES
from wheel_force_estimator.core.rainflow import check_residue
from wheel_force_estimator.core.rainflow import push_channels
from wheel_force_estimator.core.rainflow import reversal_mask
from wheel_force_estimator.core.rainflow import total_damage
from wheel_force_estimator.core.validation import as_signals
from wheel_force_estimator.core.validation import positive_float

PAPER_BANDS_HZ = ((0.0, 2.2), (1.8, 4.4), (3.6, 8.8), (7.2, 17.6), (14.4, 32.0))
"""Relative damage spectrum bands of the paper (Hz), overlapping, 0-32 Hz."""

# Butterworth order handed to scipy.signal.butter for the band filters.
_BAND_FILTER_ORDER = 4
# Band edges must stay below this fraction of Nyquist (see damage_bands_hz).
_NYQUIST_MARGIN = 0.8


class StreamingDamage:
    """
    Pseudo damage of multichannel signals arriving block by block.

    ``damage()`` after any sequence of ``update`` calls equals ``pseudo_damage`` of the
    concatenated blocks, whatever the block sizes (including empty and one-sample blocks).
    State per channel: the last sample and the direction of the last non-zero step (to detect
    a reversal across a block boundary), the rainflow stack, and the damage of the cycles
    closed so far.  The residue's contribution is evaluated on demand from the stack, so an
    update costs O(block length) and ``damage()`` O(residue length).

    Parameters
    ----------
    n_channels : int
        Number of channels (>= 1).
    sn_slope : float
        Basquin exponent k (> 0) of the pseudo S-N curve ``N = (range / 1 N)**-k``.
    residue : {'half', 'none'}
        Residue policy, see :func:`wheel_force_estimator.core.rainflow.rainflow`.

    Raises
    ------
    ConfigError
        ``n_channels`` < 1, ``sn_slope`` not finite and > 0, or unknown ``residue``.

    """

    def __init__(self, n_channels: int, sn_slope: float = 5.0, residue: str = 'half'):
        if isinstance(n_channels, bool) or not isinstance(n_channels, (int, np.integer)) \
                or n_channels < 1:
            raise ConfigError(f'n_channels must be an integer >= 1, got {n_channels!r}')
        self._n_channels = int(n_channels)
        self._sn_slope = positive_float(sn_slope, 'sn_slope')
        self._half = check_residue(residue)
        self.reset()

    @property
    def n_channels(self) -> int:
        """Return the number of channels."""
        return self._n_channels

    @property
    def sn_slope(self) -> float:
        """Return the Basquin exponent k."""
        return self._sn_slope

    @property
    def n_samples(self) -> int:
        """Return the number of samples per channel received since construction or ``reset()``."""
        return self._n_samples

    def reset(self):
        """Forget all samples: back to the state right after construction."""
        n_ch = self._n_channels
        self._n_samples = 0
        self._last = np.zeros(n_ch)
        self._direction = np.zeros(n_ch, dtype=np.int8)
        self._stacks = np.empty((n_ch, 64))
        self._n_stack = np.zeros(n_ch, dtype=np.int64)
        self._closed = np.zeros(n_ch)

    def update(self, chunk):
        """
        Add the next block of samples.

        Parameters
        ----------
        chunk : array_like, shape (n_channels, m)
            Next m >= 0 samples of every channel (1-D allowed for one channel).

        Raises
        ------
        ShapeError
            Wrong number of dimensions or channels.
        NonFiniteError
            NaN or infinity (channel and stream sample index named); the state is unchanged.

        """
        start = self._n_samples
        chunk = as_signals(chunk, f'damage stream block starting at sample {start}',
                           min_samples=0)
        if chunk.shape[0] != self._n_channels:
            raise ShapeError(
                f'damage stream block starting at sample {start}: expected '
                f'{self._n_channels} channels, got {chunk.shape[0]}')
        for first in range(0, chunk.shape[1], BLOCK_SAMPLES):
            self._update_valid(chunk[:, first:first + BLOCK_SAMPLES])

    def _update_valid(self, block):
        """Consume a validated, non-empty block of at most ``BLOCK_SAMPLES`` samples."""
        if self._n_samples == 0:
            # The first sample opens the record: it starts every channel's stack.
            self._last = block[:, 0].copy()
            self._stacks[:, 0] = self._last
            self._n_stack[:] = 1
        y = np.concatenate([self._last[:, np.newaxis], block], axis=1)
        mask, self._direction = reversal_mask(y, self._direction)
        rows, cols = np.nonzero(mask)
        values = y[rows, cols]
        offsets = np.zeros(self._n_channels + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=self._n_channels), out=offsets[1:])
        needed = int((self._n_stack + np.diff(offsets)).max())
        if needed > self._stacks.shape[1]:
            grown = np.empty((self._n_channels, max(needed, 2 * self._stacks.shape[1])))
            grown[:, :self._stacks.shape[1]] = self._stacks
            self._stacks = grown
        push_channels(values, offsets, self._stacks, self._n_stack, self._closed,
                      self._sn_slope)
        self._last = block[:, -1].copy()
        self._n_samples += block.shape[1]

    def damage(self) -> np.ndarray:
        """
        Return the pseudo damage of everything received so far.

        Returns
        -------
        numpy.ndarray, shape (n_channels,)
            Closed cycles plus, for ``residue='half'``, the current residue as half cycles
            (the last sample taken as the end of the record).  Zero before the first reversal.

        """
        return total_damage(self._stacks, self._n_stack, self._last, self._closed,
                            self._sn_slope, self._half)


class ChannelDamage:
    """
    :class:`StreamingDamage` with one Basquin exponent per channel (forces and moments).

    Channels sharing an exponent are counted by one :class:`StreamingDamage`; ``update``,
    ``damage`` and ``reset`` behave as its, channel by channel.

    Parameters
    ----------
    sn_slopes : array_like, shape (n_channels,)
        Basquin exponent of every channel [-].

    Raises
    ------
    ConfigError
        An exponent not finite and > 0, or no channels.

    """

    def __init__(self, sn_slopes):
        slopes = np.asarray(sn_slopes, dtype=np.float64).reshape(-1)
        if slopes.size < 1:
            raise ConfigError('ChannelDamage needs at least one channel')
        self._groups = [(np.flatnonzero(slopes == k), StreamingDamage(int((slopes == k).sum()),
                                                                      float(k)))
                        for k in np.unique(slopes)]
        self._n = slopes.size

    @property
    def n_channels(self) -> int:
        """Return the number of channels."""
        return self._n

    def reset(self):
        """Forget everything counted so far."""
        for _, stream in self._groups:
            stream.reset()

    def update(self, chunk):
        """Count a chunk ``(n_channels, m)`` (any length, chunked == batch)."""
        chunk = np.asarray(chunk, dtype=np.float64)
        for rows, stream in self._groups:
            stream.update(chunk[rows] if len(self._groups) > 1 else chunk)

    def damage(self) -> np.ndarray:
        """Return the pseudo damage per channel so far, ``(n_channels,)``."""
        if len(self._groups) == 1:
            return self._groups[0][1].damage()
        out = np.zeros(self._n)
        for rows, stream in self._groups:
            out[rows] = stream.damage()
        return out


def pseudo_damage(x, sn_slope: float = 5.0, residue: str = 'half') -> np.ndarray:
    """
    Return the rainflow pseudo damage of every channel.

    Parameters
    ----------
    x : array_like, shape (n_channels, n_samples) or (n_samples,)
        Load histories, time last, e.g. force_n.
    sn_slope : float
        Basquin exponent k (> 0).  Damage is ``sum(counts * ranges**k)`` in (unit of x)**k,
        i.e. Miner's sum with a reference range of 1 unit failing at one cycle.
    residue : {'half', 'none'}
        Residue policy, see :func:`wheel_force_estimator.core.rainflow.rainflow`.

    Returns
    -------
    numpy.ndarray, shape (n_channels,)
        Zero for channels with no reversal (constant, monotonic, < 3 samples).

    Raises
    ------
    ShapeError
        ``x`` is not 1-D or 2-D.
    NonFiniteError
        NaN or infinity (channel and sample named).
    ConfigError
        ``sn_slope`` not finite and > 0, or unknown ``residue``.

    """
    x = as_signals(x, 'pseudo damage input', min_samples=0)
    sn_slope = positive_float(sn_slope, 'sn_slope')
    check_residue(residue)
    if x.shape[0] == 0:
        return np.zeros(0)
    stream = StreamingDamage(x.shape[0], sn_slope, residue)
    for first in range(0, x.shape[1], BLOCK_SAMPLES):
        stream._update_valid(x[:, first:first + BLOCK_SAMPLES])
    return stream.damage()


def damage_bands_hz(fs_hz: float) -> tuple:
    """
    Return the relative damage spectrum bands usable at a sample rate.

    The band filters are Butterworth designs whose upper skirt needs room below Nyquist (and
    the bilinear transform squeezes the response near it), so every band edge must stay
    below 0.8 x Nyquist.  At rates where the paper's top edge (32 Hz) fits, the paper bands
    are returned unchanged; otherwise all edges are scaled by ``(0.8 * fs_hz / 2) / 32`` so
    the five bands keep their relative layout and overlap.

    Parameters
    ----------
    fs_hz : float
        Sample rate in Hz (> 0).

    Returns
    -------
    tuple of (lo_hz, hi_hz) float pairs
        Five bands, ascending.

    Raises
    ------
    ConfigError
        ``fs_hz`` not finite and > 0.

    """
    fs_hz = positive_float(fs_hz, 'fs_hz')
    usable_hz = _NYQUIST_MARGIN * fs_hz / 2.0
    top_hz = PAPER_BANDS_HZ[-1][1]
    if top_hz < usable_hz:
        return PAPER_BANDS_HZ
    scale = usable_hz / top_hz
    return tuple((lo * scale, hi * scale) for lo, hi in PAPER_BANDS_HZ)


def _check_bands(bands_hz, fs_hz):
    """Return bands as a tuple of float pairs with 0 <= lo < hi < fs/2."""
    try:
        bands = tuple((float(lo), float(hi)) for lo, hi in bands_hz)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'bands_hz must be a sequence of (lo_hz, hi_hz) pairs, got '
                          f'{bands_hz!r}') from err
    if not bands:
        raise ConfigError('bands_hz is empty')
    nyquist_hz = fs_hz / 2.0
    for lo, hi in bands:
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi < nyquist_hz):
            raise ConfigError(f'band ({lo}, {hi}) Hz: need 0 <= lo < hi < Nyquist '
                              f'{nyquist_hz} Hz')
    return bands


def relative_damage_spectrum(x, fs_hz: float, sn_slope: float = 5.0, bands_hz=None,
                             residue: str = 'half') -> np.ndarray:
    """
    Return the pseudo damage of every channel band-filtered into each frequency band.

    Each band is a zero-phase Butterworth filter (``scipy.signal.butter`` order 4 per edge,
    run forward and backward with ``sosfiltfilt``, so the amplitude gain at an edge is 1/2);
    a band starting at 0 Hz is a low-pass.  Comparing the result of a prediction with the
    target's band by band shows where in frequency the damage is lost or gained.

    Parameters
    ----------
    x : array_like, shape (n_channels, n_samples) or (n_samples,)
        Load histories, time last, e.g. force_n.
    fs_hz : float
        Sample rate in Hz.
    sn_slope : float
        Basquin exponent k (> 0), see :func:`pseudo_damage`.
    bands_hz : sequence of (lo_hz, hi_hz), optional
        Bands with ``0 <= lo < hi < fs_hz / 2``; default ``damage_bands_hz(fs_hz)``.
    residue : {'half', 'none'}
        Residue policy, see :func:`wheel_force_estimator.core.rainflow.rainflow`.

    Returns
    -------
    numpy.ndarray, shape (n_channels, n_bands)
        Pseudo damage per channel and band, (unit of x)**k.  Zeros for an empty record.

    Raises
    ------
    ShapeError
        ``x`` is not 1-D or 2-D.
    NonFiniteError
        NaN or infinity (channel and sample named).
    InsufficientDataError
        Non-empty record too short for the zero-phase filters' edge padding.
    ConfigError
        Invalid ``fs_hz``, ``sn_slope``, ``residue`` or band.

    """
    x = as_signals(x, 'relative damage spectrum input', min_samples=0)
    fs_hz = positive_float(fs_hz, 'fs_hz')
    sn_slope = positive_float(sn_slope, 'sn_slope')
    check_residue(residue)
    bands = _check_bands(damage_bands_hz(fs_hz) if bands_hz is None else bands_hz, fs_hz)
    out = np.zeros((x.shape[0], len(bands)))
    if x.shape[1] == 0:
        return out
    filters = []
    for lo, hi in bands:
        if lo == 0.0:
            sos = butter_sos(_BAND_FILTER_ORDER, float(hi), 'lowpass', fs_hz)
        else:
            sos = butter_sos(_BAND_FILTER_ORDER, (float(lo), float(hi)), 'bandpass', fs_hz)
        filters.append(sos)
    # sosfiltfilt's default odd-extension padding; it refuses records not longer than that.
    min_samples = max(3 * (2 * sos.shape[0] + 1) for sos in filters) + 1
    if x.shape[1] < min_samples:
        raise InsufficientDataError(
            f'relative damage spectrum input: {x.shape[1]} samples, at least {min_samples} '
            'required by the zero-phase band filters')
    # One channel at a time keeps memory at a few copies of one channel for hour-long records.
    for ch in range(x.shape[0]):
        for band, sos in enumerate(filters):
            filtered = signal.sosfiltfilt(sos, x[ch])
            out[ch, band] = pseudo_damage(filtered, sn_slope, residue)[0]
    return out
