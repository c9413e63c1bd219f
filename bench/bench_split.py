# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
A measured lead for issue 29's Fx (not in the product yet): the traction/braking split.

A wheel's longitudinal force is not one linear function of the car's longitudinal specific
force ``f_x``: braking loads all four wheels in the brake balance's ratio, traction only the
driven ones in the drive's ratio, so each wheel's quasi-static ``Fx`` is piecewise linear in
``f_x`` with a kink at zero.  Every car has this; a linear model (the paper's H1, our LS FIR)
can only fit the training's mix of braking and traction with one slope, and the slope it learns
from short events extrapolates badly to long ones (docs/fit_design.md §2, known limit).

This script gives the fit two derived inputs, computed causally from the 12 accelerations
alone: ``f_x`` = the mean of the four spindle ``ax`` through a 2nd-order Butterworth low-pass
(``--cutoff-hz``, 1 Hz by default: driver-controlled braking and traction), its positive part
(traction) and its negative part (braking).  The search then offers every output row the
nested input sets ``accel`` and ``accel+split``, exactly as ``fit`` offers ``accel+spin``, and
each row chooses by the same blocked cross-validation (the accelerations alone stay a
candidate, so a row that does not gain keeps its design).

Printed per vehicle and training regime, mean per direction, RMSE % unfiltered | 1 Hz HP:
``paper`` (plain H1), ``offline`` / ``live50`` (``fit``'s defaults on the 12 accelerations),
``split`` / ``split_live50`` (the same defaults with the two derived inputs offered).

Regimes: ``10min`` (10 min of the course at seed 1 -> seed 2 at half length, the README's
table), ``2min`` (the course with every event x0.2 -> seed 2 the same), ``2min_long`` (x0.2 ->
seed 2 with events x0.5: events longer than any the training saw).

Run: ``python bench/bench_split.py [--cars compact,suv,van] [--regimes 10min,2min,2min_long]
[--cutoff-hz 1.0]``
"""
import argparse
import time

import numpy as np
import scipy.signal

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core import search as search_module
from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim.vehicle import load_vehicle

from bench_design import by_direction  # noqa: I100
from bench_design import CARS
from bench_design import LIVE_S
from bench_design import product_config

SPLIT_CHANNELS = ('traction_fx_mps2', 'braking_fx_mps2')
REGIMES = {'10min': (1.0, 10.0, 0.5), '2min': (0.2, None, 0.2), '2min_long': (0.2, None, 0.5)}


def with_split(accel_mps2: np.ndarray, fs_hz: float, cutoff_hz: float) -> np.ndarray:
    """
    Return the 12 accelerations with the traction and braking parts of ``f_x`` appended.

    ``f_x``: the mean of the four spindle ``ax`` [m/s²], low-passed causally (2nd-order
    Butterworth at ``cutoff_hz``, started at the first sample's steady state so nothing is
    invented before the record); traction = ``max(f_x, 0)``, braking = ``min(f_x, 0)``.
    """
    sos = scipy.signal.butter(2, cutoff_hz, fs=fs_hz, output='sos')
    mean_ax = accel_mps2[0::3].mean(axis=0)
    zi = scipy.signal.sosfilt_zi(sos) * mean_ax[0]
    f_x, _ = scipy.signal.sosfilt(sos, mean_ax, zi=zi)
    return np.vstack([accel_mps2, np.maximum(f_x, 0.0)[None], np.minimum(f_x, 0.0)[None]])


def nested_sets(input_channels):
    """Return ``fit``'s nested input sets with ``accel+split`` after ``accel``."""
    names = tuple(input_channels)
    n_acc = len(INPUT_CHANNELS)
    if names == INPUT_CHANNELS + SPLIT_CHANNELS:
        return (('accel', tuple(range(n_acc))), ('accel+split', tuple(range(len(names)))))
    return ORIGINAL_SETS(input_channels)


ORIGINAL_SETS = search_module.input_sets


def scores(target, prediction, fs_hz):
    """Return (unfiltered, 1 Hz HP) RMSE % per direction."""
    return (by_direction(rmse_pct(target, prediction)),
            by_direction(rmse_hp_pct(target, prediction, fs_hz)))


def regime_rows(name, regime, cutoff_hz):
    """Fit and judge one vehicle in one regime; return {estimator: figures}, fit times."""
    train_scale, minutes, val_scale = REGIMES[regime]
    vehicle = load_vehicle(CARS[name]) if CARS[name] else None
    train = simulate(seed=1, vehicle=vehicle, duration_scale=train_scale)
    val = simulate(seed=2, vehicle=vehicle, duration_scale=val_scale)
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
            ('split', with_split(x, fs, cutoff_hz), INPUT_CHANNELS + SPLIT_CHANNELS,
             with_split(val.accel_mps2, fs, cutoff_hz))):
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
    parser.add_argument('--cutoff-hz', type=float, default=1.0,
                        help='low-pass of the longitudinal specific force [Hz]')
    args = parser.parse_args()
    search_module.input_sets = nested_sets   # offer accel+split as fit offers accel+spin
    for regime in args.regimes.split(','):
        for name in args.cars.split(','):
            rows, times, train_s = regime_rows(name, regime, args.cutoff_hz)
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
