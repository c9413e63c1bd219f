# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Corner alignment on header.stamp, without ROS."""
import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.ros.aligner import AlignedSamples
from wheel_force_estimator.ros.aligner import CornerAligner
from wheel_force_estimator.ros.aligner import OutOfTolerance
from wheel_force_estimator.ros.aligner import StampJump

PERIOD = 1_953_125  # ns at 512 Hz


def stamps(first, n):
    return 10**12 + (first + np.arange(n, dtype=np.int64)) * PERIOD


def values(corner, st):
    """Per-corner values that encode corner and stamp, so misalignment is visible."""
    k = (st - 10**12) // PERIOD
    return np.stack([1000.0 * corner + k, 1000.0 * corner + k + 0.25,
                     1000.0 * corner + k + 0.5])


def collect(events):
    """Concatenate AlignedSamples; return (stamps, values, n_jumps, order of kinds)."""
    blocks = [e for e in events if isinstance(e, AlignedSamples)]
    kinds = ['s' if isinstance(e, AlignedSamples) else 'j' for e in events]
    if not blocks:
        return np.empty(0, dtype=np.int64), np.empty((12, 0)), kinds.count('j'), kinds
    return (np.concatenate([b.stamp_ns for b in blocks]),
            np.concatenate([b.accel_mps2 for b in blocks], axis=1), kinds.count('j'), kinds)


def check_accounting(aligner):
    c = aligner.counters()
    total = (c['aligned'] + c['duplicate'] + c['late'] + c['incomplete']
             + c['out_of_tolerance'] + c['pending'])
    np.testing.assert_array_equal(c['received'], total)
    return c


def test_in_order_corners_release_every_sample_corner_major():
    al = CornerAligner()
    st = stamps(0, 10)
    for c in range(4):
        al.push(c, st, values(c, st))
    got_st, got_x, jumps, _ = collect(al.drain())
    np.testing.assert_array_equal(got_st, st)
    np.testing.assert_array_equal(got_x, np.concatenate([values(c, st) for c in range(4)]))
    assert jumps == 0
    c = check_accounting(al)
    np.testing.assert_array_equal(c['aligned'], [10] * 4)


def test_nothing_released_until_all_corners_have_the_stamp():
    al = CornerAligner()
    st = stamps(0, 5)
    for c in range(3):
        al.push(c, st, values(c, st))
    assert collect(al.drain())[0].size == 0
    al.push(3, st[:2], values(3, st[:2]))
    np.testing.assert_array_equal(collect(al.drain())[0], st[:2])
    np.testing.assert_array_equal(al.counters()['pending'], [3, 3, 3, 0])


def test_shuffled_bursts_across_topics_give_the_in_order_result():
    rng = np.random.default_rng(3)
    st = stamps(0, 600)
    pieces = []
    for c in range(4):
        cuts = np.sort(rng.choice(np.arange(1, 600), size=40, replace=False))
        pieces.append([(c, p) for p in np.split(np.arange(600), cuts)])
    al = CornerAligner(max_pending=1000)
    released = []
    cursors = [0] * 4
    # Random interleaving across corners; each corner's own order is kept (one DDS writer).
    while any(cursors[c] < len(pieces[c]) for c in range(4)):
        c = int(rng.choice([k for k in range(4) if cursors[k] < len(pieces[k])]))
        _, idx = pieces[c][cursors[c]]
        cursors[c] += 1
        al.push(c, st[idx], values(c, st[idx]))
        if rng.random() < 0.3:
            released += al.drain()
    released += al.drain()
    got_st, got_x, _, _ = collect(released)
    np.testing.assert_array_equal(got_st, st)
    np.testing.assert_array_equal(got_x, np.concatenate([values(c, st) for c in range(4)]))
    check_accounting(al)


def test_missing_sample_is_dropped_for_every_corner_and_counted():
    al = CornerAligner()
    st = stamps(0, 8)
    for c in range(4):
        keep = st if c != 1 else np.delete(st, 3)
        al.push(c, keep, values(c, keep))
    got_st, _, _, _ = collect(al.drain())
    np.testing.assert_array_equal(got_st, np.delete(st, 3))
    c = check_accounting(al)
    np.testing.assert_array_equal(c['incomplete'], [1, 0, 1, 1])


def test_duplicates_are_counted_not_used():
    al = CornerAligner()
    st = stamps(0, 4)
    for c in range(4):
        al.push(c, st, values(c, st))
    al.drain()
    al.push(0, st[[-1, -1]], values(0, st[[-1, -1]]))     # same stamp again, twice
    c = check_accounting(al)
    assert c['duplicate'][0] == 2
    assert not al.in_transition


def test_corner_behind_by_more_than_max_pending_delivers_late_messages():
    al = CornerAligner(max_pending=10)
    st = stamps(0, 30)
    for c in range(3):
        al.push(c, st, values(c, st))
    al.drain()
    np.testing.assert_array_equal(al.counters()['pending'], [10, 10, 10, 0])
    al.push(3, st, values(3, st))
    got_st, _, _, _ = collect(al.drain())
    np.testing.assert_array_equal(got_st, st[20:])
    c = check_accounting(al)
    np.testing.assert_array_equal(c['late'], [0, 0, 0, 20])
    np.testing.assert_array_equal(c['incomplete'], [20, 20, 20, 0])


def test_skipped_samples_of_one_corner_are_incomplete_for_the_others():
    al = CornerAligner()
    st = stamps(0, 6)
    for c in (0, 1, 2):
        al.push(c, st, values(c, st))
    al.push(3, st[:2], values(3, st[:2]))
    al.push(3, st[4:], values(3, st[4:]))             # corner 3 skipped samples 2 and 3
    np.testing.assert_array_equal(collect(al.drain())[0], st[[0, 1, 4, 5]])
    c = check_accounting(al)
    np.testing.assert_array_equal(c['incomplete'], [2, 2, 2, 0])
    np.testing.assert_array_equal(c['aligned'], [4] * 4)


def test_silent_corner_bounds_pending_then_resumes():
    al = CornerAligner(max_pending=50)
    st = stamps(0, 300)
    released = []
    for lo in range(0, 300, 10):
        for c in range(4):
            if c == 0 and 10 <= lo < 250:
                continue                                    # lf silent for 240 samples
            al.push(c, st[lo:lo + 10], values(c, st[lo:lo + 10]))
        released += al.drain()
        assert max(al.counters()['pending']) <= 50
    got_st, got_x, _, _ = collect(released)
    expected = st[np.r_[0:10, 250:300]]
    np.testing.assert_array_equal(got_st, expected)
    np.testing.assert_array_equal(got_x, np.concatenate([values(c, expected)
                                                         for c in range(4)]))
    c = check_accounting(al)
    np.testing.assert_array_equal(c['aligned'], [60] * 4)
    np.testing.assert_array_equal(c['incomplete'], [0, 240, 240, 240])


def test_clean_loop_with_staggered_corners_is_one_jump_and_loses_nothing():
    al = CornerAligner(max_pending=500)
    first = stamps(0, 100)
    second = stamps(0, 100)          # the recording plays again from its start
    events = []
    for c in range(4):
        al.push(c, first[:80], values(c, first[:80]))
    events += al.drain()
    # lf and rf loop while lr and rr still send the end of the first pass.
    for c in (0, 1):
        al.push(c, np.r_[first[80:], second[:30]], np.c_[values(c, first[80:]),
                                                         values(c, second[:30])])
    events += al.drain()
    for c in (2, 3):
        al.push(c, np.r_[first[80:], second[:30]], np.c_[values(c, first[80:]),
                                                         values(c, second[:30])])
    events += al.drain()
    for c in range(4):
        al.push(c, second[30:], values(c, second[30:]))
    events += al.drain()
    got_st, _, jumps, kinds = collect(events)
    assert jumps == 1
    np.testing.assert_array_equal(got_st, np.r_[first, second])
    j = kinds.index('j')
    before = collect(events[:j])[0]
    np.testing.assert_array_equal(before, first)
    c = check_accounting(al)
    np.testing.assert_array_equal(c['aligned'], [200] * 4)
    np.testing.assert_array_equal(c['incomplete'], [0] * 4)
    assert [e for e in events if isinstance(e, StampJump)][0].stamp_ns == second[0]


def test_single_corner_clock_reset_forces_the_epoch_change():
    al = CornerAligner(max_pending=20)
    st = stamps(1000, 100)
    old = stamps(0, 100)
    for c in range(4):
        al.push(c, st[:50], values(c, st[:50]))
    al.push(0, old[:60], values(0, old[:60]))       # lf's clock restarts alone
    for c in (1, 2, 3):
        al.push(c, st[50:], values(c, st[50:]))
    events = al.drain()
    assert collect(events)[2] == 1
    c = check_accounting(al)
    # Nothing after the reset can align: no fabricated sample, everything accounted for.
    np.testing.assert_array_equal(c['aligned'], [50] * 4)
    assert not al.in_transition


def test_random_fault_sequences_always_account_for_every_message():
    rng = np.random.default_rng(11)
    for trial in range(20):
        al = CornerAligner(max_pending=int(rng.integers(5, 60)))
        base = [0] * 4
        last_epoch_stamps = []
        for _ in range(60):
            c = int(rng.integers(4))
            n = int(rng.integers(1, 15))
            st = stamps(base[c], n)
            if rng.random() < 0.2:
                st = np.delete(st, rng.integers(n))           # lost message
            if rng.random() < 0.1 and st.size:
                st = np.r_[st, st[-1]]                        # duplicate
            if rng.random() < 0.05:
                base[c] = 0                                   # loop back
                st = stamps(0, n)
            else:
                base[c] += n
            al.push(c, st, values(c, st))
            for e in al.drain():
                if isinstance(e, AlignedSamples):
                    assert np.all(np.diff(e.stamp_ns) > 0)
                    last_epoch_stamps.append(e.stamp_ns)
        check_accounting(al)


def jittered(st, corner, rng, fraction=0.2):
    """Stamps of one corner's own clock: each off the grid by up to +-fraction of a period."""
    return st + np.round(rng.uniform(-fraction, fraction, st.size) * PERIOD).astype(np.int64)


def test_jitter_within_the_tolerance_releases_every_sample_stamped_by_the_median():
    # Bug caught: exact-stamp matching (0 samples out), or a corner paired with its neighbour
    # sample (values of k and k +- 1 mixed), or a float median rounding 1e12-ns stamps.
    rng = np.random.default_rng(7)
    st = stamps(0, 400)
    corner_st = [jittered(st, c, rng) for c in range(4)]
    al = CornerAligner(tolerance_ns=PERIOD // 2, period_ns=PERIOD)
    released = []
    for lo in range(0, 400, 7):
        for c in rng.permutation(4):
            part = corner_st[c][lo:lo + 7]
            al.push(int(c), part, values(c, st[lo:lo + 7]))
        released += al.drain()
    got_st, got_x, _, _ = collect(released)
    np.testing.assert_array_equal(got_x, np.concatenate([values(c, st) for c in range(4)]))
    ordered = np.sort(np.stack(corner_st), axis=0)
    np.testing.assert_array_equal(got_st, ordered[1] + (ordered[2] - ordered[1]) // 2)
    c = check_accounting(al)
    np.testing.assert_array_equal(c['aligned'], [400] * 4)
    assert c['incomplete'].sum() == c['out_of_tolerance'].sum() == 0


def test_missing_sample_under_jitter_is_incomplete_not_out_of_tolerance():
    rng = np.random.default_rng(8)
    st = stamps(0, 50)
    al = CornerAligner(tolerance_ns=PERIOD // 2, period_ns=PERIOD)
    for c in range(4):
        keep = np.delete(np.arange(50), [20, 21]) if c == 2 else np.arange(50)
        al.push(c, jittered(st, c, rng)[keep], values(c, st[keep]))
    got_st, got_x, _, _ = collect(al.drain())
    kept = np.delete(st, [20, 21])
    np.testing.assert_array_equal(got_x, np.concatenate([values(c, kept) for c in range(4)]))
    c = check_accounting(al)
    np.testing.assert_array_equal(c['incomplete'], [2, 2, 0, 2])
    assert c['out_of_tolerance'].sum() == 0


def test_corner_clock_offset_beyond_the_tolerance_is_counted_with_the_offset_never_merged():
    # Bug caught: stamps outside the tolerance merged anyway, or dropped without a trace.
    st = stamps(0, 40)
    al = CornerAligner(tolerance_ns=PERIOD // 10, period_ns=PERIOD)
    offset = 3 * PERIOD // 10
    for c in range(4):
        al.push(c, st + (offset if c == 0 else 0), values(c, st))
    events = al.drain()
    assert collect(events)[0].size == 0
    reports = [e for e in events if isinstance(e, OutOfTolerance)]
    assert {r.corner for r in reports} == {0, 1, 2, 3}
    for r in reports:
        assert abs(r.offset_ns - offset) <= 1, r
    c = check_accounting(al)
    assert c['out_of_tolerance'].sum() > 0 and c['aligned'].sum() == 0
    # The same offset within a wider tolerance is one sample, stamped by the median.
    al = CornerAligner(tolerance_ns=PERIOD // 2, period_ns=PERIOD)
    for c in range(4):
        al.push(c, st + (offset if c == 0 else 0), values(c, st))
    got_st, _, _, _ = collect(al.drain())
    np.testing.assert_array_equal(got_st, st)


def test_random_jittered_fault_sequences_account_for_every_message():
    rng = np.random.default_rng(12)
    for trial in range(20):
        al = CornerAligner(max_pending=int(rng.integers(5, 60)), tolerance_ns=PERIOD // 2,
                           period_ns=PERIOD)
        base = [0] * 4
        for _ in range(60):
            c = int(rng.integers(4))
            n = int(rng.integers(1, 15))
            st = jittered(stamps(base[c], n), c, rng, 0.25)
            if rng.random() < 0.2:
                st = np.delete(st, rng.integers(n))
            base[c] += n
            al.push(c, st, np.zeros((3, st.size)))
            for e in al.drain():
                if isinstance(e, AlignedSamples):
                    assert np.all(np.diff(e.stamp_ns) > 0)
        check_accounting(al)


def test_bad_arguments_are_rejected():
    with pytest.raises(ConfigError, match='half the sample period'):
        CornerAligner(tolerance_ns=PERIOD // 2 + 1, period_ns=PERIOD)
    with pytest.raises(ConfigError, match='tolerance_ns must be >= 0'):
        CornerAligner(tolerance_ns=-1)
    with pytest.raises(ConfigError, match='max_pending'):
        CornerAligner(max_pending=0)
    al = CornerAligner()
    with pytest.raises(ShapeError, match='corner index 4'):
        al.push(4, stamps(0, 1), np.zeros((3, 1)))
    with pytest.raises(ShapeError, match='expected \\(3, 2\\)'):
        al.push(0, stamps(0, 2), np.zeros((3, 1)))
    al.push(0, np.empty(0, dtype=np.int64), np.empty((3, 0)))
    assert al.counters()['received'][0] == 0


def test_a_fifth_stream_with_its_own_value_count_aligns_like_a_corner():
    # issue 33: the JointState spin rates (4 values) align with the four Imu corners (3 each)
    # by the same rules: a sample missing on the fifth stream is dropped everywhere (bug
    # caught: an extra stream released with the wrong sample, or its rows lost)
    al = CornerAligner(5, (3, 3, 3, 3, 4), tolerance_ns=1000, period_ns=PERIOD)
    t = stamps(0, 6)
    for c in range(4):
        al.push(c, t, np.full((3, 6), float(c)) + np.arange(6))
    keep = np.array([True, True, False, True, True, True])
    al.push(4, t[keep] + 400, np.full((4, 5), 10.0) + np.arange(6)[keep])
    out = al.drain()
    aligned = [e for e in out if isinstance(e, AlignedSamples)]
    got_t = np.concatenate([e.stamp_ns for e in aligned])
    got = np.concatenate([e.accel_mps2 for e in aligned], axis=1)
    assert np.array_equal(got_t, t[[0, 1, 3, 4, 5]])   # median of 5 stamps: an Imu stamp
    assert got.shape == (16, 5)
    assert np.array_equal(got[12:], np.full((4, 5), 10.0) + np.arange(6)[keep])
    assert np.array_equal(got[3:6], np.full((3, 5), 1.0) + np.arange(6)[keep])
    counts = al.counters()
    assert counts['incomplete'].tolist() == [1, 1, 1, 1, 0]
    with pytest.raises(ShapeError, match=r'expected \(4, 1\)'):
        al.push(4, stamps(6, 1), np.zeros((3, 1)))
    with pytest.raises(ConfigError, match='value counts'):
        CornerAligner(5, (3, 3, 3, 4))
