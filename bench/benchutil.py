# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the benchmark scripts (run as ``python bench/bench_x.py``)."""
import importlib
from pathlib import Path
import sys
import time

#: The tests' support package (``test/support``): the ROS helpers live there, not in the
#: installed package.
TEST_DIR = Path(__file__).resolve().parents[1] / 'test'
#: ``test/support/ros_testing.py``, also run as a script (the message counter process).
ROS_TESTING_SCRIPT = TEST_DIR / 'support' / 'ros_testing.py'


def test_support(name: str):
    """Return the module ``test/support/<name>.py`` (test fixtures the package does not ship)."""
    if str(TEST_DIR) not in sys.path:
        sys.path.insert(0, str(TEST_DIR))
    return importlib.import_module(f'support.{name}')


def ros_testing():
    """Return the module ``test/support/ros_testing.py`` (synthetic models, DDS isolation)."""
    return test_support('ros_testing')


def best_of(func, repeat=3):
    """
    Return the best wall time of ``repeat`` calls of ``func()`` [s], and the last result.

    The minimum is the figure least disturbed by other load on a shared machine.
    """
    best = float('inf')
    result = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = func()
        best = min(best, time.perf_counter() - t0)
    return best, result
