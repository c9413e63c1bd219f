# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Cost of the search for physics inside a structure (diagnosis/dynamic.py) in a generic diagnose.

Two linear recordings (nothing to find, so the search runs on every channel), each diagnosed
in its own child process (peak RSS is per process) as the CLI runs it (the Welch segment
chosen by cross-validation), with and - the baseline, same run - without the search:

- a 3-input / 2-output base-excited structure, 2 x 300 s at 2048 Hz to fit, 2 x 300 s holdout;
- 12 inputs / 12 outputs under names that do not pair, 2 x 120 s at 512 Hz, 2 x 120 s holdout.

Run: ``.venv/bin/python bench/bench_dynamic.py [--scale X]`` (about 6 min at scale 1; the
12-input records need scale >= 0.2 for the integrators to settle).
"""
import argparse
import multiprocessing
import resource
import time


def _twelve(seed, seconds):
    import numpy as np
    from scipy import signal
    from wheel_force_estimator.diagnosis import MotionRecording
    fs = 512.0
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    b, a = signal.butter(2, [1 / (fs / 2), 30 / (fs / 2)], 'bandpass')
    x = signal.lfilter(b, a, rng.standard_normal((12, n)), axis=1) * 10
    mix = np.random.default_rng(0).normal(size=(12, 12)) * 30 + np.eye(12) * 300
    bb, aa = signal.butter(2, 20 / (fs / 2))
    y = signal.lfilter(bb, aa, mix @ x, axis=1) + 3000.0
    y += 0.03 * y.std(axis=1, keepdims=True) * rng.standard_normal(y.shape)
    return MotionRecording(f'r{seed}', fs, x, y, tuple(f'in{i}' for i in range(12)),
                           tuple(f'out{i}' for i in range(12)))


def _run(case, search, scale, queue):
    from wheel_force_estimator.diagnosis import diagnose
    import wheel_force_estimator.diagnosis.run as run
    from wheel_force_estimator.diagnosis.run import DiagnosisConfig
    from benchutil import test_support
    structure_recording = test_support('diagnosis_synthetic').structure_recording
    if not search:
        run.dynamic_findings = lambda *args, **kwargs: []
    if case == 'structure':
        recs = [structure_recording('linear, 3 inputs', s, 300.0 * scale, 2048.0)
                for s in (1, 2, 3, 4)]
    else:
        recs = [_twelve(s, 120.0 * scale) for s in (1, 2, 3, 4)]
    t0 = time.perf_counter()
    try:
        result = diagnose(recs[:2], None, recs[2:], DiagnosisConfig(choose_resolution=True))
    except Exception as err:    # report it in the parent instead of leaving it waiting
        queue.put(err)
        return
    wall = time.perf_counter() - t0
    queue.put((wall, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
               [f.physics for f in result.findings]))


def main():
    """Print wall time and peak RSS with and without the search."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--scale', type=float, default=1.0, help='record duration scale')
    args = parser.parse_args()
    ctx = multiprocessing.get_context('spawn')
    for case, label in (('structure', '3 inputs, 2048 Hz, 2 x 300 s'),
                        ('twelve', '12 x 12 unpaired, 512 Hz, 2 x 120 s')):
        cells = []
        for search in (False, True):
            queue = ctx.Queue()
            proc = ctx.Process(target=_run, args=(case, search, args.scale, queue))
            proc.start()
            got = queue.get()
            proc.join()
            if isinstance(got, Exception):
                raise SystemExit(f'{label}: {got} (records too short: raise --scale)')
            wall, rss, named = got
            cells.append(f'{"with" if search else "without"} the search: {wall:6.1f} s, '
                         f'{rss:.2f} GB peak, named {named or "nothing"}')
        print(f'{label} (x{args.scale:g}): ' + ' | '.join(cells), flush=True)


if __name__ == '__main__':
    main()
