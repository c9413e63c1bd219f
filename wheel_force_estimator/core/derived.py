# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Derived inputs: the wheel spin acceleration from the recorded spin rate (issue 33).

A model does not take the spin *rate* itself: it holds the vehicle speed (tens of rad/s
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
"""
from typing import Sequence, Tuple

import numpy as np

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
