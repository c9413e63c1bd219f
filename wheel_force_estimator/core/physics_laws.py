# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The force laws of the physics vocabulary: one pure function per effect [N].

Each function takes the feature it acts on (displacement, velocity, acceleration of a wheel,
the predicted load, the recorded level) and its parameters in SI units, and returns the force
the effect adds.  :mod:`core.physics_terms` binds them to typed parameters, and
:class:`core.physics.PhysicsStage` evaluates them causally.
"""
import numpy as np

VOCABULARY = ('bump_stop', 'rebound_stop', 'cubic_stiffness', 'damper_asymmetry',
              'coulomb_friction', 'backlash', 'tire_lift_off', 'anti_roll_bar', 'time_delay',
              'sensor_saturation', 'mass_error', 'stiffness_error', 'damping_error')

STATES = ('motion', 'load')
QUANTITIES = ('displacement', 'velocity', 'acceleration')
#: Load excess at which the ``gain`` of a load-driven progressive stop is the secant gain.
REFERENCE_LOAD_N = 1000.0
#: Depth at which ``stiffness_n_per_m`` of a progressive stop is the secant stiffness.
REFERENCE_DEPTH_M = 0.01


# --- one pure function per vocabulary entry: the force the effect adds [N] -------------------

def bump_stop_force(disp_m, gap_m, stiffness_n_per_m, exponent):
    """
    Progressive stop in compression: ``k * d * (d / 0.01 m)**(p - 1)``, ``d = max(0, x - gap)``.

    ``stiffness_n_per_m`` is the secant stiffness at 10 mm penetration, so it reads in N/m for
    any exponent.
    """
    depth = np.maximum(np.asarray(disp_m) - gap_m, 0.0)
    return stiffness_n_per_m * depth * (depth / REFERENCE_DEPTH_M) ** (exponent - 1.0)


def rebound_stop_force(disp_m, gap_m, stiffness_n_per_m, exponent):
    """Progressive stop in extension (negative displacement); negative force, see bump_stop."""
    return -bump_stop_force(-np.asarray(disp_m), gap_m, stiffness_n_per_m, exponent)


def load_stop_force(load_n, threshold_n, gain, exponent, sign=1.0):
    """
    Progressive stop driven by the predicted load (``sign`` -1: below the threshold).

    ``gain * d * (d / 1000 N)**(p - 1)`` with ``d = max(0, sign * (load - threshold))``,
    negated for ``sign`` -1 (a rebound stop pulls).
    """
    depth = np.maximum(sign * (np.asarray(load_n) - threshold_n), 0.0)
    return sign * gain * depth * (depth / REFERENCE_LOAD_N) ** (exponent - 1.0)


def load_cubic_force(load_n, center_n, gain):
    """Symmetric hardening in the predicted load: ``gain * 1000 N * ((F - F0) / 1000 N)**3``."""
    return gain * REFERENCE_LOAD_N * ((np.asarray(load_n) - center_n) / REFERENCE_LOAD_N) ** 3


def load_backlash_force(load_n, center_n, threshold_n, gain):
    """
    Clearance driven by the predicted load: ``-gain * clip(F - F0, -thr, thr)``.

    The load through a bushing tracks its deflection; a dead zone of ``+-gap`` in a spring of
    rate ``k`` loses ``k * clip(x, -gap, gap)``, i.e. up to ``thr = k * gap`` of force around
    the unloaded point ``F0``.
    """
    return -gain * np.clip(np.asarray(load_n) - center_n, -threshold_n, threshold_n)


def load_linear_force(load_n, center_n, gain):
    """
    Linear omission seen through the predicted load: ``gain * (F - F0)``.

    A wrong sprung mass scales every quasi-static load (``gain`` = relative mass error, load
    low-passed below the body mode); a wrong spring scales the spring part ``k x`` of the
    suspension force, which is the suspension force through ``k / (k + c s)``.
    """
    return gain * (np.asarray(load_n) - center_n)


def cubic_stiffness_force(disp_m, stiffness_n_per_m3):
    """Symmetric hardening ``k3 * x**3``."""
    return stiffness_n_per_m3 * np.asarray(disp_m) ** 3


def damper_asymmetry_force(vel_mps, compression_minus_rebound_n_s_per_m):
    """
    Damping ``c_c`` in compression (v > 0), ``c_r`` in rebound, beyond their mean.

    ``c_c v`` (v > 0) / ``c_r v`` (v < 0) equals ``(c_c + c_r)/2 v + (c_c - c_r)/2 |v|``; the
    linear model carries the first part, this term the second.
    """
    return 0.5 * compression_minus_rebound_n_s_per_m * np.abs(vel_mps)


def load_rate(state_n, fs_hz: float, previous_n=None) -> np.ndarray:
    """
    Rate of a load state [N/s]: backward difference, ``previous_n`` the sample before.

    ``previous_n`` None: the first sample's own value (a run starts at rate 0).
    """
    state = np.asarray(state_n, dtype=np.float64)
    return np.diff(state, prepend=state[0] if previous_n is None else previous_n) * fs_hz


def coulomb_friction_force(vel_mps, friction_n, velocity_scale_mps):
    """Coulomb friction regularised at low speed: ``F_c * tanh(v / v0)``."""
    return friction_n * np.tanh(np.asarray(vel_mps) / velocity_scale_mps)


def play_operator(disp_m, half_width_m, start_m):
    """
    Backlash (play) operator: ``y[n] = clip(y[n-1], x[n] - b, x[n] + b)``, ``y[-1] = start``.

    Computed as a prefix scan of clamp compositions (a clamp after a clamp is a clamp), so it
    is vectorised and bit-identical for any split of the record.
    """
    x = np.asarray(disp_m, dtype=np.float64)
    lo, hi = x - half_width_m, x + half_width_m
    shift = 1
    while shift < x.size:
        # Compose the clamp over [i-2s+1, i-s] (earlier) with the one over [i-s+1, i] (later).
        new_lo = np.clip(lo[:-shift], lo[shift:], hi[shift:])
        new_hi = np.clip(hi[:-shift], lo[shift:], hi[shift:])
        lo = np.concatenate([lo[:shift], new_lo])
        hi = np.concatenate([hi[:shift], new_hi])
        shift *= 2
    return np.clip(start_m, lo, hi)


def backlash_force(lost_motion_m, stiffness_n_per_m):
    """
    Force lost in a clearance: ``-k * lost_motion``.

    ``lost_motion`` is ``clip(x, -gap, gap)`` for a centred clearance in a restoring spring
    (``hysteretic = 0``: dead zone ``k * (x - clip)`` instead of ``k * x``), or ``x - play(x)``
    for a clearance in front of a non-restoring element (``hysteretic = 1``: lost motion of the
    play operator, the Prandtl elasto-plastic loop).
    """
    return -stiffness_n_per_m * np.asarray(lost_motion_m)


def tire_lift_off_force(force_total_n, threshold_n, gain):
    """Unilateral contact: the load cannot fall below ``threshold``: ``g * max(0, thr - F)``."""
    return gain * np.maximum(threshold_n - np.asarray(force_total_n), 0.0)


def anti_roll_bar_force(disp_m, partner_disp_m, stiffness_n_per_m):
    """Left-right coupling: ``k * (x_this_side - x_other_side)``."""
    return stiffness_n_per_m * (np.asarray(disp_m) - np.asarray(partner_disp_m))


def load_roll_force(load_n, partner_load_n, gain):
    """
    Left-right coupling seen through the predicted loads: ``g/2 * (F_this - F_other)``.

    A bar the model leaves out changes the axle's share of the roll moment, so the axle's
    left-right load difference is ``(1 + g)`` times the predicted one below the roll mode;
    half of the change goes to each side, with opposite signs.
    """
    return 0.5 * gain * (np.asarray(load_n) - np.asarray(partner_load_n))


def time_delay_force(force_n, delayed_force_n):
    """Force and acceleration streams offset: ``F(t - d) - F(t)`` (d > 0: force lags)."""
    return np.asarray(delayed_force_n) - np.asarray(force_n)


def clip_indicator(level, limit):
    """``sign(level)`` where the sensor sits at or beyond its range ``limit``, else 0."""
    level = np.asarray(level, dtype=np.float64)
    return np.sign(level) * (np.abs(level) >= limit)


def sensor_saturation_force(clip_feature, force_n):
    """
    Clipped sensor: the lost peaks cost ``force_n`` times the clip indicator.

    ``clip_feature`` is :func:`clip_indicator` passed through the feature filter that is
    ``integration`` (0, 1, 2) orders below the recorded quantity: the missing part of a
    clipped acceleration peak reaches the force directly (0) and through the integrated
    velocity (1) and displacement (2) the linear model builds from it.
    """
    return force_n * np.asarray(clip_feature)


def mass_error_force(accel_mps2, mass_kg):
    """Missing mass ``dm * a``."""
    return mass_kg * np.asarray(accel_mps2)


def stiffness_error_force(disp_m, stiffness_n_per_m):
    """Missing stiffness ``dk * x``."""
    return stiffness_n_per_m * np.asarray(disp_m)


def damping_error_force(vel_mps, damping_n_s_per_m):
    """Missing damping ``dc * v``."""
    return damping_n_s_per_m * np.asarray(vel_mps)
