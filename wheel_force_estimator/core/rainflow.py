# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Rainflow counting (ASTM E1049-85) of load histories, batch and streaming kernels.

Conventions (stated once, used everywhere in this module and in
:mod:`wheel_force_estimator.core.fatigue`):

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

The four-point stack loop is written here by hand instead of taken from a library because the
streaming estimator needs the residue stack as state between blocks, which neither fatpack nor
rainflow exposes (and neither is a dependency).  The loop runs under numba; the turning-point
search is vectorised with numpy.  The streaming kernels add up ``range**k`` of the cycles they
close, for :class:`wheel_force_estimator.core.fatigue.StreamingDamage`.
"""
from dataclasses import dataclass

from numba import njit
import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import as_signals
from wheel_force_estimator.core.validation import read_only_array

RESIDUE_POLICIES = ('half', 'none')

# Samples per internal block: bounds the temporaries of the turning-point search (~25 B per
# sample and channel) whatever the record length; results do not depend on it.
BLOCK_SAMPLES = 1 << 16


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
        """Store read-only float64 arrays (copied unless frozen) after checking they match."""
        arrays = [read_only_array(a, np.float64) for a in (self.ranges, self.means, self.counts)]
        if any(a.ndim != 1 for a in arrays) or len({a.shape for a in arrays}) != 1:
            raise ShapeError(
                'RainflowCycles: ranges, means and counts must be 1-D of equal length, got '
                f'shapes {[a.shape for a in arrays]}')
        for field, arr in zip(('ranges', 'means', 'counts'), arrays):
            object.__setattr__(self, field, arr)


def check_residue(residue) -> bool:
    """Return True when residue half cycles are counted; reject unknown policies."""
    if residue not in RESIDUE_POLICIES:
        raise ConfigError(f'residue must be one of {RESIDUE_POLICIES}, got {residue!r}')
    return residue == 'half'


def reversal_mask(y, direction):
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
def push_channels(values, offsets, stacks, n_stack, closed, sn_slope):
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
def total_damage(stacks, n_stack, last, closed, sn_slope, half):
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
    for start in range(0, x.size, BLOCK_SAMPLES):
        prev = x[max(start - 1, 0):max(start, 1)]
        y = np.concatenate([prev, x[start:start + BLOCK_SAMPLES]])[np.newaxis, :]
        mask, direction = reversal_mask(y, direction)
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
    half = check_residue(residue)
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
