# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Declared channels of a generic recording: ``NAME:QUANTITY:UNIT`` role specs and unit tables.

A role spec is ``NAME:QUANTITY:UNIT``, e.g. ``disp:displacement:m`` or ``data[2]:force:kip``:

- ``NAME`` is a CSV header (or a 0-based column number), a MAT / NPZ variable or a JSON key;
  ``NAME[i]`` takes column ``i`` of a 2-D array (rows = samples).
- ``QUANTITY`` is ``displacement``, ``velocity`` or ``acceleration`` for inputs (all inputs of
  a recording share one) and ``force`` for outputs.
- ``UNIT`` is converted to SI (m, m/s, m/s^2, N); the table is :data:`UNITS`, the SI unit of
  each quantity (as written in a model file's ``units``) is :data:`SI_UNITS`.
"""
from dataclasses import dataclass
import re
from typing import Dict, Optional, Sequence, Tuple

from wheel_force_estimator import GRAVITY_MPS2
from wheel_force_estimator.core.design import INPUT_UNITS
from wheel_force_estimator.core.errors import RecordingError
from wheel_force_estimator.core.physics import QUANTITIES

_INCH = 0.0254
_LBF = 4.4482216152605
UNITS: Dict[str, Dict[str, float]] = {
    'displacement': {'m': 1.0, 'cm': 1e-2, 'mm': 1e-3, 'um': 1e-6, 'in': _INCH, 'ft': 0.3048},
    'velocity': {'m/s': 1.0, 'cm/s': 1e-2, 'mm/s': 1e-3, 'in/s': _INCH, 'ft/s': 0.3048},
    'acceleration': {'m/s^2': 1.0, 'm/s2': 1.0, 'mm/s^2': 1e-3, 'mm/s2': 1e-3,
                     'in/s^2': _INCH, 'in/s2': _INCH, 'g': GRAVITY_MPS2},
    'force': {'N': 1.0, 'kN': 1e3, 'lbf': _LBF, 'lb': _LBF, 'kip': 1e3 * _LBF},
}
SI_UNITS: Dict[str, str] = {**INPUT_UNITS, 'force': 'N'}
#: Motion quantities an input may declare (the physics features' quantities).
INPUT_QUANTITIES = QUANTITIES
ROLES = ('input', 'output')
_NAME = re.compile(r'^(?P<key>[^\[\]]+?)(?:\[(?P<col>\d+)\])?$')


@dataclass(frozen=True)
class ChannelSpec:
    """
    One declared channel: where it is in the file, what it measures, its unit.

    Attributes
    ----------
    key : str
        CSV header / column number, MAT or NPZ variable, JSON key.
    column : int or None
        Column of a 2-D variable (rows = samples), ``None`` for a vector.
    quantity : str
        ``displacement``, ``velocity``, ``acceleration`` or ``force``.
    unit : str
        Unit in the file, a key of ``UNITS[quantity]``.

    """

    key: str
    column: Optional[int]
    quantity: str
    unit: str

    @property
    def label(self) -> str:
        """Channel name used in models and results (``key`` or ``key[col]``)."""
        return self.key if self.column is None else f'{self.key}[{self.column}]'

    @property
    def scale(self) -> float:
        """Factor from the file's unit to SI (:data:`SI_UNITS`) [-]."""
        return UNITS[self.quantity][self.unit]

    @property
    def text(self) -> str:
        """Return the spec as written on the command line (``NAME:QUANTITY:UNIT``)."""
        return f'{self.label}:{self.quantity}:{self.unit}'


def parse_spec(text: str, role: str) -> ChannelSpec:
    """
    Parse ``NAME:QUANTITY:UNIT`` for ``role`` ``'input'`` or ``'output'``.

    Parameters
    ----------
    text : str
        The spec, e.g. ``disp:displacement:mm`` or ``data[2]:force:kip``.
    role : str
        ``'input'`` (motion) or ``'output'`` (force).

    Returns
    -------
    ChannelSpec

    Raises
    ------
    RecordingError
        Malformed spec, a quantity not allowed for the role, or an unknown unit.

    """
    if role not in ROLES:
        raise RecordingError(f'role must be one of {list(ROLES)}, got {role!r}')
    name, sep, unit = text.rpartition(':')
    key, sep2, quantity = name.rpartition(':')
    if not sep or not sep2 or not key:
        raise RecordingError(f'{role} spec {text!r}: expected NAME:QUANTITY:UNIT, e.g. '
                             f'disp:displacement:m')
    allowed = INPUT_QUANTITIES if role == 'input' else ('force',)
    if quantity not in allowed:
        raise RecordingError(f'{role} spec {text!r}: quantity must be one of {list(allowed)}')
    if unit not in UNITS[quantity]:
        raise RecordingError(f'{role} spec {text!r}: unknown {quantity} unit {unit!r} '
                             f'(known: {", ".join(UNITS[quantity])})')
    match = _NAME.match(key)
    if match is None:
        raise RecordingError(f'{role} spec {text!r}: bad channel name {key!r}')
    col = match.group('col')
    return ChannelSpec(match.group('key'), None if col is None else int(col), quantity, unit)


def check_specs(inputs: Sequence[ChannelSpec],
                outputs: Sequence[ChannelSpec]) -> Tuple[Tuple[ChannelSpec, ...],
                                                         Tuple[ChannelSpec, ...]]:
    """
    Check a set of declared channels before any file is read.

    Parameters
    ----------
    inputs, outputs : sequence of ChannelSpec
        Declared motion and force channels.

    Returns
    -------
    (tuple of ChannelSpec, tuple of ChannelSpec)
        ``inputs`` and ``outputs`` as tuples.

    Raises
    ------
    RecordingError
        No input or no output, inputs of different quantities, a channel declared twice
        in one role, or a spec in the wrong role.

    """
    inputs, outputs = tuple(inputs), tuple(outputs)
    if not inputs or not outputs:
        raise RecordingError('declare at least one --input and one --output channel')
    quantities = sorted({s.quantity for s in inputs})
    if len(quantities) != 1:
        named = '; '.join(f'{q}: ' + ', '.join(s.label for s in inputs if s.quantity == q)
                          for q in quantities)
        raise RecordingError(f'all inputs must share one quantity (one FRF input unit), got '
                             f'{named}')
    if quantities[0] not in INPUT_QUANTITIES or any(s.quantity != 'force' for s in outputs):
        raise RecordingError('inputs must be motion and outputs force channels')
    for role, specs in (('input', inputs), ('output', outputs)):
        seen = set()
        for spec in specs:
            if spec.label in seen:
                raise RecordingError(f'{role} channel {spec.label!r} is declared twice')
            seen.add(spec.label)
    return inputs, outputs


def quantity_of_unit(unit: str) -> Optional[str]:
    """Return the quantity whose SI unit is ``unit`` (``'m/s^2'`` -> acceleration), or None."""
    for quantity, si in SI_UNITS.items():
        if UNITS[quantity].get(unit) == 1.0 and unit in (si, si.replace('^', '')):
            return quantity
    return None
