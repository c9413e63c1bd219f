# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Align the four corner streams on ``header.stamp`` (pure numpy; no ROS).

Each corner's Imu messages arrive on their own topic, independently of the others: in bursts,
out of order *across* topics.  Within one topic DDS delivers the samples of one writer in
order, so each corner's stamps increase; the aligner relies on that and on nothing else.

Rules
-----
* A sample is **complete** when every corner has delivered a message with exactly that stamp.
  Complete samples are released in stamp order.
* When stamp ``s`` completes, every pending stamp below ``s`` is incomplete for good (the
  corner missing it has already moved past it) and is dropped: ``incomplete``.
* At most ``max_pending`` samples wait per corner (a silent corner must not grow memory
  without bound); beyond that the oldest are dropped as ``incomplete``.
* A message whose stamp equals the corner's previous one is a ``duplicate``; one at or below
  the last released/dropped stamp is ``late``.  Both are dropped.
* A stamp **below** the corner's previous one (a bag restarted or looped) starts a new epoch.
  The epoch change completes when every corner has jumped back, so a clean loop loses no
  sample: until then the old epoch keeps aligning, the jumped corners' new samples wait.  Then
  what is left of the old epoch is dropped (``incomplete``), a :class:`StampJump` is emitted and
  the new epoch aligns.  A corner that jumps alone (its clock reset) forces the change once its
  new samples exceed ``max_pending``; the other corners then continue in the new epoch.

Every message pushed is accounted for once: ``received == aligned + duplicate + late +
incomplete + pending`` per corner (:meth:`CornerAligner.counters`).
"""
from dataclasses import dataclass
from typing import Dict, List, Optional, Union

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError

#: Per-corner counters kept by :class:`CornerAligner` (messages).
COUNTER_NAMES = ('received', 'aligned', 'duplicate', 'late', 'incomplete')


@dataclass(frozen=True, eq=False)
class AlignedSamples:
    """
    Complete samples, in increasing stamp order.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (m,), int64
        Common ``header.stamp`` [ns].
    accel_mps2 : numpy.ndarray, shape (3 * n_corners, m)
        Corner-major values (lf x y z, rf x y z, ...) [m/s²].

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


AlignerEvent = Union[AlignedSamples, StampJump]


class _Buffer:
    """Pending samples of one corner: increasing stamps and their values."""

    def __init__(self, n_values: int):
        self.stamps = np.empty(0, dtype=np.int64)
        self.values = np.empty((n_values, 0))

    def __len__(self) -> int:
        return self.stamps.size

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
    n_values : int
        Values per message (3: acceleration x, y, z).
    max_pending : int
        Samples a corner may hold while waiting for the others, >= 1.

    Raises
    ------
    ConfigError
        On a non-positive size.

    """

    def __init__(self, n_corners: int = 4, n_values: int = 3, max_pending: int = 1024):
        for name, value in (('n_corners', n_corners), ('n_values', n_values),
                            ('max_pending', max_pending)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ConfigError(f'aligner: {name} must be an integer >= 1, got {value!r}')
        self._n = int(n_corners)
        self._n_values = int(n_values)
        self._max_pending = int(max_pending)
        self._counts = {name: np.zeros(self._n, dtype=np.int64) for name in COUNTER_NAMES}
        self.reset()

    def reset(self):
        """Forget all pending samples and stamps (counters are kept)."""
        n = self._n
        self._cur = [_Buffer(self._n_values) for _ in range(n)]
        self._nxt = [_Buffer(self._n_values) for _ in range(n)]
        self._jumped = np.zeros(n, dtype=bool)
        self._last: List[Optional[int]] = [None] * n       # last accepted stamp per corner
        self._floor: Optional[int] = None   # stamps <= floor are decided in this epoch
        self._jump_stamp: Optional[int] = None
        self._events: List[AlignerEvent] = []

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
        accel : array_like, shape (n_values, m)
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
        if stamps.ndim != 1 or values.shape != (self._n_values, stamps.size):
            raise ShapeError(f'aligner: corner {corner}: {stamps.shape} stamps with values '
                             f'{values.shape}, expected ({self._n_values}, {stamps.size})')
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
            late = fresh & (run <= self._floor)
            self._counts['late'][corner] += int(late.sum())
            fresh &= ~late
        self._cur[corner].append(run[fresh], vals[:, fresh])
        self._last[corner] = int(run[-1])

    def _release(self):
        """Emit the complete samples of the current epoch; drop what can no longer complete."""
        first = self._cur[0].stamps
        if all(np.array_equal(first, buf.stamps) for buf in self._cur[1:]):
            # The usual case: every corner delivered the same stamps.
            if first.size:
                values = np.concatenate([buf.values for buf in self._cur], axis=0)
                self._counts['aligned'] += first.size
                self._events.append(AlignedSamples(first, values))
                self._floor = int(first[-1])
                for buf in self._cur:
                    buf.keep(np.zeros(first.size, dtype=bool))
            return
        common = first
        for buf in self._cur[1:]:
            if common.size == 0:
                break
            common = np.intersect1d(common, buf.stamps, assume_unique=True)
        if common.size:
            top = int(common[-1])
            parts = []
            for c, buf in enumerate(self._cur):
                done = buf.stamps <= top
                hit = np.isin(buf.stamps, common, assume_unique=True)
                parts.append(buf.values[:, hit])
                self._counts['aligned'][c] += common.size
                self._counts['incomplete'][c] += int(done.sum()) - common.size
                buf.keep(~done)
            self._events.append(AlignedSamples(common, np.concatenate(parts, axis=0)))
            self._floor = top
        longest = max(len(buf) for buf in self._cur)
        if longest > self._max_pending:
            cut = max(int(buf.stamps[len(buf) - self._max_pending - 1])
                      for buf in self._cur if len(buf) > self._max_pending)
            self._drop_through(cut)

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
        self._cur = [self._nxt[c] if jumped[c] else _Buffer(self._n_values)
                     for c in range(self._n)]
        self._nxt = [_Buffer(self._n_values) for _ in range(self._n)]
        for c in np.flatnonzero(~jumped):
            # Forced change: this corner never went back; its next stamp starts afresh.
            self._last[c] = None
        self._jumped[:] = False
        self._jump_stamp = None
        self._floor = None
