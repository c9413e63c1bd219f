# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of sim.vehicle and sim.effects configuration: defaults, YAML, validation."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.sim.effects import apply_parameter_effects
from wheel_force_estimator.sim.effects import EFFECT_DEFAULTS
from wheel_force_estimator.sim.effects import load_effect_params
from wheel_force_estimator.sim.effects import loop_effect_arrays
from wheel_force_estimator.sim.effects import resolve_effects
from wheel_force_estimator.sim.vehicle import corner_layout
from wheel_force_estimator.sim.vehicle import GRAVITY_MPS2
from wheel_force_estimator.sim.vehicle import load_vehicle
from wheel_force_estimator.sim.vehicle import quarter_car
from wheel_force_estimator.sim.vehicle import vehicle_to_dict
from wheel_force_estimator.sim.vehicle import VehicleParams

CONFIG_DIR = Path(__file__).resolve().parents[1] / 'config' / 'vehicles'


def test_default_car_is_the_papers_gvw():
    car = VehicleParams()
    assert car.total_mass_kg == pytest.approx(1421.0)


def test_static_loads_balance_weight_and_moments():
    car = VehicleParams()
    lay = corner_layout(car)
    # vertical equilibrium of the whole car and pitch equilibrium of the sprung mass, exact
    assert lay.tyre_load_n.sum() == pytest.approx(car.total_mass_kg * GRAVITY_MPS2, rel=1e-12)
    assert np.sum(lay.sprung_load_n * lay.x_m) == pytest.approx(0.0, abs=1e-9)
    assert lay.sprung_load_n[0] == lay.sprung_load_n[1]
    # the WFT does not carry the weight of the mass outboard of it
    np.testing.assert_allclose(lay.tyre_load_n - lay.wft_load_n,
                               GRAVITY_MPS2 * np.array([21.0, 21.0, 20.0, 20.0]))
    # 58 % front axle load like a typical FWD compact car
    assert lay.tyre_load_n[:2].sum() / lay.tyre_load_n.sum() == pytest.approx(0.58, abs=0.01)


@pytest.mark.parametrize('field, value, match', [
    ('sprung_mass_kg', -1.0, 'must be > 0'),
    ('tyre_damping_ns_per_m', -1.0, 'must be >= 0'),
    ('front_brake_fraction', 1.5, r'in \[0, 1\]'),
    ('spring_rate_front_n_per_m', float('nan'), 'finite'),
    ('body_model', 'half_car', 'body_model'),
    ('horizontal_dynamics', 1, 'true or false'),
    ('outboard_mass_front_kg', 45.0, 'less than unsprung'),
    ('cg_to_front_axle_m', 3.0, 'less than wheelbase'),
    ('wheelbase_m', 'long', 'must be a number'),
])
def test_invalid_vehicle_rejected(field, value, match):
    with pytest.raises(ConfigError, match=match):
        replace(VehicleParams(), **{field: value})


def test_quarter_car_switches_body_and_horizontal():
    q = quarter_car(VehicleParams())
    assert q.body_model == 'quarter_car' and q.horizontal_dynamics is False


def test_load_vehicle_yaml_overrides(tmp_path):
    path = tmp_path / 'car.yaml'
    path.write_text('vehicle:\n  name: test_car\n  sprung_mass_kg: 1500\n')
    car = load_vehicle(path)
    assert car.name == 'test_car' and car.sprung_mass_kg == 1500.0
    assert car.spring_rate_front_n_per_m == VehicleParams().spring_rate_front_n_per_m


@pytest.mark.parametrize('text, match', [
    ('sprung_mass: 1500\n', "unknown vehicle parameter 'sprung_mass'"),
    ('sprung_mass_kg: heavy\n', 'wrong type'),
    ('sprung_mass_kg: -3\n', 'must be > 0'),
    ('[1, 2]\n', 'expected a mapping'),
    ('sprung_mass_kg: [\n', 'invalid YAML'),
])
def test_load_vehicle_errors_name_the_file(tmp_path, text, match):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as err:
        load_vehicle(path)
    assert 'bad.yaml' in str(err.value)


def test_load_vehicle_missing_file(tmp_path):
    with pytest.raises(ConfigError, match='cannot read'):
        load_vehicle(tmp_path / 'none.yaml')


@pytest.mark.skipif(not CONFIG_DIR.is_dir(), reason='config/vehicles not in this checkout')
def test_example_vehicle_files_load():
    files = sorted(CONFIG_DIR.glob('*.yaml'))
    assert files
    for path in files:
        if path.name.startswith('effects'):
            load_effect_params(path)
        else:
            load_vehicle(path)
    # the shipped default file is exactly the built-in default car
    assert vehicle_to_dict(load_vehicle(CONFIG_DIR / 'compact_fwd_1421kg.yaml')) == \
        vehicle_to_dict(VehicleParams())


def test_resolve_effects_defaults_and_overrides():
    eff = resolve_effects('time_delay,bump_stop', {'bump_stop': {'gap_m': 0.02}})
    assert eff.names == ('bump_stop', 'time_delay')  # vocabulary order
    assert eff.get('bump_stop', 'gap_m') == 0.02
    assert eff.get('bump_stop', 'stiffness_n_per_m') == EFFECT_DEFAULTS['bump_stop'][
        'stiffness_n_per_m']
    assert eff.get('time_delay', 'delay_s') == EFFECT_DEFAULTS['time_delay']['delay_s']


@pytest.mark.parametrize('physics, params, match', [
    ('bump_stopp', None, "unknown physics effect 'bump_stopp'"),
    ('bump_stop', {'bump_stop': {'gap': 0.01}}, "no parameter 'gap'"),
    ('bump_stop', {'bump_stop': {'gap_m': -0.01}}, 'must be >= 0'),
    ('mass_error', {'mass_error': {'fraction': -1.5}}, 'must be > -1'),
    ('time_delay', {'time_delay': {'delay_s': 'x'}}, 'not a number'),
    ((), {'nonsense': {}}, "unknown physics effect 'nonsense'"),
    ((), [1], 'expected a mapping'),
])
def test_resolve_effects_errors(physics, params, match):
    with pytest.raises(ConfigError, match=match):
        resolve_effects(physics, params)


def test_load_effect_params_yaml(tmp_path):
    path = tmp_path / 'eff.yaml'
    path.write_text('effects:\n  bump_stop:\n    gap_m: 0.025\n')
    assert load_effect_params(path) == {'bump_stop': {'gap_m': 0.025}}
    path.write_text('bump_stop:\n  gap: 0.025\n')
    with pytest.raises(ConfigError, match='eff.yaml'):
        load_effect_params(path)


def test_parameter_effects_scale_only_their_parameters():
    car = VehicleParams()
    eff = resolve_effects('mass_error,stiffness_error,damping_error')
    real = apply_parameter_effects(car, eff)
    assert real.sprung_mass_kg == pytest.approx(car.sprung_mass_kg * 1.07)
    assert real.roll_inertia_kgm2 == pytest.approx(car.roll_inertia_kgm2 * 1.07)
    assert real.spring_rate_rear_n_per_m == pytest.approx(car.spring_rate_rear_n_per_m * 1.15)
    assert real.damping_front_ns_per_m == pytest.approx(car.damping_front_ns_per_m * 0.75)
    changed = {k for k, v in vehicle_to_dict(real).items() if v != vehicle_to_dict(car)[k]}
    assert changed == {'sprung_mass_kg', 'pitch_inertia_kgm2', 'roll_inertia_kgm2',
                       'spring_rate_front_n_per_m', 'spring_rate_rear_n_per_m',
                       'damping_front_ns_per_m', 'damping_rear_ns_per_m'}
    assert apply_parameter_effects(car, resolve_effects('bump_stop')) is car


def test_loop_effect_arrays_layout():
    on, par = loop_effect_arrays(resolve_effects('bump_stop,anti_roll_bar'))
    assert on.tolist() == [1, 0, 0, 0, 0, 0, 0, 1]
    np.testing.assert_array_equal(par[0, :3], [0.030, 5.0e4, 2.0e8])
    np.testing.assert_array_equal(par[7, :2], [18000.0, 9000.0])
