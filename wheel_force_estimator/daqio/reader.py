# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Read one generic recording (CSV, MAT, NPZ, JSON) into SI arrays with declared channel roles.

Each file is one gap-free segment sampled at the declared rate: files carry no time stamps
that could be checked, so none are read.  Nothing is resampled, padded or cleaned: unequal
channel lengths, non-finite values and files without samples are refused with the file and
channel named.

File formats (by suffix):

- ``.csv``: one column per channel; a first row that is not all numbers is the header
  (names), otherwise the columns are named ``0``, ``1``, ...
- ``.mat``: MATLAB v4 - v7.2 (``scipy.io.loadmat``; v7.3 files are HDF5 and refused).
- ``.npz``: numpy archive, read with ``allow_pickle=False``.
- ``.json``: one object whose keys hold numbers or arrays.
"""
import csv
from dataclasses import dataclass
import json
from pathlib import Path
from typing import Dict, Sequence, Tuple
import zipfile

import numpy as np

from wheel_force_estimator.core.errors import RecordingError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.core.validation import freeze_paired_record
from wheel_force_estimator.daqio.channels import ChannelSpec
from wheel_force_estimator.daqio.channels import check_specs
from wheel_force_estimator.daqio.channels import INPUT_QUANTITIES
from wheel_force_estimator.daqio.channels import SI_UNITS

SUFFIXES = ('.csv', '.mat', '.npz', '.json')


def is_generic_path(path) -> bool:
    """Return True when ``path`` names a file format this reader handles (by suffix)."""
    return Path(path).suffix.lower() in SUFFIXES


@dataclass(frozen=True)
class DaqRecording:
    """
    One generic recording: synchronous inputs (motion) and outputs (force), SI units.

    Attributes
    ----------
    path : str
        The file it was read from (used in messages and provenance).
    fs_hz : float
        Declared sample rate [Hz].
    inputs : numpy.ndarray, shape (n_inputs, n)
        Motion in the SI unit of ``input_quantity`` (m, m/s or m/s^2); read-only.
    outputs : numpy.ndarray, shape (n_outputs, n)
        Force [N]; read-only.
    input_channels, output_channels : tuple of str
        Row names (the spec labels, ``key`` or ``key[col]``).
    input_quantity : str
        ``'displacement'``, ``'velocity'`` or ``'acceleration'``.

    Raises
    ------
    RecordingError
        Bad sample rate, unknown quantity, no samples, or unequal input/output lengths.
    ShapeError, NonFiniteError
        Arrays that do not match the channel lists or hold NaN / infinity.

    """

    path: str
    fs_hz: float
    inputs: np.ndarray
    outputs: np.ndarray
    input_channels: Tuple[str, ...]
    output_channels: Tuple[str, ...]
    input_quantity: str

    def __post_init__(self):
        """Validate; freeze the arrays."""
        freeze_paired_record(self, str(self.path), INPUT_QUANTITIES, RecordingError)

    @property
    def n_samples(self) -> int:
        """Return the number of samples."""
        return int(self.inputs.shape[1])

    @property
    def duration_s(self) -> float:
        """Return the length of the record [s]."""
        return self.n_samples / self.fs_hz

    @property
    def input_unit(self) -> str:
        """Return the SI unit of the inputs (``m``, ``m/s`` or ``m/s^2``)."""
        return SI_UNITS[self.input_quantity]

    def stamp_ns(self) -> np.ndarray:
        """Return sample times from 0 at the declared rate [ns] (int64, increasing)."""
        return np.round(np.arange(self.n_samples) * (1e9 / self.fs_hz)).astype(np.int64)


def _load_csv(path: Path) -> Dict[str, np.ndarray]:
    with path.open(newline='') as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise RecordingError(f'{path}: empty CSV file')
    try:
        [float(v) for v in rows[0]]
        header, body = [str(i) for i in range(len(rows[0]))], rows
    except ValueError:
        header, body = [h.strip() for h in rows[0]], rows[1:]
    for i, row in enumerate(body):
        if len(row) != len(header):
            raise RecordingError(f'{path}: line {i + 1 + (header[0] != "0")} has {len(row)} '
                                 f'fields, the header {len(header)}')
    try:
        data = np.array(body, dtype=np.float64).reshape(len(body), len(header))
    except ValueError as err:
        raise RecordingError(f'{path}: non-numeric CSV value: {err}') from err
    return {h: data[:, i] for i, h in enumerate(header)}


def _load_json(path: Path) -> Dict[str, np.ndarray]:
    try:
        doc = json.loads(path.read_text())
    except ValueError as err:
        raise RecordingError(f'{path}: invalid JSON: {err}') from err
    if not isinstance(doc, dict):
        raise RecordingError(f'{path}: expected a JSON object of arrays')
    return doc


def _load_mat(path: Path) -> Dict:
    import scipy.io
    from scipy.io.matlab import MatReadError
    try:
        return scipy.io.loadmat(str(path))
    except (MatReadError, IndexError, TypeError, EOFError) as err:
        # scipy's header parser fails on garbage with these rather than MatReadError
        detail = str(err) or type(err).__name__
        raise RecordingError(f'{path}: cannot read MAT file: {detail}') from err


def _load(path: Path) -> Dict:
    suffix = path.suffix.lower()
    try:
        if suffix == '.csv':
            return _load_csv(path)
        if suffix == '.json':
            return _load_json(path)
        if suffix == '.mat':
            return _load_mat(path)
        if suffix == '.npz':
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
    except (OSError, ValueError, NotImplementedError, EOFError, zipfile.BadZipFile) as err:
        if isinstance(err, WheelForceError):
            raise
        raise RecordingError(f'{path}: cannot read {suffix[1:].upper()} file: {err}') from err
    raise RecordingError(f'{path}: unsupported file type {suffix!r} (use '
                         f'{", ".join(SUFFIXES)})')


def _column(path: Path, contents: Dict, spec: ChannelSpec) -> np.ndarray:
    if spec.key not in contents:
        known = ', '.join(k for k in contents if not k.startswith('__'))
        raise RecordingError(f'{path}: no channel {spec.key!r} (has: {known})')
    try:
        arr = np.asarray(contents[spec.key], dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise RecordingError(f'{path}: channel {spec.key!r} is not numeric') from err
    if arr.ndim == 2 and 1 in arr.shape and spec.column is None:
        arr = arr.reshape(-1)
    if spec.column is not None:
        if arr.ndim != 2 or spec.column >= arr.shape[1]:
            raise RecordingError(f'{path}: {spec.label}: {spec.key!r} has shape {arr.shape}, '
                                 f'no column {spec.column}')
        arr = arr[:, spec.column]
    if arr.ndim != 1:
        raise RecordingError(f'{path}: {spec.label} has shape {arr.shape}; pick a column with '
                             f'{spec.key}[i]')
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise RecordingError(f'{path}: {spec.label} has a non-finite value at sample '
                             f'{bad[0]}')
    return arr * spec.scale


def read_daq(path, inputs: Sequence[ChannelSpec], outputs: Sequence[ChannelSpec],
             fs_hz: float) -> DaqRecording:
    """
    Read one generic recording, converting every declared channel to SI.

    Parameters
    ----------
    path : str or os.PathLike
        ``.csv``, ``.mat``, ``.npz`` or ``.json`` file.
    inputs : sequence of ChannelSpec
        Motion channels (one quantity for all), in the order of the result's rows.
    outputs : sequence of ChannelSpec
        Force channels.
    fs_hz : float
        Sample rate of the file [Hz] (declared: files carry no stamps).

    Returns
    -------
    DaqRecording

    Raises
    ------
    RecordingError
        Missing or unreadable file, unsupported suffix, invalid declared channels (see
        :func:`check_specs`), missing channel, non-numeric or non-finite values, unequal
        channel lengths, no samples, bad sample rate.

    """
    path = Path(path)
    try:
        inputs, outputs = check_specs(inputs, outputs)
    except RecordingError as err:
        raise RecordingError(f'{path}: {err}') from err
    if not path.is_file():
        raise RecordingError(f'{path}: no such file')
    contents = _load(path)
    specs = inputs + outputs
    cols = tuple(_column(path, contents, s) for s in specs)
    lengths = {s.label: c.size for s, c in zip(specs, cols)}
    if len(set(lengths.values())) != 1:
        raise RecordingError(f'{path}: channels differ in length {lengths}; nothing is '
                             f'padded or cut')
    n_in = len(inputs)
    return DaqRecording(
        path=str(path), fs_hz=fs_hz, inputs=np.stack(cols[:n_in]),
        outputs=np.stack(cols[n_in:]), input_channels=tuple(s.label for s in inputs),
        output_channels=tuple(s.label for s in outputs), input_quantity=inputs[0].quantity)
