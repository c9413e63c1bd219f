# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Cost and gain of choosing the Welch segment by blocked cross-validation (core/resolution.py).

Generic records of a base-excited structure (8 Hz mode, 5 % damping, 2 % force noise), as
``wheel-force fit`` gets them from a DAQ export: the fit with the segment chosen (what the CLI
does for generic records) against the plain fit with the paper's 1024 samples (baseline, same
run), both timed (best of 3) and scored on a held-out run (1 Hz high-pass RMSE %).  Both with
the CLI's settings: the live estimators at every stored look-ahead are designed too.
"""
import dataclasses
import time

from benchutil import best_of
import numpy as np
from scipy import signal

from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.design import product_fit_config
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import SWEEP_LOOK_AHEADS_S
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces


def structure_run(fs_hz, seconds, seed):
    """Return a TrainingSegment: base acceleration in, base force out."""
    rng = np.random.default_rng(seed)
    n = int(seconds * fs_hz)
    b, a = signal.butter(4, [1.0 / (fs_hz / 2), 40.0 / (fs_hz / 2)], 'bandpass')
    accel = signal.lfilter(b, a, rng.standard_normal(n))
    wn, zeta, mass_kg = 2 * np.pi * 8.0, 0.05, 100.0
    mode = signal.lti([mass_kg * 2 * zeta * wn, mass_kg * wn ** 2],
                      [1.0, 2 * zeta * wn, wn ** 2])
    force = signal.lsim(mode, accel, np.arange(n) / fs_hz)[1]
    force = force + 0.02 * force.std() * rng.standard_normal(n)
    return TrainingSegment(accel[None], force[None], f'run {seed}')


def main():
    # what ``wheel-force fit`` adds to the product's settings: the live estimators
    config = dataclasses.replace(product_fit_config(),
                                 live=LiveDesign(look_aheads_s=(0.05,) + SWEEP_LOOK_AHEADS_S))
    print(f'{"records":28s} {"plain fit (1024)":>24s} {"segment chosen":>30s}')
    for fs_hz, seconds in ((512.0, 60.0), (2048.0, 300.0)):
        train = [structure_run(fs_hz, seconds, s) for s in (1, 2)]
        hold = structure_run(fs_hz, seconds, 3)
        cells = []
        for choose in (False, True):
            t_s, fitted = best_of(lambda: fit_design(
                train, fs_hz, config, ('a',), ('f',), 'acceleration', None,
                True, True, choose))
            pct = float(rmse_hp_pct(hold.force_n, predict_forces(fitted.model,
                                                                 hold.accel_mps2), fs_hz)[0])
            cells.append(f'{t_s:5.2f} s  {pct:5.1f} %  ({fitted.config.segment_length:5d})')
        print(f'2 x {seconds:3.0f} s at {fs_hz:4.0f} Hz, 1 in 1 out  {cells[0]:>24s} '
              f'{cells[1]:>30s}', flush=True)


if __name__ == '__main__':
    t0 = time.time()
    main()
    print(f'total {time.time() - t0:.0f} s')
