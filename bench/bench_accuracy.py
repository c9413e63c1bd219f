# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Held-out accuracy of the default fit against the two-resolution fit, on the simulator.

Training: ``sim.simulate(seed=1)`` (full proving-ground course, ~10 min); validation:
``sim.simulate(seed=2, duration_scale=0.5)`` (other roads, manoeuvres and noise), both in
memory (nothing cached).  Each configuration is fitted with ``core.pipeline.fit_model`` and
judged with ``core.evaluation.evaluate_segments`` like the ``evaluate`` command:

- full record, offline (``predict_forces``: full look-ahead, edges held at the first/last
  sample, as the CLI does),
- interior: the same prediction without the first and last 10 s (the FIR edge transients),
- edges held at the mean of the first/last look-ahead window instead of one sample (what-if
  for ``core/predict.py``, public API only: a held prefix is fed and discarded),
- live: the node's look-ahead (0.25 s) through ``Predictor``.

Run: ``.venv/bin/python bench/bench_accuracy.py`` (about 1-2 min on 2 cores).
"""
import time

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.evaluation import EvalSegment
from wheel_force_estimator.core.evaluation import evaluate_segments
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import with_delay
from wheel_force_estimator.core.overlap_add import OverlapAddFilter
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.predict import Predictor
from wheel_force_estimator.sim import simulate

CONFIGS = {
    'baseline': FitConfig(),
    'two-res': FitConfig(long_segment_length=8192, crossover_hz=2.0, long_regularisation=5e-2),
}
EVENTS = ('twist', 'figure_8', 'braking', 'highway')
TRIM_S = 10.0
LIVE_LOOKAHEAD_S = 0.25


def predict_mean_edges(model, accel_mps2):
    """Predict with the edges held at the mean of the first/last look-ahead (what-if)."""
    predictor = Predictor(model)
    delay = predictor.delay_samples
    n_edge = max(delay, 1)
    head = accel_mps2[:, :n_edge].mean(axis=1, keepdims=True)
    tail = accel_mps2[:, -n_edge:].mean(axis=1, keepdims=True)
    n_prefix = model.n_taps
    predictor.process(np.repeat(head, n_prefix, axis=1))
    parts = [predictor.process(accel_mps2), predictor.process(np.repeat(tail, delay, axis=1))]
    y = np.concatenate(parts, axis=1)
    return y[:, delay:]


def evaluate(target, prediction, stamps, fs_hz, events, trim=0):
    """Evaluate (optionally without ``trim`` samples at each end)."""
    sel = slice(trim, target.shape[1] - trim)
    return evaluate_segments([EvalSegment(target[:, sel], prediction[:, sel], stamps[sel], 'v')],
                             fs_hz, OUTPUT_CHANNELS, events=events)


def stream_cost_us(model, block=128, n_blocks=400):
    """Mean time per block of the live (0.25 s look-ahead) overlap-add filter [us]."""
    fir = FirFilter(model.fir_taps, model.fir_delay_samples, model.fs_hz)
    fir = with_delay(fir, int(LIVE_LOOKAHEAD_S * model.fs_hz))
    engine = OverlapAddFilter(fir)
    x = np.random.default_rng(0).normal(size=(fir.n_in, block))
    engine.process(x)
    t0 = time.perf_counter()
    for _ in range(n_blocks):
        engine.process(x)
    return 1e6 * (time.perf_counter() - t0) / n_blocks


def main():
    """Run the comparison and print the tables."""
    t0 = time.perf_counter()
    train = simulate(seed=1)
    val = simulate(seed=2, duration_scale=0.5)
    fs = train.fs_hz
    print(f'simulated {train.accel_mps2.shape[1] / fs:.0f} s training, '
          f'{val.accel_mps2.shape[1] / fs:.0f} s validation in {time.perf_counter() - t0:.1f} s')
    x, y, stamps, events = val.accel_mps2, val.force_n, val.stamp_ns, val.events
    trim = int(TRIM_S * fs)
    results = {}
    for name, cfg in CONFIGS.items():
        t1 = time.perf_counter()
        model = fit_model([TrainingSegment(train.accel_mps2, train.force_n, 'seed1')], fs,
                          cfg, INPUT_CHANNELS, OUTPUT_CHANNELS)
        t_fit = time.perf_counter() - t1
        t1 = time.perf_counter()
        pred = predict_forces(model, x)
        t_pred = time.perf_counter() - t1
        live = predict_forces(model, x, causal_delay_samples=int(LIVE_LOOKAHEAD_S * fs))
        results[name] = {
            'full': evaluate(y, pred, stamps, fs, events),
            'interior': evaluate(y, pred, stamps, fs, events, trim),
            'mean_edges': evaluate(y, predict_mean_edges(model, x), stamps, fs, events),
            'live': evaluate(y, live, stamps, fs, events),
            'live_interior': evaluate(y, live, stamps, fs, events, trim),
            'fit_s': t_fit, 'predict_s': t_pred, 'taps': model.n_taps,
            'block_us': stream_cost_us(model),
        }
    names = list(CONFIGS)
    a, b = names

    def table(title, getter, fmt='{:7.1f}'):
        print(f'\n{title}')
        print(f'{"channel":8s} ' + ' '.join(f'{n:>9s}' for n in names))
        for i, ch in enumerate(OUTPUT_CHANNELS):
            print(f'{ch:8s} ' + ' '.join(f'  {fmt.format(getter(results[n], i))}' for n in names))

    for key, label in (('full', 'full record, offline (as `evaluate`)'),
                       ('interior', f'interior (first/last {TRIM_S:g} s excluded)'),
                       ('mean_edges', 'edges held at the look-ahead mean (what-if)'),
                       ('live', f'live look-ahead {LIVE_LOOKAHEAD_S} s, full record'),
                       ('live_interior', f'live look-ahead {LIVE_LOOKAHEAD_S} s, interior')):
        table(f'RMSE % unfiltered -- {label}', lambda r, i, k=key: r[k].rmse_pct[i])
        table(f'RMSE % 1 Hz high-passed -- {label}',
              lambda r, i, k=key: r[k].rmse_hp1_pct[i])
    table('pseudo damage ratio (k = 5) -- full record', lambda r, i: r['full'].damage_ratio[i],
          '{:7.2f}')
    for key in ('full', 'interior'):
        print(f'\nper-event RMSE % unfiltered ({key}): {a} / {b}')
        print(f'{"channel":8s} ' + ' '.join(f'{e:>15s}' for e in EVENTS))
        for i, ch in enumerate(OUTPUT_CHANNELS):
            cells = []
            for e in EVENTS:
                va = results[a][key].events[e]['rmse_pct'][i]
                vb = results[b][key].events[e]['rmse_pct'][i]
                cells.append(f'{va:7.0f}/{vb:<7.0f}')
            print(f'{ch:8s} ' + ' '.join(cells))
    print('\ncost')
    for n in names:
        r = results[n]
        print(f'{n:9s} taps {r["taps"]:5d}  fit {r["fit_s"]:5.2f} s  predict '
              f'{r["predict_s"]:5.2f} s  live overlap-add block of 128: {r["block_us"]:6.0f} us')


if __name__ == '__main__':
    main()
