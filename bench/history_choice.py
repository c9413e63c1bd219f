# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Would the folds choose the live history well?  Both histories fitted, choices simulated.

A sweep for issue 29, not part of ``make bench`` (about 45 minutes for eight cars on 1 and
10 minutes of training, two at a time on two cores).  For each car and training length it
runs ``fit``'s search twice, with ``LiveDesign.history_s`` at the shipped 4 s and at the
shorter one (the offline LS candidates share the live basis), and judges both on the
held-out course at seed 2 (``bench_design.py``'s protocol: 16 inputs, seed 1 training).
Then it simulates a choice of the history made by the folds: each direction (x, y, z) of
each estimator takes the history whose folds' criterion (``meta.fit.design``: the chosen
candidate's relative mean-square errors, unfiltered plus 1 Hz high-passed, summed over the
direction's rows) is lower, and prints what the held-out course says of that choice.

Measured 2026-12-07 (docs/performance.md): on 1 and 10 minutes the folds rank the two
histories per direction as the held-out course does; on 2 minutes they pick 2 s for z, and
z loses 1.5-3 points.

Run: ``python bench/history_choice.py [--cars compact,suv] [--train-scales 0.1,1.0]
[--short-history 2] [--fir]``.  ``--fir`` also prints the plain causal LS FIR baseline
(slow on long records).
"""
import argparse
import dataclasses
import sys

from bench_design import baseline
from bench_design import by_direction
from bench_design import input_channels
from bench_design import input_signals
from bench_design import LIVE_S
from bench_design import product_config
from bench_design import simulated_pair
import numpy as np

from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.crossval import HeldOutPower
from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces

INPUTS = 'accel+split+cornering'
DIRECTIONS = 'xyz'


def fold_figures(design: dict, estimator: str) -> np.ndarray:
    """
    Return the folds' RMSE % per output row, shape (n_out, 2): unfiltered, high-passed.

    ``estimator`` 'offline': each row's chosen candidate; 'live': its chosen live ridge and
    input set.
    """
    live = {(c['regularisation'], c['inputs']): c for c in design['live_candidates']}
    out = []
    for o, name in enumerate(OUTPUT_CHANNELS):
        row = design['rows'][name]
        if estimator == 'offline':
            out.append((row['cv_rmse_pct'], row['cv_rmse_hp1_pct']))
        else:
            cand = live[(row['live_regularisation'], row['live_inputs'])]
            out.append((cand['cv_rmse_pct'][o], cand['cv_rmse_hp1_pct'][o]))
    return np.asarray(out)


def criterion(figures: np.ndarray) -> np.ndarray:
    """Return ``fit``'s criterion per row (:meth:`.HeldOutPower.criterion`) of RMSE % figures."""
    return HeldOutPower(error=(figures.T / 100.0) ** 2, target=np.ones(figures.T.shape)
                        ).criterion()


def held_figures(target, prediction, fs_hz) -> np.ndarray:
    """Return the held-out RMSE % per output, shape (2, n_out): unfiltered, high-passed."""
    return np.stack([rmse_pct(target, prediction), rmse_hp_pct(target, prediction, fs_hz)])


def one_history(x, y, xv, yv, fs, history_s):
    """Fit with the live history ``history_s``; return folds and held-out figures."""
    config = product_config()
    config = dataclasses.replace(config, live=dataclasses.replace(config.live,
                                                                  history_s=history_s))
    model = fit_design([TrainingSegment(x, y, 'train')], fs, config, input_channels(INPUTS),
                       OUTPUT_CHANNELS, long_window_fallback=True).model
    design = model.fit['design']
    d = int(round(LIVE_S * fs))
    out = {'model': model}
    for estimator, pred in (('offline', predict_forces(model, xv)),
                            ('live', predict_forces(model, xv, d))):
        out[estimator] = {'folds': criterion(fold_figures(design, estimator)),
                          'held': held_figures(yv, pred, fs)}
    return out


def line(tag, held):
    """Format per-direction means of held-out figures (2, n_out): unfiltered | high-passed."""
    u, h = by_direction(held[0]), by_direction(held[1])
    return (f'  {tag:24s}' + ' '.join(f'{v:5.1f}' for v in u) + '  |'
            + ' '.join(f'{v:5.1f}' for v in h))


def run_car(name, train_scale, short_s, fir):
    """Fit both histories on one car and print the held-out figures of every choice."""
    train, held = simulated_pair(name, train_scale)
    fs = train.fs_hz
    x, y = input_signals(train, INPUTS), train.force_n
    xv, yv = input_signals(held, INPUTS), held.force_n
    long_s = product_config().live.history_s
    fits = {h: one_history(x, y, xv, yv, fs, h) for h in (long_s, short_s)}
    print(f'== {name}, training scale {train_scale} ({x.shape[1] / fs:.0f} s); RMSE % '
          'unfiltered | 1 Hz high-passed, x y z', flush=True)
    if fir:
        model = fits[long_s]['model']
        pred = baseline(x, y, xv, model.static_accel_mps2, model.static_force_n, fs)
        print(line('plain LS FIR', held_figures(yv, pred, fs)))
    for estimator in ('offline', 'live'):
        a, b = fits[long_s][estimator], fits[short_s][estimator]
        short = np.zeros(len(OUTPUT_CHANNELS), dtype=bool)
        for k in range(len(DIRECTIONS)):
            short[k::3] = b['folds'][k::3].sum() < a['folds'][k::3].sum()
        chosen = np.where(short[None, :], b['held'], a['held'])
        picks = ''.join(d if short[k] else '-' for k, d in enumerate(DIRECTIONS))
        print(line(f'{estimator} {long_s:g} s', a['held']))
        print(line(f'{estimator} {short_s:g} s', b['held']))
        print(line(f'{estimator} folds ({picks} {short_s:g} s)', chosen), flush=True)


def main(argv=None):
    """Run the sweep."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--cars', default='compact,suv,van,coupe,pickup,hatch,mpv,sedan')
    parser.add_argument('--train-scales', default='0.1,1.0')
    parser.add_argument('--short-history', type=float, default=2.0)
    parser.add_argument('--fir', action='store_true')
    args = parser.parse_args(argv)
    for scale in (float(v) for v in args.train_scales.split(',')):
        for name in args.cars.split(','):
            run_car(name, scale, args.short_history, args.fir)
    return 0


if __name__ == '__main__':
    sys.exit(main())
