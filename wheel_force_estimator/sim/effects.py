# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Switchable physics effects: what the "real" car has and the nominal model leaves out.

Names are the DESIGN.md vocabulary.  The nominal simulation is the linear(-ish) model without
any effect; :func:`wheel_force_estimator.sim.api.simulate_pair` gives the "real" car the
selected effects with the same roads, manoeuvres and noise.  Each effect changes one element:

================== ===================================================================
bump_stop          jounce bumper: ``F = k e + k3 e^3`` for compression ``e`` beyond ``gap_m``
rebound_stop       rebound stop: ``F = -k e`` for extension ``e`` beyond ``gap_m``
cubic_stiffness    symmetric hardening of the spring: ``+ k3 c^3``
damper_asymmetry   rebound damping ``ratio`` times compression damping, same mean
coulomb_friction   strut friction ``F_c tanh(c_dot / v_s)``
backlash           clearance ``+-gap_m`` in the fore-aft hub bushing (spring dead zone)
tire_lift_off      unilateral tyre contact: vertical tyre force ``max(0, F)``
anti_roll_bar      left-right coupling: front bar and rear twist-beam torsion (wheel rates)
time_delay         WFT stream late by ``delay_s`` (resolution: one integration step)
sensor_saturation  accelerometer range ``+-limit_mps2`` (ADC clip after noise)
mass_error         sprung mass and inertias x (1 + fraction) (payload at the CG)
stiffness_error    suspension spring rates x (1 + fraction)
damping_error      damper rates x (1 + fraction)
================== ===================================================================

Defaults (:data:`EFFECT_DEFAULTS`) are typical magnitudes for the default car and are sized so
that each effect shows up on the default proving-ground course.  ``effect_params`` (dict or
YAML, :func:`load_effect_params`) override them per effect and parameter.
"""
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
import math
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError

EFFECT_DEFAULTS = MappingProxyType({
    'bump_stop': MappingProxyType(
        {'gap_m': 0.030, 'stiffness_n_per_m': 5.0e4, 'progressive_n_per_m3': 2.0e8}),
    'rebound_stop': MappingProxyType({'gap_m': 0.040, 'stiffness_n_per_m': 1.0e5}),
    'cubic_stiffness': MappingProxyType({'coefficient_n_per_m3': 5.0e6}),
    'damper_asymmetry': MappingProxyType({'rebound_to_compression_ratio': 3.0}),
    'coulomb_friction': MappingProxyType({'force_n': 80.0, 'velocity_scale_mps': 0.005}),
    'backlash': MappingProxyType({'gap_m': 0.0005}),
    'tire_lift_off': MappingProxyType({}),
    'anti_roll_bar': MappingProxyType({'front_n_per_m': 18000.0, 'rear_n_per_m': 9000.0}),
    'time_delay': MappingProxyType({'delay_s': 0.00390625}),
    'sensor_saturation': MappingProxyType({'limit_mps2': 60.0}),
    'mass_error': MappingProxyType({'fraction': 0.07}),
    'stiffness_error': MappingProxyType({'fraction': 0.15}),
    'damping_error': MappingProxyType({'fraction': -0.25}),
})
EFFECT_NAMES = tuple(EFFECT_DEFAULTS)

# Parameters allowed to be zero or negative; every other parameter must be > 0.
_SIGNED_PARAMS = frozenset({('mass_error', 'fraction'), ('stiffness_error', 'fraction'),
                            ('damping_error', 'fraction')})
_NON_NEGATIVE_PARAMS = frozenset({('bump_stop', 'gap_m'), ('rebound_stop', 'gap_m'),
                                  ('bump_stop', 'progressive_n_per_m3'),
                                  ('time_delay', 'delay_s'), ('backlash', 'gap_m'),
                                  ('anti_roll_bar', 'front_n_per_m'),
                                  ('anti_roll_bar', 'rear_n_per_m')})

# Effects evaluated inside the integrator (index into the flag / parameter arrays).
LOOP_EFFECTS = ('bump_stop', 'rebound_stop', 'cubic_stiffness', 'damper_asymmetry',
                'coulomb_friction', 'backlash', 'tire_lift_off', 'anti_roll_bar')
N_EFFECT_PARAMS = 4


@dataclass(frozen=True)
class EffectSet:
    """
    The effects of one simulated car with their resolved parameters.

    Attributes
    ----------
    names : tuple of str
        Enabled effects, vocabulary order, no duplicates.
    params : Mapping[str, Mapping[str, float]]
        Every enabled effect's parameters (defaults overridden).

    """

    names: Tuple[str, ...] = ()
    params: Mapping[str, Mapping[str, float]] = field(
        default_factory=lambda: MappingProxyType({}))

    def __contains__(self, name: str) -> bool:
        """Return True when effect ``name`` is enabled."""
        return name in self.names

    def get(self, name: str, key: str) -> float:
        """Return parameter ``key`` of enabled effect ``name``."""
        return self.params[name][key]

    def to_dict(self) -> dict:
        """Return ``{effect: {param: value}}`` (JSON friendly)."""
        return {n: dict(self.params[n]) for n in self.names}


def _parse_names(physics) -> Tuple[str, ...]:
    if physics is None:
        return ()
    if isinstance(physics, str):
        items = [p.strip() for p in physics.split(',') if p.strip()]
    else:
        items = list(physics)
    for name in items:
        if name not in EFFECT_DEFAULTS:
            raise ConfigError(f'unknown physics effect {name!r} '
                              f'(known: {", ".join(EFFECT_NAMES)})')
    return tuple(n for n in EFFECT_NAMES if n in items)


def _check_param(effect: str, key: str, value, where: str) -> float:
    known = EFFECT_DEFAULTS[effect]
    if key not in known:
        listed = ', '.join(known) or 'none'
        raise ConfigError(f'{where}: effect {effect} has no parameter {key!r} '
                          f'(known: {listed})')
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{where}: {effect}.{key} = {value!r} is not a number')
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f'{where}: {effect}.{key} = {value!r} is not finite')
    if (effect, key) in _SIGNED_PARAMS:
        if v <= -1.0:
            raise ConfigError(f'{where}: {effect}.{key} = {v} must be > -1')
    elif (effect, key) in _NON_NEGATIVE_PARAMS:
        if v < 0.0:
            raise ConfigError(f'{where}: {effect}.{key} = {v} must be >= 0')
    elif v <= 0.0:
        raise ConfigError(f'{where}: {effect}.{key} = {v} must be > 0')
    return v


def resolve_effects(physics=(), effect_params=None, where: str = 'effect_params') -> EffectSet:
    """
    Validate effect names and parameters; return the resolved :class:`EffectSet`.

    Parameters
    ----------
    physics : str or sequence of str
        Effect names (a comma-separated string is accepted).
    effect_params : mapping, optional
        ``{effect: {param: value}}`` overriding :data:`EFFECT_DEFAULTS`.  Parameters of effects
        that are not enabled are validated and otherwise ignored (one YAML file can describe
        every effect).
    where : str
        Name of the source in error messages (e.g. the YAML file).

    Raises
    ------
    ConfigError
        Unknown effect or parameter, or a value out of range.

    """
    names = _parse_names(physics)
    overrides = {}
    if effect_params is not None:
        if not isinstance(effect_params, Mapping):
            raise ConfigError(f'{where}: expected a mapping {{effect: {{param: value}}}}, '
                              f'got {type(effect_params).__name__}')
        for effect, values in effect_params.items():
            if effect not in EFFECT_DEFAULTS:
                raise ConfigError(f'{where}: unknown physics effect {effect!r} '
                                  f'(known: {", ".join(EFFECT_NAMES)})')
            if values is None:
                continue
            if not isinstance(values, Mapping):
                raise ConfigError(f'{where}: parameters of {effect!r} must be a mapping')
            for key, value in values.items():
                overrides.setdefault(effect, {})[key] = _check_param(effect, key, value, where)
    params = {}
    for name in names:
        merged = dict(EFFECT_DEFAULTS[name])
        merged.update(overrides.get(name, {}))
        params[name] = MappingProxyType(merged)
    return EffectSet(names=names, params=MappingProxyType(params))


def load_effect_params(path) -> dict:
    """
    Read ``{effect: {param: value}}`` from a YAML file (validated).

    Raises
    ------
    ConfigError
        Unreadable file, YAML error, unknown effect / parameter or bad value (file named).

    """
    import yaml
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except OSError as err:
        raise ConfigError(f'{path}: cannot read effect parameters: '
                          f'{err.strerror or err}') from err
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: invalid YAML: {err}') from err
    if isinstance(doc, dict) and set(doc) == {'effects'}:
        doc = doc['effects'] or {}
    resolve_effects((), doc, where=str(path))
    return doc


def apply_parameter_effects(vehicle, effects: EffectSet):
    """Return ``vehicle`` with the parameter-error effects applied (others untouched)."""
    changes = {}
    if 'mass_error' in effects:
        k = 1.0 + effects.get('mass_error', 'fraction')
        changes.update(sprung_mass_kg=vehicle.sprung_mass_kg * k,
                       pitch_inertia_kgm2=vehicle.pitch_inertia_kgm2 * k,
                       roll_inertia_kgm2=vehicle.roll_inertia_kgm2 * k)
    if 'stiffness_error' in effects:
        k = 1.0 + effects.get('stiffness_error', 'fraction')
        changes.update(spring_rate_front_n_per_m=vehicle.spring_rate_front_n_per_m * k,
                       spring_rate_rear_n_per_m=vehicle.spring_rate_rear_n_per_m * k)
    if 'damping_error' in effects:
        k = 1.0 + effects.get('damping_error', 'fraction')
        changes.update(damping_front_ns_per_m=vehicle.damping_front_ns_per_m * k,
                       damping_rear_ns_per_m=vehicle.damping_rear_ns_per_m * k)
    return replace(vehicle, **changes) if changes else vehicle


def loop_effect_arrays(effects: EffectSet) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the flags (int64, (8,)) and parameters (float64, (8, 4)) for the integrator.

    Parameter columns per effect (unused columns are 0):
    bump_stop (gap, k, k3), rebound_stop (gap, k), cubic_stiffness (k3),
    damper_asymmetry (ratio), coulomb_friction (force, velocity scale), backlash (gap),
    tire_lift_off (-), anti_roll_bar (front, rear).
    """
    on = np.zeros(len(LOOP_EFFECTS), dtype=np.int64)
    par = np.zeros((len(LOOP_EFFECTS), N_EFFECT_PARAMS))
    for i, name in enumerate(LOOP_EFFECTS):
        if name not in effects:
            continue
        on[i] = 1
        values = list(effects.params[name].values())
        par[i, :len(values)] = values
    return on, par
