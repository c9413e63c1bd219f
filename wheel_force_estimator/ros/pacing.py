# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Output pacing of the live node: how many waiting estimates may be published now.

The node computes estimates a block at a time but publishes them one sample at a time, at the
rhythm of the input (DESIGN.md: outputs at the input rate, spread over the block period, never
as one burst).  Two rules, kept together here (no ROS, a steady-clock time passed in):

* **credit**: every input message pays for ``1 / n_inputs`` output sample (four corners: a
  quarter), so in the long run the output leaves exactly at the input rate, whatever the
  replay rate;
* **a short-term rate bound** (a token bucket on the steady clock): output leaves at most at
  :data:`CATCH_UP_FACTOR` x the measured input rate, and at most :data:`PACE_BURST_S` of it at
  once.  When the input comes in a burst (its publisher or this node was descheduled for tens
  of ms), the credit comes in a burst too; spending it at once sent the burst on, faster than
  a keep-last-5 subscriber (``ros2 topic echo``, ``ros2 bag record``) takes messages, and it
  lost some.  With the bound, the backlog of a stall of S seconds leaves over about
  S / (CATCH_UP_FACTOR - 1), and a subscriber has 1 / (CATCH_UP_FACTOR x rate) per message
  during a catch-up instead of microseconds.
* **bounded wait**: more than ``max_waiting`` (two blocks in the node) waiting, the bound is
  raised by :data:`HURRY_FACTOR` (a long stall, a flush: still spread); more than twice that
  (the node itself got no CPU for long) leaves at once.

The input rate is measured on the steady clock over the last ~0.25 s (:meth:`measure`, from the
node's housekeeping timer), so the bound follows a replay at 5x or 20x: the pacing scales with
the input, not with the model's sample rate (used only until a rate is measured).

:class:`PacedOutput` is the queue those rules pace: the node's serialized estimates, published
sample-major through the publish functions it is given (no ROS here either), with the wait of
each measured (the pacing latency of ``/diagnostics``).
"""
import collections
import time
from typing import Callable, List, Optional, Sequence

import numpy as np

#: Output may leave at most this multiple of the measured input rate (a catch-up after a stall).
CATCH_UP_FACTOR = 2.0
#: Catch-up rate multiplier while more than ``max_waiting`` samples wait.
HURRY_FACTOR = 2.0
#: At most this much output (at the catch-up rate; one sample at least) leaves at once [s].
PACE_BURST_S = 0.002
#: Rate measurements (housekeeping ticks, 20 ms) over which the input rate is averaged: long
#: enough that a stall of a few tens of ms barely moves it.
RATE_WINDOW_TICKS = 12
#: Shortest time over which the input rate is measured: over one tick a burst of input would
#: look like a fast stream [s].
RATE_MIN_SPAN_S = 0.035
#: Pacing latencies kept for the percentiles.
LATENCY_WINDOW = 4096
#: Step of a paced drain (:meth:`PacedOutput.drain`) [s].
DRAIN_STEP_S = 0.002


class OutputPacer:
    """
    Credit per input message plus a bound on the short-term output rate (see the module notes).

    Parameters
    ----------
    nominal_hz : float
        Output sample rate assumed until the input rate is measured (the model's) [Hz].
    max_waiting : int
        More output samples than this waiting are caught up :data:`HURRY_FACTOR` times faster;
        more than twice this never wait (the rest leaves at once) [samples].
    n_inputs : int
        Input messages per output sample (one per corner).

    """

    def __init__(self, nominal_hz: float, max_waiting: int, n_inputs: int = 4):
        if not nominal_hz > 0 or max_waiting < 0 or n_inputs < 1:
            raise ValueError(f'OutputPacer: nominal_hz = {nominal_hz} must be > 0, max_waiting '
                             f'= {max_waiting} >= 0, n_inputs = {n_inputs} >= 1')
        self.max_waiting = max_waiting
        self._per_message = 1.0 / n_inputs
        self._credit = 0.0
        self._allow = 0.0
        self._allow_s = None
        self._marks = collections.deque(maxlen=RATE_WINDOW_TICKS + 1)
        self._idle_ticks = 0
        self._set_input_hz(nominal_hz)

    @property
    def input_hz(self) -> float:
        """Return the input sample rate the bound follows [Hz] (measured, else nominal)."""
        return self._input_hz

    def on_message(self, now_s: float, waiting: int) -> int:
        """
        Book one input message; return how many of the ``waiting`` samples may leave now.

        Call :meth:`published` with the number actually published.
        """
        self._credit += self._per_message
        due = int(self._credit)
        hurry = 1.0
        if waiting > self.max_waiting:
            # Behind by more than max_waiting (a long stall, a flush): faster, still spread.
            due, hurry = max(due, waiting - self.max_waiting), HURRY_FACTOR
        due = min(due, int(self._refill(now_s, hurry)))
        # The node itself got no CPU for long: the wait must stay bounded.
        return max(due, waiting - 2 * self.max_waiting)

    def on_idle(self, now_s: float, waiting: int) -> int:
        """
        Return how many waiting samples may leave at a tick without input (0 or 1).

        The node ticks at the model's sample rate while no input comes (a stall, the tail of a
        replay); a tick that comes late (the node was descheduled) does not add up to a burst.
        """
        return min(1, int(self._refill(now_s, 1.0)), waiting)

    def _refill(self, now_s: float, hurry: float) -> float:
        cap = self._cap * hurry
        if self._allow_s is None:
            allow = cap
        else:
            allow = min(self._allow + (now_s - self._allow_s) * self._catch_up_hz * hurry, cap)
        self._allow, self._allow_s = allow, now_s
        return allow

    def published(self, n: int, waiting: int):
        """Book ``n`` samples published; ``waiting`` samples still wait."""
        # Never below 0: what left without credit (a tick without input, a catch-up) is not
        # owed, else the output would stop until later input had paid for it.
        self._credit = max(self._credit - n, 0.0)
        self._allow = max(self._allow - n, 0.0)
        if not waiting:
            self._credit = min(self._credit, 1.0)   # no saving up while nothing waits

    def measure(self, now_s: float, n_messages: int):
        """Follow the input rate: ``n_messages`` received in total by ``now_s`` (steady clock)."""
        marks = self._marks
        # After a whole window without input, a new stream is measured from its start, not
        # averaged with the silence before it.  (A shorter pause is averaged over: dropping
        # it would count the burst after it over too short a time.)
        if marks and n_messages == marks[-1][1]:
            self._idle_ticks += 1
        else:
            if self._idle_ticks >= RATE_WINDOW_TICKS:
                last = marks[-1]
                marks.clear()
                marks.append(last)
            self._idle_ticks = 0
        marks.append((now_s, n_messages))
        (t0, n0), (t1, n1) = marks[0], marks[-1]
        # Kept while no input comes (a stall, the tail of a replay is paced at the last rate).
        if len(marks) > 1 and n1 > marks[-2][1] and t1 - t0 >= RATE_MIN_SPAN_S:
            self._set_input_hz((n1 - n0) * self._per_message / (t1 - t0))

    def _set_input_hz(self, input_hz: float):
        self._input_hz = input_hz
        self._catch_up_hz = CATCH_UP_FACTOR * input_hz
        self._cap = max(1.0, self._catch_up_hz * PACE_BURST_S)


class PacedOutput:
    """
    Serialized estimates waiting to be published, and their publication as paced.

    Blocks are queued as the estimation emits them, one list of serialized messages per
    output topic, and published oldest first and **sample-major** (a subscriber sees the
    corners of a sample together), as many as the :class:`OutputPacer` allows.

    Parameters
    ----------
    publish_fns : sequence of callable
        One publish function per output topic (the corners), each taking one message.
    nominal_hz : float
        The model's sample rate [Hz]: the pace until the input rate is measured, and of a
        drain without input.
    max_waiting : int
        See :class:`OutputPacer` [samples].

    Attributes
    ----------
    waiting : int
        Samples queued, not published yet.
    published : int
        Samples published since this object was made.

    """

    def __init__(self, publish_fns: Sequence[Callable], nominal_hz: float, max_waiting: int):
        self._publish = list(publish_fns)
        self._nominal_hz = float(nominal_hz)
        self._pacer = OutputPacer(nominal_hz, max_waiting, len(self._publish))
        # [per-topic serialized messages, next index, when computed (None: a tail)]
        self._queue = collections.deque()
        self._latency_s = collections.deque(maxlen=LATENCY_WINDOW)
        self.waiting = 0
        self.published = 0

    def add(self, blobs: List[list], ready_s: Optional[float]):
        """
        Queue one block: ``blobs[k]`` the messages of topic ``k``, all of one length.

        ``ready_s`` is when the block was computed (steady clock); ``None`` for a tail
        (flushed after the input stopped): it has no input to pace it and is left out of the
        latency, which measures steady running.
        """
        n = len(blobs[0])
        if n:
            self._queue.append([blobs, 0, ready_s])
            self.waiting += n

    def measure(self, now_s: float, n_messages: int):
        """Follow the input rate (:meth:`OutputPacer.measure`)."""
        self._pacer.measure(now_s, n_messages)

    def on_message(self, now_s: float):
        """Publish what the pacing allows now that one input message arrived."""
        due = self._pacer.on_message(now_s, self.waiting)
        if due > 0:
            self._pacer.published(self.pump(due, now_s), self.waiting)

    def on_idle(self, now_s: float):
        """Publish what the pacing allows on a tick without input (the idle rate)."""
        due = self._pacer.on_idle(now_s, self.waiting)
        if due:
            self._pacer.published(self.pump(due, now_s), self.waiting)

    def pump(self, budget: int, now_s: float) -> int:
        """Publish up to ``budget`` waiting samples, oldest first; return the count."""
        publishers = self._publish
        done = 0
        while budget > done and self._queue:
            entry = self._queue[0]
            blobs, first, ready = entry
            last = min(len(blobs[0]), first + budget - done)
            if ready is not None:
                self._latency_s.append((now_s - ready, last - first))
            for k in range(first, last):
                for publish, topic_blobs in zip(publishers, blobs):
                    publish(topic_blobs[k])
            done += last - first
            if last == len(blobs[0]):
                self._queue.popleft()
            else:
                entry[1] = last
        self.published += done
        self.waiting -= done
        return done

    def drain(self, max_s: float, clock: Callable[[], float] = time.monotonic,
              sleep: Callable[[float], None] = time.sleep):
        """
        Publish everything waiting, paced, within about ``max_s`` [s].

        At the nominal rate, faster when that would take longer than ``max_s`` (a shutdown,
        a deactivate).  ``clock`` and ``sleep`` are the steady clock and its wait.
        """
        n = self.waiting
        if not n:
            return
        rate = max(self._nominal_hz, n / max_s)
        start = clock()
        while self.waiting:
            now = clock()
            due = min(n, int(rate * (now - start)) + 1) - (n - self.waiting)
            if due > 0:
                self.pump(due, now)
            sleep(DRAIN_STEP_S)

    def latency_ms(self):
        """
        Return (p50, p99, max) of the time estimates waited to be published [ms].

        Per published sample, over the last :data:`LATENCY_WINDOW` publications, from the
        moment the estimate was computed; tails are not included.
        """
        if not self._latency_s:
            return (0.0, 0.0, 0.0)
        pairs = np.asarray(self._latency_s)
        order = np.argsort(pairs[:, 0])
        lat, weight = pairs[order, 0] * 1e3, np.cumsum(pairs[order, 1])
        p50, p99 = (lat[np.searchsorted(weight, q * weight[-1])] for q in (0.5, 0.99))
        return float(p50), float(p99), float(lat[-1])
