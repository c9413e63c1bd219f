# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The traction/braking split (issue 29): ``fit`` with and without it, side by side, one run.

A wheel's longitudinal force is not one linear function of the car's longitudinal specific
force ``f_x``: braking loads all four wheels in the brake balance's ratio, traction only the
driven ones in the drive's ratio, so each wheel's quasi-static ``Fx`` is piecewise linear in
``f_x`` with a kink at zero.  ``fit`` therefore declares two inputs derived from the 12
accelerations (:mod:`wheel_force_estimator.core.derived`: the low-passed mean ``ax``, its
positive and negative parts) and offers every output row ``accel`` and ``accel+split`` as
nested input sets; each row chooses by the blocked cross-validation.

Printed per vehicle and training regime, mean per direction, RMSE % unfiltered | 1 Hz HP:
``paper`` (plain H1), ``offline`` / ``live50`` (``fit``'s defaults on the 12 accelerations
alone: ``inputs: []``, the baseline), ``split`` / ``split_live50`` (``fit``'s shipped
defaults: the split offered).

Regimes: ``10min`` (10 min of the course at seed 1 -> seed 2 at half length, the README's
table), ``2min`` (the course with every event x0.2 -> seed 2 the same), ``2min_long`` (x0.2 ->
seed 2 with events x0.5: events longer than any the training saw).

Run: ``python bench/bench_split.py [--cars compact,suv,van] [--regimes 10min,2min,2min_long]``
"""
import argparse
import time

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import SPLIT_CHANNELS
from wheel_force_estimator.core.derived import traction_braking
from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces

from bench_design import by_direction  # noqa: I100
from bench_design import LIVE_S
from bench_design import product_config
from bench_design import simulated_pair

REGIMES = {'10min': (1.0, 10.0, 0.5), '2min': (0.2, None, 0.2), '2min_long': (0.2, None, 0.5)}


def with_split(accel_mps2, fs_hz):
    """Return the 12 accelerations with the split ``fit`` derives from them appended."""
    return np.vstack([accel_mps2, traction_braking(accel_mps2, fs_hz)])


def scores(target, prediction, fs_hz):
    """Return (unfiltered, 1 Hz HP) RMSE % per direction."""
    return (by_direction(rmse_pct(target, prediction)),
            by_direction(rmse_hp_pct(target, prediction, fs_hz)))


def regime_rows(name, regime):
    """Fit and judge one vehicle in one regime; return {estimator: figures}, fit times."""
    train_scale, minutes, val_scale = REGIMES[regime]
    train, val = simulated_pair(name, train_scale, val_scale)
    fs = train.fs_hz
    n = train.accel_mps2.shape[1] if minutes is None else int(minutes * 60 * fs)
    x, y = train.accel_mps2[:, :n], train.force_n[:, :n]
    paper = fit_model([TrainingSegment(x, y, name)], fs, FitConfig(), INPUT_CHANNELS,
                      OUTPUT_CHANNELS)
    rows = {'paper': scores(val.force_n, predict_forces(paper, val.accel_mps2), fs)}
    times = {}
    d_live = int(round(LIVE_S * fs))
    for label, inputs, channels, xv in (
            ('offline', x, INPUT_CHANNELS, val.accel_mps2),
            ('split', with_split(x, fs), INPUT_CHANNELS + SPLIT_CHANNELS,
             with_split(val.accel_mps2, fs))):
        t0 = time.perf_counter()
        model = fit_design([TrainingSegment(inputs, y, name)], fs, product_config(), channels,
                           OUTPUT_CHANNELS, long_window_fallback=True).model
        times[label] = time.perf_counter() - t0
        rows[label] = scores(val.force_n, predict_forces(model, xv), fs)
        live = 'live50' if label == 'offline' else 'split_live50'
        rows[live] = scores(val.force_n, predict_forces(model, xv, d_live), fs)
        if label == 'split':
            chosen = model.fit['design']['rows']
            times['rows_with_split'] = [o for o, r in chosen.items()
                                        if r['inputs'] == 'accel+split']
    return rows, times, n / fs


def main():
    """Run and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cars', default='compact,suv,van')
    parser.add_argument('--regimes', default='10min,2min,2min_long')
    args = parser.parse_args()
    for regime in args.regimes.split(','):
        for name in args.cars.split(','):
            rows, times, train_s = regime_rows(name, regime)
            print(f'\n== {name}, {regime} ({train_s:.0f} s training; fit {times["offline"]:.0f}'
                  f' s, with split {times["split"]:.0f} s); RMSE % unfiltered | 1 Hz HP, '
                  'x y z', flush=True)
            for k, (u, h) in rows.items():
                print(f'  {k:13s} ' + ' '.join(f'{v:5.1f}' for v in u) + '  | '
                      + ' '.join(f'{v:5.1f}' for v in h), flush=True)
            print(f'  rows that chose accel+split: {", ".join(times["rows_with_split"])}',
                  flush=True)


if __name__ == '__main__':
    main()
