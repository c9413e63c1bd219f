# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Rainflow counting and pseudo damage, batch and streaming, as durability engineers use them.

Conventions (stated once, used everywhere in this module):

* **Turning points.**  Repeated equal samples are merged and points that do not reverse the
  load direction are dropped.  When the history holds at least one reversal, its first and
  last samples are turning points too (ASTM E1049-85 counts from the start to the end of the
  record).  A history without any reversal (empty, one sample, constant, monotonic) has no
  turning points, hence no cycles and zero damage: a cycle, even a half one, needs a load
  reversal.
* **Rainflow.**  ASTM E1049-85 section 5.4.4, implemented as the equivalent four-point stack
  algorithm: with the last four points ``a, b, c, d`` on the stack, ``(b, c)`` is a closed
  cycle when ``|b - c| <= |a - b|`` and ``|b - c| <= |c - d|``.  Closed cycles count 1.0.
  What is left on the stack at the end (the *residue*) is counted per the ``residue`` policy:
  ``'half'`` counts each range between neighbouring residue points as a half cycle, which is
  exactly ASTM's step 5/6 result (the standard's start-point half cycles are the residue's
  rising ranges); ``'none'`` drops the residue (closed cycles only).
* **Pseudo damage.**  Palmgren-Miner sum over cycles of ``count * range**k`` with the Basquin
  S-N curve ``N(dS) = (dS / 1 N)**-k``: a reference range of 1 N fails at one cycle.  The
  reference is arbitrary, so the absolute value has no physical meaning; only ratios of
  damages computed with the same ``k`` (prediction / target, band / band) are meaningful.
  Units: force_n**k when the input is in N.

The four-point stack loop is written here by hand instead of taken from a library because the
streaming estimator needs the residue stack as state between blocks, which neither fatpack nor
rainflow exposes (and neither is a dependency).  The loop runs under numba; the turning-point
search is vectorised with numpy.  Batch damage is computed by the streaming engine fed with
large blocks, so chunked and batch results are the same arithmetic in the same order.
"""
from dataclasses import dataclass

from numba import njit
import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import as_signals
from wheel_force_estimator.core.validation import positive_float

PAPER_BANDS_HZ = ((0.0, 2.2), (1.8, 4.4), (3.6, 8.8), (7.2, 17.6), (14.4, 32.0))
"""Relative damage spectrum bands of the paper (Hz), overlapping, 0-32 Hz."""

RESIDUE_POLICIES = ('half', 'none')

# Samples per internal block: bounds the temporaries of the turning-point search (~25 B per
# sample and channel) whatever the record length; results do not depend on it.
_BLOCK_SAMPLES = 1 << 16
# Butterworth order handed to scipy.signal.butter for the band filters.
_BAND_FILTER_ORDER = 4
# Band edges must stay below this fraction of Nyquist (see damage_bands_hz).
_NYQUIST_MARGIN = 0.8


@dataclass(frozen=True, eq=False)
class RainflowCycles:
    """
    Rainflow count of one channel.

    Attributes
    ----------
    ranges : numpy.ndarray, shape (n_cycles,)
        Cycle ranges (peak to valley, >= 0), in the unit of the input.
    means : numpy.ndarray, shape (n_cycles,)
        Cycle means ``(peak + valley) / 2``, in the unit of the input.
    counts : numpy.ndarray, shape (n_cycles,)
        1.0 for a closed cycle, 0.5 for a residue half cycle.  Closed cycles come first, in the
        order they closed, then the residue ranges from the start of the record to its end.

    """

    ranges: np.ndarray
    means: np.ndarray
    counts: np.ndarray

    def __post_init__(self):
        """Store read-only float64 copies after checking the three arrays match."""
        arrays = [np.array(a, dtype=np.float64) for a in (self.ranges, self.means, self.counts)]
        if any(a.ndim != 1 for a in arrays) or len({a.shape for a in arrays}) != 1:
            raise ShapeError(
                'RainflowCycles: ranges, means and counts must be 1-D of equal length, got '
                f'shapes {[a.shape for a in arrays]}')
        for field, arr in zip(('ranges', 'means', 'counts'), arrays):
            arr.flags.writeable = False
            object.__setattr__(self, field, arr)


def _check_residue(residue) -> bool:
    """Return True when residue half cycles are counted; reject unknown policies."""
    if residue not in RESIDUE_POLICIES:
        raise ConfigError(f'residue must be one of {RESIDUE_POLICIES}, got {residue!r}')
    return residue == 'half'


def _reversal_mask(y, direction):
    """
    Find the reversals of a block of samples given the direction the load was moving in.

    Parameters
    ----------
    y : numpy.ndarray, shape (n_ch, m + 1)
        The sample preceding the block, then the block's m samples.
    direction : numpy.ndarray, shape (n_ch,), int8
        Sign of the last non-zero step before the block (0: no movement yet).

    Returns
    -------
    mask : numpy.ndarray, shape (n_ch, m), bool
        ``mask[c, j]`` is True when ``y[c, j]`` is a reversal.  The block's last sample is never
        one yet: it needs the next sample to be confirmed.
    direction : numpy.ndarray, shape (n_ch,), int8
        Direction after the block.

    """
    step = np.sign(np.diff(y, axis=1)).astype(np.int8)
    signs = np.concatenate([direction[:, np.newaxis], step], axis=1)
    # Forward-fill the last non-zero sign so plateaus (zero steps) keep the direction they
    # interrupt: a peak followed by a flat top is still one peak.
    last_moving = np.where(signs != 0, np.arange(signs.shape[1], dtype=np.int32), 0)
    np.maximum.accumulate(last_moving, axis=1, out=last_moving)
    held = np.take_along_axis(signs, last_moving, axis=1)
    return step * held[:, :-1] < 0, held[:, -1].copy()


@njit(cache=True)
def _push_point(stack, n, value, sn_slope, cycles, n_cycles, record):
    """
    Push one turning point on a four-point rainflow stack and close the cycles it closes.

    Returns the new stack size, the new number of recorded cycles and the damage
    ``sum(range**sn_slope)`` of the cycles closed by this point.
    """
    stack[n] = value
    n += 1
    damage = 0.0
    while n >= 4:
        inner = abs(stack[n - 3] - stack[n - 2])
        if inner > abs(stack[n - 4] - stack[n - 3]) or inner > abs(stack[n - 2] - stack[n - 1]):
            break
        damage += inner ** sn_slope
        if record:
            cycles[0, n_cycles] = inner
            cycles[1, n_cycles] = 0.5 * (stack[n - 3] + stack[n - 2])
            n_cycles += 1
        stack[n - 3] = stack[n - 1]
        n -= 2
    return n, n_cycles, damage


@njit(cache=True)
def _push_channels(values, offsets, stacks, n_stack, closed, sn_slope):
    """Push each channel's turning points ``values[offsets[c]:offsets[c + 1]]`` on its stack."""
    no_cycles = np.empty((2, 0))
    for ch in range(n_stack.shape[0]):
        n = n_stack[ch]
        for i in range(offsets[ch], offsets[ch + 1]):
            n, _, damage = _push_point(stacks[ch], n, values[i], sn_slope, no_cycles, 0, False)
            closed[ch] += damage
        n_stack[ch] = n


@njit(cache=True)
def _count_points(points, stack, cycles):
    """Rainflow-count a whole turning-point sequence; returns (stack size, closed cycles)."""
    n = 0
    n_cycles = 0
    for i in range(points.shape[0]):
        n, n_cycles, _ = _push_point(stack, n, points[i], 1.0, cycles, n_cycles, True)
    return n, n_cycles


@njit(cache=True)
def _total_damage(stacks, n_stack, last, closed, sn_slope, half):
    """Damage so far: closed cycles, cycles the last sample closes, residue if ``half``."""
    out = closed.copy()
    no_cycles = np.empty((2, 0))
    for ch in range(n_stack.shape[0]):
        n = n_stack[ch]
        if n < 2:
            # Only the first sample on the stack: no reversal yet, no cycle.
            continue
        # The last sample ends the record: push it on a scratch copy so the live stack stays
        # open for the samples still to come.
        scratch = np.empty(n + 1)
        scratch[:n] = stacks[ch, :n]
        n, _, damage = _push_point(scratch, n, last[ch], sn_slope, no_cycles, 0, False)
        out[ch] += damage
        if half:
            residue = 0.0
            for i in range(n - 1):
                residue += abs(scratch[i + 1] - scratch[i]) ** sn_slope
            out[ch] += 0.5 * residue
    return out


def _as_channel(x, name):
    """Return ``x`` as a finite 1-D float64 array (any length)."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 1:
        raise ShapeError(f'{name}: expected one channel (1-D), got shape {arr.shape}')
    return as_signals(arr, name, min_samples=0)[0]


def turning_points(x) -> np.ndarray:
    """
    Return the turning points (reversals plus both ends) of one channel.

    Parameters
    ----------
    x : array_like, shape (n_samples,)
        Load history, any unit.

    Returns
    -------
    numpy.ndarray, shape (n_points,), float64
        ``x[0]``, every sample where the load direction reverses (one sample per flat
        peak/valley), and ``x[-1]``.  Empty when ``x`` has no reversal at all (empty, a single
        sample, constant or monotonic): such a history has no cycles.

    Raises
    ------
    ShapeError
        ``x`` is not 1-D.
    NonFiniteError
        ``x`` contains NaN or infinity (sample named).

    """
    x = _as_channel(x, 'rainflow input')
    direction = np.zeros(1, dtype=np.int8)
    found = []
    for start in range(0, x.size, _BLOCK_SAMPLES):
        prev = x[max(start - 1, 0):max(start, 1)]
        y = np.concatenate([prev, x[start:start + _BLOCK_SAMPLES]])[np.newaxis, :]
        mask, direction = _reversal_mask(y, direction)
        found.append(y[0, :-1][mask[0]])
    reversals = np.concatenate(found) if found else np.empty(0)
    if reversals.size == 0:
        return reversals
    return np.concatenate([x[:1], reversals, x[-1:]])


def rainflow(x, residue: str = 'half') -> RainflowCycles:
    """
    Rainflow-count one channel (ASTM E1049-85 section 5.4.4).

    Parameters
    ----------
    x : array_like, shape (n_samples,)
        Load history, any unit (ranges and means come out in the same unit).
    residue : {'half', 'none'}
        ``'half'``: each range left on the stack at the end counts as a half cycle (ASTM);
        ``'none'``: only closed cycles are returned.

    Returns
    -------
    RainflowCycles
        Empty arrays when ``x`` has no reversal.

    Raises
    ------
    ShapeError
        ``x`` is not 1-D.
    NonFiniteError
        ``x`` contains NaN or infinity.
    ConfigError
        Unknown ``residue`` policy.

    """
    half = _check_residue(residue)
    points = turning_points(x)
    stack = np.empty(points.size)
    cycles = np.empty((2, points.size // 2))
    n_stack, n_closed = _count_points(points, stack, cycles)
    ranges = [cycles[0, :n_closed]]
    means = [cycles[1, :n_closed]]
    counts = [np.ones(n_closed)]
    if half and n_stack >= 2:
        rest = stack[:n_stack]
        ranges.append(np.abs(np.diff(rest)))
        means.append(0.5 * (rest[1:] + rest[:-1]))
        counts.append(np.full(n_stack - 1, 0.5))
    return RainflowCycles(np.concatenate(ranges), np.concatenate(means), np.concatenate(counts))


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
        Residue policy, see :func:`rainflow`.

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
        self._half = _check_residue(residue)
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
        for first in range(0, chunk.shape[1], _BLOCK_SAMPLES):
            self._update_valid(chunk[:, first:first + _BLOCK_SAMPLES])

    def _update_valid(self, block):
        """Consume a validated, non-empty block of at most ``_BLOCK_SAMPLES`` samples."""
        if self._n_samples == 0:
            # The first sample opens the record: it starts every channel's stack.
            self._last = block[:, 0].copy()
            self._stacks[:, 0] = self._last
            self._n_stack[:] = 1
        y = np.concatenate([self._last[:, np.newaxis], block], axis=1)
        mask, self._direction = _reversal_mask(y, self._direction)
        rows, cols = np.nonzero(mask)
        values = y[rows, cols]
        offsets = np.zeros(self._n_channels + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=self._n_channels), out=offsets[1:])
        needed = int((self._n_stack + np.diff(offsets)).max())
        if needed > self._stacks.shape[1]:
            grown = np.empty((self._n_channels, max(needed, 2 * self._stacks.shape[1])))
            grown[:, :self._stacks.shape[1]] = self._stacks
            self._stacks = grown
        _push_channels(values, offsets, self._stacks, self._n_stack, self._closed,
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
        return _total_damage(self._stacks, self._n_stack, self._last, self._closed,
                             self._sn_slope, self._half)


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
        Residue policy, see :func:`rainflow`.

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
    _check_residue(residue)
    if x.shape[0] == 0:
        return np.zeros(0)
    stream = StreamingDamage(x.shape[0], sn_slope, residue)
    for first in range(0, x.shape[1], _BLOCK_SAMPLES):
        stream._update_valid(x[:, first:first + _BLOCK_SAMPLES])
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
        Residue policy, see :func:`rainflow`.

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
    _check_residue(residue)
    bands = _check_bands(damage_bands_hz(fs_hz) if bands_hz is None else bands_hz, fs_hz)
    out = np.zeros((x.shape[0], len(bands)))
    if x.shape[1] == 0:
        return out
    filters = []
    for lo, hi in bands:
        if lo == 0.0:
            sos = signal.butter(_BAND_FILTER_ORDER, hi, btype='lowpass', fs=fs_hz, output='sos')
        else:
            sos = signal.butter(_BAND_FILTER_ORDER, (lo, hi), btype='bandpass', fs=fs_hz,
                                output='sos')
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
