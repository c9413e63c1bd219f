# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The shipped defaults on held-out data: three simulated vehicles and the real MR damper.

Every figure here comes from ``wheel-force fit`` with no settings (the product), fitted on one
course seed and judged on another.  The bounds are the claims of issue 29, not one run's
values plus a margin:

- offline is at most 0.8x the paper's plain H1 method in every direction (issue 29's bar: the
  design search exists to do better than the paper's constants on data it was not tuned on;
  x reaches it through the traction/braking split, which ``fit`` offers every row);
- offline is never worse than the live estimator at 50 ms (it may look into the future, and
  the live estimator is itself one of its candidates);
- live at 50 ms is within 1.25x offline in x and y and 2x in z (the live node's contract).
"""
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from support.shared_data import dataset

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parents[1]
VEHICLES = {'compact': None, 'suv': ROOT / 'config/vehicles/suv_awd_2180kg.yaml',
            'van': ROOT / 'config/vehicles/van_rwd_2650kg.yaml'}
LIVE_LIMIT = {'x': 1.25, 'y': 1.25, 'z': 2.0}
#: Relative difference of one filter's two realisations (offline FIR vs live running sums).
SAME_FILTER = 1e-6


def by_direction(pct):
    """Mean over the four corners per direction (x, y, z)."""
    return {a: float(np.mean(pct[k::3])) for k, a in enumerate('xyz')}


@pytest.mark.slow
@pytest.mark.parametrize('vehicle', sorted(VEHICLES))
def test_shipped_defaults_beat_the_paper_and_never_lose_to_live(vehicle, tmp_path):
    car = load_vehicle(VEHICLES[vehicle]) if VEHICLES[vehicle] else None
    train = simulate(seed=3, vehicle=car, duration_scale=0.5)
    held = simulate(seed=4, vehicle=car, duration_scale=0.25)
    write_recording(tmp_path / 'train', train.stamp_ns, train.accel_mps2, train.force_n)
    assert main(['fit', str(tmp_path / 'train'), '-o', str(tmp_path / 'm.npz')]) == 0
    model = load_model(tmp_path / 'm.npz')
    assert model.fit['design']['method'] == 'blocked_cross_validation'
    assert model.fit['design']['imposed'] == []
    paper = fit_model([TrainingSegment(train.accel_mps2, train.force_n, 'train')],
                      train.fs_hz, FitConfig(), INPUT_CHANNELS, OUTPUT_CHANNELS)
    x, y = held.accel_mps2, held.force_n
    offline = by_direction(rmse_pct(y, predict_forces(model, x)))
    live_pred = predict_forces(model, x, 26)
    live = by_direction(rmse_pct(y, live_pred))
    base = by_direction(rmse_pct(y, predict_forces(paper, x)))
    for a in 'xyz':
        assert offline[a] <= 0.8 * base[a], (a, offline, base)
        # A row whose offline design is the live estimator itself (one of its candidates) is
        # one filter computed two ways (overlap-add FIR vs running sums): equal to ~1e-7
        # relative, either way round (measured on the van's Fx rows when they chose it).
        assert offline[a] <= live[a] * (1 + SAME_FILTER), (a, offline, live)
        assert live[a] <= LIVE_LIMIT[a] * offline[a], (a, live, offline)
    # the high-passed figure is not traded away for the unfiltered one
    off_hp = by_direction(rmse_hp_pct(y, predict_forces(model, x), held.fs_hz))
    live_hp = by_direction(rmse_hp_pct(y, live_pred, held.fs_hz))
    assert all(off_hp[a] <= live_hp[a] * (1 + SAME_FILTER) for a in 'xyz'), (off_hp, live_hp)


@pytest.fixture(scope='module')
def mr_damper(tmp_path_factory):
    """Fit runs 4.1-4.3 through the CLI (velocity -> force); return RMSE % on run 4.4."""
    folder = dataset('mr_damper')
    tmp_path = tmp_path_factory.mktemp('mr')
    runs = [folder / f'data_simulation_4.{k}_MRdamper.mat' for k in (1, 2, 3, 4)]
    roles = ['--input', 'x_F[1]:velocity:mm/s', '--output', 'x_F[2]:force:N', '--fs', '100']
    assert main(['fit', *map(str, runs[:3]), '-o', str(tmp_path / 'm.npz')] + roles) == 0
    model = load_model(tmp_path / 'm.npz')
    held = scipy.io.loadmat(runs[3])['x_F']
    x, y = held[:, 1:2].T * 1e-3, held[:, 2:3].T
    train = [scipy.io.loadmat(r)['x_F'] for r in runs[:3]]
    paper = fit_model([TrainingSegment(r[:, 1:2].T * 1e-3, r[:, 2:3].T, 'r') for r in train],
                      100.0, FitConfig(), ('v',), ('f',), input_quantity='velocity')
    return {'offline': rmse_pct(y, predict_forces(model, x))[0],
            'live': rmse_pct(y, predict_forces(model, x, 5))[0],
            'paper': rmse_pct(y, predict_forces(paper, x))[0]}


@pytest.mark.slow
def test_shipped_defaults_on_the_real_mr_damper(mr_damper):
    # A hysteretic damper: every linear model scores ~63 % on run 4.4, and on 145 s of data
    # the candidates' held-out scores differ by less than run 4.4 disagrees with them, so
    # the search may pick any of the near-equal ones (measured: 63.9 % offline, 63.1 % the
    # paper's, 63.6 % live).  What it must not do is pick a clearly worse model: more than
    # one point behind either (the few-long-windows H1 of this data scored 162 %).
    r = mr_damper
    assert r['offline'] <= r['paper'] + 1.0 and r['offline'] <= r['live'] + 1.0, r


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason='issue 29, open: on run 4.4 the two-sided LS row the '
                   'folds rank first (48.3 % against 51.0 % for live) scores 63.9 % against '
                   '63.6 % for live; 145 s of three runs cannot rank them the way run 4.4 does')
def test_offline_is_never_worse_than_live_on_the_real_mr_damper(mr_damper):
    assert mr_damper['offline'] <= mr_damper['live'], mr_damper
