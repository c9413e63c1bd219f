# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Replay tool: settings, config, CLI errors, publishing without a node."""
import subprocess
import sys

import numpy as np
import pytest
from support.ros_testing import isolated_ros_env
from support.ros_testing import sample_stamps

from wheel_force_estimator.cli.node import build_ros_args
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.ros.replay import imu_frame_ids_from_config
from wheel_force_estimator.ros.replay import replay_samples
from wheel_force_estimator.ros.replay import ReplaySettings

pytestmark = pytest.mark.ros


@pytest.mark.parametrize('kwargs, match', [
    ({'rate': 0.0}, 'rate must be'),
    ({'rate': float('inf')}, 'rate must be'),
    ({'imu_frame_ids': ('a', 'b')}, 'imu_frame_ids'),
    ({'settle_s': -1.0}, 'settle_s'),
    ({'qos_depth': 0}, 'qos_depth'),
])
def test_settings_are_validated(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        ReplaySettings(**kwargs)


def test_imu_frame_ids_follow_the_node_config(tmp_path):
    assert imu_frame_ids_from_config(None) == ('lf_spindle', 'rf_spindle', 'lr_spindle',
                                               'rr_spindle')
    cfg = tmp_path / 'p.yaml'
    cfg.write_text('wheel_force_node:\n  ros__parameters:\n'
                   '    imu_frame_ids: ["a", "", "c", "d"]\n')
    assert imu_frame_ids_from_config(cfg) == ('a', 'rf_spindle', 'c', 'd')
    cfg.write_text('wheel_force_node:\n  ros__parameters:\n    imu_frame_ids: ["a"]\n')
    with pytest.raises(ConfigError, match='imu_frame_ids must be'):
        imu_frame_ids_from_config(cfg)
    with pytest.raises(ConfigError, match='cannot read'):
        imu_frame_ids_from_config(tmp_path / 'missing.yaml')


def test_node_cli_builds_ros_arguments(tmp_path):
    args = build_ros_args(tmp_path / 'c.yaml', 'm.npz', ['-p', 'block_size:=64'])
    assert args[1:] == ['--ros-args', '--params-file', str(tmp_path / 'c.yaml'), '-p',
                        'model_path:=m.npz', '--ros-args', '-p', 'block_size:=64']


def test_replay_cli_reports_a_missing_bag_without_traceback(tmp_path):
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator', 'replay',
                           str(tmp_path / 'nope')], capture_output=True, text=True, timeout=60,
                          env=isolated_ros_env())
    assert proc.returncode == 1
    assert 'nope' in proc.stderr and 'Traceback' not in proc.stderr
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator', 'replay', 'x',
                           '--rate', 'fast'], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2


def test_replay_without_node_publishes_on_schedule(monkeypatch):
    for key, value in isolated_ros_env().items():
        monkeypatch.setenv(key, value)
    rate = 8.0
    stamps = sample_stamps(1024)
    settings = ReplaySettings(rate=rate, wait_subscribers_s=0.0, match_delay_s=0.0,
                              record=True, settle_s=0.1)
    result = replay_samples(stamps, np.zeros((12, 1024)), settings)
    assert result.n_samples == 1024
    # The last sample is due (stamp span) / rate after the first: 2.0 s / 8 = 0.25 s.  The
    # player sleeps until each sample is due, so it cannot finish earlier (a rate applied
    # twice would take 31 ms); it ends later only by the lateness it measured itself
    # (max_behind_s) plus the publishing of one last burst (32 samples x 4 corners, well under
    # 50 ms), so a replay at half the rate (0.5 s) fails too.  Whatever the lateness, a replay
    # that ignores --rate takes the 2 s of real time, over half of which is refused.
    due_s = (stamps[-1] - stamps[0]) * 1e-9 / rate
    assert due_s <= result.wall_s <= due_s + result.max_behind_s + 0.05
    assert result.wall_s < 0.5 * rate * due_s
    assert result.output_stamp_ns.size == 0 and result.output_counts == (0, 0, 0, 0)
    assert result.damage is None
    with pytest.raises(ShapeError, match='not increasing'):
        replay_samples(stamps[::-1], np.zeros((12, 1024)), settings)
