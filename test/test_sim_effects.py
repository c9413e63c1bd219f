# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Each physics effect changes what it should, when it should, and nothing else."""
from dataclasses import replace

import numpy as np
import pytest

from wheel_force_estimator.sim import dynamics
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim.dynamics import _suspension_force
from wheel_force_estimator.sim.effects import EFFECT_NAMES
from wheel_force_estimator.sim.effects import loop_effect_arrays
from wheel_force_estimator.sim.effects import resolve_effects
from wheel_force_estimator.sim.linear import linearise
from wheel_force_estimator.sim.linear import modes
from wheel_force_estimator.sim.vehicle import corner_layout
from wheel_force_estimator.sim.vehicle import VehicleParams

# noise off: real and nominal then differ only by the effect (bit for bit before it acts)
CAR = replace(VehicleParams(), accel_noise_mps2=0.0, force_noise_n=0.0)
COURSE = [('pothole', 12.0), ('speed_bump', 12.0), ('slalom', 14.0), ('braking', 12.0)]
SEED = 7
# the anti-alias FIR reaches 20 output samples ahead: an effect acting at sample k can change
# the recorded output from sample k - 20 on
FIR_REACH = 20
FZ = slice(2, 12, 3)
K_S, C_S = 25000.0, 2100.0


@pytest.fixture(scope='module')
def nominal():
    return simulate(COURSE, seed=SEED, vehicle=CAR)


def _real(name, params=None):
    return simulate(COURSE, physics=(name,), seed=SEED, vehicle=CAR, effect_params=params)


def _flags(name):
    return loop_effect_arrays(resolve_effects((name,)))


def _first_change(a, b, tol):
    diff = np.flatnonzero(np.any(np.abs(a - b) > tol, axis=0))
    return int(diff[0]) if diff.size else None


def test_force_element_nominal_is_linear():
    on, par = _flags('time_delay')  # no suspension effect
    for c, cd in ((0.05, 0.3), (-0.05, -0.3), (0.0, 0.0)):
        assert _suspension_force(c, cd, K_S, C_S, on, par) == pytest.approx(K_S * c + C_S * cd)


def test_bump_stop_element():
    on, par = _flags('bump_stop')
    assert _suspension_force(0.029, 0.0, K_S, C_S, on, par) == pytest.approx(K_S * 0.029)
    e = 0.05 - 0.03
    expected = K_S * 0.05 + 5.0e4 * e + 2.0e8 * e ** 3
    assert _suspension_force(0.05, 0.0, K_S, C_S, on, par) == pytest.approx(expected)
    assert _suspension_force(-0.05, 0.0, K_S, C_S, on, par) == pytest.approx(-K_S * 0.05)


def test_rebound_stop_element():
    on, par = _flags('rebound_stop')
    assert _suspension_force(-0.039, 0.0, K_S, C_S, on, par) == pytest.approx(-K_S * 0.039)
    assert _suspension_force(-0.05, 0.0, K_S, C_S, on, par) == pytest.approx(
        -K_S * 0.05 - 1.0e5 * 0.01)
    assert _suspension_force(0.05, 0.0, K_S, C_S, on, par) == pytest.approx(K_S * 0.05)


def test_cubic_stiffness_element_is_odd():
    on, par = _flags('cubic_stiffness')
    for c in (0.01, 0.04):
        f = _suspension_force(c, 0.0, K_S, C_S, on, par)
        assert f == pytest.approx(K_S * c + 5.0e6 * c ** 3)
        assert _suspension_force(-c, 0.0, K_S, C_S, on, par) == pytest.approx(-f)


def test_damper_asymmetry_keeps_the_mean_damping():
    on, par = _flags('damper_asymmetry')
    comp = _suspension_force(0.0, 0.2, K_S, C_S, on, par) / 0.2
    reb = _suspension_force(0.0, -0.2, K_S, C_S, on, par) / -0.2
    assert reb / comp == pytest.approx(3.0)
    assert 0.5 * (comp + reb) == pytest.approx(C_S)


def test_coulomb_friction_element():
    on, par = _flags('coulomb_friction')
    assert _suspension_force(0.0, 0.0, K_S, C_S, on, par) == 0.0
    f = _suspension_force(0.0, 0.1, K_S, C_S, on, par) - C_S * 0.1
    assert f == pytest.approx(80.0 * np.tanh(0.1 / 0.005))


@pytest.mark.parametrize('name', [n for n in EFFECT_NAMES if n not in (
    'mass_error', 'time_delay', 'sensor_saturation')])
def test_effects_are_silent_at_static_equilibrium(name):
    # standing still on a flat road every suspension / tyre / bushing effect is at its
    # neutral point and a parameter error of stiffness or damping carries no static load
    nom = simulate([('standstill', 2.0)], seed=1)
    real = simulate([('standstill', 2.0)], physics=(name,), seed=1)
    np.testing.assert_array_equal(real.force_n, nom.force_n)
    np.testing.assert_array_equal(real.accel_mps2, nom.accel_mps2)


def test_time_delay_shifts_only_the_wft(nominal):
    real = _real('time_delay')
    np.testing.assert_array_equal(real.accel_mps2, nominal.accel_mps2)
    d = 2  # default 3.90625 ms = 2 samples at 512 Hz (8 integration steps)
    # the delay is applied before the linear anti-alias filter, so it commutes: exact shift
    np.testing.assert_allclose(real.force_n[:, 50 + d:], nominal.force_n[:, 50:-d],
                               rtol=0, atol=1e-6)
    assert np.abs(real.force_n - nominal.force_n).max() > 100.0


def test_sensor_saturation_clips_only_large_accelerations(nominal):
    real = _real('sensor_saturation', {'sensor_saturation': {'limit_mps2': 40.0}})
    np.testing.assert_array_equal(real.force_n, nominal.force_n)
    np.testing.assert_array_equal(real.accel_mps2, np.clip(nominal.accel_mps2, -40.0, 40.0))
    assert (np.abs(nominal.accel_mps2) > 40.0).sum() > 10  # the course does reach the limit


def test_bump_stop_acts_only_beyond_the_gap(nominal):
    real = _real('bump_stop')
    comp = nominal.states['suspension_compression_m']
    first_contact = int(np.flatnonzero(np.any(comp > 0.030, axis=0))[0])
    first = _first_change(real.force_n, nominal.force_n, 1e-6)
    assert first is not None and first >= first_contact - FIR_REACH
    assert np.abs(real.force_n[FZ] - nominal.force_n[FZ]).max() > 100.0
    # the stop limits the jounce travel
    assert real.states['suspension_compression_m'].max() < comp.max() - 0.002


def test_rebound_stop_acts_only_beyond_the_gap(nominal):
    real = _real('rebound_stop')
    comp = nominal.states['suspension_compression_m']
    first_contact = int(np.flatnonzero(np.any(comp < -0.040, axis=0))[0])
    first = _first_change(real.force_n, nominal.force_n, 1e-6)
    assert first is not None and first >= first_contact - FIR_REACH
    assert real.states['suspension_compression_m'].min() > comp.min() + 0.002


def test_tire_lift_off_makes_contact_unilateral(nominal):
    real = _real('tire_lift_off')
    tyre_nom = nominal.states['tyre_force_n'][2::3]
    first_pull = int(np.flatnonzero(np.any(tyre_nom < 0.0, axis=0))[0])
    first = _first_change(real.force_n, nominal.force_n, 1e-6)
    assert first is not None and first >= first_pull - FIR_REACH
    # a clipped force rings slightly through the anti-alias FIR: allow 2 % of the static load
    static = corner_layout(CAR).tyre_load_n
    assert real.states['tyre_force_n'][2::3].min(axis=1).min() > -0.02 * static.min()
    assert tyre_nom.min() < -0.1 * static.min()  # the nominal (linear) tyre does pull


def test_anti_roll_bar_couples_left_and_right_only():
    packed = dynamics.pack(CAR)
    a0 = linearise(packed, 20.0)
    a1 = linearise(packed, 20.0, *loop_effect_arrays(resolve_effects('anti_roll_bar')))
    names = dynamics.state_names()

    def coupling(a, row, col):
        return a[names.index(row), names.index(col)]

    # wheel acceleration per displacement of the other wheel of the axle: k_bar / m_u,
    # nothing nominally, nothing between axles (finite-difference Jacobian: 1e-6 relative)
    assert coupling(a0, 'lf_z_mps', 'rf_z_m') == pytest.approx(0.0, abs=1e-3)
    assert coupling(a1, 'lf_z_mps', 'rf_z_m') == pytest.approx(18000.0 / 40.0, rel=1e-6)
    assert coupling(a1, 'rr_z_mps', 'lr_z_m') == pytest.approx(9000.0 / 35.0, rel=1e-6)
    assert coupling(a1, 'lf_z_mps', 'lr_z_m') == pytest.approx(0.0, abs=1e-3)
    # the car is left-right symmetric: heave and pitch do not twist the bar
    for state in ('heave_mps', 'pitch_radps'):
        f0 = [m.f_hz for m in modes(CAR, 20.0) if m.dominant == state][0]
        f1 = [m.f_hz for m in modes(CAR, 20.0, resolve_effects('anti_roll_bar'))
              if m.dominant == state][0]
        assert f1 == pytest.approx(f0, rel=1e-6)


def test_anti_roll_bar_reduces_roll_in_the_slalom(nominal):
    real = _real('anti_roll_bar')
    t0, t1 = (int(24.0 * nominal.fs_hz), int(38.0 * nominal.fs_hz))  # the slalom
    roll_nom = np.std(nominal.states['body_roll_rad'][t0:t1])
    roll_arb = np.std(real.states['body_roll_rad'][t0:t1])
    assert roll_arb < 0.8 * roll_nom
    # and the left-right difference of the front Fz grows (load through the bar)
    dz_nom = np.std(nominal.force_n[2, t0:t1] - nominal.force_n[5, t0:t1])
    dz_arb = np.std(real.force_n[2, t0:t1] - real.force_n[5, t0:t1])
    assert dz_arb > dz_nom


def test_backlash_acts_on_the_fore_aft_channels(nominal):
    real = _real('backlash')

    def rel_change(axis):
        a, b = real.accel_mps2[axis::3], nominal.accel_mps2[axis::3]
        return np.std(a - b) / np.std(b)

    # a clearance in the fore-aft bushing: x channels change a lot, vertical ones barely
    assert rel_change(0) > 0.2
    assert rel_change(0) > 10.0 * rel_change(2)


@pytest.mark.parametrize('name, field, factor', [
    ('stiffness_error', 'spring_rate_front_n_per_m', 1.15),
    ('damping_error', 'damping_front_ns_per_m', 0.75),
])
def test_parameter_errors_keep_static_loads(nominal, name, field, factor):
    real = _real(name)
    assert getattr(real.vehicle, field) == pytest.approx(getattr(CAR, field) * factor)
    np.testing.assert_array_equal(real.states['static_force_n'],
                                  nominal.states['static_force_n'])
    # static loads unchanged: mean Fz over the run within 0.5 %, dynamics changed
    np.testing.assert_allclose(real.force_n[FZ].mean(axis=1), nominal.force_n[FZ].mean(axis=1),
                               rtol=0.005)
    assert np.std(real.force_n[FZ] - nominal.force_n[FZ]) > 20.0


def test_mass_error_adds_payload_load(nominal):
    real = _real('mass_error')
    extra = 0.07 * CAR.sprung_mass_kg * 9.80665
    static_gain = real.states['static_force_n'][FZ] - nominal.states['static_force_n'][FZ]
    assert static_gain.sum() == pytest.approx(extra, rel=1e-9)
    mean_gain = real.force_n[FZ].mean(axis=1) - nominal.force_n[FZ].mean(axis=1)
    np.testing.assert_allclose(mean_gain, static_gain, rtol=0.05)  # dynamics change the mean
    # a heavier body lowers the bounce frequency ~ 1 / sqrt(1.07)
    bounce = [m.f_hz for m in modes(real.vehicle, 20.0) if m.dominant == 'heave_mps'][0]
    bounce0 = [m.f_hz for m in modes(CAR, 20.0) if m.dominant == 'heave_mps'][0]
    assert bounce / bounce0 == pytest.approx(1.07 ** -0.5, rel=0.02)
