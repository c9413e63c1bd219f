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

**Spin inputs** (``spin_rows``, six components): those rows arrive as wheel spin rates and
enter the Predictor as their time derivative, taken per gap-free stretch exactly as the
offline reader takes it per segment
(:class:`~wheel_force_estimator.core.derived.SpinAccelerationStream`).  The derivative at a
sample needs the next one, so every sample waits one more sample before it is fed: the
latency is ``delay + 1`` (:attr:`ForceStream.delay_samples`), and a break or flush first
releases the held sample with its one-sided difference.  The stamps follow the samples, so
each estimate still carries the stamp of the sample it estimates.  A stretch of a single
sample has no derivative and no estimate (``counts['single_samples']``; the offline reader
keeps no segment under two samples either).

**Split inputs** (``derived``, issue 29): a model whose inputs end with the traction/braking
split and/or the cornering split gets those rows derived here from the 12 accelerations
(:class:`~wheel_force_estimator.core.derived.SpecificForceParts`), causally and with no
delay; they are not fed.  The filter restarts wherever the Predictor does (gap, stall, jump),
so a gap-free stretch gets exactly what the offline reader derives for that segment.

Discontinuities (each is counted):

* **gap** — a step between consecutive stamps longer than 1.5 periods, or shorter than half
  a period (:mod:`wheel_force_estimator.core.gaps`: the rule the offline reader cuts
  segments with, so a gap-free stretch here is exactly an offline segment): the samples in
  flight are **flushed** (their estimates are completed by ``Predictor.flush``, exactly as the
  offline ``predict`` ends a segment) and the filter restarts afresh at the next sample.
  Nothing received is discarded, nothing missing is invented.  Each break is kept as a
  :class:`StreamBreak` (stamps either side, samples missing) for the node to log.
* **stall** — :meth:`ForceStream.flush` called by the node when no sample arrived for a while
  (end of a recording): the same flush, so the last ``delay`` samples are not held forever.
* **jump** — the stamps went back (:meth:`ForceStream.restart`): flush, then the pseudo damage
  starts again from zero as well.

A damage **run** can be ended without touching the filter: :meth:`ForceStream.reset_damage`
(now: the final report of the run so far, then zero) and :meth:`ForceStream.split_damage`
(in data time: estimates stamped after the given stamp count in a new, named run; a proving
ground event).

The running pseudo damage is reported in **data time**: every ``damage_period_s`` of sample
stamps (counted from the first estimate after a start or jump) a :class:`DamageReport` is
made of the damage of the estimates stamped before that boundary, so a replay at any rate,
and any chunking of the input, gives the same reports.
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.derived import SpecificForceParts
from wheel_force_estimator.core.derived import SpinAccelerationStream
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.evaluation import channel_sn_slopes
from wheel_force_estimator.core.fatigue import ChannelDamage
from wheel_force_estimator.core.gaps import classify_steps
from wheel_force_estimator.core.gaps import missing_samples
from wheel_force_estimator.core.lag import LeadDrop
from wheel_force_estimator.core.predict import Predictor

_NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class StreamBreak:
    """
    Where the stream was cut (gap or impossible step).

    Attributes
    ----------
    kind : str
        ``'gap'`` (samples missing) or ``'short_step'`` (step under half a period).
    before_ns, after_ns : int
        Stamps either side of the break [ns].
    missing_samples : int
        Sample periods missing in the step (0 for a short step).

    """

    kind: str
    before_ns: int
    after_ns: int
    missing_samples: int

    def __str__(self) -> str:
        """Describe the break for a log line."""
        step_ms = (self.after_ns - self.before_ns) * 1e-6
        if self.kind == 'gap':
            what = f'{self.missing_samples} sample(s) missing'
        else:
            what = 'step under half a sample period'
        return (f'{what} between stamps {self.before_ns} ns and {self.after_ns} ns '
                f'({step_ms:.3f} ms step)')


@dataclass(frozen=True, eq=False)
class DamageReport:
    """
    The running pseudo damage at a data-time boundary.

    Attributes
    ----------
    stamp_ns : int
        Boundary stamp: the damage covers every estimate stamped before it (after the last
        start or jump) [ns].
    damage : numpy.ndarray, shape (n_outputs,)
        Accumulated pseudo damage per output channel [N^k].
    rate_per_s : numpy.ndarray, shape (n_outputs,)
        Damage increase since the previous report per second of data time [N^k/s].
    n_samples : int
        Number of estimates the damage covers.
    final : bool
        Made at an end of stream (stall, shutdown, jump) or of a run, not at a period
        boundary.
    run : str
        Name of the damage run (the proving-ground event it belongs to; ``''`` before the
        first).

    """

    stamp_ns: int
    damage: np.ndarray
    rate_per_s: np.ndarray
    n_samples: int
    final: bool = False
    run: str = ''


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
    damage_period_s : float, optional
        Data time between two :class:`DamageReport` s [s]; ``None``: no reports.
    sn_slope_moment : float, optional
        Basquin exponent of the moment outputs (default ``sn_slope``).
    spin_rows : sequence of int, optional
        Input rows fed as wheel spin rates [rad/s], differentiated to the model's spin
        accelerations [rad/s²] (see the module notes); empty: none.
    derived : sequence of str, optional
        The model's last inputs that are derived here from the accelerations (the
        traction/braking and cornering splits, by name): samples are fed without them (see
        the module notes).

    Raises
    ------
    ConfigError
        On a bad block size, slope, period or spin row.

    """

    def __init__(self, predictor: Predictor, block_size: int, sn_slope: float,
                 damage_period_s: Optional[float] = None,
                 sn_slope_moment: Optional[float] = None, spin_rows: Sequence[int] = (),
                 derived: Sequence[str] = ()):
        if isinstance(block_size, bool) or not isinstance(block_size, (int, np.integer)) \
                or block_size < 1:
            raise ConfigError(f'block_size must be an integer >= 1, got {block_size!r}')
        self._predictor = predictor
        self._block = int(block_size)
        self._split = (SpecificForceParts(predictor.model.fs_hz, derived) if derived
                       else None)
        # rows fed: the model's inputs but the splits, which are derived here
        self._n_in = predictor.n_inputs - len(derived)
        self._spin = None
        if len(spin_rows):
            try:
                self._spin = SpinAccelerationStream(self._n_in, spin_rows)
            except ShapeError as err:
                raise ConfigError(f'spin_rows: {err}') from err
        # the spin derivative holds each sample until the next one has arrived
        self._delay = predictor.delay_samples + (1 if self._spin is not None else 0)
        self._n_out = len(predictor.model.output_channels)
        self._period_ns = 1e9 / predictor.model.fs_hz
        self._damage = ChannelDamage(channel_sn_slopes(
            predictor.model.output_channels, sn_slope, sn_slope_moment))
        if damage_period_s is not None and not damage_period_s > 0.0:
            raise ConfigError(f'damage_period_s must be > 0, got {damage_period_s!r}')
        self._report_ns = None if damage_period_s is None else int(
            round(damage_period_s * _NS_PER_S))
        self.counts = {'samples_in': 0, 'samples_out': 0, 'gaps': 0, 'short_steps': 0,
                       'missing_samples': 0, 'flushes': 0, 'jumps': 0, 'single_samples': 0}
        self._last_stamp = None
        self._lead = LeadDrop(predictor.delay_samples)
        self._reset_filter()
        self._out: List[StampedForces] = []
        self._breaks: List[StreamBreak] = []
        self._reports: List[DamageReport] = []
        self._splits: List[Tuple[int, str]] = []        # (after_ns, name) of runs to come
        self._run_name = ''
        self._reset_reports()

    @property
    def delay_samples(self) -> int:
        """Return the lag of the estimates behind the inputs [samples] (spin: one more)."""
        return self._delay

    @property
    def block_size(self) -> int:
        """Return the samples per Predictor call."""
        return self._block

    @property
    def in_flight(self) -> int:
        """Return the number of samples received whose estimate is not emitted yet."""
        return self.queued + int(self._fifo.size)

    @property
    def queued(self) -> int:
        """Return the number of samples waiting for their block to fill (or their spin)."""
        return self._n_queued + (self._spin.held if self._spin is not None else 0)

    def damage(self) -> np.ndarray:
        """Return the pseudo damage of all emitted since start or the last jump, per output."""
        return self._damage.damage()

    @property
    def fallback(self) -> Optional[str]:
        """Why the Predictor cuts the offline FIR (no live estimator), else None."""
        return self._predictor.fallback

    def _reset_reports(self):
        self._first_out_ns: Optional[int] = None          # first estimate after (re)start
        self._next_report_ns: Optional[int] = None        # next data-time boundary
        self._last_report = None                          # (stamp_ns, damage)
        self._last_out_ns: Optional[int] = None
        self._n_damaged = 0                               # estimates in the damage

    def _reset_filter(self):
        self._predictor.reset()
        self._lead.reset()
        if self._spin is not None:
            self._spin.reset()
        if self._split is not None:
            self._split.reset()
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
            Finite accelerations [m/s²] (and rates, spin rates), the model's inputs without
            the splits, which the stream derives (``n_inputs`` = the model's less those).

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
        if self._last_stamp is None:
            step = np.diff(stamps, prepend=stamps[0] - round(self._period_ns))
        else:
            step = np.diff(stamps, prepend=self._last_stamp)
        gap, short = classify_steps(step, self._period_ns)
        breaks = np.flatnonzero(gap | short)
        starts = [0, *breaks[breaks > 0].tolist()]
        for lo, hi in zip(starts, starts[1:] + [stamps.size]):
            if lo in breaks:
                before = int(stamps[lo - 1]) if lo else int(self._last_stamp)
                self._break(gap[lo], before, int(stamps[lo]))
            self._take_in(stamps[lo:hi], x[:, lo:hi])
        self._last_stamp = int(stamps[-1])
        self.counts['samples_in'] += stamps.size

    def _break(self, is_gap: bool, before_ns: int, after_ns: int):
        if is_gap:
            missing = missing_samples(after_ns - before_ns, self._period_ns)
            self.counts['gaps'] += 1
            self.counts['missing_samples'] += missing
            self._breaks.append(StreamBreak('gap', before_ns, after_ns, missing))
        else:
            self.counts['short_steps'] += 1
            self._breaks.append(StreamBreak('short_step', before_ns, after_ns, 0))
        self.flush()

    def take_breaks(self) -> List[StreamBreak]:
        """Return and forget the breaks (gaps, short steps) found since the last call."""
        out, self._breaks = self._breaks, []
        return out

    def take_damage_reports(self) -> List[DamageReport]:
        """Return and forget the damage reports made since the last call, in order."""
        out, self._reports = self._reports, []
        return out

    def final_damage_report(self) -> Optional[DamageReport]:
        """
        Report the damage of everything emitted so far (end of stream); ``None`` if nothing.

        Stamped one sample period after the last estimate (the report covers the estimates
        stamped before it).  Nothing is reset: the next period boundary stays where it was.
        """
        if self._last_out_ns is None:
            return None
        stamp = self._last_out_ns + int(round(self._period_ns))
        return self._report(stamp, final=True)

    def _report(self, stamp_ns: int, final: bool = False) -> DamageReport:
        damage = self._damage.damage()
        if self._last_report is None:
            since_ns, before = self._first_out_ns, np.zeros_like(damage)
        else:
            since_ns, before = self._last_report
        span_s = (stamp_ns - since_ns) / _NS_PER_S
        rate = (damage - before) / span_s if span_s > 0 else np.zeros_like(damage)
        if not final:
            self._last_report = (stamp_ns, damage)
        return DamageReport(int(stamp_ns), damage, rate, self._n_damaged, final, self._run_name)

    def reset_damage(self) -> Optional[DamageReport]:
        """
        End the damage run now: return its final report (``None`` if empty), restart at zero.

        The filter and the estimates in flight are untouched; they count in the new run.
        """
        final = self.final_damage_report()
        self._damage.reset()
        self._reset_reports()
        return final

    def split_damage(self, after_ns: int, name: str) -> None:
        """
        Start a new damage run, named ``name``, with the estimates stamped after ``after_ns``.

        The run before ends with a final :class:`DamageReport` when the first estimate of the
        new run is emitted (data time: the filter's lag does not move the split).
        """
        self._splits.append((int(after_ns), str(name)))

    @property
    def run(self) -> str:
        """Return the name of the current damage run."""
        return self._run_name

    def flush(self) -> None:
        """Complete the estimates in flight (stall / end of stream); the filter restarts."""
        if self.in_flight:
            self._flush()

    def restart(self) -> None:
        """Stamps went back: flush, report, then start afresh including the pseudo damage."""
        self.counts['jumps'] += 1
        self.flush()
        if self._report_ns is not None:
            final = self.final_damage_report()
            if final is not None:
                self._reports.append(final)
        self._last_stamp = None
        self._damage.reset()
        self._reset_reports()

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

    def _take_in(self, stamps: np.ndarray, x: np.ndarray):
        """Queue samples of one gap-free stretch (spin rows differentiated, one sample late)."""
        if self._spin is not None:
            stamps, x = self._spin.push(stamps, x)
        if stamps.size:
            self._queue(stamps, self._with_split(x))

    def _with_split(self, x: np.ndarray) -> np.ndarray:
        """Return the samples with the derived rows appended (a model with a split)."""
        if self._split is None:
            return x
        return np.concatenate([x, self._split.push(x)])

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
        self._emit(y)

    def _emit(self, y: np.ndarray):
        force = self._lead(y)
        n = force.shape[1]
        if n == 0:
            return
        stamps, self._fifo = self._fifo[:n], self._fifo[n:]
        lo = 0
        while self._splits and stamps[-1] > self._splits[0][0]:
            after_ns, name = self._splits.pop(0)
            cut = int(np.searchsorted(stamps, after_ns, side='right'))
            self._account(stamps[lo:max(cut, lo)], force[:, lo:max(cut, lo)])
            lo = max(cut, lo)
            final = self.reset_damage()
            if final is not None:
                self._reports.append(final)
            self._run_name = name
        self._account(stamps[lo:], force[:, lo:])
        self.counts['samples_out'] += n
        self._out.append(StampedForces(stamps, force))

    def _account(self, stamps: np.ndarray, force: np.ndarray):
        if not stamps.size:
            return
        if self._report_ns is None:
            self._damage.update(force)
            self._n_damaged += stamps.size
            if self._first_out_ns is None:
                self._first_out_ns = int(stamps[0])
            self._last_out_ns = int(stamps[-1])
        else:
            self._update_reporting(stamps, force)

    def _update_reporting(self, stamps: np.ndarray, force: np.ndarray):
        """Accumulate damage, reporting at every data-time boundary the stamps cross."""
        if self._next_report_ns is None:
            self._first_out_ns = int(stamps[0])
            self._next_report_ns = int(stamps[0]) + self._report_ns
        lo = 0
        while True:
            cut = int(np.searchsorted(stamps, self._next_report_ns, side='left'))
            if cut >= stamps.size:
                break
            self._damage.update(force[:, lo:cut])
            self._n_damaged += cut - lo
            # After a long gap several boundaries may lie before the next stamp: one report,
            # at the last of them.
            k = (int(stamps[cut]) - self._next_report_ns) // self._report_ns
            boundary = self._next_report_ns + k * self._report_ns
            self._reports.append(self._report(boundary))
            self._next_report_ns = boundary + self._report_ns
            lo = cut
        self._damage.update(force[:, lo:])
        self._n_damaged += stamps.size - lo
        self._last_out_ns = int(stamps[-1])

    def _flush(self):
        self.counts['flushes'] += 1
        if self._spin is not None:
            held = self._spin.held
            last_t, last_x = self._spin.finish()
            if last_t.size:
                self._queue(last_t, self._with_split(last_x))
            elif held:      # a stretch of one sample: no derivative, no estimate
                self.counts['single_samples'] += 1
        if self._queued:
            self._run(np.concatenate(self._queued), np.concatenate(self._queued_x, axis=1))
            self._queued, self._queued_x, self._n_queued = [], [], 0
        if self._fifo.size:
            self._emit(self._predictor.flush())
        self._reset_filter()
