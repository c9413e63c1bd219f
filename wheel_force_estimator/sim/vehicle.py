# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Vehicle parameters of the proving-ground simulator and their YAML override.

The default :class:`VehicleParams` describe a typical front-wheel-drive compact car like the
paper's test vehicle (GVW 1421 kg, McPherson front, twist-beam rear): 1271 kg sprung mass,
40 kg / 35 kg unsprung mass per front / rear corner, 58 % front axle load, wheelbase 2.60 m.
Rates are *wheel rates* (spring and damper motion ratios already applied), so a corner is
described by what the wheel centre feels.  Values are textbook magnitudes for such a car; the
resulting modes (body bounce ~1.3 Hz, wheel hop ~12-13 Hz, hub fore-aft ~25 Hz, hub lateral
~50 Hz, wheel spin-tyre ~30 Hz) are checked by the tests from the linearised model.

Another vehicle is a YAML file away (:func:`load_vehicle`): a mapping of field names to values,
either at the top level or under a ``vehicle:`` key; fields not given keep their defaults.
"""
from dataclasses import dataclass
from dataclasses import fields
from dataclasses import replace
import math
from pathlib import Path
from typing import Dict, Tuple

import numpy as np

from wheel_force_estimator import GRAVITY_MPS2
from wheel_force_estimator.core.errors import ConfigError

BODY_MODELS = ('rigid', 'quarter_car')

# Fields that may be zero (everything else numeric must be > 0).
_NON_NEGATIVE = frozenset({
    'tyre_damping_ns_per_m',
    'tyre_contact_length_m', 'rolling_resistance_coefficient', 'rolling_radius_coupling',
    'track_change_front_m_per_m', 'track_change_rear_m_per_m', 'drag_area_m2',
    'driver_speed_integral_per_s2', 'accel_noise_mps2', 'force_noise_n',
    'moment_noise_nm', 'gyro_noise_radps', 'spin_noise_radps',
    'hub_long_damping_front_ns_per_m', 'hub_long_damping_rear_ns_per_m',
    'hub_lat_damping_front_ns_per_m', 'hub_lat_damping_rear_ns_per_m',
})
# Fields that may have either sign.
_SIGNED = frozenset({'bump_steer_front_rad_per_m', 'bump_steer_rear_rad_per_m'})
# Fields that are fractions in [0, 1].
_FRACTIONS = frozenset({'front_brake_fraction', 'drive_front_fraction'})


@dataclass(frozen=True)
class VehicleParams:
    """
    Physical parameters of the simulated car (SI units in the names).

    Attributes
    ----------
    name : str
        Label written to reports.
    sprung_mass_kg, pitch_inertia_kgm2, roll_inertia_kgm2 : float
        Rigid body above the springs (about its own centre of gravity).
    unsprung_mass_front_kg, unsprung_mass_rear_kg : float
        Per corner: wheel, tyre, hub, brake, share of links / twist beam.
    outboard_mass_front_kg, outboard_mass_rear_kg : float
        Part of the unsprung mass outboard of the WFT measuring plane (rim, tyre, WFT rotor).
        The WFT reads the tyre force minus the inertia force of this mass.
    wheel_spin_inertia_front_kgm2, wheel_spin_inertia_rear_kgm2 : float
        Spin inertia of a wheel (front includes half a drive shaft).
    outboard_spin_inertia_front_kgm2, outboard_spin_inertia_rear_kgm2 : float
        Part of the spin inertia outboard of the WFT (rim, tyre): the WFT's ``My`` is the
        tyre's moment minus this inertia times the spin acceleration.
    wheelbase_m, cg_to_front_axle_m, cg_height_m, track_front_m, track_rear_m : float
        Geometry; the centre of gravity is that of the sprung mass, on the centre line.
    wheel_radius_m : float
        Loaded radius; lever of the spin dynamics.
    spring_rate_*_n_per_m, damping_*_ns_per_m : float
        Vertical suspension wheel rates (linear: the nominal model).
    hub_long_*, hub_lat_* : float
        Fore-aft and lateral compliance of the wheel centre relative to the body (bushings),
        stiffness [N/m] and damping [N s/m].
    track_change_*_m_per_m : float
        Outward lateral travel of the contact patch per metre of compression (kinematics).
        By virtual work the tyre's lateral force then jacks the wheel with ``tc F_y``: the
        geometric (link) lateral load transfer, i.e. a roll centre ``tc * track / 2`` high.
    bump_steer_*_rad_per_m : float
        Toe-in per metre of compression.
    tyre_stiffness_n_per_m, tyre_damping_ns_per_m : float
        Radial tyre spring and damper (Kelvin element).
    tyre_contact_length_m : float
        Enveloping: the tyre follows the road averaged over this length (0 = point contact).
    rolling_resistance_coefficient, friction_coefficient : float
        Rolling resistance force / load; peak friction (friction circle).
    longitudinal_slip_stiffness_per_load : float
        C_kappa / Fz [1 per unit slip]; the slip stiffness is proportional to the load.
    cornering_stiffness_front_per_rad, cornering_stiffness_rear_per_rad : float
        C_alpha / Fz [1/rad], also load-proportional.
    relaxation_length_long_m, relaxation_length_lat_m : float
        Transient tyre: first-order lag over this rolled distance (stiffness C/sigma at rest).
    pneumatic_trail_m : float
        Distance the lateral force acts behind the wheel centre at small slip; it falls
        linearly to 0 as the lateral deflection reaches the sliding limit (aligning moment).
    tyre_lateral_stiffness_n_per_m : float
        Lateral carcass stiffness: the contact patch moves ``F_y / k`` sideways, so the
        vertical load gives an overturning moment and the longitudinal force an aligning
        moment.
    rolling_radius_coupling : float
        Change of effective rolling radius per tyre compression (about 1/3): couples
        vertical tyre deflection into longitudinal slip.
    front_brake_fraction, drive_front_fraction : float
        Brake torque share of the front axle; drive torque share of the front axle (1 = FWD).
    drag_area_m2 : float
        Cd * A of the aerodynamic drag (air density 1.2 kg/m^3).
    driver_speed_gain_per_s, driver_speed_integral_per_s2 : float
        Driver's speed tracking (PI on speed error, per kg of vehicle mass).
    accel_noise_mps2, force_noise_n : float
        White sensor noise standard deviation at the output rate.
    moment_noise_nm, gyro_noise_radps, spin_noise_radps : float
        The same for the WFT moments, the spindle gyros and the wheel speed sensors.
    body_model : {'rigid', 'quarter_car'}
        ``quarter_car`` replaces the rigid body by one independent sprung mass per corner
        (its static corner mass): the paper's quarter-car model, used to check eq. (8).
    horizontal_dynamics : bool
        False switches off the fore-aft / lateral degrees of freedom (vertical only).

    """

    name: str = 'compact_fwd_1421kg'
    sprung_mass_kg: float = 1271.0
    pitch_inertia_kgm2: float = 1950.0
    roll_inertia_kgm2: float = 420.0
    unsprung_mass_front_kg: float = 40.0
    unsprung_mass_rear_kg: float = 35.0
    outboard_mass_front_kg: float = 21.0
    outboard_mass_rear_kg: float = 20.0
    wheel_spin_inertia_front_kgm2: float = 1.1
    wheel_spin_inertia_rear_kgm2: float = 0.9
    outboard_spin_inertia_front_kgm2: float = 0.8
    outboard_spin_inertia_rear_kgm2: float = 0.75
    wheelbase_m: float = 2.60
    cg_to_front_axle_m: float = 1.08
    cg_height_m: float = 0.55
    track_front_m: float = 1.48
    track_rear_m: float = 1.46
    wheel_radius_m: float = 0.30
    spring_rate_front_n_per_m: float = 25000.0
    spring_rate_rear_n_per_m: float = 21000.0
    damping_front_ns_per_m: float = 2100.0
    damping_rear_ns_per_m: float = 1800.0
    hub_long_stiffness_front_n_per_m: float = 1.2e6
    hub_long_stiffness_rear_n_per_m: float = 0.8e6
    hub_long_damping_front_ns_per_m: float = 1200.0
    hub_long_damping_rear_ns_per_m: float = 900.0
    hub_lat_stiffness_front_n_per_m: float = 4.0e6
    hub_lat_stiffness_rear_n_per_m: float = 3.0e6
    hub_lat_damping_front_ns_per_m: float = 2500.0
    hub_lat_damping_rear_ns_per_m: float = 2000.0
    track_change_front_m_per_m: float = 0.11
    track_change_rear_m_per_m: float = 0.05
    bump_steer_front_rad_per_m: float = 0.05
    bump_steer_rear_rad_per_m: float = 0.03
    tyre_stiffness_n_per_m: float = 230000.0
    tyre_damping_ns_per_m: float = 150.0
    tyre_contact_length_m: float = 0.18
    rolling_resistance_coefficient: float = 0.011
    friction_coefficient: float = 1.0
    longitudinal_slip_stiffness_per_load: float = 18.0
    cornering_stiffness_front_per_rad: float = 15.0
    cornering_stiffness_rear_per_rad: float = 18.0
    relaxation_length_long_m: float = 0.15
    relaxation_length_lat_m: float = 0.45
    pneumatic_trail_m: float = 0.03
    tyre_lateral_stiffness_n_per_m: float = 150000.0
    rolling_radius_coupling: float = 0.3
    front_brake_fraction: float = 0.70
    drive_front_fraction: float = 1.0
    drag_area_m2: float = 0.70
    driver_speed_gain_per_s: float = 1.0
    driver_speed_integral_per_s2: float = 0.1
    accel_noise_mps2: float = 0.02
    force_noise_n: float = 8.0
    moment_noise_nm: float = 0.5
    gyro_noise_radps: float = 0.002
    spin_noise_radps: float = 0.01
    body_model: str = 'rigid'
    horizontal_dynamics: bool = True

    def __post_init__(self):
        """Check types and physical ranges; reject, never repair."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == 'name':
                if not isinstance(value, str) or not value:
                    raise ConfigError(f'vehicle name must be a non-empty string, got {value!r}')
                continue
            if f.name == 'body_model':
                if value not in BODY_MODELS:
                    raise ConfigError(f'vehicle body_model must be one of {BODY_MODELS}, '
                                      f'got {value!r}')
                continue
            if f.name == 'horizontal_dynamics':
                if not isinstance(value, bool):
                    raise ConfigError(f'vehicle horizontal_dynamics must be true or false, '
                                      f'got {value!r}')
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f'vehicle {f.name} must be a number, got {value!r}')
            v = float(value)
            if not math.isfinite(v):
                raise ConfigError(f'vehicle {f.name} must be finite, got {value!r}')
            if f.name in _FRACTIONS:
                ok = 0.0 <= v <= 1.0
                need = 'in [0, 1]'
            elif f.name in _SIGNED:
                ok, need = True, ''
            elif f.name in _NON_NEGATIVE:
                ok, need = v >= 0.0, '>= 0'
            else:
                ok, need = v > 0.0, '> 0'
            if not ok:
                raise ConfigError(f'vehicle {f.name} must be {need}, got {value!r}')
            object.__setattr__(self, f.name, v)
        if self.cg_to_front_axle_m >= self.wheelbase_m:
            raise ConfigError(f'vehicle cg_to_front_axle_m ({self.cg_to_front_axle_m}) must be '
                              f'less than wheelbase_m ({self.wheelbase_m})')
        for axle in ('front', 'rear'):
            mo = getattr(self, f'outboard_mass_{axle}_kg')
            mu = getattr(self, f'unsprung_mass_{axle}_kg')
            if mo >= mu:
                raise ConfigError(f'vehicle outboard_mass_{axle}_kg ({mo}) must be less than '
                                  f'unsprung_mass_{axle}_kg ({mu})')
            io = getattr(self, f'outboard_spin_inertia_{axle}_kgm2')
            iw = getattr(self, f'wheel_spin_inertia_{axle}_kgm2')
            if io >= iw:
                raise ConfigError(f'vehicle outboard_spin_inertia_{axle}_kgm2 ({io}) must be '
                                  f'less than wheel_spin_inertia_{axle}_kgm2 ({iw})')

    @property
    def total_mass_kg(self) -> float:
        """Sprung plus the four unsprung masses [kg]."""
        return (self.sprung_mass_kg + 2.0 * self.unsprung_mass_front_kg
                + 2.0 * self.unsprung_mass_rear_kg)


@dataclass(frozen=True, eq=False)
class CornerLayout:
    """
    Per-corner static quantities derived from :class:`VehicleParams` (order lf rf lr rr).

    Attributes
    ----------
    x_m, y_m : numpy.ndarray, shape (4,)
        Corner position relative to the sprung centre of gravity (x forward, y left).
    side : numpy.ndarray, shape (4,)
        +1 left, -1 right.
    sprung_load_n : numpy.ndarray, shape (4,)
        Static spring force (preload) carrying the body.
    tyre_load_n : numpy.ndarray, shape (4,)
        Static vertical tyre force (sprung share plus unsprung weight).
    wft_load_n : numpy.ndarray, shape (4,)
        Static vertical force a WFT reads: tyre load minus the weight of the outboard mass.

    """

    x_m: np.ndarray
    y_m: np.ndarray
    side: np.ndarray
    sprung_load_n: np.ndarray
    tyre_load_n: np.ndarray
    wft_load_n: np.ndarray


def per_corner(vehicle: VehicleParams, stem: str) -> np.ndarray:
    """
    Return ``{stem}_front…`` / ``{stem}_rear…`` as a (4,) array in corner order.

    ``stem`` is the field name with ``front`` replaced by ``{}``, e.g.
    ``'spring_rate_{}_n_per_m'``.
    """
    front = float(getattr(vehicle, stem.format('front')))
    rear = float(getattr(vehicle, stem.format('rear')))
    return np.array([front, front, rear, rear])


def corner_layout(vehicle: VehicleParams) -> CornerLayout:
    """Return positions and static loads of the four corners."""
    a = vehicle.cg_to_front_axle_m
    b = vehicle.wheelbase_m - a
    x = np.array([a, a, -b, -b])
    half_track = 0.5 * per_corner(vehicle, 'track_{}_m')
    side = np.array([1.0, -1.0, 1.0, -1.0])
    weight = vehicle.sprung_mass_kg * GRAVITY_MPS2
    sprung = 0.5 * weight * np.array([b, b, a, a]) / vehicle.wheelbase_m
    tyre = sprung + per_corner(vehicle, 'unsprung_mass_{}_kg') * GRAVITY_MPS2
    wft = tyre - per_corner(vehicle, 'outboard_mass_{}_kg') * GRAVITY_MPS2
    return CornerLayout(x_m=x, y_m=side * half_track, side=side, sprung_load_n=sprung,
                        tyre_load_n=tyre, wft_load_n=wft)


def quarter_car(vehicle: VehicleParams) -> VehicleParams:
    """Return ``vehicle`` as four independent vertical quarter cars (paper Figure 1)."""
    return replace(vehicle, body_model='quarter_car', horizontal_dynamics=False)


def vehicle_to_dict(vehicle: VehicleParams) -> Dict[str, object]:
    """Return every field as a plain dict (YAML / JSON friendly)."""
    return {f.name: getattr(vehicle, f.name) for f in fields(vehicle)}


def _field_types() -> Dict[str, Tuple[type, ...]]:
    out = {}
    for f in fields(VehicleParams):
        if f.name in ('name', 'body_model'):
            out[f.name] = (str,)
        elif f.name == 'horizontal_dynamics':
            out[f.name] = (bool,)
        else:
            out[f.name] = (int, float)
    return out


def vehicle_from_mapping(values, where: str = 'vehicle') -> VehicleParams:
    """
    Return the defaults overridden by ``values`` (a mapping of field name -> value).

    Raises
    ------
    ConfigError
        Not a mapping, unknown field, wrong type or out-of-range value (``where`` named).

    """
    if not isinstance(values, dict):
        raise ConfigError(f'{where}: expected a mapping of vehicle parameters, '
                          f'got {type(values).__name__}')
    types = _field_types()
    for key, value in values.items():
        if key not in types:
            raise ConfigError(f'{where}: unknown vehicle parameter {key!r} '
                              f'(known: {", ".join(sorted(types))})')
        if isinstance(value, bool) and types[key] != (bool,):
            raise ConfigError(f'{where}: {key} = {value!r} is not a number')
        if not isinstance(value, types[key]):
            raise ConfigError(f'{where}: {key} = {value!r} has the wrong type '
                              f'(expected {types[key][0].__name__})')
    try:
        return replace(VehicleParams(), **values)
    except ConfigError as err:
        raise ConfigError(f'{where}: {err}') from err


def load_vehicle(path) -> VehicleParams:
    """
    Read a vehicle YAML file (field overrides, optionally under a ``vehicle:`` key).

    Parameters
    ----------
    path : str or os.PathLike
        YAML file.

    Returns
    -------
    VehicleParams

    Raises
    ------
    ConfigError
        Unreadable file, YAML syntax error, unknown field or invalid value (file and key
        named).

    """
    import yaml
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as err:
        raise ConfigError(f'{path}: cannot read vehicle file: {err.strerror or err}') from err
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: invalid YAML: {err}') from err
    if doc is None:
        doc = {}
    if isinstance(doc, dict) and set(doc) == {'vehicle'}:
        doc = doc['vehicle'] or {}
    return vehicle_from_mapping(doc, where=str(path))
