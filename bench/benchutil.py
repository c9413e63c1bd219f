# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the benchmark scripts (run as ``python bench/bench_x.py``)."""
import importlib
from pathlib import Path
import sys
import time


def test_support(name: str):
    """Import and return ``test/support/NAME.py``: fixtures the benchmarks share with tests."""
    root = str(Path(__file__).resolve().parents[1] / 'test')
    if root not in sys.path:
        sys.path.insert(0, root)
    return importlib.import_module(f'support.{name}')


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
