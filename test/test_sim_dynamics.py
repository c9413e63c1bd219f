# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Known-answer tests of the vehicle model: statics, modes, the paper's quarter-car FRF.

Paper eq. (3) defines ``f_z = c_t (z_u' - z_r') + k_t (z_u - z_r)``: the tyre's *extension*
force, i.e. minus the upward contact force.  Solving eqs. (1)-(3) for ``F_z / Z_u''`` gives

    H_paper(s) = -[m_u + m_s (c_s s + k_s) / (m_s s^2 + c_s s + k_s)]

which is exactly eq. (8) as printed (checked numerically below by evaluating eq. (8)
literally).  Our WFT force is the upward force on the wheel (ISO 8855 z up, +static load) and
is measured inboard of the outboard mass ``m_w`` (rim, tyre, WFT rotor), so the FRF from
spindle acceleration to WFT Fz is ``-H_paper`` with ``m_u`` replaced by ``m_u - m_w``.
"""
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal

from wheel_force_estimator.sim import dynamics
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim.dynamics import N_STATE
from wheel_force_estimator.sim.linear import linearise
from wheel_force_estimator.sim.linear import modes
from wheel_force_estimator.sim.linear import road_input_matrix
from wheel_force_estimator.sim.vehicle import corner_layout
from wheel_force_estimator.sim.vehicle import GRAVITY_MPS2
from wheel_force_estimator.sim.vehicle import quarter_car
from wheel_force_estimator.sim.vehicle import VehicleParams


def corner_accel_response(packed, speed_mps: float, corner: int, f_hz: np.ndarray):
    """Return the linear FRF road height -> vertical spindle acceleration of one corner."""
    a = linearise(packed, speed_mps)
    b = road_input_matrix(packed, speed_mps, corner)
    idx = dynamics.S_CORNER + 9 * corner + dynamics.C_ZD
    eye = np.eye(N_STATE)
    h = np.empty(len(f_hz), dtype=complex)
    for k, f in enumerate(f_hz):
        s = 2j * np.pi * f
        u = b[:, 0] + b[:, 1] * s / speed_mps
        x = np.linalg.solve(s * eye - a, u)
        h[k] = a[idx] @ x + u[idx]
    return h


CAR = VehicleParams()


def paper_eq8(f_hz, m_s, m_u, k_s, c_s):
    """Evaluate the paper's eq. (8) literally, as printed."""
    w = 2.0 * np.pi * np.asarray(f_hz)
    i = 1j
    return 1.0 / (i * w ** 2) * ((c_s * w - k_s * i) ** 2 / (m_s * i * w ** 2 + c_s * w - k_s * i)
                                 - (m_u * i * w ** 2 + c_s * w - k_s * i))


def test_eq8_is_minus_the_total_mass_operator():
    f = np.linspace(0.1, 50.0, 200)
    s = 2j * np.pi * f
    m_s, m_u, k_s, c_s = 350.0, 40.0, 25000.0, 2100.0
    derived = -(m_u + m_s * (c_s * s + k_s) / (m_s * s ** 2 + c_s * s + k_s))
    np.testing.assert_allclose(paper_eq8(f, m_s, m_u, k_s, c_s), derived, rtol=1e-12)


@pytest.fixture(scope='module')
def flat_run():
    return simulate(course='flat', seed=3)


def test_static_equilibrium_on_a_flat_road(flat_run):
    r = flat_run
    static = corner_layout(CAR).wft_load_n
    rest = slice(256, int(3.5 * r.fs_hz))  # standing still (first 4 s), filter edge skipped
    rolling = slice(int(10.0 * r.fs_hz), r.stamp_ns.size)  # 30 km/h, flat road
    for sl in (rest, rolling):
        # 0.5 %: the brief's bound; at rest the error is the 8 N noise / sqrt(n); at 30 km/h
        # drag (~30 N) moves ~3 N per corner to the rear: < 0.1 %
        np.testing.assert_allclose(r.force_n[2::3, sl].mean(axis=1), static, rtol=0.005)
    np.testing.assert_allclose(r.states['static_force_n'][2::3], static)
    tyre = r.states['tyre_force_n'][2::3, rest].mean(axis=1)
    np.testing.assert_allclose(tyre, corner_layout(CAR).tyre_load_n, rtol=1e-6)


def test_accelerometers_read_plus_g_at_rest(flat_run):
    rest = slice(256, int(3.5 * flat_run.fs_hz))
    a = flat_run.accel_mps2[:, rest].mean(axis=1)
    # noise 0.02 m/s^2 over ~1500 samples: mean within 1e-3; nothing else moves at rest
    np.testing.assert_allclose(a[2::3], GRAVITY_MPS2, atol=2e-3)
    np.testing.assert_allclose(a[0::3], 0.0, atol=2e-3)
    np.testing.assert_allclose(a[1::3], 0.0, atol=2e-3)


@pytest.mark.parametrize('speed_mps', [0.0, 0.5, 5.0, 20.0, 40.0])
def test_linearised_model_is_stable(speed_mps):
    lam = np.linalg.eigvals(linearise(dynamics.pack(CAR), speed_mps))
    # a passive car: no growing mode; tolerance = finite-difference noise of the Jacobian
    assert lam.real.max() <= 1e-6


def test_modal_frequencies():
    found = modes(CAR, 20.0)
    bounce = [m for m in found if m.dominant == 'heave_mps']
    hop = [m for m in found if m.dominant.endswith('_z_mps')]
    assert len(bounce) == 1 and 1.0 <= bounce[0].f_hz <= 1.6
    assert len(hop) == 4 and all(9.0 <= m.f_hz <= 15.0 for m in hop)
    assert 0.2 <= bounce[0].damping_ratio <= 0.45  # a comfortable passenger car


@pytest.fixture(scope='module')
def highway_run():
    return simulate(course=[('highway', 90.0)], seed=0)


def test_simulated_bounce_peak_matches_the_eigenfrequency(highway_run):
    r = highway_run
    bounce = [m for m in modes(CAR, 100 / 3.6) if m.dominant == 'heave_mps'][0]
    f, p = scipy.signal.welch(r.states['body_heave_m'], fs=r.fs_hz, nperseg=2048)
    # an ISO road has a white velocity spectrum in time, so the heave velocity PSD is the
    # transmissibility; with damping 0.3 its peak is within a few % of the eigenfrequency,
    # and the 0.25 Hz line spacing bounds the read-out error
    pv = p * (2 * np.pi * f) ** 2
    band = (f > 0.5) & (f < 3.0)
    assert abs(f[band][np.argmax(pv[band])] - bounce.f_hz) <= 0.25


def test_simulated_wheel_hop_peak_matches_the_linear_model(highway_run):
    r = highway_run
    packed = dynamics.pack(CAR)
    f_lin = np.arange(6.0, 20.0, 0.02)
    for corner in range(4):
        f, pxy = scipy.signal.csd(r.states['road_m'][corner], r.accel_mps2[3 * corner + 2],
                                  fs=r.fs_hz, nperseg=1024)
        _, pxx = scipy.signal.welch(r.states['road_m'][corner], fs=r.fs_hz, nperseg=1024)
        band = (f > 6.0) & (f < 20.0)
        sim_peak = f[band][np.argmax(np.abs(pxy / pxx)[band] / (2 * np.pi * f[band]) ** 2)]
        lin = np.abs(corner_accel_response(packed, 100 / 3.6, corner, f_lin)) / (
            2 * np.pi * f_lin) ** 2
        # the wheel-hop transmissibility peak is broad (damping ~0.35); the single-input H1
        # ignores the small coupling through the body; 0.5 Hz line spacing: +-1 Hz
        assert abs(sim_peak - f_lin[np.argmax(lin)]) <= 1.0


def test_rear_wheels_see_the_front_road_a_wheelbase_later(highway_run):
    r = highway_run
    lag = CAR.wheelbase_m / (100 / 3.6) * r.fs_hz  # 47.9 samples at constant 100 km/h
    front = r.states['road_m'][:2]
    n = front.shape[1]
    w = 2 * np.pi * np.fft.rfftfreq(n)
    delayed = np.fft.irfft(np.fft.rfft(front) * np.exp(-1j * w * lag), n)  # exact delay
    keep = slice(100, n - 100)  # the circular shift wraps the first samples
    err = r.states['road_m'][2:, keep] - delayed[:, keep]
    # the enveloped road is band-limited well below 256 Hz, so the Fourier delay is exact up
    # to the anti-alias filter's stop-band leakage
    assert np.std(err) < 1e-3 * np.std(front)


def test_quarter_car_reproduces_paper_eq8():
    car = replace(quarter_car(CAR), accel_noise_mps2=0.0, force_noise_n=0.0)
    fs = 256.0  # 40 Hz band; RK4 at 1024 Hz resolves the 13 Hz wheel hop with ~1e-5 error
    r = simulate(course=[('highway', 600.0)], vehicle=car, seed=3, fs_hz=fs)
    m_s = corner_layout(car).sprung_load_n[0] / GRAVITY_MPS2
    m_u = car.unsprung_mass_front_kg - car.outboard_mass_front_kg
    x, y = r.accel_mps2[2], r.force_n[2]
    nper = 8192
    f, pxy = scipy.signal.csd(x, y, fs=fs, nperseg=nper, noverlap=3 * nper // 4)
    _, pxx = scipy.signal.welch(x, fs=fs, nperseg=nper, noverlap=3 * nper // 4)
    band = (f >= 0.5) & (f <= 40.0)
    h = pxy[band] / pxx[band]
    expected = -paper_eq8(f[band], m_s, m_u, car.spring_rate_front_n_per_m,
                          car.damping_front_ns_per_m)
    # The simulated force is the exact eq. (8) filter of the acceleration (0.1 % in the time
    # domain); what remains is the H1 estimator's finite-record error around the body
    # resonance (window length 32 s vs the ~0.4 s memory of the body mode, 600 s of data):
    # <= 1 % over four seeds, so 2 % holds with margin.
    np.testing.assert_allclose(h, expected, rtol=0.02)
    # the horizontal channels of a vertical-only quarter car carry no force and no motion
    assert np.abs(r.force_n[0]).max() == 0.0 and np.abs(r.accel_mps2[1]).max() == 0.0
