# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live estimation stream behind the node (pure numpy; no ROS).

:class:`ForceStream` takes aligned, stamp-ordered samples and returns stamped forces.  It
owns the same :class:`~wheel_force_estimator.core.predict.Predictor` the offline ``predict``
command uses, the running pseudo damage of what it emits, and the bookkeeping that maps the
filter's lagged output back to input stamps.

Samples are fed to the Predictor in blocks of ``block_size``.  Output sample ``j`` of the
filter stream estimates input sample ``j - delay``; the first ``delay`` outputs after a
(re)start estimate nothing that was received and are discarded.

Discontinuities (each is counted):

* **gap** — consecutive stamps not one sample period apart (within ±25 %, which tolerates
  clock jitter but not another sample rate): the samples in flight are **flushed** (their
  estimates are completed by ``Predictor.flush``, the signal held at its last value, exactly as
  the offline ``predict`` ends a segment) and the filter restarts afresh at the next sample.
  Nothing received is discarded, nothing missing is invented, and each gap-free stretch equals
  the offline prediction of that stretch.
* **stall** — :meth:`ForceStream.flush` called by the node when no sample arrived for a while
  (end of a recording): the same flush, so the last ``delay`` samples are not held forever.
* **jump** — the stamps went back (:meth:`ForceStream.restart`): flush, then the pseudo damage
  starts again from zero as well.
"""
from dataclasses import dataclass
from typing import List, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.fatigue import StreamingDamage
from wheel_force_estimator.core.predict import Predictor

#: Stamp spacing accepted as "one sample period" (fraction of the period either way).
PERIOD_TOLERANCE = 0.25


@dataclass(frozen=True, eq=False)
class StampedForces:
    """
    Estimated forces ready to publish.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (m,), int64
        Stamp of the input sample each column estimates [ns].
    force_n : numpy.ndarray, shape (n_outputs, m)
        Forces in the model's output channel order [N].

    """

    stamp_ns: np.ndarray
    force_n: np.ndarray


class ForceStream:
    """
    Blocks, gap handling and damage around a :class:`Predictor` (see the module notes).

    Parameters
    ----------
    predictor : Predictor
        The streaming estimator (its ``delay_samples`` sets the latency).
    block_size : int
        Samples per ``Predictor.process`` call, >= 1.
    sn_slope : float
        Basquin exponent of the running pseudo damage.

    Raises
    ------
    ConfigError
        On a bad block size or slope.

    """

    def __init__(self, predictor: Predictor, block_size: int, sn_slope: float):
        if isinstance(block_size, bool) or not isinstance(block_size, (int, np.integer)) \
                or block_size < 1:
            raise ConfigError(f'block_size must be an integer >= 1, got {block_size!r}')
        self._predictor = predictor
        self._block = int(block_size)
        self._delay = predictor.delay_samples
        self._n_in = predictor.n_inputs
        self._n_out = len(predictor.model.output_channels)
        self._period_ns = 1e9 / predictor.model.fs_hz
        self._damage = StreamingDamage(self._n_out, sn_slope)
        self.counts = {'samples_in': 0, 'samples_out': 0, 'gaps': 0, 'flushes': 0,
                       'jumps': 0}
        self._last_stamp = None
        self._reset_filter()
        self._out: List[StampedForces] = []

    @property
    def delay_samples(self) -> int:
        """Return the lag of the estimates behind the inputs [samples]."""
        return self._delay

    @property
    def block_size(self) -> int:
        """Return the samples per Predictor call."""
        return self._block

    @property
    def in_flight(self) -> int:
        """Return the number of samples received whose estimate is not emitted yet."""
        return self._n_queued + int(self._fifo.size)

    @property
    def queued(self) -> int:
        """Return the number of samples waiting for their block to fill."""
        return self._n_queued

    def damage(self) -> np.ndarray:
        """Return the pseudo damage of all emitted since start or the last jump, per output."""
        return self._damage.damage()

    def _reset_filter(self):
        self._predictor.reset()
        self._n_fed = 0                                   # filter inputs since restart
        self._fifo = np.empty(0, dtype=np.int64)          # stamps fed, estimate pending
        self._queued: List[np.ndarray] = []               # stamps waiting for a full block
        self._queued_x: List[np.ndarray] = []
        self._n_queued = 0

    def feed(self, stamp_ns, accel_mps2) -> None:
        """
        Add aligned samples (increasing stamps) in the model's input channel order.

        Parameters
        ----------
        stamp_ns : array_like, shape (m,), int
            Sample stamps [ns].
        accel_mps2 : array_like, shape (n_inputs, m)
            Finite accelerations [m/s²].

        Raises
        ------
        ShapeError
            On mismatched shapes.

        """
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        x = np.asarray(accel_mps2, dtype=np.float64)
        if stamps.ndim != 1 or x.shape != (self._n_in, stamps.size):
            raise ShapeError(f'stream: {stamps.shape} stamps with samples {x.shape}, '
                             f'expected ({self._n_in}, {stamps.size})')
        if stamps.size == 0:
            return
        prev = stamps[0] - round(self._period_ns) if self._last_stamp is None \
            else self._last_stamp
        step = np.diff(stamps, prepend=prev)
        breaks = np.flatnonzero(np.abs(step - self._period_ns)
                                > PERIOD_TOLERANCE * self._period_ns)
        starts = [0, *breaks[breaks > 0].tolist()]
        for lo, hi in zip(starts, starts[1:] + [stamps.size]):
            if lo in breaks:
                self.counts['gaps'] += 1
                self.flush()
            self._queue(stamps[lo:hi], x[:, lo:hi])
        self._last_stamp = int(stamps[-1])
        self.counts['samples_in'] += stamps.size

    def flush(self) -> None:
        """Complete the estimates in flight (stall / end of stream); the filter restarts."""
        if self.in_flight:
            self._flush()

    def restart(self) -> None:
        """Stamps went back: flush, then start afresh including the pseudo damage."""
        self.counts['jumps'] += 1
        self.flush()
        self._last_stamp = None
        self._damage.reset()

    def take(self) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return and forget the estimates emitted so far.

        Returns
        -------
        stamp_ns : numpy.ndarray, shape (m,), int64
            Stamps of the estimated input samples [ns], increasing except across a jump.
        force_n : numpy.ndarray, shape (n_outputs, m)
            Forces [N].

        """
        out, self._out = self._out, []
        if not out:
            return np.empty(0, dtype=np.int64), np.empty((self._n_out, 0))
        if len(out) == 1:
            return out[0].stamp_ns, out[0].force_n
        return (np.concatenate([o.stamp_ns for o in out]),
                np.concatenate([o.force_n for o in out], axis=1))

    def _queue(self, stamps: np.ndarray, x: np.ndarray):
        self._queued.append(stamps)
        self._queued_x.append(x)
        self._n_queued += stamps.size
        n_queued = self._n_queued
        if n_queued < self._block:
            return
        all_stamps = np.concatenate(self._queued)
        all_x = np.concatenate(self._queued_x, axis=1)
        n_full = (n_queued // self._block) * self._block
        for lo in range(0, n_full, self._block):
            self._run(all_stamps[lo:lo + self._block], all_x[:, lo:lo + self._block])
        rest = slice(n_full, None)
        self._queued = [all_stamps[rest]] if n_queued > n_full else []
        self._queued_x = [all_x[:, rest]] if n_queued > n_full else []
        self._n_queued = n_queued - n_full

    def _run(self, stamps: np.ndarray, x: np.ndarray):
        """Filter one block; emit the estimates that map to received samples."""
        y = self._predictor.process(x)
        self._fifo = np.concatenate([self._fifo, stamps])
        self._n_fed += stamps.size
        self._emit(y)

    def _emit(self, y: np.ndarray):
        # Outputs j < delay (counted from the restart) estimate samples before the restart.
        first_j = self._n_fed - y.shape[1]
        skip = min(max(self._delay - first_j, 0), y.shape[1])
        n = y.shape[1] - skip
        if n <= 0:
            return
        stamps, self._fifo = self._fifo[:n], self._fifo[n:]
        force = y[:, skip:]
        self._damage.update(force)
        self.counts['samples_out'] += n
        self._out.append(StampedForces(stamps, force))

    def _flush(self):
        self.counts['flushes'] += 1
        if self._queued:
            self._run(np.concatenate(self._queued), np.concatenate(self._queued_x, axis=1))
            self._queued, self._queued_x, self._n_queued = [], [], 0
        if self._n_fed:
            y = self._predictor.flush()
            self._n_fed += y.shape[1]
            self._emit(y)
        self._reset_filter()
