# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Linearised vehicle model: state matrix, road input matrix, modes and frequency responses.

Built by central differences of the integrator's own right-hand side
(:func:`wheel_force_estimator.sim.dynamics.derivatives`) at static equilibrium on a flat road
at constant speed, so it is the model that is simulated, not a separate derivation.  Used by
the tests (modal sanity, passivity) and handy for choosing vehicle parameters.
"""
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from wheel_force_estimator.sim import dynamics
from wheel_force_estimator.sim.dynamics import N_STATE
from wheel_force_estimator.sim.dynamics import N_W
from wheel_force_estimator.sim.dynamics import Packed
from wheel_force_estimator.sim.vehicle import per_corner


def _no_effects():
    return np.zeros(8, dtype=np.int64), np.zeros((8, 4))


def _rhs(packed: Packed, s, speed_mps, xf, road, x0, inv_dx, eon, ep):
    ds = np.zeros(N_STATE)
    dynamics.derivatives(s, speed_mps, 0.0, 0.0, xf, road, x0, inv_dx, packed.body_map,
                         packed.body_mass, packed.corner, packed.glob, eon, ep, ds,
                         np.zeros((4, N_W)), np.zeros(dynamics.N_OUT), False)
    return ds


def linearise(packed: Packed, speed_mps: float, eon=None, ep=None, eps: float = 1e-6):
    """
    Return the state matrix A (N_STATE x N_STATE) at static equilibrium on a flat road.

    Central differences of the right-hand side at zero state, constant ``speed_mps``, no
    manoeuvre.  Without effects the model is linear apart from the friction-circle and
    lift-off clamps, which are inactive at equilibrium.  ``eon`` / ``ep`` are the in-loop
    effect arrays (:func:`~wheel_force_estimator.sim.effects.loop_effect_arrays`).
    """
    if eon is None:
        eon, ep = _no_effects()
    road = np.zeros((4, 2))
    a = np.zeros((N_STATE, N_STATE))
    for k in range(N_STATE):
        s = np.zeros(N_STATE)
        s[k] = eps
        dp = _rhs(packed, s, speed_mps, 0.0, road, -1e9, 1e-12, eon, ep)
        s[k] = -eps
        dm = _rhs(packed, s, speed_mps, 0.0, road, -1e9, 1e-12, eon, ep)
        a[:, k] = (dp - dm) / (2.0 * eps)
    return a


def road_input_matrix(packed: Packed, speed_mps: float, corner: int, eps: float = 1e-6):
    """
    Return B (N_STATE, 2): sensitivity of ds/dt to the road height and slope under a corner.

    With :func:`linearise`: ``ds/dt = A s + B [r, dr/dx]``, ``dr/dx = r' / v``, the other
    corners on a flat road.
    """
    dx = 0.25
    grid = np.arange(-20.0, 20.0 + dx / 2, dx)
    row = int(packed.corner[corner, dynamics.CP_ROW])
    # the corner sits at x = 0; the other axle is a wheelbase away, the other side another row
    xf = -packed.corner[corner, dynamics.CP_ROAD_OFFSET]
    near = np.abs(grid) < 1.0
    eon, ep = _no_effects()
    cols = []
    for shape in (np.where(near, 1.0, 0.0), np.where(near, grid, 0.0)):
        res = []
        for sign in (1.0, -1.0):
            road = np.zeros((4, grid.size))
            road[row] = sign * eps * shape
            res.append(_rhs(packed, np.zeros(N_STATE), speed_mps, xf, road, grid[0], 1.0 / dx,
                            eon, ep))
        cols.append((res[0] - res[1]) / (2.0 * eps))
    return np.stack(cols, axis=1)


@dataclass(frozen=True)
class Mode:
    """One oscillating mode of the linearised model."""

    f_hz: float
    damping_ratio: float
    dominant: str        # state whose kinetic energy share is the largest
    energy_share: float  # that share [-]


def _kinetic_weights(vehicle) -> Tuple[np.ndarray, Tuple[str, ...]]:
    """Mass per velocity state, so |v|^2 m compares kinetic energies across states."""
    w = np.zeros(N_STATE)
    w[4:8] = [vehicle.sprung_mass_kg, vehicle.pitch_inertia_kgm2, vehicle.roll_inertia_kgm2, 0.0]
    w[dynamics.S_VBX] = w[dynamics.S_VBY] = vehicle.sprung_mass_kg
    mu = per_corner(vehicle, 'unsprung_mass_{}_kg')
    iw = per_corner(vehicle, 'wheel_spin_inertia_{}_kgm2') / vehicle.wheel_radius_m ** 2
    for i in range(4):
        b = dynamics.S_CORNER + 9 * i
        w[b + dynamics.C_ZD] = w[b + dynamics.C_XD] = w[b + dynamics.C_YD] = mu[i]
        w[b + dynamics.C_OM] = iw[i]
    return w, dynamics.state_names()


def modes(vehicle, speed_mps: float, effects=None) -> Tuple[Mode, ...]:
    """
    Return the oscillating modes of the linearised car, lowest frequency first.

    Each mode is labelled with the velocity state carrying the largest share of its kinetic
    energy (``heave_mps``, ``pitch_radps``, ``roll_radps``, ``lf_z_mps``, ...).
    ``effects`` is an :class:`~wheel_force_estimator.sim.effects.EffectSet` (in-loop effects
    only, e.g. ``anti_roll_bar``).
    """
    from wheel_force_estimator.sim.effects import loop_effect_arrays
    eon, ep = loop_effect_arrays(effects) if effects is not None else _no_effects()
    a = linearise(dynamics.pack(vehicle), speed_mps, eon, ep)
    lam, vec = np.linalg.eig(a)
    weights, names = _kinetic_weights(vehicle)
    out = []
    for k in np.argsort(np.abs(lam)):
        if lam[k].imag <= 1e-6:
            continue
        energy = weights * np.abs(vec[:, k]) ** 2
        j = int(np.argmax(energy))
        out.append(Mode(f_hz=float(abs(lam[k]) / (2.0 * np.pi)),
                        damping_ratio=float(-lam[k].real / abs(lam[k])),
                        dominant=names[j], energy_share=float(energy[j] / energy.sum())))
    return tuple(out)
