# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Cost of the motion findings (clip and lift-off tests) against the FRF fit of a diagnosis.

One full proving-ground course (``duration_scale`` 1.0, ~10 min at 512 Hz, 12 + 12 channels)
for the nominal car (sim) and a car with tyre lift-off (real), both in memory.  Timed in the
same run: ``diagnosis.finders.motion.motion_findings(real, sim)`` and, as the baseline, the
linear MIMO FRF fit that every diagnosis makes on the simulation (``core.pipeline.fit_model``).

Run: ``nice -n 5 .venv/bin/python bench/bench_motion.py [--scale X]`` (about 1 min).
"""
import argparse
import time

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.finders.motion import motion_findings
from wheel_force_estimator.diagnosis.recording import MotionRecording
from wheel_force_estimator.diagnosis.run import DiagnosisConfig
from wheel_force_estimator.diagnosis.run import fit_linear
from wheel_force_estimator.sim.api import simulate


def _rec(result, name):
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS)


def main():
    """Print the timings (best of 3)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--scale', type=float, default=1.0, help='course duration scale')
    args = parser.parse_args()
    sim = _rec(simulate('proving_ground', (), 0, args.scale), 'sim')
    real = _rec(simulate('proving_ground', ('tire_lift_off',), 0, args.scale), 'real')
    sources, _ = pairing(OUTPUT_CHANNELS, INPUT_CHANNELS)
    print(f'{sim.n_samples} samples x 24 channels per recording')
    for label, run in (('motion_findings (clip + lift-off)',
                        lambda: motion_findings([real], [sim], sources)),
                       ('baseline: FRF fit on the sim',
                        lambda: fit_linear([sim], DiagnosisConfig(), 'sim', sim))):
        best = float('inf')
        for _ in range(3):
            t0 = time.perf_counter()
            out = run()
            best = min(best, time.perf_counter() - t0)
        print(f'{label:40s} {best:7.2f} s')
        if isinstance(out, list):
            print('   named:', [(f.physics, f.channels) for f in out])


if __name__ == '__main__':
    main()
