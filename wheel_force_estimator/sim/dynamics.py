# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Equations of motion of the full vehicle and their fixed-step RK4 integrator (numba).

Frame: ISO 8855 (x forward, y left, z up), moving with the planned speed ``v(t)`` along the
planned path (lateral demand ``a_y(t) = v^2 kappa``); states are deviations from static
equilibrium, so gravity enters only through the static preloads and the sensors.

Body (sprung mass ``M_s``): heave ``z``, pitch ``theta`` (+ nose down), roll ``phi`` (+ left
up), and velocity deviations ``v_bx``, ``v_by`` from the plan.  Corner ``i`` at ``(x_i, y_i)``
from the CG moves ``z_bc = z - x_i theta + y_i phi`` (``T`` maps body coordinates to corners;
``body_model='quarter_car'`` uses ``T = I`` with one sprung mass per corner: paper Fig. 1)::

    M_b q''  = T^T (F_s - G)  + [0, -h_cg sum F_bx, h_cg sum F_by, 0]       (rigid body)
    M_s v_bx' = sum F_bx - F_aero - M_s a_x,ref ;   M_s v_by' = sum F_by - M_s a_y,ref

Corner ``i`` (unsprung mass ``m_u``): vertical ``z_u``, fore-aft ``x_u`` and lateral ``y_u``
bushing deflections relative to the body, wheel circumferential speed deviation ``Omega``,
tyre deflections ``u_x``, ``u_y`` (transient tyre, Pacejka's relaxation-length model)::

    c = z_u - z_bc                                  suspension compression (+ jounce)
    F_s = F_s0 + k_s c + c_s c' (+ effects)         spring / damper (+ anti-roll bar)
    F_tz = F_t0 + k_t (r - z_u) + c_t (r' - z_u')   radial tyre, r = enveloped road
    m_u z_u'' = (F_tz - F_t0) - (F_s - F_s0) + G    G = s_i tc F_y (jacking, see below)
    F_bx = k_bx x_u + c_bx x_u' ;  F_by = k_by y_u + c_by y_u'        hub bushings
    m_u (a_x,ref + v_bx' - h theta'' + x_u'') = F_x - F_bx
    m_u (a_y,ref + v_by' + h phi'' + y_u'') = F_y - F_by       h = h_cg
    F_x = k_tx lambda u_x - f_rr F_z - F_z dr/dx ;  F_y = k_ty lambda u_y - F_z dr/dy
    lambda = max(F_tz, 0) / F_t0   (slip and cornering stiffness proportional to load)
    u_x' = -V_sx - (v / sigma_x) u_x ,  V_sx = v_bx - h theta' + x_u' - Omega
                                                 + eta (v / R) (r - z_u)
    u_y' = -V_sy - (v / sigma_y) u_y ,  V_sy = v_by + h phi' + y_u' + s_i tc c'
                                                 - v (delta_i - s_i bs c)
    I_w (Omega' + a_x,ref) / R = T_i - R k_tx lambda u_x

``k_tx = C_kappa / sigma_x`` (a spring at standstill, a slip stiffness at speed), ``|(F_x, F_y)|``
is limited to ``mu F_z`` (friction circle), ``tc`` / ``bs`` are the kinematic track change and bump
steer (``s_i`` = +1 left, -1 right), ``delta_i = a_y,ref / (g c_alpha,i)`` the steer / yaw-geometry
slip angle that gives every tyre its static-load share of the centripetal force, and ``T_i`` the
driver's drive / brake torque: front axle drive, fixed brake balance, PI on ``v_bx`` plus
feed-forward of the planned acceleration, drag and rolling resistance; at standstill the brakes
lock the wheels (``Omega -> -v`` with a 10 ms time constant). The contact patch moves ``s_i tc c``
sideways with compression, so by virtual work the tyre's lateral force jacks the wheel with
``G = s_i tc F_y`` (and the body with ``-G``): the geometric lateral load transfer of a roll centre
``tc * track / 2`` high, reciprocal to the scrub term in ``V_sy`` (without it the model is not
passive). The hub bushings connect the wheel to the body's ground-level point under the corner,
which moves ``-h theta`` / ``+h phi`` with pitch / roll: the horizontal forces give the body the
moments ``-h sum F_bx`` / ``h sum F_by`` (the whole load transfer goes through the springs: no
anti-dive / anti-squat) and the kinematics are their exact virtual-work pair, so the linearised
model is passive at standstill too (checked by the tests).

Simplifications (stated, not hidden): no yaw or steering dynamics (the plan fixes the path),
no camber, hub orientation = body orientation, road speed from the plan (``v_bx`` does not move
the road), kinematic track change moves the contact patch only (slip and jacking), not the hub
mass; tyre vertical force has no lag (the radial tyre is a Kelvin element).

Sensors (per corner, in the spindle frame tilted by ``theta``, ``phi``): specific force
``R^T (a + g e_z)`` (+9.81 m/s^2 on z at rest) and WFT force ``R^T F_tyre - m_w f`` (the tyre force
minus the inertia of the outboard mass ``m_w``).

Integration: classical RK4 at a fixed step (default 4 x the output rate).  A numba loop, not
vectorised numpy: the state at step ``k+1`` depends on step ``k`` and the effects (stops,
friction, lift-off, backlash) are branches per step, so there is nothing to vectorise over
time, and the same loop in plain Python is ~200-400x slower (bench/bench_sim.py measures
both).
"""
from dataclasses import dataclass

from numba import njit
import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator import GRAVITY_MPS2
from wheel_force_estimator.sim.vehicle import corner_layout
from wheel_force_estimator.sim.vehicle import per_corner

# corner parameter columns
(CP_ROAD_OFFSET, CP_ROW, CP_SIDE, CP_MU, CP_MW, CP_KS, CP_CS, CP_KT, CP_CT, CP_FS0, CP_FT0,
 CP_KBX, CP_CBX, CP_KBY, CP_CBY, CP_KTX, CP_KTY, CP_SIGX, CP_SIGY, CP_IW, CP_TC, CP_BS,
 CP_STEER, CP_BRAKE, CP_DRIVE, CP_IOUT, CP_TRAIL, CP_KCY) = range(28)
N_CP = 28
# global parameters
(GP_RIGID, GP_HORIZ, GP_MS, GP_HCG, GP_R, GP_G, GP_FRR, GP_MU, GP_ETA, GP_DRAG, GP_KP, GP_KI,
 GP_MEFF, GP_MTOT) = range(14)
N_GP = 14
# state layout: body q (4), q' (4), v_bx, v_by, integral of v_bx, then 9 per corner
S_VBX, S_VBY, S_IVBX, S_CORNER = 8, 9, 10, 11
(C_Z, C_ZD, C_X, C_XD, C_Y, C_YD, C_OM, C_UX, C_UY) = range(9)
N_STATE = S_CORNER + 36
STATE_NAMES = (('heave_m', 'pitch_rad', 'roll_rad', 'body_q3'),
               ('heave_mps', 'pitch_radps', 'roll_radps', 'body_q3_dot'))
# outputs recorded per step: sensors, states, then the six-component extras (issue 33):
# WFT moments (12), spindle angular rates (12, non-rotating frame), wheel spin rates (4)
O_ACC, O_FORCE, O_COMP, O_TYRE, O_ROAD, O_BODY, O_SPEED = 0, 12, 24, 28, 40, 44, 47
O_MOMENT, O_GYRO, O_SPIN = 48, 60, 72
N_OUT = 76
# workspace columns
(W_C, W_CD, W_FS, W_FT, W_R, W_SLOPE, W_CROSS, W_DEFL, W_FX, W_FY, W_FBX, W_FBY, W_G,
 W_XDD, W_YDD, W_ZDD, W_ALPHA, W_SLIP) = range(18)
N_W = 18
# in-loop effects (order of effects.LOOP_EFFECTS)
E_BUMP, E_REBOUND, E_CUBIC, E_DAMPER, E_COULOMB, E_BACKLASH, E_LIFTOFF, E_ARB = range(8)
# an airborne tyre's deflection decays with this time constant [s]
TAU_FREE_S = 0.01
# brakes lock a standing wheel within this time constant [s]
TAU_HOLD_S = 0.01
# below this speed the path's yaw rate a_y / v is faded out (the curvature is undefined) [m/s]
YAW_FADE_MPS = 0.5
AIR_DENSITY_KGPM3 = 1.2


def state_names():
    """Return the name of every state (order of the state vector)."""
    names = list(STATE_NAMES[0]) + list(STATE_NAMES[1]) + ['v_bx_mps', 'v_by_mps', 'int_v_bx_m']
    for c in CORNERS:
        names += [f'{c}_{n}' for n in ('z_m', 'z_mps', 'x_m', 'x_mps', 'y_m', 'y_mps',
                                       'omega_mps', 'ux_m', 'uy_m')]
    return tuple(names)


@dataclass(frozen=True, eq=False)
class Packed:
    """Numeric arrays handed to the integrator (built by :func:`pack`)."""

    body_map: np.ndarray      # T (4, 4)
    body_mass: np.ndarray     # diagonal of M_b (4,)
    corner: np.ndarray        # (4, N_CP)
    glob: np.ndarray          # (N_GP,)


def pack(vehicle) -> Packed:
    """Return the integrator arrays of a vehicle (``VehicleParams``)."""
    lay = corner_layout(vehicle)
    g = GRAVITY_MPS2
    cp = np.zeros((4, N_CP))
    cp[:, CP_ROAD_OFFSET] = [0.0, 0.0, -vehicle.wheelbase_m, -vehicle.wheelbase_m]
    cp[:, CP_ROW] = [0, 1, 0, 1]
    cp[:, CP_SIDE] = lay.side
    cp[:, CP_MU] = per_corner(vehicle, 'unsprung_mass_{}_kg')
    cp[:, CP_MW] = per_corner(vehicle, 'outboard_mass_{}_kg')
    cp[:, CP_KS] = per_corner(vehicle, 'spring_rate_{}_n_per_m')
    cp[:, CP_CS] = per_corner(vehicle, 'damping_{}_ns_per_m')
    cp[:, CP_KT] = vehicle.tyre_stiffness_n_per_m
    cp[:, CP_CT] = vehicle.tyre_damping_ns_per_m
    cp[:, CP_FS0] = lay.sprung_load_n
    cp[:, CP_FT0] = lay.tyre_load_n
    cp[:, CP_KBX] = per_corner(vehicle, 'hub_long_stiffness_{}_n_per_m')
    cp[:, CP_CBX] = per_corner(vehicle, 'hub_long_damping_{}_ns_per_m')
    cp[:, CP_KBY] = per_corner(vehicle, 'hub_lat_stiffness_{}_n_per_m')
    cp[:, CP_CBY] = per_corner(vehicle, 'hub_lat_damping_{}_ns_per_m')
    c_alpha = per_corner(vehicle, 'cornering_stiffness_{}_per_rad')
    cp[:, CP_SIGX] = vehicle.relaxation_length_long_m
    cp[:, CP_SIGY] = vehicle.relaxation_length_lat_m
    cp[:, CP_KTX] = (vehicle.longitudinal_slip_stiffness_per_load * lay.tyre_load_n
                     / vehicle.relaxation_length_long_m)
    cp[:, CP_KTY] = c_alpha * lay.tyre_load_n / vehicle.relaxation_length_lat_m
    cp[:, CP_IW] = per_corner(vehicle, 'wheel_spin_inertia_{}_kgm2')
    cp[:, CP_TC] = per_corner(vehicle, 'track_change_{}_m_per_m')
    cp[:, CP_BS] = per_corner(vehicle, 'bump_steer_{}_rad_per_m')
    cp[:, CP_STEER] = 1.0 / (g * c_alpha)
    fb = vehicle.front_brake_fraction
    fd = vehicle.drive_front_fraction
    cp[:, CP_BRAKE] = 0.5 * np.array([fb, fb, 1.0 - fb, 1.0 - fb])
    cp[:, CP_DRIVE] = 0.5 * np.array([fd, fd, 1.0 - fd, 1.0 - fd])
    cp[:, CP_IOUT] = per_corner(vehicle, 'outboard_spin_inertia_{}_kgm2')
    cp[:, CP_TRAIL] = vehicle.pneumatic_trail_m
    cp[:, CP_KCY] = vehicle.tyre_lateral_stiffness_n_per_m

    rigid = vehicle.body_model == 'rigid'
    if rigid:
        body_map = np.zeros((4, 4))
        body_map[:, 0] = 1.0
        body_map[:, 1] = -lay.x_m
        body_map[:, 2] = lay.y_m
        # q3 is unused by the rigid body: no corner moves it and its mass only avoids 0 / 0
        body_mass = np.array([vehicle.sprung_mass_kg, vehicle.pitch_inertia_kgm2,
                              vehicle.roll_inertia_kgm2, 1.0])
    else:
        body_map = np.eye(4)
        body_mass = lay.sprung_load_n / g
    gp = np.zeros(N_GP)
    gp[GP_RIGID] = 1.0 if rigid else 0.0
    gp[GP_HORIZ] = 1.0 if vehicle.horizontal_dynamics else 0.0
    gp[GP_MS] = vehicle.sprung_mass_kg
    gp[GP_HCG] = vehicle.cg_height_m
    gp[GP_R] = vehicle.wheel_radius_m
    gp[GP_G] = g
    gp[GP_FRR] = vehicle.rolling_resistance_coefficient
    gp[GP_MU] = vehicle.friction_coefficient
    gp[GP_ETA] = vehicle.rolling_radius_coupling
    gp[GP_DRAG] = 0.5 * AIR_DENSITY_KGPM3 * vehicle.drag_area_m2
    m_tot = vehicle.total_mass_kg
    m_eff = m_tot + float(np.sum(cp[:, CP_IW])) / vehicle.wheel_radius_m ** 2
    gp[GP_KP] = vehicle.driver_speed_gain_per_s * m_eff
    gp[GP_KI] = vehicle.driver_speed_integral_per_s2 * m_eff
    gp[GP_MEFF] = m_eff
    gp[GP_MTOT] = m_tot
    return Packed(body_map=body_map, body_mass=body_mass, corner=cp, glob=gp)


@njit(cache=True)
def _lookup(road, row, x, x0, inv_dx):
    """Linear interpolation of ``road[row]`` at distance x: (value, slope)."""
    u = (x - x0) * inv_dx
    n = road.shape[1]
    i = int(np.floor(u))
    if i < 0:
        i = 0
    elif i > n - 2:
        i = n - 2
    a = road[row, i]
    b = road[row, i + 1]
    return a + (u - i) * (b - a), (b - a) * inv_dx


@njit(cache=True)
def _suspension_force(c, cd, ks, cs, eon, ep):
    """Spring + damper (+ effects) force deviation [N], + pushing the body up."""
    if eon[E_DAMPER] != 0:
        r = ep[E_DAMPER, 0]
        damp = cs * (2.0 / (1.0 + r) if cd > 0.0 else 2.0 * r / (1.0 + r)) * cd
    else:
        damp = cs * cd
    f = ks * c + damp
    if eon[E_CUBIC] != 0:
        f += ep[E_CUBIC, 0] * c * c * c
    if eon[E_BUMP] != 0:
        e = c - ep[E_BUMP, 0]
        if e > 0.0:
            f += ep[E_BUMP, 1] * e + ep[E_BUMP, 2] * e * e * e
    if eon[E_REBOUND] != 0:
        e = -c - ep[E_REBOUND, 0]
        if e > 0.0:
            f -= ep[E_REBOUND, 1] * e
    if eon[E_COULOMB] != 0:
        f += ep[E_COULOMB, 0] * np.tanh(cd / ep[E_COULOMB, 1])
    return f


@njit(cache=True)
def _vertical(s, v, xf, road, rx0, rinv, tm, cp, eon, ep, wk):
    """Corner kinematics, suspension and radial tyre forces into the workspace."""
    for i in range(4):
        b = S_CORNER + 9 * i
        zbc = 0.0
        zbcd = 0.0
        for j in range(4):
            zbc += tm[i, j] * s[j]
            zbcd += tm[i, j] * s[4 + j]
        c = s[b + C_Z] - zbc
        cd = s[b + C_ZD] - zbcd
        row = int(cp[i, CP_ROW])
        xc = xf + cp[i, CP_ROAD_OFFSET]
        r, slope = _lookup(road, row, xc, rx0, rinv)
        cross, _ = _lookup(road, row + 2, xc, rx0, rinv)
        defl = r - s[b + C_Z]
        ft = cp[i, CP_FT0] + cp[i, CP_KT] * defl + cp[i, CP_CT] * (slope * v - s[b + C_ZD])
        if eon[E_LIFTOFF] != 0 and ft < 0.0:
            ft = 0.0
        wk[i, W_C] = c
        wk[i, W_CD] = cd
        wk[i, W_FS] = _suspension_force(c, cd, cp[i, CP_KS], cp[i, CP_CS], eon, ep)
        wk[i, W_FT] = ft
        wk[i, W_R] = r
        wk[i, W_SLOPE] = slope
        wk[i, W_CROSS] = cross
        wk[i, W_DEFL] = defl
    if eon[E_ARB] != 0:
        for left in (0, 2):
            k = ep[E_ARB, 0] if left == 0 else ep[E_ARB, 1]
            d = k * (wk[left, W_C] - wk[left + 1, W_C])
            wk[left, W_FS] += d
            wk[left + 1, W_FS] -= d


@njit(cache=True)
def _horizontal(s, v, axr, ayr, cp, gp, eon, ep, ds, wk):
    """Tyre, bushing, spin and driver; returns (v_bx', v_by', sum F_bx, sum F_by)."""
    vbx = s[S_VBX]
    vby = s[S_VBY]
    g = gp[GP_G]
    radius = gp[GP_R]
    hcg = gp[GP_HCG] if gp[GP_RIGID] > 0.5 else 0.0
    rr_ramp = min(v, 1.0)  # rolling resistance opposes motion only
    f_dem = (gp[GP_MEFF] * axr + gp[GP_DRAG] * v * v + gp[GP_FRR] * gp[GP_MTOT] * g * rr_ramp
             - gp[GP_KP] * vbx - gp[GP_KI] * s[S_IVBX])
    hold = v < 0.01 and axr <= 0.0  # brakes hold the wheels at standstill
    sum_fbx = 0.0
    sum_fby = 0.0
    for i in range(4):
        b = S_CORNER + 9 * i
        ft = wk[i, W_FT]
        fzp = ft if ft > 0.0 else 0.0
        lam = fzp / cp[i, CP_FT0]
        ux = s[b + C_UX]
        uy = s[b + C_UY]
        ulx = gp[GP_MU] * cp[i, CP_FT0] / cp[i, CP_KTX]
        uly = gp[GP_MU] * cp[i, CP_FT0] / cp[i, CP_KTY]
        nrm = np.sqrt((ux / ulx) ** 2 + (uy / uly) ** 2)
        if nrm > 1.0:  # friction circle: |F| <= mu Fz (sliding)
            ux /= nrm
            uy /= nrm
        # share of the sliding limit used laterally: the pneumatic trail falls to 0 at 1
        wk[i, W_SLIP] = min(abs(uy) / uly, 1.0)
        ffx = cp[i, CP_KTX] * lam * ux
        ffy = cp[i, CP_KTY] * lam * uy
        wk[i, W_FX] = ffx - gp[GP_FRR] * fzp * rr_ramp - fzp * wk[i, W_SLOPE]
        fy = ffy - fzp * wk[i, W_CROSS]
        wk[i, W_FY] = fy
        side = cp[i, CP_SIDE]
        wk[i, W_G] = side * cp[i, CP_TC] * fy
        xe = s[b + C_X]
        if eon[E_BACKLASH] != 0:
            gap = ep[E_BACKLASH, 0]
            xe = xe - gap if xe > gap else (xe + gap if xe < -gap else 0.0)
        fbx = cp[i, CP_KBX] * xe + cp[i, CP_CBX] * s[b + C_XD]
        fby = cp[i, CP_KBY] * s[b + C_Y] + cp[i, CP_CBY] * s[b + C_YD]
        wk[i, W_FBX] = fbx
        wk[i, W_FBY] = fby
        sum_fbx += fbx
        sum_fby += fby
        vsx = (vbx - hcg * s[5] + s[b + C_XD] - s[b + C_OM]
               + gp[GP_ETA] * v / radius * wk[i, W_DEFL])
        steer = cp[i, CP_STEER] * ayr - side * cp[i, CP_BS] * wk[i, W_C]
        vsy = vby + hcg * s[6] + s[b + C_YD] + side * cp[i, CP_TC] * wk[i, W_CD] - v * steer
        if fzp > 0.0:
            ds[b + C_UX] = -vsx - v / cp[i, CP_SIGX] * s[b + C_UX]
            ds[b + C_UY] = -vsy - v / cp[i, CP_SIGY] * s[b + C_UY]
        else:
            ds[b + C_UX] = -s[b + C_UX] / TAU_FREE_S
            ds[b + C_UY] = -s[b + C_UY] / TAU_FREE_S
        if hold:  # locked wheel: circumferential speed v + Omega -> 0 (stiff, not a jump)
            ds[b + C_OM] = -(v + s[b + C_OM]) / TAU_HOLD_S
        else:
            share = cp[i, CP_DRIVE] if f_dem >= 0.0 else cp[i, CP_BRAKE]
            torque = radius * share * f_dem
            ds[b + C_OM] = radius * (torque - radius * ffx) / cp[i, CP_IW] - axr
        # spin acceleration of the wheel [rad/s^2]: circumferential acceleration / radius
        wk[i, W_ALPHA] = (ds[b + C_OM] + axr) / radius
    f_aero = gp[GP_DRAG] * (v + vbx) * abs(v + vbx)
    vbx_dot = (sum_fbx - f_aero) / gp[GP_MS] - axr
    vby_dot = sum_fby / gp[GP_MS] - ayr
    return vbx_dot, vby_dot, sum_fbx, sum_fby


@njit(cache=True)
def derivatives(s, v, axr, ayr, xf, road, rx0, rinv, tm, mb, cp, gp, eon, ep, ds, wk, out,
                record):
    """Write ds/dt into ``ds``; when ``record`` also the sensor / state outputs into ``out``."""
    _vertical(s, v, xf, road, rx0, rinv, tm, cp, eon, ep, wk)
    rigid = gp[GP_RIGID] > 0.5
    if gp[GP_HORIZ] > 0.5:
        vbx_dot, vby_dot, sum_fbx, sum_fby = _horizontal(s, v, axr, ayr, cp, gp, eon, ep, ds,
                                                         wk)
    else:
        vbx_dot = vby_dot = sum_fbx = sum_fby = 0.0
        for i in range(4):
            b = S_CORNER + 9 * i
            for k in (W_FX, W_FY, W_FBX, W_FBY, W_G, W_ALPHA, W_SLIP):
                wk[i, k] = 0.0
            for k in (C_OM, C_UX, C_UY):
                ds[b + k] = 0.0
    q = np.zeros(4)
    for i in range(4):
        b = S_CORNER + 9 * i
        zdd = ((wk[i, W_FT] - cp[i, CP_FT0]) - wk[i, W_FS] + wk[i, W_G]) / cp[i, CP_MU]
        wk[i, W_ZDD] = zdd
        ds[b + C_Z] = s[b + C_ZD]
        ds[b + C_ZD] = zdd
        fb = wk[i, W_FS] - wk[i, W_G]
        for j in range(4):
            q[j] += tm[i, j] * fb
    hcg = 0.0
    if rigid:
        hcg = gp[GP_HCG]
        q[1] -= hcg * sum_fbx
        q[2] += hcg * sum_fby
    for j in range(4):
        ds[j] = s[4 + j]
        ds[4 + j] = q[j] / mb[j]
    for i in range(4):
        b = S_CORNER + 9 * i
        mu = cp[i, CP_MU]
        # hub acceleration in the world is (F - F_b) / m_u; x_u, y_u are relative to the
        # body's ground-level point under the corner
        xdd = (wk[i, W_FX] - wk[i, W_FBX]) / mu - axr - vbx_dot + hcg * ds[5]
        ydd = (wk[i, W_FY] - wk[i, W_FBY]) / mu - ayr - vby_dot - hcg * ds[6]
        wk[i, W_XDD] = (wk[i, W_FX] - wk[i, W_FBX]) / mu
        wk[i, W_YDD] = (wk[i, W_FY] - wk[i, W_FBY]) / mu
        ds[b + C_X] = s[b + C_XD]
        ds[b + C_XD] = xdd
        ds[b + C_Y] = s[b + C_YD]
        ds[b + C_YD] = ydd
    ds[S_VBX] = vbx_dot
    ds[S_VBY] = vby_dot
    ds[S_IVBX] = s[S_VBX]
    if record:
        _record(s, v, ayr, rigid, cp, gp, wk, out)


@njit(cache=True)
def _record(s, v, ayr, rigid, cp, gp, wk, out):
    th = s[1] if rigid else 0.0
    ph = s[2] if rigid else 0.0
    ct, st, cf, sf = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    # body axes in the world: R = Ry(theta) Rx(phi); sensor reading = R^T (world vector)
    xb0, xb2 = ct, -st
    yb0, yb1, yb2 = st * sf, cf, ct * sf
    zb0, zb1, zb2 = st * cf, -sf, ct * cf
    g = gp[GP_G]
    for i in range(4):
        ax = wk[i, W_XDD]
        ay = wk[i, W_YDD]
        az = wk[i, W_ZDD] + g
        fsx = xb0 * ax + xb2 * az
        fsy = yb0 * ax + yb1 * ay + yb2 * az
        fsz = zb0 * ax + zb1 * ay + zb2 * az
        fx, fy, fz = wk[i, W_FX], wk[i, W_FY], wk[i, W_FT]
        mw = cp[i, CP_MW]
        out[O_ACC + 3 * i] = fsx
        out[O_ACC + 3 * i + 1] = fsy
        out[O_ACC + 3 * i + 2] = fsz
        out[O_FORCE + 3 * i] = xb0 * fx + xb2 * fz - mw * fsx
        out[O_FORCE + 3 * i + 1] = yb0 * fx + yb1 * fy + yb2 * fz - mw * fsy
        out[O_FORCE + 3 * i + 2] = zb0 * fx + zb1 * fy + zb2 * fz - mw * fsz
        out[O_COMP + i] = wk[i, W_C]
        out[O_TYRE + 3 * i] = fx
        out[O_TYRE + 3 * i + 1] = fy
        out[O_TYRE + 3 * i + 2] = fz
        out[O_ROAD + i] = wk[i, W_R]
        _record_six(s, v, ayr, rigid, i, cp, gp, wk, out, (xb0, 0.0, xb2), (yb0, yb1, yb2),
                    (zb0, zb1, zb2))
    out[O_BODY] = s[0]
    out[O_BODY + 1] = th
    out[O_BODY + 2] = ph
    out[O_SPEED] = v + s[S_VBX]


@njit(cache=True)
def _record_six(s, v, ayr, rigid, i, cp, gp, wk, out, xb, yb, zb):
    """
    Six-component extras of corner ``i``: WFT moments, spindle angular rates, spin rate.

    Moments about the wheel centre of the tyre force acting at the contact patch, which lies
    ``r_l`` below the centre (loaded radius: the static radius less the dynamic tyre
    deflection), ``y_p = F_y / k_cy`` to the side (lateral carcass deflection) and the
    pneumatic trail ``t`` behind it, minus the spin inertia of the outboard part::

        M_x = r_l F_y + y_p F_z         lateral force lever + tyre overturning moment
        M_y = -r_l F_x - I_out alpha    drive / brake torque reaching the road + spin inertia
        M_z = -t F_y - y_p F_x          aligning moment, t = t_0 (1 - |u_y| / u_y,slide)

    As for the forces, the WFT reads the load the wheel puts on the hub, in the body-aligned
    frame.  The spindle gyro (non-rotating knuckle) reads the body rates (roll, pitch, the
    path's yaw rate a_y / v faded below ``YAW_FADE_MPS``) plus the bump-steer rate about z;
    the spin rate is the wheel's circumferential speed over the radius [rad/s].
    """
    b = S_CORNER + 9 * i
    radius = gp[GP_R]
    fx, fy, fz = wk[i, W_FX], wk[i, W_FY], wk[i, W_FT]
    r_l = radius - wk[i, W_DEFL]
    y_p = fy / cp[i, CP_KCY]
    trail = cp[i, CP_TRAIL] * (1.0 - wk[i, W_SLIP])
    mx = r_l * fy + y_p * fz
    my = -r_l * fx - cp[i, CP_IOUT] * wk[i, W_ALPHA]
    mz = -trail * fy - y_p * fx
    out[O_MOMENT + 3 * i] = xb[0] * mx + xb[1] * my + xb[2] * mz
    out[O_MOMENT + 3 * i + 1] = yb[0] * mx + yb[1] * my + yb[2] * mz
    out[O_MOMENT + 3 * i + 2] = zb[0] * mx + zb[1] * my + zb[2] * mz
    roll_rate = s[6] if rigid else 0.0
    pitch_rate = s[5] if rigid else 0.0
    yaw_rate = ayr * v / (v * v + YAW_FADE_MPS * YAW_FADE_MPS)
    ph = s[2] if rigid else 0.0
    steer_rate = -cp[i, CP_SIDE] * cp[i, CP_BS] * wk[i, W_CD]
    out[O_GYRO + 3 * i] = roll_rate + xb[2] * yaw_rate
    out[O_GYRO + 3 * i + 1] = pitch_rate * np.cos(ph) + yb[2] * yaw_rate
    out[O_GYRO + 3 * i + 2] = -pitch_rate * np.sin(ph) + zb[2] * yaw_rate + steer_rate
    out[O_SPIN + i] = (v + s[b + C_OM]) / radius


@njit(cache=True)
def _clamp_slip(s, cp, gp):
    """Project the tyre deflections back onto the friction circle (sliding)."""
    for i in range(4):
        b = S_CORNER + 9 * i
        ulx = gp[GP_MU] * cp[i, CP_FT0] / cp[i, CP_KTX]
        uly = gp[GP_MU] * cp[i, CP_FT0] / cp[i, CP_KTY]
        nrm = np.sqrt((s[b + C_UX] / ulx) ** 2 + (s[b + C_UY] / uly) ** 2)
        if nrm > 1.0:
            s[b + C_UX] /= nrm
            s[b + C_UY] /= nrm


@njit(cache=True)
def integrate(state, k0, n_steps, dt, speed, accel_x, accel_y, x_front, road, rx0, rinv, tm,
              mb, cp, gp, eon, ep, out):
    """
    Advance ``state`` in place by ``n_steps`` RK4 steps from plan index ``k0``.

    ``out[m]`` receives the outputs at the *start* of step m (plan index ``k0 + m``).
    Returns -1, or the first step whose state is not finite (divergence).
    """
    ns = state.size
    k1 = np.empty(ns)
    k2 = np.empty(ns)
    k3 = np.empty(ns)
    k4 = np.empty(ns)
    tmp = np.empty(ns)
    wk = np.zeros((4, N_W))
    half = 0.5 * dt
    for m in range(n_steps):
        j = k0 + m
        v0, v1 = speed[j], speed[j + 1]
        a0, a1 = accel_x[j], accel_x[j + 1]
        b0, b1 = accel_y[j], accel_y[j + 1]
        x0, x1 = x_front[j], x_front[j + 1]
        vm, am, bm, xm = 0.5 * (v0 + v1), 0.5 * (a0 + a1), 0.5 * (b0 + b1), 0.5 * (x0 + x1)
        derivatives(state, v0, a0, b0, x0, road, rx0, rinv, tm, mb, cp, gp, eon, ep, k1, wk,
                    out[m], True)
        for n in range(ns):
            tmp[n] = state[n] + half * k1[n]
        derivatives(tmp, vm, am, bm, xm, road, rx0, rinv, tm, mb, cp, gp, eon, ep, k2, wk,
                    out[m], False)
        for n in range(ns):
            tmp[n] = state[n] + half * k2[n]
        derivatives(tmp, vm, am, bm, xm, road, rx0, rinv, tm, mb, cp, gp, eon, ep, k3, wk,
                    out[m], False)
        for n in range(ns):
            tmp[n] = state[n] + dt * k3[n]
        derivatives(tmp, v1, a1, b1, x1, road, rx0, rinv, tm, mb, cp, gp, eon, ep, k4, wk,
                    out[m], False)
        finite = True
        for n in range(ns):
            state[n] += dt / 6.0 * (k1[n] + 2.0 * k2[n] + 2.0 * k3[n] + k4[n])
            if not np.isfinite(state[n]):
                finite = False
        if not finite:
            return m
        if gp[GP_HORIZ] > 0.5:
            _clamp_slip(state, cp, gp)
    return -1
