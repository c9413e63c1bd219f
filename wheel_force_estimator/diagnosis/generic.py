# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Generic recordings (CSV, MAT, NPZ, JSON) with declared channel roles, quantities and units.

A role spec is ``NAME:QUANTITY:UNIT``, e.g. ``disp:displacement:m`` or ``data[2]:force:kip``:

- ``NAME`` is a CSV header (or a 0-based column number), a MAT / NPZ variable or a JSON key;
  ``NAME[i]`` takes column ``i`` of a 2-D array (rows = samples).
- ``QUANTITY`` is ``displacement``, ``velocity`` or ``acceleration`` for inputs (all inputs of
  a recording share one) and ``force`` for outputs.
- ``UNIT`` is converted to SI (m, m/s, m/s**2, N); the table is :data:`UNITS`.

Nothing is resampled, padded or cleaned: unequal lengths and non-finite values are refused.
"""
import csv
from dataclasses import dataclass
import json
from pathlib import Path
import re
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.diagnosis.recording import MotionRecording

_INCH = 0.0254
_LBF = 4.4482216152605
UNITS: Dict[str, Dict[str, float]] = {
    'displacement': {'m': 1.0, 'cm': 1e-2, 'mm': 1e-3, 'um': 1e-6, 'in': _INCH, 'ft': 0.3048},
    'velocity': {'m/s': 1.0, 'cm/s': 1e-2, 'mm/s': 1e-3, 'in/s': _INCH, 'ft/s': 0.3048},
    'acceleration': {'m/s^2': 1.0, 'm/s2': 1.0, 'mm/s^2': 1e-3, 'mm/s2': 1e-3,
                     'in/s^2': _INCH, 'in/s2': _INCH, 'g': 9.80665},
    'force': {'N': 1.0, 'kN': 1e3, 'lbf': _LBF, 'lb': _LBF, 'kip': 1e3 * _LBF},
}
INPUT_QUANTITIES = ('displacement', 'velocity', 'acceleration')
_NAME = re.compile(r'^(?P<key>[^\[\]]+?)(?:\[(?P<col>\d+)\])?$')


@dataclass(frozen=True)
class ChannelSpec:
    """One declared channel: where it is in the file, what it measures, its unit."""

    key: str
    column: Optional[int]
    quantity: str
    unit: str

    @property
    def label(self) -> str:
        """Channel name used in results (``key`` or ``key[col]``)."""
        return self.key if self.column is None else f'{self.key}[{self.column}]'

    @property
    def scale(self) -> float:
        """Factor to SI."""
        return UNITS[self.quantity][self.unit]


def parse_spec(text: str, role: str) -> ChannelSpec:
    """
    Parse ``NAME:QUANTITY:UNIT`` for ``role`` ``'input'`` or ``'output'``.

    Raises
    ------
    DiagnosisError
        Malformed spec, a quantity not allowed for the role, or an unknown unit.

    """
    name, sep, rest = text.rpartition(':')
    key, sep2, quantity = name.rpartition(':')
    unit = rest
    if not sep or not sep2 or not key:
        raise DiagnosisError(f'{role} spec {text!r}: expected NAME:QUANTITY:UNIT, e.g. '
                             f'disp:displacement:m')
    allowed = INPUT_QUANTITIES if role == 'input' else ('force',)
    if quantity not in allowed:
        raise DiagnosisError(f'{role} spec {text!r}: quantity must be one of {list(allowed)}')
    if unit not in UNITS[quantity]:
        raise DiagnosisError(f'{role} spec {text!r}: unknown {quantity} unit {unit!r} '
                             f'(known: {", ".join(UNITS[quantity])})')
    match = _NAME.match(key)
    if match is None:
        raise DiagnosisError(f'{role} spec {text!r}: bad channel name {key!r}')
    col = match.group('col')
    return ChannelSpec(match.group('key'), None if col is None else int(col), quantity, unit)


def _load_csv(path: Path) -> Dict[str, np.ndarray]:
    with path.open(newline='') as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise DiagnosisError(f'{path}: empty CSV file')
    try:
        [float(v) for v in rows[0]]
        header, body = [str(i) for i in range(len(rows[0]))], rows
    except ValueError:
        header, body = [h.strip() for h in rows[0]], rows[1:]
    for i, row in enumerate(body):
        if len(row) != len(header):
            raise DiagnosisError(f'{path}: line {i + 1 + (header[0] != "0")} has {len(row)} '
                                 f'fields, the header {len(header)}')
    try:
        data = np.array(body, dtype=np.float64).reshape(len(body), len(header))
    except ValueError as err:
        raise DiagnosisError(f'{path}: non-numeric CSV value: {err}') from err
    return {h: data[:, i] for i, h in enumerate(header)}


def _load_json(path: Path) -> Dict[str, np.ndarray]:
    try:
        doc = json.loads(path.read_text())
    except ValueError as err:
        raise DiagnosisError(f'{path}: invalid JSON: {err}') from err
    if not isinstance(doc, dict):
        raise DiagnosisError(f'{path}: expected a JSON object of arrays')
    return doc


def _load(path: Path) -> Dict:
    suffix = path.suffix.lower()
    try:
        if suffix == '.csv':
            return _load_csv(path)
        if suffix == '.json':
            return _load_json(path)
        if suffix == '.mat':
            import scipy.io
            return scipy.io.loadmat(str(path))
        if suffix == '.npz':
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
    except (OSError, ValueError, NotImplementedError) as err:
        if isinstance(err, WheelForceError):
            raise
        raise DiagnosisError(f'{path}: cannot read {suffix[1:].upper()} file: {err}') from err
    raise DiagnosisError(f'{path}: unsupported file type {suffix!r} (use .csv, .mat, .npz, '
                         f'.json)')


def _column(path: Path, contents: Dict, spec: ChannelSpec) -> np.ndarray:
    if spec.key not in contents:
        known = ', '.join(k for k in contents if not k.startswith('__'))
        raise DiagnosisError(f'{path}: no channel {spec.key!r} (has: {known})')
    try:
        arr = np.asarray(contents[spec.key], dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise DiagnosisError(f'{path}: channel {spec.key!r} is not numeric') from err
    if arr.ndim == 2 and 1 in arr.shape and spec.column is None:
        arr = arr.reshape(-1)
    if spec.column is not None:
        if arr.ndim != 2 or spec.column >= arr.shape[1]:
            raise DiagnosisError(f'{path}: {spec.label}: {spec.key!r} has shape {arr.shape}, '
                                 f'no column {spec.column}')
        arr = arr[:, spec.column]
    if arr.ndim != 1:
        raise DiagnosisError(f'{path}: {spec.label} has shape {arr.shape}; pick a column with '
                             f'{spec.key}[i]')
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise DiagnosisError(f'{path}: {spec.label} has a non-finite value at sample '
                             f'{bad[0]}')
    return arr * spec.scale


def load_generic(path, inputs: Sequence[ChannelSpec], outputs: Sequence[ChannelSpec],
                 fs_hz: float) -> MotionRecording:
    """
    Read one generic recording into a :class:`MotionRecording` (SI units).

    Raises
    ------
    DiagnosisError
        Unreadable file, missing channel, mixed input quantities, unequal lengths,
        non-finite values.

    """
    path = Path(path)
    if not inputs or not outputs:
        raise DiagnosisError(f'{path}: declare at least one --input and one --output channel')
    quantities = {s.quantity for s in inputs}
    if len(quantities) != 1:
        raise DiagnosisError(f'{path}: all inputs must share one quantity, got '
                             f'{sorted(quantities)}')
    if not path.is_file():
        raise DiagnosisError(f'{path}: no such file')
    contents = _load(path)
    cols: Tuple[np.ndarray, ...] = tuple(_column(path, contents, s)
                                         for s in tuple(inputs) + tuple(outputs))
    lengths = {s.label: c.size for s, c in zip(tuple(inputs) + tuple(outputs), cols)}
    if len(set(lengths.values())) != 1:
        raise DiagnosisError(f'{path}: channels differ in length {lengths}; nothing is '
                             f'padded or cut')
    n_in = len(inputs)
    return MotionRecording(
        name=str(path), fs_hz=fs_hz, inputs=np.stack(cols[:n_in]),
        outputs=np.stack(cols[n_in:]), input_channels=tuple(s.label for s in inputs),
        output_channels=tuple(s.label for s in outputs), input_quantity=quantities.pop())
