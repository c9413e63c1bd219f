# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The search's least-squares factorisations of two nested input sets: bordered vs from scratch.

At the shipped live design (4 s history, 32 blocks per octave, 0.25 s two-sided look-ahead,
512 Hz) the ``accel`` set has 12 inputs and ``accel+split`` 14.  Per fold and ridge the
search needs both sets' FIRs at two look-aheads (the live 50 ms and the two-sided 0.25 s).

- ``baseline``: each set factorised on its own (:class:`.LagOrderedFactor`), as the search
  did until 2026-11-29;
- ``bordered``: the ``accel`` factor, and the larger set's bordered from it
  (:class:`.nested_factor.BorderedFactor`).

Prints both wall times (best of ``--repeat``) and the largest tap difference between the
two solutions (relative to the largest tap).  Inputs: coloured noise, 90 s, 12 outputs.

Usage: ``python bench/bench_nested_factor.py [--repeat 3]``
"""
import argparse
import time

import numpy as np
from scipy import signal

from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.nested_factor import BorderedFactor
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations

FS_HZ = 512.0
LOOKS_S = (0.05, 0.25)


def equations():
    """Return the 14-input normal equations of 90 s of coloured noise (12 outputs)."""
    rng = np.random.default_rng(0)
    n = int(90 * FS_HZ)
    b, a = signal.butter(2, 40.0, fs=FS_HZ)
    x = signal.lfilter(b, a, rng.normal(size=(14, n)), axis=1)
    y = rng.normal(size=(12, 14)) @ x + 0.1 * rng.normal(size=(12, n))
    design = LiveDesign(look_aheads_s=(LOOKS_S[-1],))
    d_max = look_ahead_samples(LOOKS_S[-1], FS_HZ)
    acc = CorrelationAccumulator(14, 12, design.max_lag(FS_HZ))
    acc.add(x, y)
    return NormalEquations(acc.result(FS_HZ), d_max, design)


def main() -> int:
    """Time both ways and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    full = equations()
    inner_eq = full.subset(tuple(range(12)))
    looks = [look_ahead_samples(v, FS_HZ) for v in LOOKS_S]
    times = {'baseline': [], 'bordered': []}
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        inner = LagOrderedFactor(inner_eq)
        [inner.estimator(d) for d in looks]
        alone = LagOrderedFactor(full)
        want = [alone.estimator(d) for d in looks]
        times['baseline'].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        inner = LagOrderedFactor(inner_eq)
        [inner.estimator(d) for d in looks]
        bordered = BorderedFactor(inner, full, full.info['regularisation'])
        got = [bordered.estimator(d) for d in looks]
        times['bordered'].append(time.perf_counter() - t0)
    diff = max(max(np.abs(g.fine_taps - w.fine_taps).max(), np.abs(g.coarse_taps
                                                                   - w.coarse_taps).max())
               / np.abs(w.fine_taps).max() for g, w in zip(got, want))
    n_unknowns = full.rhs.shape[0]
    print(f'two nested sets, 12 and 14 inputs ({inner_eq.rhs.shape[0]} and {n_unknowns} '
          f'unknowns), look-aheads {", ".join(f"{v * 1e3:.0f} ms" for v in LOOKS_S)}')
    for name, values in times.items():
        print(f'{name:10s} {min(values):7.2f} s (best of {len(values)})')
    print(f'speed-up {min(times["baseline"]) / min(times["bordered"]):.2f}x; largest tap '
          f'difference {diff:.1e} of the largest tap')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
