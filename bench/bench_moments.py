# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Six components (issue 33): RMSE % and damage ratio of every force and moment, held out.

Per car (the compact car and the SUV of ``config/vehicles/``): ``wheel-force simulate
--six`` writes a training bag (proving ground, seed 1, ``--train-scale``) and a held-out bag
(seed 2, ``--test-scale``); ``wheel-force fit`` (shipped defaults, design by blocked
cross-validation) and ``wheel-force evaluate`` run on them, once per input set:

- ``accel+rates+spin``: the 12 accelerations, the 12 spindle angular rates, the 4 spin rates;
- ``accel+rates``: without the wheel spin (a logger without wheel speeds);
- ``accel``: the 12 accelerations only;
- ``auto``: no ``inputs`` key: every group the bags carry, and the search chooses each
  output row's input set by blocked cross-validation (the shipped default).

Printed per car and input set, as ``evaluate --json`` gives them (mean over the four
corners): RMSE % unfiltered and 1 Hz high-passed, and the damage ratio, per component; then
the issue's targets: Mx and Mz within 1.5x of Fy's RMSE, My within 1.5x of Fx's when spin
is recorded.  The figures are written to ``--out``/moments.json.

Run: ``python bench/bench_moments.py [--train-scale 0.3] [--test-scale 0.1]
[--cars compact,suv] [--inputs accel+rates+spin,accel] [--out bench_out/moments]``
"""
import argparse
import json
from pathlib import Path
import time

import numpy as np

from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.model import load_model

ROOT = Path(__file__).resolve().parents[1]
CARS = {'compact': ROOT / 'config/vehicles/compact_fwd_1421kg.yaml',
        'suv': ROOT / 'config/vehicles/suv_awd_2180kg.yaml'}
INPUT_SETS = {'accel+rates+spin': ['rates', 'spin'], 'accel+rates': ['rates'], 'accel': [],
              'auto': None}
COMPONENTS = ('fx', 'fy', 'fz', 'mx', 'my', 'mz')


def _config(out: Path, groups) -> Path:
    if groups is None:                    # the shipped default: the search chooses
        path = out / 'fit_auto.yaml'
        path.write_text('wheel_force_fit:\n  ros__parameters:\n    moments: true\n')
        return path
    path = out / f'fit_{"_".join(groups) or "accel"}.yaml'
    path.write_text('wheel_force_fit:\n  ros__parameters:\n'
                    f'    inputs: {json.dumps(list(groups))}\n    moments: true\n')
    return path


def _run(argv):
    rc = main([str(a) for a in argv])
    if rc != 0:
        raise SystemExit(f'failed ({rc}): wheel-force {" ".join(map(str, argv))}')


def _per_component(doc):
    rows = {}
    for comp in COMPONENTS:
        chans = [v for k, v in doc['channels'].items() if k.endswith('_' + comp)]
        ratio = [c['damage_ratio'] for c in chans if c['damage_ratio'] is not None]
        rows[comp] = {'rmse_pct': float(np.mean([c['rmse_pct'] for c in chans])),
                      'rmse_hp1_pct': float(np.mean([c['rmse_hp1_pct'] for c in chans])),
                      'damage_ratio': float(np.exp(np.mean(np.log(ratio)))) if ratio else None}
    return rows


def _chosen_inputs(model_path):
    """Return, per component, how many corners' rows chose each input set (offline, live)."""
    rows = (load_model(model_path).fit.get('design') or {}).get('rows') or {}
    out = {}
    for comp in COMPONENTS:
        for key in ('inputs', 'live_inputs'):
            for name, row in rows.items():
                if name.endswith('_' + comp) and key in row:
                    count = out.setdefault(comp, {}).setdefault(key, {})
                    count[row[key]] = count.get(row[key], 0) + 1
    return out


def main_bench(argv=None) -> int:
    """Run the benchmark; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--train-scale', type=float, default=0.3)
    parser.add_argument('--test-scale', type=float, default=0.1)
    parser.add_argument('--cars', default='compact,suv')
    parser.add_argument('--inputs', default='accel+rates+spin,accel+rates,accel')
    parser.add_argument('--out', default=str(ROOT / 'bench_out' / 'moments'))
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for car in args.cars.split(','):
        cdir = out / car
        train, test = cdir / 'train', cdir / 'test'
        if not train.exists():
            _run(['simulate', train, '--six', '--seed', 1, '--duration-scale',
                  args.train_scale, '--vehicle', CARS[car]])
        if not test.exists():
            _run(['simulate', test, '--six', '--seed', 2, '--duration-scale', args.test_scale,
                  '--vehicle', CARS[car]])
        for name in args.inputs.split(','):
            groups = INPUT_SETS[name]
            model = cdir / f'model_{name}.npz'
            t0 = time.perf_counter()
            if not model.exists():
                _run(['fit', train, '-o', model, '--config', _config(cdir, groups)])
            fit_s = time.perf_counter() - t0
            doc_path = cdir / f'evaluate_{name}.json'
            _run(['evaluate', model, test, '--json', doc_path, '--sn-slope-moment', 5.0])
            doc = json.loads(doc_path.read_text())
            results.setdefault(car, {})[name] = {'fit_s': fit_s,
                                                 'components': _per_component(doc),
                                                 'chosen_inputs': _chosen_inputs(model)}
    (out / 'moments.json').write_text(json.dumps(results, indent=1))
    print('\nheld-out RMSE % (unfiltered / 1 Hz high-passed) and damage ratio, mean of 4 '
          'corners (damage ratio: geometric mean)')
    for car, sets in results.items():
        for name, res in sets.items():
            comps = res['components']
            print(f'{car:8s} inputs {name:17s} ' + '  '.join(
                f'{c} {r["rmse_pct"]:5.1f}/{r["rmse_hp1_pct"]:5.1f} '
                f'x{(r["damage_ratio"] or float("nan")):.2f}' for c, r in comps.items()))
            fy, fx = comps['fy']['rmse_pct'], comps['fx']['rmse_pct']
            checks = [f'Mx/Fy {comps["mx"]["rmse_pct"] / fy:.2f}',
                      f'Mz/Fy {comps["mz"]["rmse_pct"] / fy:.2f}',
                      f'My/Fx {comps["my"]["rmse_pct"] / fx:.2f}']
            print(f'{"":8s} targets (<= 1.5): {", ".join(checks)}')
            chosen = res['chosen_inputs']
            if any(len(v.get('inputs', {})) > 1 or 'auto' == name for v in chosen.values()):
                print(f'{"":8s} fit {res["fit_s"]:.0f} s; input set chosen per row (offline | '
                      f'live, corners): ' + '; '.join(
                          f'{c} ' + ','.join(f'{k} {n}' for k, n in v['inputs'].items())
                          + ' | ' + ','.join(f'{k} {n}' for k, n in v['live_inputs'].items())
                          for c, v in chosen.items()))
    print(f'json: {out / "moments.json"}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main_bench())
