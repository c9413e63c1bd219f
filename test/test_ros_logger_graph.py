# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The node in a vehicle logger graph, through real rclpy/DDS (issue 31).

Four IMU drivers with their own clocks (stamps jittered around the sample grid) and a replay
paused in the middle: in both, every sample must come out, equal to offline
``predict --causal`` on the same data.
"""
import signal
import time

import numpy as np
import pytest
from rclpy.qos import ReliabilityPolicy
from support.loggers import Loggers
from support.loggers import stop_and_collect
from support.ros_testing import remove_dead_shared_memory
from support.ros_testing import sample_stamps
from support.ros_testing import start_node
from support.ros_testing import stop_node
from support.ros_testing import synthetic_accel
from support.ros_testing import synthetic_model
from support.ros_testing import wait_until

from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.ros.diagnostics import status_values

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

FS_HZ = 512.0
PERIOD_NS = 1e9 / FS_HZ
DELAY = 48
CORNERS = ('lf', 'rf', 'lr', 'rr')
# The node and predict_forces run the same Predictor; they differ by FFT rounding only
# (~1e-15 of the force scale).  A misplaced or lost sample, or a restarted filter, is O(1).
RTOL = 1e-9
# Reliable inputs, set the standard way: these tests count every sample, which best-effort
# delivery on a loaded 2-core machine cannot promise (the best-effort default has its own
# test below).
RELIABLE_INPUTS = {f'qos_overrides./spindle/{c}/imu.subscription.{policy}': value
                   for c in CORNERS for policy, value in (('reliability', 'reliable'),
                                                          ('depth', 5000))}
NODE_PARAMS = dict(RELIABLE_INPUTS, live_look_ahead_s=DELAY / FS_HZ,
                   damage_publish_period_s=0.5)


@pytest.fixture(scope='module')
def model_and_file(tmp_path_factory):
    model = synthetic_model(fs_hz=FS_HZ, n_taps=160, delay_samples=DELAY, seed=51)
    return model, save_model(model, tmp_path_factory.mktemp('model') / 'model.npz')


@pytest.mark.slow
def test_corners_from_separate_clocks_give_every_sample_equal_to_offline(
        ros_env, model_and_file, tmp_path):
    # Bug caught: exact-stamp matching (nothing out), a corner paired with its neighbour
    # sample, or jitter taken for gaps (filter restarted: O(1) errors after each).
    model, path = model_and_file
    n = 2048
    rng = np.random.default_rng(52)
    grid = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=53)
    jitter = [np.round(rng.uniform(-0.2, 0.2, n) * PERIOD_NS).astype(np.int64)
              for _ in CORNERS]
    corner_stamps = [grid + j for j in jitter]
    log = tmp_path / 'node.log'
    proc = start_node(path, ros_env, NODE_PARAMS, log_path=log)
    peer = Loggers('jittered_loggers')
    try:
        assert peer.wait_for_node(), 'node did not come up'
        peer.publish(corner_stamps, accel, rate=2.0)
        stop_and_collect(proc, peer, n)
    finally:
        peer.close()
        stop_node(proc)
    expected = predict_forces(model, accel, DELAY)
    ordered = np.sort(np.stack(corner_stamps), axis=0)
    median = ordered[1] + (ordered[2] - ordered[1]) // 2
    for c, corner in enumerate(CORNERS):
        stamps, wrench = peer.forces(corner)
        np.testing.assert_array_equal(stamps, median)
        np.testing.assert_allclose(wrench[:3], expected[3 * c:3 * c + 3], rtol=0,
                                   atol=RTOL * np.abs(expected).max())
    text = log.read_text()
    assert 'input gap' not in text and 'sync_tolerance_s' not in text
    last = {s.name.rsplit(': ', 1)[-1]: status_values(s) for s in peer.health[-1].status}
    assert [last[c]['dropped'] for c in CORNERS] == ['0'] * 4


@pytest.mark.slow
def test_a_two_second_pause_keeps_the_filter_output_equals_offline(
        ros_env, model_and_file, tmp_path):
    # Bug caught: a steady-clock stall taken for the end of the data (look-ahead flushed with
    # zeros before the pause, filter restarted after it): O(1) errors either side.
    model, path = model_and_file
    n = 2048
    stamps = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=54)
    log = tmp_path / 'node.log'
    proc = start_node(path, ros_env, NODE_PARAMS, log_path=log)
    peer = Loggers('paused_replay')
    half = 1000                       # not a multiple of the block: a partial block waits too
    try:
        assert peer.wait_for_node(), 'node did not come up'
        peer.publish([stamps[:half]] * 4, accel[:, :half], rate=2.0)
        time.sleep(2.0)
        # Held during the pause: the look-ahead and the partial block, nothing flushed.
        assert max(len(r) for r in peer.raw.values()) <= half - DELAY
        paused = [status_values(s) for s in peer.health[-1].status
                  if s.name.endswith(': lf')][0]
        assert paused['stale'] == 'true', paused
        peer.publish([stamps[half:]] * 4, accel[:, half:], rate=2.0)
        stop_and_collect(proc, peer, n)
    finally:
        peer.close()
        stop_node(proc)
    expected = predict_forces(model, accel, DELAY)
    for c, corner in enumerate(CORNERS):
        got_stamps, wrench = peer.forces(corner)
        np.testing.assert_array_equal(got_stamps, stamps)
        np.testing.assert_allclose(wrench[:3], expected[3 * c:3 * c + 3], rtol=0,
                                   atol=RTOL * np.abs(expected).max())
    text = log.read_text()
    assert 'held for the look-ahead' in text and 'input gap' not in text


@pytest.mark.slow
def test_shipped_best_effort_inputs_at_1x_equal_offline(ros_env, model_and_file, tmp_path):
    # The shipped QoS (best-effort inputs, depth 200) with no override: the path every
    # plain `ros2 run` takes.  Bug caught: a default profile that matches no publisher, or
    # samples best effort lost taken for present (estimates across the hole).  Best effort
    # may lose messages when this 2-core machine is overloaded: what arrived must then be
    # exactly the offline estimate of each stretch without a hole.
    model, path = model_and_file
    n = 1024                                    # 2 s at 1x
    stamps = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=55)
    log = tmp_path / 'node.log'
    proc = start_node(path, ros_env, {'live_look_ahead_s': DELAY / FS_HZ}, log_path=log)
    peer = Loggers('best_effort_path')
    try:
        assert peer.wait_for_node(), 'node did not come up'
        infos = peer.node.get_subscriptions_info_by_topic('/spindle/lf/imu')
        assert [i.qos_profile.reliability for i in infos] == [ReliabilityPolicy.BEST_EFFORT]
        peer.publish([stamps] * 4, accel, rate=1.0, burst=1)
        time.sleep(1.5)                         # two health periods: the counters settle
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 0
        last = {s.name.rsplit(': ', 1)[-1]: status_values(s) for s in peer.health[-1].status}
        published = int(last['lf']['published'])
        assert published >= n // 2, last['lf']
        assert wait_until(lambda: all(len(r) == published for r in peer.raw.values()), 5.0)
    finally:
        peer.close()
        stop_node(proc)
    got_stamps, _ = peer.forces('lf')
    index = np.searchsorted(stamps, got_stamps)
    np.testing.assert_array_equal(stamps[index], got_stamps)
    cuts = np.flatnonzero(np.diff(index) > 1) + 1
    for c, corner in enumerate(CORNERS):
        got_stamps, wrench = peer.forces(corner)
        np.testing.assert_array_equal(got_stamps, stamps[index])
        for part, cols in zip(np.split(index, cuts), np.split(np.arange(index.size), cuts)):
            expected = predict_forces(model, accel[:, part], DELAY)
            np.testing.assert_allclose(wrench[:3, cols], expected[3 * c:3 * c + 3], rtol=0,
                                       atol=RTOL * np.abs(expected).max())
    assert 'deprecated' not in log.read_text()


@pytest.mark.slow
def test_health_carries_the_damage_budget_and_a_running_stamp_without_clock(
        ros_env, model_and_file, tmp_path):
    # Bug caught: the budget ERROR only on the damage topic, or a health stamp of 0 under
    # use_sim_time with no /clock (rqt_robot_monitor shows it as stale).
    _, path = model_and_file
    n = 512
    stamps = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=56)
    proc = start_node(path, ros_env, dict(NODE_PARAMS, use_sim_time=True, damage_budget=1.0),
                      log_path=tmp_path / 'node.log')
    peer = Loggers('budget')
    try:
        assert peer.wait_for_node(), 'node did not come up'
        peer.publish([stamps] * 4, accel, rate=2.0)

        def over_budget():
            status = {s.name: s for s in peer.health[-1].status} if peer.health else {}
            node = status.get('/wheel_force_node')
            return node is not None and node.level == b'\x02'
        assert wait_until(over_budget, 10.0), peer.health[-1] if peer.health else None
        status = {s.name: s for s in peer.health[-1].status}
        assert 'damage budget exceeded' in status['/wheel_force_node'].message
        assert all(status[f'/wheel_force_node: {c}'].level == b'\x02' for c in CORNERS)
        assert status['/wheel_force_node'].hardware_id == '/wheel_force_node'
        stamp = peer.health[-1].header.stamp
        assert stamp.sec > 0                      # the steady clock: no /clock was published
        assert time.clock_gettime(time.CLOCK_MONOTONIC) - (stamp.sec + 1e-9 * stamp.nanosec) \
            < 5.0
    finally:
        peer.close()
        assert stop_node(proc) == 0


@pytest.mark.slow
def test_shutdown_under_a_stalled_subscriber_within_5_s_and_twice_at_once(
        ros_env, model_and_file, tmp_path):
    # A reliable subscriber frozen (SIGSTOP: it never acknowledges).  Bugs caught: one
    # acknowledgement wait per publisher one after another (10 s, launch escalates at 5 s),
    # and a second Ctrl-C that does nothing.
    import subprocess
    import sys
    from pathlib import Path
    _, path = model_and_file
    counter = Path(__file__).resolve().parent / 'support' / 'ros_testing.py'
    topics = [f'/virtual_wft/{c}/wrench' for c in CORNERS] + ['/virtual_wft/damage']
    n = 1024
    stamps = sample_stamps(n)
    accel = synthetic_accel(n, FS_HZ, seed=57)
    elapsed = {}
    for run in ('once', 'twice'):
        log = tmp_path / f'{run}.log'
        proc = start_node(path, ros_env, NODE_PARAMS, log_path=log)
        reader = subprocess.Popen(
            [sys.executable, str(counter), 'reliable', '5', str(10 * n), '60', *topics[:4]],
            env=ros_env, stdout=subprocess.PIPE, text=True)
        peer = Loggers(f'stalled_{run}')
        try:
            assert reader.stdout.readline().strip() == 'ready'
            assert peer.wait_for_node(), 'node did not come up'
            time.sleep(0.5)
            reader.send_signal(signal.SIGSTOP)
            peer.publish([stamps] * 4, accel, rate=4.0)
            time.sleep(0.5)
            started = time.monotonic()
            proc.send_signal(signal.SIGINT)
            if run == 'twice':
                time.sleep(0.3)
                proc.send_signal(signal.SIGINT)
            code = proc.wait(20)
            elapsed[run] = time.monotonic() - started
        finally:
            peer.close()
            stop_node(proc)
            # The reader thawed and stopped like Ctrl-C: killed, it left its shared-memory
            # ports, and the next run's reader, same domain and participant id, was never
            # discovered (remove_dead_shared_memory).
            reader.send_signal(signal.SIGCONT)
            stop_node(reader)
            # The second Ctrl-C exits at once (os._exit): its ports stay behind too.
            remove_dead_shared_memory()
        text = log.read_text()
        if run == 'once':
            assert code == 0
            assert 'not every subscriber acknowledged' in text
        else:
            assert code == 130
            assert 'SIGINT again: exiting at once' in text and 'not published' in text
    assert elapsed['once'] < 5.0, elapsed
    assert elapsed['twice'] < elapsed['once'] and elapsed['twice'] < 1.5, elapsed
