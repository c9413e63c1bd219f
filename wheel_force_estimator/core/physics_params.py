# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Typed parameters of the physics terms: one frozen dataclass per physics family, SI fields.

Every field is a finite number, range-checked when the object is built (the error names the
field); flags and orders are typed (``bool``, ``int``) but written to JSON as floats, so the
model file format is the one untyped terms used.  :mod:`core.physics_terms` binds each class
to its physics kinds in the ``TERM_KINDS`` registry.
"""
import dataclasses
from dataclasses import dataclass
import math
from typing import Any, Dict, Mapping, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError


def finite_number(value, name: str) -> float:
    """Return ``value`` as a finite float, or raise ConfigError naming ``name``."""
    if isinstance(value, (bool, np.bool_)):
        return float(value)
    try:
        v = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'{name} must be a number, got {value!r}') from err
    if not math.isfinite(v):
        raise ConfigError(f'{name} must be finite, got {value!r}')
    return v


def _field(minimum=None, strict=False, choices=None, reason=''):
    """Field with range metadata checked by :class:`TermParams` (``reason`` ends the error)."""
    return dataclasses.field(metadata={'min': minimum, 'strict': strict, 'choices': choices,
                                       'reason': reason})


@dataclass(frozen=True)
class TermParams:
    """
    Base of the typed parameters: every field a finite number in SI units, range-checked.

    Raises
    ------
    ConfigError
        A field that is not a finite number, out of its range or not one of its choices; the
        message starts with the field name.

    """

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = finite_number(getattr(self, f.name), f.name)
            meta = f.metadata
            low, choices = meta.get('min'), meta.get('choices')
            if choices is not None and value not in choices:
                raise ConfigError(f'{f.name} must be one of {", ".join(map(str, choices))}, '
                                  f'got {getattr(self, f.name)!r}')
            if low is not None and (value <= low if meta['strict'] else value < low):
                raise ConfigError(f'{f.name} must be {">" if meta["strict"] else ">="} {low}'
                                  f'{meta["reason"]}, got {value}')
            object.__setattr__(self, f.name, f.type(value))

    @classmethod
    def names(cls) -> Tuple[str, ...]:
        """Return the parameter names, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> 'TermParams':
        """
        Parse ``{name: number}``; exactly :meth:`names` must be present.

        Raises
        ------
        ConfigError
            Missing or unknown names, or a field out of range.

        """
        if sorted(data) != sorted(cls.names()):
            raise ConfigError(f'parameters must be {list(cls.names())}, got {sorted(data)}')
        return cls(**{k: data[k] for k in cls.names()})

    def as_dict(self) -> Dict[str, float]:
        """Return ``{name: float}`` (the JSON form; flags and orders as 0.0/1.0/2.0)."""
        return {k: float(getattr(self, k)) for k in self.names()}


@dataclass(frozen=True)
class StopParams(TermParams):
    """Progressive stop on the wheel displacement (bump or rebound)."""

    gap_m: float = _field(0.0)
    stiffness_n_per_m: float = _field()
    exponent: float = _field(1.0)


@dataclass(frozen=True)
class LoadStopParams(TermParams):
    """Progressive stop on the predicted load (secant ``gain`` at 1 kN beyond the threshold)."""

    threshold_n: float = _field()
    gain: float = _field()
    exponent: float = _field(1.0)


@dataclass(frozen=True)
class CubicStiffnessParams(TermParams):
    """Symmetric hardening ``k3 x**3``."""

    stiffness_n_per_m3: float = _field()


@dataclass(frozen=True)
class LoadLinearParams(TermParams):
    """A gain on the predicted load around ``center_n`` (cubic or linear, by kind)."""

    center_n: float = _field()
    gain: float = _field()


@dataclass(frozen=True)
class DamperAsymmetryParams(TermParams):
    """Compression minus rebound damping rate."""

    compression_minus_rebound_n_s_per_m: float = _field()


@dataclass(frozen=True)
class CoulombFrictionParams(TermParams):
    """Friction level and its regularising velocity."""

    friction_n: float = _field()
    velocity_scale_mps: float = _field(0.0, strict=True)


@dataclass(frozen=True)
class LoadFrictionParams(TermParams):
    """Friction level and its regularising rate of the predicted load (its deflection rate)."""

    friction_n: float = _field()
    rate_scale_n_per_s: float = _field(0.0, strict=True)


@dataclass(frozen=True)
class BacklashParams(TermParams):
    """Clearance of half-width ``gap_m`` in a spring; ``hysteretic`` = play operator."""

    gap_m: float = _field(0.0)
    stiffness_n_per_m: float = _field()
    hysteretic: bool = _field(choices=(0.0, 1.0))


@dataclass(frozen=True)
class LoadBacklashParams(TermParams):
    """Clearance seen in the predicted load (``threshold_n`` = rate times gap)."""

    center_n: float = _field()
    threshold_n: float = _field()
    gain: float = _field()


@dataclass(frozen=True)
class LiftOffParams(TermParams):
    """Unilateral contact: load floor and gain."""

    threshold_n: float = _field()
    gain: float = _field()


@dataclass(frozen=True)
class AntiRollBarParams(TermParams):
    """Cross-corner rate on the relative displacement of the two wheels of an axle."""

    stiffness_n_per_m: float = _field()


@dataclass(frozen=True)
class LoadRollParams(TermParams):
    """Relative change of the axle's left-right load difference (missing roll stiffness)."""

    gain: float = _field()


@dataclass(frozen=True)
class TimeDelayParams(TermParams):
    """Delay of the force stream behind the acceleration stream."""

    delay_s: float = _field(0.0, reason=' (a force that leads the acceleration needs '
                                        'look-ahead; shift the force stamps instead)')


@dataclass(frozen=True)
class SaturationParams(TermParams):
    """Clip level of the recorded input, force per unit clip feature, integration order."""

    limit: float = _field(0.0, strict=True)
    force_n: float = _field()
    integration: int = _field(choices=(0.0, 1.0, 2.0))


@dataclass(frozen=True)
class MassErrorParams(TermParams):
    """Missing mass."""

    mass_kg: float = _field()


@dataclass(frozen=True)
class StiffnessErrorParams(TermParams):
    """Missing stiffness."""

    stiffness_n_per_m: float = _field()


@dataclass(frozen=True)
class DampingErrorParams(TermParams):
    """Missing damping."""

    damping_n_s_per_m: float = _field()
