# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Align the four corner streams on ``header.stamp`` (pure numpy; no ROS).

Each corner's Imu messages arrive on their own topic, independently of the others: in bursts,
out of order *across* topics.  Within one topic DDS delivers the samples of one writer in
order, so each corner's stamps increase; the aligner relies on that and on nothing else.

A "corner" below is any input stream: a model with wheel spin inputs adds a fifth, the
``{corner}_wheel`` velocities of the JointState topic, aligned by the same rules as the four
Imu topics (its stamps take part in the median); each stream has its own number of values.

Rules
-----
* A sample is **complete** when every corner has delivered one message and the stamps of these
  messages lie within ``tolerance_ns`` of each other (largest minus smallest).  Four IMU
  drivers, or IMUs stamped by the host on arrival, never give equal stamps; with a tolerance of
  zero the stamps must be equal.  The complete sample is stamped with the **median** of its
  corner stamps (exact, in integer ns: the mean of the two middle ones for four corners), so
  one late or early corner does not move it, and equal stamps give that stamp.  Complete
  samples are released in stamp order.
* A pending stamp more than ``tolerance_ns`` older than another corner's oldest pending stamp
  can no longer complete (that corner has moved past it; each corner's stamps increase) and is
  dropped.  It is counted ``incomplete`` when the distance to that corner's stamp is a whole
  number of sample periods give or take the tolerance (a sample missing on a corner), else
  ``out_of_tolerance`` (the corners' clocks disagree by more than the tolerance), with the
  distance seen (:class:`OutOfTolerance`).  Never silently merged.
* At most ``max_pending`` samples wait per corner (a silent corner must not grow memory
  without bound); beyond that the oldest are dropped as ``incomplete``.
* A message whose stamp equals the corner's previous one is a ``duplicate``; one older than the
  last released/dropped stamp by more than the tolerance is ``late``.  Both are dropped.
* A stamp **below** the corner's previous one (a bag restarted or looped) starts a new epoch.
  The epoch change completes when every corner has jumped back, so a clean loop loses no
  sample: until then the old epoch keeps aligning, the jumped corners' new samples wait.  Then
  what is left of the old epoch is dropped (``incomplete``), a :class:`StampJump` is emitted and
  the new epoch aligns.  A corner that jumps alone (its clock reset) forces the change once its
  new samples exceed ``max_pending``; the other corners then continue in the new epoch.

Every message pushed is accounted for once: ``received == aligned + duplicate + late +
incomplete + out_of_tolerance + pending`` per corner (:meth:`CornerAligner.counters`).
"""
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError

#: Per-corner counters kept by :class:`CornerAligner` (messages).
COUNTER_NAMES = ('received', 'aligned', 'duplicate', 'late', 'incomplete', 'out_of_tolerance')


@dataclass(frozen=True, eq=False)
class AlignedSamples:
    """
    Complete samples, in increasing stamp order.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (m,), int64
        Common ``header.stamp`` [ns].
    accel_mps2 : numpy.ndarray, shape (sum of n_values, m)
        Corner-major values (lf x y z, rf x y z, ...) [m/s²], then those of any further
        stream (the wheel spin rates [rad/s]) in stream order.

    """

    stamp_ns: np.ndarray
    accel_mps2: np.ndarray


@dataclass(frozen=True)
class StampJump:
    """
    The stamps went back: everything before belongs to another epoch (a bag loop).

    Attributes
    ----------
    stamp_ns : int
        First stamp of the new epoch seen from the first corner that jumped [ns].

    """

    stamp_ns: int


@dataclass(frozen=True)
class OutOfTolerance:
    """
    Messages of one corner dropped because no other corner had a stamp close enough.

    Attributes
    ----------
    corner : int
        Corner index.
    n_messages : int
        Messages dropped (in one :meth:`CornerAligner.drain`).
    first_stamp_ns : int
        Stamp of the first of them [ns].
    offset_ns : int
        Largest distance seen to the other corner's stamp, minus the whole sample periods
        in it [ns]; above the tolerance by definition.

    """

    corner: int
    n_messages: int
    first_stamp_ns: int
    offset_ns: int


AlignerEvent = Union[AlignedSamples, StampJump, OutOfTolerance]


class _Buffer:
    """Pending samples of one corner: increasing stamps and their values."""

    def __init__(self, n_values: int):
        self.stamps = np.empty(0, dtype=np.int64)
        self.values = np.empty((n_values, 0))

    def __len__(self) -> int:
        return self.stamps.size

    def drop_head(self, n: int):
        self.stamps = self.stamps[n:]
        self.values = self.values[:, n:]

    def append(self, stamps: np.ndarray, values: np.ndarray):
        if self.stamps.size:
            self.stamps = np.concatenate([self.stamps, stamps])
            self.values = np.concatenate([self.values, values], axis=1)
        else:
            self.stamps, self.values = stamps, values

    def keep(self, mask: np.ndarray):
        self.stamps = self.stamps[mask]
        self.values = self.values[:, mask]


class CornerAligner:
    """
    Stamp alignment of ``n_corners`` independent streams (see the module notes).

    Parameters
    ----------
    n_corners : int
        Number of streams (4 for a car).
    n_values : int or sequence of int
        Values per message (3: acceleration x, y, z), or one count per stream (the Imu
        corners and a JointState stream of the four wheel spin rates: ``(3, 3, 3, 3, 4)``).
    max_pending : int
        Samples a corner may hold while waiting for the others, >= 1.
    tolerance_ns : int
        Corner stamps at most this far apart are one sample, >= 0 [ns].
    period_ns : float, optional
        Sample period [ns]: tells a missing sample (``incomplete``) from a clock offset
        (``out_of_tolerance``).  ``None``: every drop is ``incomplete``.

    Raises
    ------
    ConfigError
        On a non-positive size, a negative tolerance, or a tolerance of half a period or more
        (two samples of one corner could then be one sample).

    """

    def __init__(self, n_corners: int = 4, n_values: Union[int, Sequence[int]] = 3,
                 max_pending: int = 1024, tolerance_ns: int = 0,
                 period_ns: Optional[float] = None):
        def check(name, value):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ConfigError(f'aligner: {name} must be an integer >= 1, got {value!r}')
        check('n_corners', n_corners)
        check('max_pending', max_pending)
        per_stream = (tuple(n_values) if isinstance(n_values, (tuple, list))
                      else (n_values,) * int(n_corners))
        if len(per_stream) != n_corners:
            raise ConfigError(f'aligner: {len(per_stream)} value counts n_values for '
                              f'{n_corners} streams')
        for value in per_stream:
            check('n_values', value)
        if not tolerance_ns >= 0:
            raise ConfigError(f'aligner: tolerance_ns must be >= 0, got {tolerance_ns!r}')
        if period_ns is not None and not (period_ns > 0 and 2 * tolerance_ns <= period_ns):
            raise ConfigError(f'aligner: tolerance {tolerance_ns} ns must be at most half the '
                              f'sample period ({period_ns:g} ns)')
        self._tol = int(tolerance_ns)
        self._period_ns = period_ns
        self._n = int(n_corners)
        self._n_values = tuple(int(v) for v in per_stream)
        self._max_pending = int(max_pending)
        self._counts = {name: np.zeros(self._n, dtype=np.int64) for name in COUNTER_NAMES}
        self.reset()

    def reset(self):
        """Forget all pending samples and stamps (counters are kept)."""
        n = self._n
        self._cur = [_Buffer(v) for v in self._n_values]
        self._nxt = [_Buffer(v) for v in self._n_values]
        self._jumped = np.zeros(n, dtype=bool)
        self._last: List[Optional[int]] = [None] * n       # last accepted stamp per corner
        self._floor: Optional[int] = None   # stamps <= floor - tolerance are decided
        self._jump_stamp: Optional[int] = None
        self._events: List[AlignerEvent] = []
        self._off = [None] * n               # per corner: [count, first stamp, worst offset]

    @property
    def n_corners(self) -> int:
        """Return the number of streams."""
        return self._n

    def counters(self) -> Dict[str, np.ndarray]:
        """Return copies of the per-corner message counts, with ``pending`` (waiting now)."""
        out = {name: value.copy() for name, value in self._counts.items()}
        out['pending'] = np.array([len(self._cur[c]) + len(self._nxt[c])
                                   for c in range(self._n)], dtype=np.int64)
        return out

    def last_stamp_ns(self, corner: int) -> Optional[int]:
        """Return the newest stamp accepted from ``corner`` in its epoch, or ``None``."""
        return self._last[corner]

    @property
    def in_transition(self) -> bool:
        """Tell whether some but not all corners have jumped back (epoch change under way)."""
        return bool(self._jumped.any())

    def push(self, corner: int, stamp_ns, accel) -> None:
        """
        Add the next messages of one corner, in arrival order.

        Parameters
        ----------
        corner : int
            Corner index, ``0 <= corner < n_corners``.
        stamp_ns : array_like, shape (m,), int
            ``header.stamp`` of each message [ns].
        accel : array_like, shape (n_values of the corner, m)
            Values of each message (already checked finite by the caller).

        Raises
        ------
        ShapeError
            Bad corner index or shapes.

        """
        if not 0 <= corner < self._n:
            raise ShapeError(f'aligner: corner index {corner} outside [0, {self._n})')
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        values = np.asarray(accel, dtype=np.float64)
        n_values = self._n_values[corner]
        if stamps.ndim != 1 or values.shape != (n_values, stamps.size):
            raise ShapeError(f'aligner: corner {corner}: {stamps.shape} stamps with values '
                             f'{values.shape}, expected ({n_values}, {stamps.size})')
        if stamps.size == 0:
            return
        self._counts['received'][corner] += stamps.size
        # Split where the stamps go back: each run is non-decreasing.
        back = np.flatnonzero(stamps[1:] < stamps[:-1]) + 1
        bounds = [0, *back.tolist(), stamps.size]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            run, vals = stamps[lo:hi], values[:, lo:hi]
            last = self._last[corner]
            if last is not None and run[0] < last:
                self._start_jump(corner, int(run[0]))
            self._accept(corner, run, vals)

    def drain(self) -> List[AlignerEvent]:
        """
        Align what has been pushed; return the events since the last call, in order.

        Alignment runs here rather than in :meth:`push` so that one call serves a whole burst
        of messages from all corners.
        """
        self._release()
        events, self._events = self._events, []
        return events

    def _start_jump(self, corner: int, stamp_ns: int):
        if self._jumped[corner]:
            # Jumped twice before the others followed once: settle the first change now.
            self._complete_jump()
        if not self._jumped.any():
            self._jump_stamp = stamp_ns
        self._jumped[corner] = True
        self._last[corner] = None

    def _accept(self, corner: int, run: np.ndarray, vals: np.ndarray):
        last = self._last[corner]
        # Non-decreasing run: equal neighbours (or equal to `last`) are duplicates.
        prev = np.concatenate([[last if last is not None else run[0] - 1], run[:-1]])
        fresh = run > prev
        self._counts['duplicate'][corner] += run.size - int(fresh.sum())
        if self._jumped[corner]:
            self._nxt[corner].append(run[fresh], vals[:, fresh])
            self._last[corner] = int(run[-1])
            if self._jumped.all() or len(self._nxt[corner]) > self._max_pending:
                self._complete_jump()
            return
        if self._floor is not None:
            late = fresh & (run <= self._floor - self._tol)
            self._counts['late'][corner] += int(late.sum())
            fresh &= ~late
        self._cur[corner].append(run[fresh], vals[:, fresh])
        self._last[corner] = int(run[-1])

    def _release(self):
        """Emit the complete samples of the current epoch; drop what can no longer complete."""
        bufs = self._cur
        tol = self._tol
        while True:
            n = min(len(buf) for buf in bufs)
            if n == 0:
                break
            heads = np.stack([buf.stamps[:n] for buf in bufs])
            spread = heads.max(axis=0) - heads.min(axis=0)
            bad = np.flatnonzero(spread > tol)
            k = int(bad[0]) if bad.size else n
            if k:
                self._emit(heads[:, :k], k)
            if k == n:
                break
            # The corners' oldest stamps are too far apart: whatever lies more than the
            # tolerance before the newest of them can never complete.
            top = int(heads[:, k].max())
            for c, buf in enumerate(bufs):
                cut = int(np.searchsorted(buf.stamps, top - tol, side='left'))
                if cut:
                    self._count_unmatched(c, buf.stamps[:cut], top)
                    buf.drop_head(cut)
        self._report_offsets()
        longest = max(len(buf) for buf in bufs)
        if longest > self._max_pending:
            cut = max(int(buf.stamps[len(buf) - self._max_pending - 1])
                      for buf in bufs if len(buf) > self._max_pending)
            self._drop_through(cut)

    def _emit(self, heads: np.ndarray, k: int):
        """Release the first ``k`` pending samples of every corner as one block."""
        if self._tol:
            ordered = np.sort(heads, axis=0)
            lo, hi = ordered[(self._n - 1) // 2], ordered[self._n // 2]
            stamps = lo + (hi - lo) // 2          # median in integer ns: no float rounding
        else:
            stamps = heads[0]
        values = np.concatenate([buf.values[:, :k] for buf in self._cur], axis=0)
        for buf in self._cur:
            buf.drop_head(k)
        self._counts['aligned'] += k
        self._events.append(AlignedSamples(stamps.copy(), values))
        top = int(heads[:, -1].max())
        self._floor = top if self._floor is None else max(self._floor, top)

    def _count_unmatched(self, corner: int, dropped: np.ndarray, top_ns: int):
        """Count stamps of ``corner`` that no other corner matched (missing or offset)."""
        if self._period_ns is None:
            self._counts['incomplete'][corner] += dropped.size
            return
        dist = (top_ns - dropped).astype(np.float64)
        rest = np.abs(dist - np.round(dist / self._period_ns) * self._period_ns)
        off = rest > self._tol
        n_off = int(off.sum())
        self._counts['incomplete'][corner] += dropped.size - n_off
        if n_off:
            self._counts['out_of_tolerance'][corner] += n_off
            worst = int(round(rest[off].max()))
            seen = self._off[corner]
            if seen is None:
                self._off[corner] = [n_off, int(dropped[off][0]), worst]
            else:
                seen[0] += n_off
                seen[2] = max(seen[2], worst)

    def _report_offsets(self):
        for c, seen in enumerate(self._off):
            if seen is not None:
                self._events.append(OutOfTolerance(c, *seen))
                self._off[c] = None

    def _drop_through(self, stamp_ns: int):
        """Drop every pending sample of the current epoch stamped <= ``stamp_ns``."""
        for c, buf in enumerate(self._cur):
            done = buf.stamps <= stamp_ns
            self._counts['incomplete'][c] += int(done.sum())
            buf.keep(~done)
        self._floor = stamp_ns if self._floor is None else max(self._floor, stamp_ns)

    def _complete_jump(self):
        """Close the old epoch and continue with the samples of the new one."""
        self._release()
        for c, buf in enumerate(self._cur):
            self._counts['incomplete'][c] += len(buf)
        self._events.append(StampJump(int(self._jump_stamp)))
        jumped = self._jumped.copy()
        self._cur = [self._nxt[c] if jumped[c] else _Buffer(self._n_values[c])
                     for c in range(self._n)]
        self._nxt = [_Buffer(v) for v in self._n_values]
        for c in np.flatnonzero(~jumped):
            # Forced change: this corner never went back; its next stamp starts afresh.
            self._last[c] = None
        self._jumped[:] = False
        self._jump_stamp = None
        self._floor = None
