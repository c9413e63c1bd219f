# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Fixtures shared by the test files that start real ROS participants."""
import pytest

from wheel_force_estimator.ros.testing import isolated_ros_env


@pytest.fixture
def ros_env(monkeypatch):
    """Return a random-domain, localhost-only ROS environment, also set for this process."""
    env = isolated_ros_env()
    for key in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'RMW_IMPLEMENTATION'):
        monkeypatch.setenv(key, env[key])
    return env
