# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Timing helper shared by the benchmark scripts (run as ``python bench/bench_x.py``)."""
import time


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
