# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Time rainflow / pseudo damage on one hour of random-road force at 512 Hz.

Prints measured figures next to baselines measured in the same run: ``numpy.sort`` of the same
channel (an O(n log n) pass every reader can place) and the same four-point stack loop run as
plain Python (numba's ``py_func``, no JIT) on a slice, extrapolated to the hour.
"""
import time

from benchutil import best_of
import numpy as np
from scipy import signal

from wheel_force_estimator.core import fatigue
from wheel_force_estimator.core import rainflow

FS_HZ = 512.0
DURATION_S = 3600.0
N_CHANNELS = 12


def road_force_n(rng, n):
    """Return a wheel-force-like record: body (1.5 Hz) and wheel-hop (12 Hz) resonances."""
    white = rng.standard_normal(n)
    force = np.zeros(n)
    for f_hz, zeta, gain_n in ((1.5, 0.3, 800.0), (12.0, 0.15, 400.0)):
        sos = signal.butter(2, (f_hz * (1 - zeta), f_hz * (1 + zeta)), btype='bandpass',
                            fs=FS_HZ, output='sos')
        part = signal.sosfilt(sos, white)
        force += gain_n * part / part.std()
    return 4000.0 + force + 20.0 * rng.standard_normal(n)


def python_stack_loop_s(points):
    """Time the four-point loop as plain Python (no JIT) on ``points``."""
    jitted = rainflow._push_point
    rainflow._push_point = jitted.py_func  # the py_func below looks the helper up here
    try:
        stack = np.empty(points.size)
        cycles = np.empty((2, points.size // 2))
        t0 = time.perf_counter()
        rainflow._count_points.py_func(points, stack, cycles)
        return time.perf_counter() - t0
    finally:
        rainflow._push_point = jitted


def main():
    """Run the benchmark and print the figures."""
    rng = np.random.default_rng(2026)
    n = int(FS_HZ * DURATION_S)
    x = road_force_n(rng, n)
    fatigue.pseudo_damage(x[:1000])  # JIT compile / cache load outside the timings
    rainflow.rainflow(x[:1000])
    stream = fatigue.StreamingDamage(N_CHANNELS)
    stream.update(np.zeros((N_CHANNELS, 3)))
    stream.damage()

    print(f'one channel, {DURATION_S / 3600:.0f} h at {FS_HZ:.0f} Hz = {n} samples')
    t_sort, _ = best_of(lambda: np.sort(x))
    print(f'  baseline numpy.sort                 {t_sort * 1e3:8.1f} ms')
    t_tp, points = best_of(lambda: rainflow.turning_points(x))
    print(f'  turning_points                      {t_tp * 1e3:8.1f} ms '
          f'({points.size} points)')
    t_rf, cycles = best_of(lambda: rainflow.rainflow(x))
    print(f'  rainflow                            {t_rf * 1e3:8.1f} ms '
          f'({int(np.sum(cycles.counts == 1.0))} closed, {int(np.sum(cycles.counts < 1.0))} '
          'residue half cycles)')
    t_pd, _ = best_of(lambda: fatigue.pseudo_damage(x))
    print(f'  pseudo_damage                       {t_pd * 1e3:8.1f} ms')
    part = points[:100_000]
    t_py = python_stack_loop_s(part) * points.size / part.size
    t_jit, _ = best_of(lambda: rainflow._count_points(
        points, np.empty(points.size), np.empty((2, points.size // 2))))
    print(f'  stack loop numba                    {t_jit * 1e3:8.1f} ms')
    print(f'  baseline stack loop plain Python    {t_py * 1e3:8.1f} ms '
          f'(extrapolated from {part.size} points)')
    t_rds, _ = best_of(lambda: fatigue.relative_damage_spectrum(x, FS_HZ), repeat=1)
    print(f'  relative_damage_spectrum (5 bands)  {t_rds * 1e3:8.1f} ms')

    x12 = np.stack([road_force_n(rng, int(FS_HZ * 120)) for _ in range(N_CHANNELS)])
    print(f'streaming, {N_CHANNELS} channels, {x12.shape[1]} samples')
    for block in (64, 512):
        stream.reset()
        starts = range(0, x12.shape[1], block)
        t0 = time.perf_counter()
        for start in starts:
            stream.update(x12[:, start:start + block])
        t_update = (time.perf_counter() - t0) / len(starts)
        t_damage, streamed = best_of(stream.damage, repeat=20)
        batch = fatigue.pseudo_damage(x12)
        err = np.max(np.abs(streamed / batch - 1.0))
        print(f'  block {block:4d}: update {t_update * 1e6:7.1f} us, damage() '
              f'{t_damage * 1e6:6.1f} us, block period {block / FS_HZ * 1e3:6.1f} ms, '
              f'max |stream/batch - 1| = {err:.1e}')
    t_b, _ = best_of(lambda: fatigue.pseudo_damage(x12))
    print(f'  batch pseudo_damage of the same     {t_b * 1e3:8.1f} ms')


if __name__ == '__main__':
    main()
