# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Derived inputs: quantities a model takes that no sensor records as such.

**Spin acceleration** (issue 33), from the recorded spin rate.  A model does not take the spin
*rate* itself: it holds the vehicle speed (tens of rad/s
changing over tens of seconds), whose power leaks through the Welch window's side lobes into
every frequency line and buries the spin dynamics there (measured: the held-out 1 Hz
high-passed RMSE of ``Fy`` tripled with the rate as an input).  Its time derivative, the spin
acceleration, is what the physics needs (``My`` = tyre moment - outboard spin inertia x spin
acceleration) and has no such slow content.

The derivative is taken per gap-free segment on the sample stamps with ``numpy.gradient``'s
formulas: second-order central differences on unequal steps inside, first-order one-sided
differences at the two ends.  Nothing is filled in, a gap is never differentiated across
(the same gap rules as every other channel: segments end at gaps).  The steps are taken from
the integer stamps (``(stamp[k + 1] - stamp[k]) * 1e-9`` s), not from float times, so the
result does not depend on where the segment starts.

One engine, two callers: :func:`spin_acceleration` on a whole segment (offline) and
:class:`SpinAccelerationStream` on chunks as they arrive (the live node).  Sample ``k`` needs
sample ``k + 1``, so the stream gives each value one sample late and the last one when the
segment ends; its values equal :func:`spin_acceleration` of the concatenation bit for bit.

**Traction/braking split** (issue 29), from the 12 spindle accelerations.  A wheel's
longitudinal force is not one linear function of the car's longitudinal specific force
``f_x``: braking loads all four wheels in the brake balance's ratio, traction only the driven
ones, so each wheel's quasi-static ``Fx`` is piecewise linear in ``f_x`` with a kink at zero.
No linear model (the paper's H1, a least-squares FIR) holds that kink.  Two derived inputs
let the linear fit learn the two slopes: ``f_x`` = the mean of the four spindle ``ax``
through a causal 2nd-order Butterworth low-pass at :data:`SPLIT_LOW_PASS_HZ` (2 Hz: driver-made
braking and traction, not the road's vibration), then its positive part (traction) and its
negative part (braking) [m/s²].  The fit offers them to every output row as one more nested
input set, and each row takes them only when the blocked cross-validation says so
(docs/fit_design.md).  Per gap-free segment the filter starts in the steady state of the
segment's first sample (nothing invented before the record, no start transient);
:class:`SpecificForceParts` carries its state across chunks, so chunked == batch, and is
restarted where the stream breaks, as the offline reader starts a new segment.

**Cornering split** (issue 29), the same for the lateral specific force ``f_y`` (the mean of
the four spindle ``ay`` through the same low-pass): a tyre's lateral force grows with its
vertical load, and in a turn the load moves to the outer wheels, so each wheel's
quasi-static ``Fy`` is close to ``a f_y + b s f_y |f_y|`` (``s`` = +1 on one side, -1 on the
other): one slope in left turns and another in right turns.  ``left_turn_ay`` =
``max(f_y, 0)`` (ISO 8855: y to the left) and ``right_turn_ay`` = ``min(f_y, 0)`` let the
linear fit learn both.  Offered after the traction/braking split as one more nested input set;
measured on held-out simulated cars (docs/fit_design.md), the ``Fy`` rows take it.

Both splits are :class:`SpecificForceParts` (and :func:`specific_force_parts` of a whole
segment): any of the four parts by name, each axis filtered once.
"""
from typing import Sequence, Tuple

import numpy as np

from wheel_force_estimator import CORNERING_CHANNELS
from wheel_force_estimator import SPLIT_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError

_S_PER_NS = 1e-9


def _central(f: np.ndarray, stamp_ns: np.ndarray) -> np.ndarray:
    """Return the central differences at samples ``1 .. n-2`` (numpy.gradient's, unequal steps)."""
    dx = np.diff(stamp_ns) * _S_PER_NS
    dx1, dx2 = dx[:-1], dx[1:]
    a = -dx2 / (dx1 * (dx1 + dx2))
    b = (dx2 - dx1) / (dx1 * dx2)
    c = dx1 / (dx2 * (dx1 + dx2))
    return a * f[:, :-2] + b * f[:, 1:-1] + c * f[:, 2:]


def _one_sided(f: np.ndarray, stamp_ns: np.ndarray) -> np.ndarray:
    """Return ``(f[1] - f[0]) / dt`` of two samples, shape (n_ch, 1)."""
    return (f[:, 1:2] - f[:, 0:1]) / ((stamp_ns[1] - stamp_ns[0]) * _S_PER_NS)


def spin_acceleration(spin_radps, stamp_ns) -> np.ndarray:
    """
    Return the spin acceleration of one gap-free segment.

    Parameters
    ----------
    spin_radps : numpy.ndarray, shape (n_ch, n)
        Spin rates [rad/s].
    stamp_ns : numpy.ndarray, shape (n,), int64
        Their stamps [ns], strictly increasing, ``n >= 2``.

    Returns
    -------
    numpy.ndarray, shape (n_ch, n)
        d(spin)/dt [rad/s²].

    Raises
    ------
    ShapeError
        Fewer than 2 samples or mismatched shapes.

    """
    spin = np.asarray(spin_radps, dtype=np.float64)
    stamps = np.asarray(stamp_ns, dtype=np.int64)
    if spin.ndim != 2 or stamps.ndim != 1 or spin.shape[1] != stamps.size or stamps.size < 2:
        raise ShapeError(f'spin_acceleration: spin {spin.shape} and stamps {stamps.shape}: '
                         'need (n_ch, n) and (n,) with n >= 2')
    return np.concatenate([_one_sided(spin[:, :2], stamps[:2]), _central(spin, stamps),
                           _one_sided(spin[:, -2:], stamps[-2:])], axis=1)


class SpinAccelerationStream:
    """
    :func:`spin_acceleration` of a segment that arrives in chunks, one sample late.

    The samples carry other rows along (the accelerations of the same stamps): rows
    ``spin_rows`` are spin rates [rad/s] and leave as their derivative [rad/s²], the others
    leave unchanged, each column once its derivative is known, so a consumer gets whole,
    coherent samples.  :meth:`push` holds back the newest sample (its central difference
    needs the next one); :meth:`finish` ends the segment (a gap, the end of the data) and
    releases it with the one-sided difference.  Values equal :func:`spin_acceleration` of
    the whole segment exactly, for any chunking.

    Parameters
    ----------
    n_rows : int
        Rows per sample.
    spin_rows : sequence of int
        Rows holding spin rates, ``0 <= row < n_rows``.

    Raises
    ------
    ShapeError
        Bad row indices.

    """

    def __init__(self, n_rows: int, spin_rows: Sequence[int]):
        rows = np.asarray(spin_rows, dtype=np.int64).reshape(-1)
        if n_rows < 1 or rows.size == 0 or rows.min() < 0 or rows.max() >= n_rows \
                or np.unique(rows).size != rows.size:
            raise ShapeError(f'spin stream: spin rows {rows.tolist()} must be distinct rows '
                             f'of the {n_rows} per sample')
        self._n_rows = int(n_rows)
        self._rows = rows
        self.reset()

    def reset(self) -> None:
        """Forget the segment in progress (its held sample is lost: call :meth:`finish`)."""
        self._stamps = np.empty(0, dtype=np.int64)     # the last <= 2 samples seen
        self._x = np.empty((self._n_rows, 0))
        self._released = 0                             # samples of the segment released

    @property
    def held(self) -> int:
        """Return the number of samples received whose value is not released yet (0 or 1)."""
        return int(self._stamps.size > 0)

    def push(self, stamp_ns, x) -> Tuple[np.ndarray, np.ndarray]:
        """
        Add the next samples of the segment; return those now complete.

        Parameters
        ----------
        stamp_ns : array_like, shape (m,), int
            Stamps, increasing, continuing the segment [ns].
        x : array_like, shape (n_rows, m)
            Samples; the spin rows in rad/s.

        Returns
        -------
        stamp_ns : numpy.ndarray, shape (k,), int64
            Stamps of the released samples (``k = m`` or ``m - 1`` at the segment start).
        x : numpy.ndarray, shape (n_rows, k)
            The samples with their spin rows replaced by the spin acceleration [rad/s²].

        Raises
        ------
        ShapeError
            Mismatched shapes.

        """
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        x = np.asarray(x, dtype=np.float64)
        if stamps.ndim != 1 or x.shape != (self._n_rows, stamps.size):
            raise ShapeError(f'spin stream: {stamps.shape} stamps with samples {x.shape}, '
                             f'expected ({self._n_rows}, {stamps.size})')
        if stamps.size == 0:
            return stamps, x[:, :0]
        # the window: up to two samples already seen (the one before the held one and the
        # held one), then the new ones
        win_t = np.concatenate([self._stamps, stamps])
        win_x = np.concatenate([self._x, x], axis=1)
        spin = win_x[self._rows]
        out_x, out_t = [], []
        lo = win_t.size - stamps.size - self.held   # first column to release
        if self._released == 0 and win_t.size >= 2:
            first = win_x[:, :1].copy()
            first[self._rows] = _one_sided(spin[:, :2], win_t[:2])
            out_x.append(first)
            out_t.append(win_t[:1])
            lo += 1
        if win_t.size >= 3:
            inner = win_x[:, 1:-1].copy()
            inner[self._rows] = _central(spin, win_t)
            skip = lo - 1          # inner column j is window column j + 1
            out_x.append(inner[:, skip:])
            out_t.append(win_t[1:-1][skip:])
        keep = min(2, win_t.size)
        self._stamps, self._x = win_t[-keep:], win_x[:, -keep:]
        if not out_t:
            return np.empty(0, dtype=np.int64), np.empty((self._n_rows, 0))
        released_t = np.concatenate(out_t)
        self._released += released_t.size
        return released_t, np.concatenate(out_x, axis=1)

    def finish(self) -> Tuple[np.ndarray, np.ndarray]:
        """
        End the segment: return its held last sample (one-sided difference), then reset.

        A segment of one sample has no derivative: nothing is returned for it (the offline
        reader keeps no segment under 2 samples either).

        Returns
        -------
        stamp_ns : numpy.ndarray, shape (k,), int64
            ``k = 1``, or 0 when nothing was held or the segment had one sample.
        x : numpy.ndarray, shape (n_rows, k)

        """
        t, x = self._stamps, self._x
        self.reset()
        if t.size < 2:
            return np.empty(0, dtype=np.int64), np.empty((self._n_rows, 0))
        last = x[:, -1:].copy()
        last[self._rows] = _one_sided(x[self._rows][:, -2:], t[-2:])
        return t[-1:].copy(), last


#: Low-pass corner of the longitudinal specific force the split is taken from [Hz].  Driver
#: inputs (braking, traction) live below it, the road's vibration above.  Its lag matters to
#: the live estimator, which cannot look ahead to undo it: the 2nd-order Butterworth delays
#: slow content by sqrt(2) / (2 pi fc), 0.23 s at 1 Hz, 0.11 s at 2 Hz.  Measured
#: (2026-11-28, shipped defaults, 5 min of the course at seed 3 -> seed 4, x offline / live at
#: 50 ms): 1 Hz compact 8.0 / 9.0, SUV 5.8 / 6.6, van 7.8 / 9.9 % (live 1.27x offline on the
#: van); 2 Hz 7.9 / 8.6, 5.8 / 6.4, 7.7 / 9.1 %.  On 2-minute courses 0.5 / 1 / 2 Hz gave x
#: within 1.7 points of each other, 2 Hz the lowest or tied on every car (bench_split.py).
SPLIT_LOW_PASS_HZ = 2.0
#: Butterworth order of that low-pass.
SPLIT_FILTER_ORDER = 2
#: The inputs derived from the 12 accelerations, in the order a model declares them: name ->
#: (axis of the mean specific force: 0 = x, 1 = y, its part: +1 positive, -1 negative).
ACCEL_PARTS = {SPLIT_CHANNELS[0]: (0, 1), SPLIT_CHANNELS[1]: (0, -1),
               CORNERING_CHANNELS[0]: (1, 1), CORNERING_CHANNELS[1]: (1, -1)}
#: Every such input, in that order.
ACCEL_DERIVED_CHANNELS = tuple(ACCEL_PARTS)


def accel_derived_count(input_channels) -> int:
    """Return how many of a model's last inputs are derived from its accelerations."""
    names = tuple(input_channels)
    n = 0
    while n < len(names) and names[len(names) - 1 - n] in ACCEL_PARTS:
        n += 1
    return n


def specific_force_parts(accel_mps2, fs_hz: float, names=SPLIT_CHANNELS) -> np.ndarray:
    """
    Return the parts ``names`` of one gap-free segment's low-passed specific force.

    Parameters
    ----------
    accel_mps2 : numpy.ndarray, shape (n_rows >= 12, n)
        The 12 spindle accelerations [m/s²] first (package order), any rows after them.
    fs_hz : float
        Sample rate [Hz].
    names : sequence of str
        Among :data:`ACCEL_DERIVED_CHANNELS`: ``traction_ax`` ``max(f_x, 0)``,
        ``braking_ax`` ``min(f_x, 0)``, ``left_turn_ay`` ``max(f_y, 0)``, ``right_turn_ay``
        ``min(f_y, 0)``.

    Returns
    -------
    numpy.ndarray, shape (len(names), n)
        The parts [m/s²], in the order of ``names``.

    Raises
    ------
    ConfigError
        An unknown name, or a sample rate with the low-pass corner at or above Nyquist.
    ShapeError
        Fewer than 12 rows.

    """
    return SpecificForceParts(fs_hz, names).push(accel_mps2)


def traction_braking(accel_mps2, fs_hz: float) -> np.ndarray:
    """Return the traction/braking split ``(max(f_x, 0), min(f_x, 0))`` (module notes)."""
    return specific_force_parts(accel_mps2, fs_hz, SPLIT_CHANNELS)


class SpecificForceParts:
    """
    :func:`specific_force_parts` of a segment that arrives in chunks (no delay).

    Causal, so every sample leaves with its chunk; the filter states carry across chunks and
    the values equal :func:`specific_force_parts` of the concatenation.  :meth:`reset` starts
    a new segment.

    Parameters
    ----------
    fs_hz : float
        Sample rate [Hz].
    names : sequence of str
        The parts to return (:func:`specific_force_parts`).

    Raises
    ------
    ConfigError
        An unknown name, or a sample rate with the low-pass corner at or above Nyquist.

    """

    def __init__(self, fs_hz: float, names=SPLIT_CHANNELS):
        self._names = tuple(names)
        unknown = [n for n in self._names if n not in ACCEL_PARTS]
        if unknown:
            raise ConfigError(f'derived inputs {unknown}: not among '
                              f'{list(ACCEL_DERIVED_CHANNELS)}')
        if not fs_hz > 2.0 * SPLIT_LOW_PASS_HZ:
            raise ConfigError(f'specific force split {list(self._names)}: sample rate '
                              f'{fs_hz!r} Hz must exceed twice the {SPLIT_LOW_PASS_HZ:g} Hz '
                              'low-pass corner')
        # imported here: scipy.signal costs ~0.7 s at import, and the bag reader imports this
        # module, so every CLI command (``--help`` included) paid it before its first line
        import scipy.signal
        self._sosfilt = scipy.signal.sosfilt
        self._sos = scipy.signal.butter(SPLIT_FILTER_ORDER, SPLIT_LOW_PASS_HZ, fs=fs_hz,
                                        output='sos')
        self._zi_unit = scipy.signal.sosfilt_zi(self._sos)
        # the axes filtered, each once however many of its parts are asked for
        self._axes = tuple(sorted({ACCEL_PARTS[n][0] for n in self._names}))
        self.reset()

    def reset(self) -> None:
        """Start a new segment: its first sample sets the filters' steady state."""
        self._zi = dict.fromkeys(self._axes)

    def push(self, accel_mps2) -> np.ndarray:
        """
        Return the parts of the next samples of the segment.

        Parameters
        ----------
        accel_mps2 : array_like, shape (n_rows >= 12, m)
            The 12 spindle accelerations [m/s²] first, any rows after them.

        Returns
        -------
        numpy.ndarray, shape (len(names), m)
            The parts [m/s²], in the order of ``names``.

        Raises
        ------
        ShapeError
            Fewer than 12 rows.

        """
        x = np.asarray(accel_mps2, dtype=np.float64)
        if x.ndim != 2 or x.shape[0] < 12:
            raise ShapeError(f'specific force split {list(self._names)}: samples {x.shape} '
                             'need the 12 spindle accelerations as their first rows')
        if x.shape[1] == 0:
            return np.empty((len(self._names), 0))
        force = {}
        for axis in self._axes:
            mean = x[axis:12:3].mean(axis=0)
            if self._zi[axis] is None:
                self._zi[axis] = self._zi_unit * mean[0]
            force[axis], self._zi[axis] = self._sosfilt(self._sos, mean, zi=self._zi[axis])
        rows = []
        for name in self._names:
            axis, sign = ACCEL_PARTS[name]
            rows.append(np.maximum(force[axis], 0.0) if sign > 0
                        else np.minimum(force[axis], 0.0))
        return np.vstack(rows)
