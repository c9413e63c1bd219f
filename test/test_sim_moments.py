# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The simulator's six-component outputs against their stated physics (issue 33).

One call of the equations of motion at a hand-made state (flat road, body level, tyres
deflected) and the recorded moments, rates and spin recomputed by hand from the tyre forces
the same call records: each formula of ``dynamics._record_six`` in one line.
"""
import numpy as np
import pytest

from wheel_force_estimator.sim import dynamics
from wheel_force_estimator.sim.vehicle import VehicleParams

SPEED_MPS = 12.0


def _record(car, ux, uy, omega, pitch_rate=0.0, roll_rate=0.0, accel_y=0.0):
    packed = dynamics.pack(car)
    s = np.zeros(dynamics.N_STATE)
    s[5], s[6] = pitch_rate, roll_rate
    for i in range(4):
        b = dynamics.S_CORNER + 9 * i
        s[b + dynamics.C_UX], s[b + dynamics.C_UY] = ux[i], uy[i]
        s[b + dynamics.C_OM] = omega[i]
    road = np.zeros((4, 64))
    ds = np.zeros(dynamics.N_STATE)
    out = np.zeros(dynamics.N_OUT)
    dynamics.derivatives(s, SPEED_MPS, 0.0, accel_y, 0.0, road, -10.0, 1.0, packed.body_map,
                         packed.body_mass, packed.corner, packed.glob,
                         np.zeros(8, dtype=np.int64), np.zeros((8, 4)), ds,
                         np.zeros((4, dynamics.N_W)), out, True)
    return packed, s, ds, out


def test_moments_follow_their_stated_physics():
    car = VehicleParams()
    ux = np.array([2e-4, -1e-4, 5e-5, 1e-4])
    uy = np.array([1e-3, -2e-3, 5e-4, 3e-3])
    packed, s, ds, out = _record(car, ux, uy, omega=np.array([0.1, -0.2, 0.0, 0.05]))
    radius = car.wheel_radius_m
    for i, axle in enumerate(('front', 'front', 'rear', 'rear')):
        fx, fy, fz = out[dynamics.O_TYRE + 3 * i:dynamics.O_TYRE + 3 * i + 3]
        mx, my, mz = out[dynamics.O_MOMENT + 3 * i:dynamics.O_MOMENT + 3 * i + 3]
        y_p = fy / car.tyre_lateral_stiffness_n_per_m
        # flat road, wheel at rest height: the loaded radius is the static one
        assert mx == pytest.approx(radius * fy + y_p * fz, rel=1e-12)     # lever + overturning
        u_slide = (car.friction_coefficient * packed.corner[i, dynamics.CP_FT0]
                   / packed.corner[i, dynamics.CP_KTY])
        trail = car.pneumatic_trail_m * (1.0 - min(abs(uy[i]) / u_slide, 1.0))
        assert mz == pytest.approx(-trail * fy - y_p * fx, rel=1e-12)      # aligning moment
        alpha = ds[dynamics.S_CORNER + 9 * i + dynamics.C_OM] / radius    # a_x,ref = 0
        inertia = getattr(car, f'outboard_spin_inertia_{axle}_kgm2')
        assert my == pytest.approx(-radius * fx - inertia * alpha, rel=1e-12)
        # a bug that drops the inertia term or flips the lever changes My by far more
        assert abs(inertia * alpha) > 1e-3 * abs(radius * fx)
        omega = s[dynamics.S_CORNER + 9 * i + dynamics.C_OM]
        assert out[dynamics.O_SPIN + i] == pytest.approx((SPEED_MPS + omega) / radius)


def test_gyro_reads_body_rates_path_yaw_and_bump_steer():
    car = VehicleParams()
    zero = np.zeros(4)
    packed, s, _, out = _record(car, zero, zero, zero, pitch_rate=0.02, roll_rate=-0.03,
                                accel_y=3.0)
    yaw = 3.0 * SPEED_MPS / (SPEED_MPS ** 2 + dynamics.YAW_FADE_MPS ** 2)   # ~ a_y / v
    for i in range(4):  # body level at this instant: rates map one to one
        # the wheel stands still while the body pitches and rolls: the suspension
        # compresses at -T q', and the knuckle steers by the bump steer times that
        compression_rate = -packed.body_map[i] @ s[4:8]
        side = packed.corner[i, dynamics.CP_SIDE]
        steer_rate = -side * packed.corner[i, dynamics.CP_BS] * compression_rate
        np.testing.assert_allclose(out[dynamics.O_GYRO + 3 * i:dynamics.O_GYRO + 3 * i + 3],
                                   [-0.03, 0.02, yaw + steer_rate], rtol=1e-12, atol=1e-15)
        assert abs(steer_rate) > 1e-5     # not a vanishing term: the check can fail
