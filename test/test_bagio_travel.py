# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Suspension travel in bags (issue #14 item 5): ``suspension/joint_states``, JointState.

Written by our writer and, independently, message by message with rosbags (names in another
order, a NaN, a missing message); read on both paths; bad names refused; ``simulate --travel``
writes the simulator's compression; ``diagnose`` names a concealed bump stop from the travel.
"""
import json
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer

from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.bagio.reader import jazzy_typestore
from wheel_force_estimator.bagio.travel import JOINT_NAMES
from wheel_force_estimator.bagio.travel import TRAVEL_TYPE
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.errors import BagError

PERIOD_NS = 1_953_125
T0_NS = 3_000_000_000
N = 400
TOPIC = TopicConfig().travel_topic


def _signals(seed=0, n=N):
    rng = np.random.default_rng(seed)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    return stamp, rng.standard_normal((12, n)), 1e3 * rng.standard_normal((12, n)), \
        0.02 * rng.standard_normal((4, n))


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_travel_round_trip_both_paths(tmp_path, storage):
    stamp, accel, force, travel = _signals()
    path = write_recording(tmp_path / 'b', stamp, accel, force, travel_m=travel, storage=storage)
    for bulk in (True, False):
        rec = read_recording(path, bulk=bulk, travel=True)
        seg, = rec.segments
        assert np.array_equal(seg.travel_m.view(np.int64), travel.view(np.int64))
        assert np.array_equal(seg.accel_mps2, accel)
        assert rec.n_read[TOPIC] == N and rec.travel_topic == TOPIC
        assert rec.travel_dropped == (0, 0)


def test_bag_without_travel_reads_as_before(tmp_path):
    stamp, accel, force, travel = _signals()
    rec = read_recording(write_recording(tmp_path / 'b', stamp, accel, force), travel=True)
    assert rec.segments[0].travel_m is None and rec.travel_topic is None
    assert 'suspension travel' not in rec.summary()
    # travel not asked for (fit, predict, evaluate): skipped and listed
    path = write_recording(tmp_path / 'c', stamp, accel, force, travel_m=travel)
    rec = read_recording(path)
    assert rec.travel_topic is None and rec.segments[0].n_samples == N
    assert rec.skipped_topics == ((TOPIC, TRAVEL_TYPE),)


def _write_travel_bag(path, stamp, accel, force, messages, storage='mcap'):
    """Our writer for Imu/WFT, then rosbags' Writer adds the JointState messages."""
    src = write_recording(path.parent / (path.name + '_src'), stamp, accel, force,
                          storage=storage)
    from rosbags.rosbag2 import Reader
    store = jazzy_typestore()
    t = store.types
    writer = Writer(path, version=8, storage_plugin=(
        StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3))
    with Reader(src) as reader, writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        joint = writer.add_connection(TOPIC, TRAVEL_TYPE, typestore=store)
        out = [(ts, k, conns[c.id], data) for k, (c, ts, data) in enumerate(reader.messages())]
        for k, (stamp_ns, names, positions) in enumerate(messages):
            msg = t[TRAVEL_TYPE](
                header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](
                    sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9)), frame_id=''),
                name=list(names), position=np.array(positions, np.float64),
                velocity=np.zeros(0), effort=np.zeros(0))
            out.append((int(stamp_ns), 10**9 + k, joint, bytes(store.serialize_cdr(
                msg, TRAVEL_TYPE))))
        for ts, _, conn, data in sorted(out, key=lambda m: (m[0], m[1])):
            writer.write(conn, ts, data)
    return path


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_independent_writer_names_in_any_order_nan_and_missing_dropped(tmp_path, storage):
    stamp, accel, force, travel = _signals(1)
    order = [3, 0, 2, 1]  # rr, lf, lr, rf: matched by name, not by position
    names = [JOINT_NAMES[i] for i in order]
    messages = [(s, names, travel[order, i]) for i, s in enumerate(stamp)]
    messages[100] = (stamp[100], names, [np.nan, 0.0, 0.0, 0.0])  # a NaN: dropped
    del messages[250]  # a missing message: dropped
    path = _write_travel_bag(tmp_path / 'b', stamp, accel, force, messages, storage)
    for bulk in (True, False):
        rec = read_recording(path, bulk=bulk, travel=True)
        assert rec.travel_dropped == (1, 1)
        assert [s.n_samples for s in rec.segments] == [100, 149, 149]
        for seg in rec.segments:
            idx = ((seg.stamp_ns - T0_NS) // PERIOD_NS).astype(int)
            assert np.array_equal(seg.travel_m, travel[:, idx])  # nothing filled in
            assert np.array_equal(seg.accel_mps2, accel[:, idx])
        assert '2 sample(s) dropped from every channel (1 without travel, 1 not finite)' in \
            rec.summary()


def test_joint_names_not_matching_corners_exit_1(tmp_path, capsys):
    stamp, accel, force, travel = _signals(2)
    names = ['front_left', 'front_right', 'rear_left', 'rear_right']
    path = _write_travel_bag(tmp_path / 'b', stamp, accel, force,
                             [(s, names, travel[:, i]) for i, s in enumerate(stamp)])
    for bulk in (True, False):
        with pytest.raises(BagError, match=rf'{TOPIC}: joint names \[.front_left., '
                                           r'.*\] do not match the corners; expected '
                                           r'\[.lf_suspension., .rf_suspension., '
                                           r'.lr_suspension., .rr_suspension.\]'):
            read_recording(path, bulk=bulk, travel=True)
    rc = main(['diagnose', '--real', str(path), '--sim', str(path), '--json',
               str(tmp_path / 'd.json')])
    err = capsys.readouterr().err
    assert rc == 1 and 'front_left' in err and 'lf_suspension' in err and TOPIC in err
    assert 'Traceback' not in err


def test_travel_off_the_sample_clock_is_refused(tmp_path):
    stamp, accel, force, travel = _signals(3)
    shifted = [(s + PERIOD_NS // 2, JOINT_NAMES, travel[:, i]) for i, s in enumerate(stamp)]
    path = _write_travel_bag(tmp_path / 'b', stamp, accel, force, shifted)
    with pytest.raises(BagError, match=rf'{TOPIC}: stamp \d+ ns .* is not a sample of the '
                                       r'spindle topics \(400 such\)'):
        read_recording(path, travel=True)


def test_simulate_travel_writes_the_simulated_compression(tmp_path):
    from wheel_force_estimator.sim.api import simulate
    out = tmp_path / 'sim'
    assert main(['simulate', str(out), '--course', 'speed_bump', '--duration-scale', '0.1',
                 '--seed', '3', '--travel']) == 0
    rec = read_recording(out, travel=True)
    result = simulate('speed_bump', (), 3, 0.1)
    seg, = rec.segments
    assert np.array_equal(seg.travel_m, result.states['suspension_compression_m'])
    # without --travel there is no travel topic
    assert main(['simulate', str(tmp_path / 'plain'), '--course', 'speed_bump',
                 '--duration-scale', '0.1']) == 0
    assert read_recording(tmp_path / 'plain', travel=True).travel_topic is None


@pytest.mark.slow
def test_concealed_bump_stop_is_named_from_bags_with_travel(tmp_path, capsys):
    # The pair of test_diagnosis_sim_silent's travel case, as bags a user would hand over: the
    # stop (concealed: the spindle accelerations alone do not show it) is named from the travel
    # topic through `wheel-force diagnose`, on the vertical channels, with a gap near the
    # simulated 33 mm; a matched pair without a stop names nothing.
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.api import write_result
    from wheel_force_estimator.sim.concealment import concealed_params
    seed = 4

    def bag(name, effect, run_seed, scale):
        params = concealed_params(effect) if effect else None
        result = simulate('proving_ground', (effect,) if effect else (), run_seed, scale,
                          effect_params=params)
        return write_result(tmp_path / name, result, travel=True)

    sim = bag('sim', None, seed, 0.2)
    cases = {'bump_stop': None, 'none': None}
    for effect in cases:
        real = bag(f'real_{effect}', None if effect == 'none' else effect, seed, 0.2)
        holdout = bag(f'holdout_{effect}', None if effect == 'none' else effect, seed + 100,
                      0.5)
        out = tmp_path / f'{effect}.json'
        assert main(['diagnose', '--real', str(real), '--sim', str(sim), '--holdout',
                     str(holdout), '--json', str(out)]) == 0
        assert 'diagnosing travel -> vertical force' in capsys.readouterr().out
        cases[effect] = json.loads(Path(out).read_text())
    found = cases['bump_stop']['findings']
    assert found and all(f['physics'] == 'bump_stop' for f in found), found
    named = {c for f in found for c in f['channels']}
    assert named <= {c for c in OUTPUT_CHANNELS if c.endswith('fz')} and len(named) >= 3
    for f in found:
        assert 0.025 < f['parameters']['gap_m'] < 0.036, f['parameters']
    # The static law on the sim travel is not an FRF and cannot be written; the written model
    # is built on the FIR fitted from the real travel, which does far worse here (seed 4,
    # integration run: 51.4 % against 21.1 % for the static law, Fz mean) - measured, not
    # asserted as a gain (as in test_concealed_bump_stop_is_named_from_suspension_travel).
    # Every written row comes from the real travel's FIR, whole or combined per channel (the
    # joint strengths on some channels since they compete as a candidate: `per_channel`).
    fit = cases['bump_stop']['fit']
    sources = set(fit.get('rows_from', {}).values()) or {fit['model']}
    assert sources <= {'real_frf+physics', 'real_linear'}, fit
    assert cases['none']['findings'] == []
