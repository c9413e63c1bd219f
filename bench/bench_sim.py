# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Time the proving-ground simulator: 10 min of course, numba compile, pure-Python baseline.

Prints (all measured in this run):
- numba compile time: first call with an empty numba cache directory (a fresh machine),
  minus a second call in the same process;
- the default 10 min ``proving_ground`` course end to end (course, integration, decimation,
  noise): wall time and real-time factor, with the integrator's share;
- the RK4 integrator's cost per step with numba and the same code as plain Python
  (``NUMBA_DISABLE_JIT=1``) on a short slice, extrapolated to the course.
The brief's budget is 10 min of course in <= 60 s.
"""
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

COURSE_S = 600.0
SLICE_STEPS_PY = 400  # plain Python: ~1 ms per step


def _child(mode: str):
    """Measurements that need a fresh interpreter (compile, no-JIT baseline)."""
    t0 = time.perf_counter()
    from wheel_force_estimator.sim import simulate
    if mode == 'compile':
        simulate('flat', duration_scale=0.1)
        first = time.perf_counter() - t0
        t1 = time.perf_counter()
        simulate('flat', duration_scale=0.1)
        print(first - (time.perf_counter() - t1))
        return
    print(_integrator_per_step_s(SLICE_STEPS_PY))


def _integrator_per_step_s(n_steps: int) -> float:
    from wheel_force_estimator.sim import dynamics
    from wheel_force_estimator.sim.courses import build_course
    from wheel_force_estimator.sim.effects import loop_effect_arrays
    from wheel_force_estimator.sim.effects import resolve_effects
    from wheel_force_estimator.sim.roads import envelope
    from wheel_force_estimator.sim.vehicle import VehicleParams
    car = VehicleParams()
    plan = build_course([('belgian_block', 5.0)], fs_int_hz=2048.0)
    road = envelope(plan.road_raw, plan.road_dx_m, car.tyre_contact_length_m)
    packed = dynamics.pack(car)
    eon, ep = loop_effect_arrays(resolve_effects(()))
    out = np.empty((n_steps, dynamics.N_OUT))
    best = np.inf
    for _ in range(3):
        state = np.zeros(dynamics.N_STATE)
        t0 = time.perf_counter()
        dynamics.integrate(state, 0, n_steps, 1.0 / 2048.0, plan.speed_mps, plan.accel_x_mps2,
                           plan.accel_y_mps2, plan.x_m, road, plan.road_x0_m,
                           1.0 / plan.road_dx_m, packed.body_map, packed.body_mass,
                           packed.corner, packed.glob, eon, ep, out)
        best = min(best, time.perf_counter() - t0)
    return best / n_steps


def _run_child(mode: str, env_extra: dict) -> float:
    env = dict(os.environ, **env_extra)
    res = subprocess.run([sys.executable, __file__, '--child', mode], env=env, check=True,
                         capture_output=True, text=True)
    return float(res.stdout.strip().splitlines()[-1])


def main():
    """Run the benchmark and print the figures."""
    with tempfile.TemporaryDirectory() as cache:
        compile_s = _run_child('compile', {'NUMBA_CACHE_DIR': cache})
    print(f'numba compile (empty cache, first call - second call): {compile_s:6.2f} s')

    from wheel_force_estimator.sim import simulate
    from wheel_force_estimator.sim.courses import build_course
    simulate('flat', duration_scale=0.05)  # load the cached machine code
    t0 = time.perf_counter()
    result = simulate('proving_ground', seed=0)
    wall = time.perf_counter() - t0
    t0 = time.perf_counter()
    build_course('proving_ground', seed=0, fs_int_hz=2048.0)
    course_s = time.perf_counter() - t0
    n_steps = int(COURSE_S * 2048)
    numba_step = _integrator_per_step_s(1 << 15)
    python_step = _run_child('python', {'NUMBA_DISABLE_JIT': '1'})
    print(f'proving_ground course: {result.duration_s:.0f} s simulated, '
          f'{result.stamp_ns.size} samples x 24 channels')
    print(f'  end to end:          {wall:6.2f} s wall   real-time factor {COURSE_S / wall:6.1f}x'
          f'   (budget 60 s)')
    print(f'  of which course/road {course_s:6.2f} s, integration '
          f'{numba_step * n_steps:6.2f} s (RK4, 2048 Hz, {n_steps} steps)')
    print(f'integrator per step:   numba {numba_step * 1e6:7.2f} us   '
          f'plain Python {python_step * 1e6:8.1f} us   ({python_step / numba_step:5.0f}x)')
    print(f'  plain Python extrapolated to the course: {python_step * n_steps / 60:6.1f} min '
          f'(measured on {SLICE_STEPS_PY} steps)')


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == '--child':
        _child(sys.argv[2])
    else:
        main()
