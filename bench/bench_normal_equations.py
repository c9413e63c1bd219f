# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The least-squares FIR's normal matrix: build, factorisation and leading-block solves vs baselines.

At the shipped live design (4 s history, 48 blocks per octave, 12 inputs, 512 Hz, the
search's longest look-ahead 0.25 s) the normal matrix has ~5300 unknowns per row, and the search
builds it once per input set and solves with leading blocks of its Cholesky factor many times
(one leading block per look-ahead).

- matrix build: the shipped :attr:`.NormalEquations.a` (the blocks with ``j >= i`` gathered,
  mirrored) against the way it was built until 2026-12-02 (every block gathered, then
  ``0.5 (a + aᵀ)``), and the largest difference relative to the largest element;
- Cholesky factorisation of the C-ordered matrix (scipy copies it to Fortran order first)
  against that of its transpose (the same symmetric matrix, already in Fortran order);
- leading-block solve, 12 right-hand sides, look-aheads 0 and 50 ms of the 0.25 s factor:
  ``scipy.linalg.solve_triangular`` of the leading block (which scipy copies to a contiguous
  array first) against :func:`.normal_equations.solve_leading` (zero padding, the whole factor).

Prints the best of ``--repeat`` wall times.  Inputs: coloured noise, 90 s, 12 outputs.

Usage: ``python bench/bench_normal_equations.py [--repeat 3]``
"""
import argparse
import time

import numpy as np
from scipy import linalg
from scipy import signal

from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations
from wheel_force_estimator.core.normal_equations import solve_leading

FS_HZ = 512.0
N_IN = 12
DESIGN = LiveDesign(history_s=4.0, blocks_per_octave=48)


def equations() -> NormalEquations:
    """Return the equations of 90 s of coloured noise at the longest look-ahead."""
    rng = np.random.default_rng(0)
    n = int(90 * FS_HZ)
    b, a = signal.butter(2, 40 / (FS_HZ / 2))
    x = signal.lfilter(b, a, rng.normal(size=(N_IN, n)), axis=1)
    y = rng.normal(size=(12, N_IN)) @ x + 0.1 * rng.normal(size=(12, n))
    d_max = look_ahead_samples(0.25, FS_HZ)
    acc = CorrelationAccumulator(N_IN, 12, d_max + int(DESIGN.history_s * FS_HZ) + 2)
    acc.add(x, y)
    return NormalEquations(acc.result(FS_HZ), d_max, DESIGN)


def full_gather_build(eq: NormalEquations) -> np.ndarray:
    """Return the normal matrix built as until 2026-12-02 (the baseline)."""
    rxx, t_max, edges, n_in = eq._rxx, eq._t_max, eq.edges, eq.n_in
    n_b = edges.size - 1
    start, end = edges[:-1], edges[1:]
    shift = 2 * t_max + 1
    pp = (end[:, None] - 1 - start[None, :] + shift, start[:, None] - 1 - start[None, :] + shift,
          end[:, None] - 1 - end[None, :] + shift, start[:, None] - 1 - end[None, :] + shift)
    a = np.empty((n_in, n_b, n_in, n_b))
    zeros = np.zeros((n_in, 1))
    for i in range(n_in):
        r = np.zeros((n_in, 4 * t_max + 1))
        r[:, t_max:3 * t_max + 1] = rxx[i]
        c2 = np.concatenate([zeros, np.cumsum(np.cumsum(r, axis=-1), axis=-1)], axis=-1)
        a[i] = (c2[:, pp[0]] - c2[:, pp[1]] - c2[:, pp[2]] + c2[:, pp[3]]).transpose(1, 0, 2)
    a = a.reshape(n_in * n_b, n_in * n_b)
    a = 0.5 * (a + a.T)
    a[np.diag_indices_from(a)] += eq.info['regularisation'] * eq.ridge_unit
    return a


def best(fn, repeat: int):
    """Return (best wall time [s], last result) of ``repeat`` calls."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> int:
    """Time both builds and both solves and print them."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    eq = equations()
    n = eq.rhs.shape[0]
    t_old, a_old = best(lambda: full_gather_build(eq), args.repeat)

    def shipped():
        eq.__dict__.pop('a', None)
        return eq.a

    t_new, a_new = best(shipped, args.repeat)
    diff = np.abs(a_new - a_old).max() / np.abs(a_old).max()
    print(f'normal matrix, {n} unknowns: full gather + symmetrise {t_old:.2f} s, '
          f'half gather + mirror {t_new:.2f} s ({t_old / t_new:.1f}x); '
          f'largest difference {diff:.1e}')
    del a_old
    a = eq.a
    t_c, l_c = best(lambda: linalg.cholesky(a, lower=True, check_finite=False), args.repeat)
    t_f, l_f = best(lambda: linalg.cholesky(a.T, lower=True, check_finite=False), args.repeat)
    diff = np.abs(l_f - l_c).max() / np.abs(l_c).max()
    print(f'Cholesky factorisation: of the C-ordered matrix (copied to Fortran order) '
          f'{t_c:.2f} s, of its transpose (no copy) {t_f:.2f} s ({t_c / t_f:.2f}x); largest '
          f'difference {diff:.1e}')
    del l_c, l_f
    factor = LagOrderedFactor(eq)
    lower = factor.cholesky
    for look_s in (0.0, 0.05):
        d = look_ahead_samples(look_s, FS_HZ)
        m = factor.order(d).size
        b = eq.rhs[factor.order(d)]
        t_copy, x_copy = best(lambda: linalg.solve_triangular(
            lower[:m, :m], b, lower=True, check_finite=False), args.repeat)
        t_pad, x_pad = best(lambda: solve_leading(lower, m, b, transposed=False), args.repeat)
        diff = np.abs(x_pad - x_copy).max() / np.abs(x_copy).max()
        print(f'leading-block solve, look-ahead {1000 * look_s:.0f} ms ({m} of {n} unknowns, '
              f'12 right-hand sides): copied block {1000 * t_copy:.0f} ms, zero-padded '
              f'{1000 * t_pad:.0f} ms ({t_copy / t_pad:.1f}x); largest difference {diff:.1e}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
