# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The known 12x12 system the CLI, live-estimator and fleet tests write their bags from."""
import numpy as np
from scipy import signal

FS_HZ = 512.0


def known_system(n, seed, road_gain=1.0):
    """
    Return ``(accel_mps2, force_n)``, each (12, n), of a fixed random linear system.

    Coloured inputs (seeded by ``seed``, scaled by ``road_gain``) through fixed random
    2nd-order paths (the same system for every seed), + gravity on z and a static load.
    """
    rng = np.random.default_rng(seed)
    b_in, a_in = signal.butter(2, 40 / (FS_HZ / 2))
    x = road_gain * signal.lfilter(b_in, a_in, rng.normal(size=(12, n)), axis=1)
    y = np.zeros((12, n))
    sys_rng = np.random.default_rng(99)
    for o in range(12):
        for i in range(12):
            gain = sys_rng.normal() * (300.0 if o == i else 30.0)
            b, a = signal.butter(2, sys_rng.uniform(5, 30) / (FS_HZ / 2))
            y[o] += gain * signal.lfilter(b, a, x[i])
    return x + np.array([0.0, 0.0, 9.81] * 4)[:, None], y + 3000.0
