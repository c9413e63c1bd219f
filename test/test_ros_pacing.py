# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Output pacing (no ROS): the node's publication schedule, on a simulated steady clock."""
import numpy as np
import pytest

from wheel_force_estimator.ros.pacing import CATCH_UP_FACTOR
from wheel_force_estimator.ros.pacing import HURRY_FACTOR
from wheel_force_estimator.ros.pacing import OutputPacer
from wheel_force_estimator.ros.pacing import PACE_BURST_S
from wheel_force_estimator.ros.pacing import PacedOutput

FS_HZ = 512.0
BLOCK = 16
TICK_S = 0.02          # the node's housekeeping period


def arrivals(n_samples, rate, stall_at=None, stall_s=0.0, burst=1):
    """
    Return the arrival times [s] of 4 messages per sample at ``rate`` x real time.

    ``burst`` samples at once; from sample ``stall_at`` on, what is held for ``stall_s``
    comes at once (taken one by one, 2 us each).
    """
    t = np.repeat(np.arange(n_samples) // burst * burst / (rate * FS_HZ), 4)
    if stall_at is not None:
        lo = 4 * stall_at
        held = (t >= t[lo]) & (t < t[lo] + stall_s)
        t[held] = t[lo] + stall_s
        t[held] += np.arange(held.sum()) * 2e-6     # taken one by one, 2 us each
    return t


def run(times, pacer):
    """
    Play the node's loop and return (publish times, counts, waiting trace).

    Blocks complete every BLOCK samples, each message may publish, housekeeping measures the
    input rate.
    """
    waiting, messages, next_tick = 0, 0, TICK_S
    out_t, out_n, trace = [], [], []
    for k, now in enumerate(times):
        while next_tick <= now:
            pacer.measure(next_tick, messages)
            next_tick += TICK_S
        messages += 1
        if (k + 1) % (4 * BLOCK) == 0:
            waiting += BLOCK                           # a block of estimates is ready
        if waiting:
            n = min(pacer.on_message(now, waiting), waiting)
            waiting -= n
            pacer.published(n, waiting)
            if n:
                out_t.append(now)
                out_n.append(n)
        trace.append(waiting)
    return np.array(out_t), np.array(out_n), np.array(trace)


def most_within(t, n, window_s):
    """Return the largest number of samples published within any ``window_s``."""
    ends = np.searchsorted(t, t + window_s, side='left')
    cum = np.concatenate([[0], np.cumsum(n)])
    return int((cum[ends] - cum[:-1]).max())


def test_steady_input_leaves_at_its_own_rhythm():
    # A burst per block (the bug paced outputs avoid) would put 16 samples in one instant.
    t, n, waiting = run(arrivals(2048, 1.0), OutputPacer(FS_HZ, 2 * BLOCK))
    assert n.sum() == 2048 - waiting[-1] and waiting.max() <= BLOCK
    assert n.max() == 1
    assert most_within(t, n, 0.005) <= np.ceil(0.005 * FS_HZ)


def test_a_stalled_input_is_caught_up_gradually_not_in_one_burst():
    # 30 ms of input (15 samples) arrive within 0.1 ms; spending the credit as it comes
    # (the flaky depth-5 test) publishes ~15 samples per topic at once.
    times = arrivals(2048, 1.0, stall_at=1000, stall_s=0.03)
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    t, n, waiting = run(times, pacer)
    assert abs(pacer.input_hz - FS_HZ) < 0.05 * FS_HZ
    cap = CATCH_UP_FACTOR * FS_HZ * PACE_BURST_S
    assert most_within(t, n, 0.001) <= cap + CATCH_UP_FACTOR * FS_HZ * 0.001 + 1
    assert most_within(t, n, 0.005) <= cap + CATCH_UP_FACTOR * FS_HZ * 0.005 + 1
    # ... but caught up: the backlog is back to at most a block within
    # stall / (CATCH_UP_FACTOR - 1) + one block after the stall.
    stall_end = times[4 * 1000] + 0.03
    back = stall_end + 0.03 / (CATCH_UP_FACTOR - 1) + BLOCK / FS_HZ
    assert waiting[times > back].max() <= BLOCK
    assert n.sum() == 2048 - waiting[-1]


@pytest.mark.parametrize('rate', [5.0, 20.0])
def test_the_bound_follows_a_fast_replay(rate):
    # Bursts of 16 samples as bench_node's publisher sends them.  A bound at the model's
    # rate (512 Hz) would let the backlog grow until it left in one go (> 4 blocks waiting).
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    t, n, waiting = run(arrivals(int(4 * rate * FS_HZ), rate, burst=16), pacer)
    assert abs(pacer.input_hz - rate * FS_HZ) < 0.05 * rate * FS_HZ
    steady = waiting[int(0.1 * rate * FS_HZ) * 4:]    # after the first rate measurements
    assert steady.max() < 4 * BLOCK
    cap = CATCH_UP_FACTOR * HURRY_FACTOR * rate * FS_HZ * PACE_BURST_S
    assert n[len(n) // 10:].max() <= cap
    assert n.sum() == waiting.size // 4 - waiting[-1]


def test_the_wait_stays_bounded():
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    # more than twice max_waiting (the node got no CPU for long): the excess at once
    assert pacer.on_message(0.0, 100) == 100 - 4 * BLOCK
    pacer.published(100 - 4 * BLOCK, 4 * BLOCK)
    # more than max_waiting, without credit (after a flush): caught up faster, still spread
    hurry_hz = CATCH_UP_FACTOR * HURRY_FACTOR * FS_HZ
    out = []
    for k in range(1, 200):
        now = k * 1e-4                                # 10x faster than 1x input
        due = pacer.on_message(now, 4 * BLOCK - sum(out))
        pacer.published(due, 4 * BLOCK - sum(out) - due)
        out.append(due)
    assert 4 * BLOCK - sum(out) <= 2 * BLOCK          # down to max_waiting (and credit)
    assert max(out) <= hurry_hz * PACE_BURST_S
    assert sum(out[:100]) <= hurry_hz * PACE_BURST_S + hurry_hz * 0.01 + 1


def test_credit_is_not_saved_up_while_nothing_waits():
    # else a pause in the output (all published) would be followed by a burst
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    for k in range(40):
        pacer.on_message(k * 1e-3, 1)
    pacer.published(1, 0)
    assert pacer.on_message(1.0, 10) <= 1


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='nominal_hz'):
        OutputPacer(0.0, 32)


def test_a_new_stream_is_measured_from_its_start():
    # Averaging over the idle time before a 10x replay would bound it at a fraction of its rate
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    for k in range(50):                              # 1 s without input
        pacer.measure(k * TICK_S, 0)
    rate_hz = 10 * FS_HZ
    for k in range(1, 4):                            # then 3 ticks at 10x
        pacer.measure((49 + k) * TICK_S, int(4 * rate_hz * k * TICK_S))
    assert abs(pacer.input_hz - rate_hz) < 0.01 * rate_hz


def test_the_rate_is_kept_through_a_pause_and_late_idle_ticks_do_not_add_up():
    # The tail after a replay leaves one sample per idle tick at the stream's rate; a bound
    # that decayed with the silence would hold it back, late ticks must not make a burst.
    pacer = OutputPacer(FS_HZ, 2 * BLOCK)
    rate_hz = 4 * FS_HZ
    for k in range(1, 20):
        pacer.measure(k * TICK_S, int(4 * rate_hz * k * TICK_S))
    for k in range(20, 40):                          # input stopped
        pacer.measure(k * TICK_S, int(4 * rate_hz * 19 * TICK_S))
    assert abs(pacer.input_hz - rate_hz) < 0.01 * rate_hz
    assert pacer.on_idle(1.0, 10) == 1
    pacer.published(1, 9)
    assert pacer.on_idle(1.0, 9) == 1                # the bucket holds a few ...
    pacer.published(1, 8)
    assert pacer.on_idle(1.5, 8) == 1                # ... and never more than one per tick
    assert pacer.on_idle(1.5, 0) == 0


def _recorders(n_topics):
    """Return (publish functions, the shared log of (topic, message) they append to)."""
    log = []
    return [lambda msg, k=k: log.append((k, msg)) for k in range(n_topics)], log


def test_paced_output_publishes_sample_major_oldest_first_and_counts():
    fns, log = _recorders(4)
    out = PacedOutput(fns, FS_HZ, 2 * BLOCK)
    out.add([[f'a{k}{i}' for i in range(3)] for k in range(4)], ready_s=1.0)
    out.add([[f'b{k}{i}' for i in range(2)] for k in range(4)], ready_s=None)   # a tail
    out.add([[] for _ in range(4)], ready_s=2.0)                                # nothing
    assert (out.waiting, out.published) == (5, 0)
    assert out.pump(4, now_s=1.5) == 4                 # across the two blocks
    assert log == [(k, f'a{k}{i}') for i in range(3) for k in range(4)] + [
        (k, 'b{}0'.format(k)) for k in range(4)]
    assert (out.waiting, out.published) == (1, 4)
    assert out.pump(10, now_s=1.6) == 1 and out.pump(10, now_s=1.7) == 0
    assert (out.waiting, out.published) == (0, 5)
    # only the computed block's three samples waited (0.5 s); the tail is not latency
    assert out.latency_ms() == (500.0, 500.0, 500.0)


def test_paced_output_drain_publishes_everything_within_its_bound():
    fns, log = _recorders(2)
    out = PacedOutput(fns, FS_HZ, 2 * BLOCK)
    n = 3000                                           # 5.9 s at the model's rate
    out.add([list(range(n)), list(range(n))], ready_s=None)
    clock = {'t': 0.0}

    def sleep(dt):
        clock['t'] += dt
    out.drain(1.0, clock=lambda: clock['t'], sleep=sleep)
    assert out.waiting == 0 and out.published == n and len(log) == 2 * n
    assert [m for k, m in log if k == 1] == list(range(n))
    assert clock['t'] <= 1.0 + 0.01                    # faster than the model's rate
    out.add([list(range(8)), list(range(8))], ready_s=None)
    clock['t'] = 0.0
    out.drain(1.0, clock=lambda: clock['t'], sleep=sleep)
    assert out.waiting == 0
    assert clock['t'] == pytest.approx(8 / FS_HZ, abs=0.005)   # a short tail at its rate
