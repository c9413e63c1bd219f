# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of the simulator façade, sensors (decimation, delay) and the ``simulate`` CLI."""
from dataclasses import replace
import json

import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import SimulationError
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim import simulate_pair
from wheel_force_estimator.sim import VehicleParams
from wheel_force_estimator.sim.api import DEFAULT_START_NS
from wheel_force_estimator.sim.sensors import Decimator
from wheel_force_estimator.sim.sensors import DelayLine

FS_HZ = 512.0


@pytest.fixture(scope='module')
def short_pg():
    return simulate(seed=5, duration_scale=0.02)  # 12 s, every event


def test_result_layout(short_pg):
    r = short_pg
    n = int(600 * 0.02 * FS_HZ)
    assert r.accel_mps2.shape == (len(INPUT_CHANNELS), n)
    assert r.force_n.shape == (len(OUTPUT_CHANNELS), n)
    assert r.stamp_ns.dtype == np.int64 and r.stamp_ns[0] == DEFAULT_START_NS
    assert np.all(np.diff(r.stamp_ns) == 1_953_125)  # 1e9 / 512 exactly
    assert r.duration_s == pytest.approx(12.0)
    stamps = set(r.stamp_ns.tolist())
    assert len(r.events) == 15 and all(s in stamps for s, _ in r.events)
    assert r.events[0] == (DEFAULT_START_NS, 'highway')
    assert all(np.all(np.isfinite(v)) for v in r.states.values())


def test_channel_order_is_corner_major(short_pg):
    # z rows carry gravity / the static loads; the rear axle carries less than the front
    a = short_pg.accel_mps2.mean(axis=1)
    assert np.all(np.abs(a[2::3] - 9.8) < 0.5) and np.all(np.abs(a[0::3]) < 3.0)
    fz = short_pg.force_n[2::3].mean(axis=1)
    assert fz[0] > fz[2] > 2000.0 and fz[1] > fz[3] > 2000.0


def test_deterministic_for_a_seed(short_pg):
    again = simulate(seed=5, duration_scale=0.02)
    np.testing.assert_array_equal(again.accel_mps2, short_pg.accel_mps2)
    np.testing.assert_array_equal(again.force_n, short_pg.force_n)
    other = simulate(seed=6, duration_scale=0.02)
    assert not np.array_equal(other.accel_mps2, short_pg.accel_mps2)


def test_duration_scale_shortens():
    r = simulate('washboard', duration_scale=0.1)
    assert r.stamp_ns.size == int(30.0 * 0.1 * FS_HZ)


def test_other_output_rate():
    r = simulate('cobblestone', duration_scale=0.1, fs_hz=1024.0, substeps=2)
    assert r.fs_hz == 1024.0 and r.stamp_ns.size == int(4.0 * 1024)
    # 1e9 / 1024 = 976562.5 ns: stamps are rounded from k * period, never accumulated
    assert np.all(np.isin(np.diff(r.stamp_ns), (976_562, 976_563)))
    assert r.stamp_ns[-1] - r.stamp_ns[0] == round((r.stamp_ns.size - 1) * 976_562.5)


@pytest.mark.parametrize('kwargs, match', [
    ({'fs_hz': 10.0}, 'fs_hz must be >= 50'),
    ({'fs_hz': 'fast'}, 'fs_hz must be a number'),
    ({'substeps': 0}, 'substeps'),
    ({'fs_hz': 100.0, 'substeps': 2}, 'too low'),
    ({'vehicle': {'sprung_mass_kg': 1}}, 'VehicleParams'),
    ({'course': 'moon'}, "unknown course 'moon'"),
    ({'physics': 'flux_capacitor'}, 'unknown physics effect'),
])
def test_invalid_arguments(kwargs, match):
    args = {'course': 'washboard', 'duration_scale': 0.05}
    args.update(kwargs)
    with pytest.raises(ConfigError, match=match):
        simulate(**args)


def test_divergence_is_reported_with_time_and_event():
    stiff = replace(VehicleParams(), tyre_stiffness_n_per_m=1e11)  # RK4 unstable at 2 kHz
    with pytest.raises(SimulationError, match=r'diverged at t = .* \(event washboard\)'):
        simulate('washboard', duration_scale=0.05, vehicle=stiff)


def test_decimator_streams_like_one_call():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((4000, 3))
    whole = Decimator(4, 3).process(x)
    dec = Decimator(4, 3)
    parts = [dec.process(x[a:b]) for a, b in ((0, 1), (1, 700), (700, 701), (701, 4000))]
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=1e-12)
    assert whole.shape == ((4000 - dec.delay - 1) // 4 + 1, 3)


def test_decimator_is_zero_phase_in_the_pass_band():
    fs_int = 2048.0
    t = np.arange(8192) / fs_int
    x = np.stack([np.sin(2 * np.pi * f * t) for f in (5.0, 60.0, 180.0)], axis=1)
    y = Decimator(4, 3).process(x)
    t_out = np.arange(y.shape[0]) * 4 / fs_int  # output j is centred on input 4 j
    expected = np.stack([np.sin(2 * np.pi * f * t_out) for f in (5.0, 60.0, 180.0)], axis=1)
    skip = 30  # start-up: the filter assumes a constant past equal to the first sample
    # Kaiser (beta 8) pass band ripple < 1e-3 up to ~200 Hz; no phase error at all
    np.testing.assert_allclose(y[skip:], expected[skip:], atol=2e-3)


def test_delay_line_chunks():
    x = np.arange(20.0).reshape(10, 2)
    line = DelayLine(3, 2)
    y = np.concatenate([line.process(x[:2]), line.process(x[2:])])
    np.testing.assert_array_equal(y[3:], x[:-3])
    np.testing.assert_array_equal(y[:3], np.repeat(x[:1], 3, axis=0))


def test_simulate_pair_writes_three_bags(tmp_path):
    from wheel_force_estimator.bagio import read_recording
    paths = simulate_pair(tmp_path / 'pair', 'time_delay', seed=2, duration_scale=0.01,
                          course='proving_ground')
    assert {p.name for p in paths.values()} == {'sim', 'real', 'holdout', 'simulation.json'}
    recs = {k: read_recording(paths[k]) for k in ('sim', 'real', 'holdout')}
    direct = simulate(seed=2, duration_scale=0.01)
    seg = recs['sim'].segments[0]
    np.testing.assert_array_equal(seg.stamp_ns, direct.stamp_ns)
    np.testing.assert_array_equal(seg.accel_mps2, direct.accel_mps2)
    np.testing.assert_array_equal(seg.force_n, direct.force_n)
    # same roads and noise: the accelerations of sim and real are identical (time_delay only
    # moves the WFT), the hold-out run is another seed
    np.testing.assert_array_equal(recs['real'].segments[0].accel_mps2, seg.accel_mps2)
    assert not np.array_equal(recs['real'].segments[0].force_n, seg.force_n)
    assert not np.array_equal(recs['holdout'].segments[0].accel_mps2, seg.accel_mps2)
    truth = json.loads(paths['truth'].read_text())
    assert truth['runs']['real']['physics'] == ['time_delay']
    assert truth['runs']['sim']['physics'] == []
    assert truth['runs']['holdout']['seed'] == 3
    with pytest.raises(BagError, match='exists already'):
        simulate_pair(tmp_path / 'pair', 'time_delay', duration_scale=0.01)


def test_simulate_pair_rejects_equal_seeds(tmp_path):
    with pytest.raises(ConfigError, match='holdout_seed'):
        simulate_pair(tmp_path / 'p', (), seed=4, holdout_seed=4, duration_scale=0.01)


def test_cli_simulate_round_trip(tmp_path, capsys):
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.cli.main import main
    out = tmp_path / 'bag'
    rc = main(['simulate', str(out), '--course', 'speed_bump', '--duration-scale', '0.1',
               '--physics', 'bump_stop', '--seed', '3', '--storage', 'sqlite3'])
    assert rc == 0
    assert 'speed_bump' in capsys.readouterr().out
    rec = read_recording(out)
    direct = simulate('speed_bump', 'bump_stop', seed=3, duration_scale=0.1)
    np.testing.assert_array_equal(rec.segments[0].force_n, direct.force_n)
    assert main(['simulate', str(out), '--course', 'speed_bump']) == 1
    assert 'exists already' in capsys.readouterr().err
    assert main(['simulate', str(tmp_path / 'b2'), '--physics', 'warp_drive']) == 1
    assert 'unknown physics effect' in capsys.readouterr().err
    vehicle = tmp_path / 'car.yaml'
    vehicle.write_text('vehicle:\n  wheelbase: 2.7\n')
    assert main(['simulate', str(tmp_path / 'b3'), '--vehicle', str(vehicle)]) == 1
    assert "unknown vehicle parameter 'wheelbase'" in capsys.readouterr().err
