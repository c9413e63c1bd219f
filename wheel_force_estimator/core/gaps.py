# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The gap rule: where a stream of sample stamps stops being one contiguous recording.

One rule for the offline reader (:mod:`wheel_force_estimator.bagio.align`) and the live node
(:mod:`wheel_force_estimator.ros.stream`), so that each gap-free stretch the node sees is
exactly a segment ``predict`` sees, and the two estimate it identically.

A step between consecutive stamps of nominal period ``T`` is

* a **gap** when it is longer than :data:`GAP_FACTOR` ``* T``: at least one sample is missing
  (a step of 1.5 T is as far from one period as from two; clock jitter of a real logger is a
  few per cent);
* **too short** when it is under :data:`MIN_STEP_FACTOR` ``* T``: no single sample clock of
  period ``T`` produces it (another rate, or two clocks mixed).  Offline this rejects the
  recording; live the stream is cut there and the fault counted.

Steps in between belong to one contiguous stretch.
"""
from typing import Tuple

import numpy as np

#: A step longer than this many nominal periods means missing samples.
GAP_FACTOR = 1.5
#: A step shorter than this many nominal periods cannot come from one sample clock.
MIN_STEP_FACTOR = 0.5


def classify_steps(step_ns, period_ns: float) -> Tuple[np.ndarray, np.ndarray]:
    """
    Classify stamp steps as gaps or impossible (too short) steps.

    Parameters
    ----------
    step_ns : array_like, shape (m,), int
        Differences between consecutive stamps [ns].
    period_ns : float
        Nominal sample period [ns], > 0.

    Returns
    -------
    gap : numpy.ndarray, shape (m,), bool
        Steps longer than ``GAP_FACTOR * period_ns``.
    too_short : numpy.ndarray, shape (m,), bool
        Steps shorter than ``MIN_STEP_FACTOR * period_ns``.

    """
    step = np.asarray(step_ns)
    return step > GAP_FACTOR * period_ns, step < MIN_STEP_FACTOR * period_ns


def missing_samples(step_ns: int, period_ns: float) -> int:
    """Return the number of samples missing in a step of ``step_ns`` (rounded, >= 0)."""
    return max(int(round(step_ns / period_ns)) - 1, 0)
