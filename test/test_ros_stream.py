# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The node's estimation stream (blocks, gaps, flush, jumps, damage), without ROS."""
import numpy as np
import pytest
from support.ros_testing import sample_stamps
from support.ros_testing import synthetic_accel
from support.ros_testing import synthetic_model

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.predict import Predictor
from wheel_force_estimator.ros.stream import ForceStream

# The stream and predict_forces run the same overlap-add engine with different call lengths;
# they differ only by FFT rounding, ~1e-15 of the signal.  1e-12 relative leaves room for the
# accumulation over a few thousand samples and still catches any misplaced sample (O(1) error).
RTOL = 1e-12


@pytest.fixture(scope='module')
def model():
    return synthetic_model(n_taps=96, delay_samples=40, seed=4)


def run(stream, stamps, x, rng, max_chunk=300):
    """Feed in random chunks, flush at the end; return everything emitted."""
    out_s, out_y = [], []
    i = 0
    while i < stamps.size:
        k = int(rng.integers(1, max_chunk))
        stream.feed(stamps[i:i + k], x[:, i:i + k])
        s, y = stream.take()
        out_s.append(s)
        out_y.append(y)
        i += k
    stream.flush()
    s, y = stream.take()
    return np.concatenate(out_s + [s]), np.concatenate(out_y + [y], axis=1)


def assert_close(actual, expected):
    scale = np.abs(expected).max()
    np.testing.assert_allclose(actual, expected, rtol=0, atol=RTOL * scale)


@pytest.mark.parametrize('block_size', [1, 7, 64, 128, 1000])
def test_any_chunking_equals_offline_prediction(model, block_size):
    rng = np.random.default_rng(block_size)
    n = 2500
    x = synthetic_accel(n, seed=2)
    stamps = sample_stamps(n)
    stream = ForceStream(Predictor(model), block_size, 5.0)
    s, y = run(stream, stamps, x, rng)
    np.testing.assert_array_equal(s, stamps)        # every sample estimated exactly once
    assert_close(y, predict_forces(model, x))
    assert stream.counts == {'samples_in': n, 'samples_out': n, 'gaps': 0, 'short_steps': 0,
                             'missing_samples': 0, 'flushes': 1, 'jumps': 0,
                             'single_samples': 0}
    # The running damage is that of exactly the emitted signal.
    np.testing.assert_allclose(stream.damage(), pseudo_damage(y, 5.0), rtol=1e-12)


def test_latency_is_block_plus_delay(model):
    block = 64
    stream = ForceStream(Predictor(model), block, 5.0)
    x = synthetic_accel(1000, seed=3)
    stamps = sample_stamps(1000)
    stream.feed(stamps[:block - 1], x[:, :block - 1])
    assert stream.take()[0].size == 0 and stream.in_flight == block - 1
    stream.feed(stamps[block - 1:block], x[:, block - 1:block])
    s, _ = stream.take()
    np.testing.assert_array_equal(s, stamps[:block - model.fir_delay_samples])
    assert stream.in_flight == model.fir_delay_samples


def test_gap_flushes_and_each_segment_equals_its_offline_prediction(model):
    n = 1500
    x = synthetic_accel(n, seed=5)
    stamps = sample_stamps(n)
    keep = np.r_[0:700, 703:n]                       # three samples missing
    stream = ForceStream(Predictor(model), 128, 5.0)
    s, y = run(stream, stamps[keep], x[:, keep], np.random.default_rng(0))
    np.testing.assert_array_equal(s, stamps[keep])
    expected = np.concatenate([predict_forces(model, x[:, :700]),
                               predict_forces(model, x[:, 703:])], axis=1)
    assert_close(y, expected)
    assert stream.counts['gaps'] == 1
    assert stream.counts['flushes'] == 2             # the gap and the final flush


def test_clock_jitter_is_not_a_gap_but_another_rate_is(model):
    x = synthetic_accel(400, seed=6)
    period = 1e9 / model.fs_hz
    # ±20 % per stamp: steps within ±40 %, inside the [0.5, 1.5] period rule.
    jitter = np.random.default_rng(1).uniform(-0.2, 0.2, 400) * period
    stamps = (10**12 + np.arange(400) * period + jitter).astype(np.int64)
    stream = ForceStream(Predictor(model), 64, 5.0)
    stream.feed(stamps, x)
    assert stream.counts['gaps'] == 0 and stream.counts['short_steps'] == 0
    fast = (10**13 + np.arange(400) * (1e9 / 1200.0)).astype(np.int64)   # 1.2 kHz input
    stream.feed(fast, x)
    # the jump forward to 1e13 is one gap, then every step is too short for 512 Hz
    assert stream.counts['gaps'] == 1 and stream.counts['short_steps'] == 399
    breaks = stream.take_breaks()
    assert [b.kind for b in breaks] == ['gap'] + ['short_step'] * 399
    assert breaks[0].before_ns == int(stamps[-1]) and breaks[0].after_ns == int(fast[0])


@pytest.mark.parametrize('step_periods, is_gap', [(1.35, False), (1.5, False), (2.0, True)])
def test_gap_rule_is_the_offline_one(model, tmp_path, step_periods, is_gap):
    """Each gap-free stretch the stream sees equals a segment of the offline reader."""
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.bagio import write_recording
    n = 900
    period = 1e9 / model.fs_hz
    x = synthetic_accel(n, seed=11)
    offsets = np.arange(n) * period
    offsets[450:] += (step_periods - 1.0) * period      # one long step after sample 449
    stamps = (10**12 + np.round(offsets)).astype(np.int64)
    write_recording(tmp_path / 'bag', stamps, accel_mps2=x)
    recording = read_recording(tmp_path / 'bag', None, require_wft=False)
    assert len(recording.segments) == (2 if is_gap else 1)
    stream = ForceStream(Predictor(model), 16, 5.0)
    s, y = run(stream, stamps, x, np.random.default_rng(3))
    np.testing.assert_array_equal(s, stamps)
    expected = np.concatenate([predict_forces(model, seg.accel_mps2)
                               for seg in recording.segments], axis=1)
    assert_close(y, expected)
    assert stream.counts['gaps'] == int(is_gap)
    if is_gap:
        (gap,) = stream.take_breaks()
        assert (gap.before_ns, gap.after_ns, gap.missing_samples) == (
            int(stamps[449]), int(stamps[450]), 1)
        assert '1 sample(s) missing' in str(gap)


def test_damage_reports_are_in_data_time_and_independent_of_chunking(model):
    n = 3000
    x = synthetic_accel(n, seed=12)
    stamps = sample_stamps(n)                        # 512 Hz: 1 s = 512 samples
    results = []
    for seed, block in ((0, 16), (1, 128), (2, 7)):
        stream = ForceStream(Predictor(model), block, 5.0, damage_period_s=1.0)
        s, y = run(stream, stamps, x, np.random.default_rng(seed))
        reports = stream.take_damage_reports()
        results.append(reports)
        assert [r.stamp_ns for r in reports] == [int(stamps[0]) + k * 10**9
                                                 for k in range(1, 6)]
        for r in reports:
            # the damage of exactly the estimates stamped before the boundary
            before = s < r.stamp_ns
            np.testing.assert_allclose(r.damage, pseudo_damage(y[:, before], 5.0),
                                       rtol=1e-9)
        final = stream.final_damage_report()
        assert final.final and final.stamp_ns == int(stamps[-1]) + round(1e9 / 512)
        np.testing.assert_allclose(final.damage, pseudo_damage(y, 5.0), rtol=1e-9)
    for other in results[1:]:
        for a, b in zip(results[0], other):
            np.testing.assert_allclose(a.damage, b.damage, rtol=1e-12)
            np.testing.assert_allclose(a.rate_per_s, b.rate_per_s, rtol=1e-9)
    # rate = increase over the period per second of data
    r0, r1 = results[0][0], results[0][1]
    np.testing.assert_allclose(r1.rate_per_s, r1.damage - r0.damage, rtol=1e-12)


def test_restart_after_stamp_jump_resets_filter_and_damage(model):
    n = 600
    x = synthetic_accel(n, seed=7)
    stamps = sample_stamps(n)
    stream = ForceStream(Predictor(model), 100, 5.0)
    stream.feed(stamps, x)
    stream.restart()
    s1, y1 = stream.take()
    np.testing.assert_array_equal(s1, stamps)
    assert_close(y1, predict_forces(model, x))
    assert np.all(stream.damage() == 0.0)
    stream.feed(stamps[:300], x[:, :300])             # the recording again from its start
    stream.flush()
    s2, y2 = stream.take()
    np.testing.assert_array_equal(s2, stamps[:300])
    assert_close(y2, predict_forces(model, x[:, :300]))
    np.testing.assert_allclose(stream.damage(), pseudo_damage(y2, 5.0), rtol=1e-12)
    assert stream.counts['jumps'] == 1 and stream.counts['gaps'] == 0


def test_event_split_damage_runs_are_the_offline_damage_of_each_event_span(model):
    # Bug caught: the split placed at the filter's output (delay samples late) instead of in
    # data time, or the filter restarted at an event (estimates no longer offline).  Spans
    # follow evaluate's event rule: a sample belongs to the last event started at or before
    # its stamp.
    n = 2000
    x = synthetic_accel(n, seed=13)
    stamps = sample_stamps(n)
    events = [(int(stamps[700]), 'belgian_block'), (int(stamps[1333]) - 1000, 'cobbles')]
    stream = ForceStream(Predictor(model), 16, 5.0, damage_period_s=1.0)
    lo = 0
    for k, (start_ns, name) in zip((700, 1333, n), events + [(None, None)]):
        stream.feed(stamps[lo:k], x[:, lo:k])
        if name is not None:
            stream.split_damage(start_ns - 1, name)      # stamps >= start_ns: the new run
        lo = k
    stream.flush()
    s, y = stream.take()
    assert_close(y, predict_forces(model, x))                    # one filter, never reset
    finals = [r for r in stream.take_damage_reports() if r.final]
    finals.append(stream.final_damage_report())
    assert [r.run for r in finals] == ['', 'belgian_block', 'cobbles']
    starts = np.searchsorted(s, [start for start, _ in events])
    for r, part in zip(finals, np.split(np.arange(n), starts)):
        assert r.n_samples == part.size
        np.testing.assert_allclose(r.damage, pseudo_damage(y[:, part], 5.0), rtol=1e-9)


def test_reset_damage_reports_the_run_and_restarts_from_zero(model):
    n = 1000
    x = synthetic_accel(n, seed=14)
    stamps = sample_stamps(n)
    stream = ForceStream(Predictor(model), 16, 5.0)
    assert stream.reset_damage() is None                      # nothing estimated yet
    stream.feed(stamps[:600], x[:, :600])
    s1, y1 = stream.take()
    final = stream.reset_damage()
    assert final.final and final.n_samples == s1.size
    np.testing.assert_allclose(final.damage, pseudo_damage(y1, 5.0), rtol=1e-12)
    assert np.all(stream.damage() == 0.0)
    stream.feed(stamps[600:], x[:, 600:])
    stream.flush()
    s2, y2 = stream.take()
    assert_close(np.concatenate([y1, y2], axis=1), predict_forces(model, x))
    np.testing.assert_allclose(stream.damage(), pseudo_damage(y2, 5.0), rtol=1e-12)


def test_short_segment_shorter_than_the_delay(model):
    x = synthetic_accel(5, seed=8)
    stream = ForceStream(Predictor(model), 128, 5.0)
    stream.feed(sample_stamps(5), x)
    stream.flush()
    s, y = stream.take()
    assert s.size == 5
    assert_close(y, predict_forces(model, x))


def test_causal_delay_setting_changes_latency_not_stamps(model):
    x = synthetic_accel(800, seed=9)
    stamps = sample_stamps(800)
    stream = ForceStream(Predictor(model, causal_delay_samples=8), 32, 5.0)
    assert stream.delay_samples == 8
    s, y = run(stream, stamps, x, np.random.default_rng(2))
    np.testing.assert_array_equal(s, stamps)
    assert_close(y, predict_forces(model, x, causal_delay_samples=8))


def test_bad_arguments(model):
    with pytest.raises(ConfigError, match='block_size'):
        ForceStream(Predictor(model), 0, 5.0)
    with pytest.raises(ConfigError, match='sn_slope'):
        ForceStream(Predictor(model), 8, -1.0)
    stream = ForceStream(Predictor(model), 8, 5.0)
    with pytest.raises(ShapeError, match='expected \\(12, 3\\)'):
        stream.feed(sample_stamps(3), np.zeros((11, 3)))


@pytest.fixture(scope='module')
def spin_model():
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import SPIN_ACCEL_CHANNELS
    return synthetic_model(n_taps=96, delay_samples=40, seed=5,
                           input_channels=INPUT_CHANNELS + SPIN_ACCEL_CHANNELS)


@pytest.mark.parametrize('block_size', [1, 16, 1000])
def test_spin_rows_enter_as_the_offline_spin_acceleration_per_segment(spin_model, block_size):
    # issue 33: the node feeds spin rates; each gap-free stretch is differentiated as the
    # offline reader differentiates a segment (central inside, one-sided at both ends of
    # each segment), one sample late, and every estimate keeps its sample's stamp (bugs
    # caught: differentiating across the gap, a one-sample shift of the spin channel or of
    # the stamps, the last sample of a segment lost at the flush)
    from wheel_force_estimator.core.derived import spin_acceleration
    n = 1500
    rng = np.random.default_rng(11)
    x = np.concatenate([synthetic_accel(n, seed=12),
                        30.0 + np.cumsum(rng.standard_normal((4, n)), axis=1) * 0.05])
    stamps = sample_stamps(n)
    keep = np.r_[0:700, 703:n]                       # three samples missing: two segments
    stream = ForceStream(Predictor(spin_model), block_size, 5.0, spin_rows=range(12, 16))
    assert stream.delay_samples == spin_model.fir_delay_samples + 1
    s, y = run(stream, stamps[keep], x[:, keep], np.random.default_rng(3))
    np.testing.assert_array_equal(s, stamps[keep])
    expected = []
    for lo, hi in ((0, 700), (703, n)):
        seg = x[:, lo:hi].copy()
        seg[12:] = spin_acceleration(seg[12:], stamps[lo:hi])
        expected.append(predict_forces(spin_model, seg))
    assert_close(y, np.concatenate(expected, axis=1))
    assert stream.counts['gaps'] == 1 and stream.counts['single_samples'] == 0


def test_spin_latency_is_one_more_sample_and_a_lone_sample_is_counted(spin_model):
    n = 200
    x = np.concatenate([synthetic_accel(n, seed=13), np.full((4, n), 20.0)])
    stamps = sample_stamps(n)
    stream = ForceStream(Predictor(spin_model), 1, 5.0, spin_rows=range(12, 16))
    stream.feed(stamps, x)
    s, _ = stream.take()
    # without spin the last fir_delay_samples are held; the spin derivative holds one more
    assert s.size == n - spin_model.fir_delay_samples - 1
    assert stream.in_flight == spin_model.fir_delay_samples + 1
    stream.flush()
    assert stream.take()[0].size == spin_model.fir_delay_samples + 1
    # one sample between two gaps: no derivative, no estimate, counted
    stream.feed(stamps[-1:] + 10 * 1_953_125, x[:, :1])
    stream.feed(stamps[-1:] + 20 * 1_953_125, x[:, :1])
    stream.flush()
    assert stream.take()[0].size == 0 and stream.counts['single_samples'] == 2
    with pytest.raises(ConfigError, match='spin_rows'):
        ForceStream(Predictor(spin_model), 8, 5.0, spin_rows=[16])


@pytest.fixture(scope='module')
def split_models():
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import SPIN_ACCEL_CHANNELS
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    return (synthetic_model(n_taps=96, delay_samples=40, seed=6,
                            input_channels=INPUT_CHANNELS + SPLIT_CHANNELS),
            synthetic_model(n_taps=96, delay_samples=40, seed=7,
                            input_channels=INPUT_CHANNELS + SPIN_ACCEL_CHANNELS
                            + SPLIT_CHANNELS + CORNERING_CHANNELS))


@pytest.mark.parametrize('block_size', [1, 16, 1000])
def test_split_rows_are_derived_per_segment_as_offline(split_models, block_size):
    # issue 29: the node feeds the accelerations (and spin rates) only; the stream derives
    # the traction/braking (and cornering) split, restarting its low-pass at each gap exactly
    # as the offline reader derives it per segment (bugs caught: the filter carried across a
    # gap, the split taken before the spin derivative releases its held sample, a row order
    # mix-up)
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.derived import specific_force_parts
    from wheel_force_estimator.core.derived import spin_acceleration
    split_model, spin_split_model = split_models
    n = 1500
    rng = np.random.default_rng(21)
    accel = synthetic_accel(n, seed=22)
    accel[0::3] += np.sin(np.arange(n) * 2 * np.pi / 900)[None] * 3.0   # braking and traction
    accel[1::3] += np.cos(np.arange(n) * 2 * np.pi / 700)[None] * 3.0   # left and right turns
    spin = 30.0 + np.cumsum(rng.standard_normal((4, n)), axis=1) * 0.05
    stamps = sample_stamps(n)
    keep = np.r_[0:700, 703:n]
    for model, fed, spin_rows, derived in (
            (split_model, accel, (), SPLIT_CHANNELS),
            (spin_split_model, np.concatenate([accel, spin]), range(12, 16),
             SPLIT_CHANNELS + CORNERING_CHANNELS)):
        stream = ForceStream(Predictor(model), block_size, 5.0, spin_rows=spin_rows,
                             derived=derived)
        s, y = run(stream, stamps[keep], fed[:, keep], np.random.default_rng(3))
        np.testing.assert_array_equal(s, stamps[keep])
        expected = []
        for lo, hi in ((0, 700), (703, n)):
            seg = fed[:, lo:hi].copy()
            if len(spin_rows):
                seg[12:] = spin_acceleration(seg[12:], stamps[lo:hi])
            seg = np.concatenate([seg, specific_force_parts(seg, model.fs_hz, derived)])
            expected.append(predict_forces(model, seg))
        assert_close(y, np.concatenate(expected, axis=1))
    with pytest.raises(ShapeError, match='expected \\(12, 3\\)'):
        ForceStream(Predictor(split_model), 8, 5.0, derived=SPLIT_CHANNELS).feed(
            sample_stamps(3), np.zeros((14, 3)))
