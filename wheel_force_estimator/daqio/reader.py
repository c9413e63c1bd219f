# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Read one generic recording (text table, MAT, NPZ, JSON) into SI arrays with declared roles.

Each file is one gap-free segment sampled at the declared rate: files carry no time stamps
that could be checked, so none are read.  Nothing is resampled, padded or cleaned: unequal
channel lengths, non-finite values and files without samples are refused with the file and
channel named.

File formats (by suffix):

- ``.csv``, ``.txt``, ``.tsv`` (text tables, as DAQ software exports them): one column per
  channel, separated by ``;``, tab or ``,`` (the first, in that order, that splits most of
  the last lines of the file alike into two or more fields) or else by white space, which
  also gives the number of columns; lines starting with ``#`` or ``%`` and blank lines are
  comments.  Rows before the first all-numeric row with one field per column are header
  rows: the first with one field per column names the columns (units rows and other
  metadata lines below or above it hold no samples and are not read); with no such row the
  columns are named ``0``, ``1``, ...  With ``;``, tab or white-space separators a decimal
  comma (``1,25``) is read as a decimal point when the file writes no decimal point.
  Every row from the first sample row on must be numbers with one field per column, else
  the line is named.
- ``.mat``: MATLAB v4 - v7.2 (``scipy.io.loadmat``) and v7.3 (HDF5, read with ``h5py``: real
  numeric arrays); fields of a struct are channels named ``struct.field``.
- ``.npz``: numpy archive, read with ``allow_pickle=False``.
- ``.json``: one object whose keys hold numbers or arrays (nested objects: ``outer.inner``).

``NAME[i]`` picks channel ``i`` of a 2-D array: a column when the array has at least as many
rows as columns (rows = samples), a row otherwise (channels x samples, as MATLAB users often
store them; time runs along the longer axis).
"""
import csv
from dataclasses import dataclass
import json
from pathlib import Path
import re
from typing import Dict, Optional, Sequence, Tuple
import zipfile

import numpy as np

from wheel_force_estimator.core.errors import RecordingError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.core.validation import freeze_paired_record
from wheel_force_estimator.daqio.channels import ChannelSpec
from wheel_force_estimator.daqio.channels import check_specs
from wheel_force_estimator.daqio.channels import INPUT_QUANTITIES
from wheel_force_estimator.daqio.channels import SI_UNITS

TEXT_SUFFIXES = ('.csv', '.txt', '.tsv')
SUFFIXES = TEXT_SUFFIXES + ('.mat', '.npz', '.json')


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


#: Field separators tried for text tables, in order of preference (None = white space).
_SEPARATORS = (';', '\t', ',')
#: Content lines at the end of a table looked at to choose the separator.
_SNIFF_LINES = 20


def _layout(lines) -> Tuple[Optional[str], int]:
    """
    Return ``(separator, columns)`` of a text table from its last lines.

    The first of :data:`_SEPARATORS` that splits most of the last lines alike into two or
    more fields, with that count; else white space (None) and its most common count.  The
    last lines are samples, whatever metadata the export writes above them; "most" rather
    than "all" so that one ragged line is reported as such, not misread.
    """
    tail = lines[-_SNIFF_LINES:]
    for sep in _SEPARATORS + (None,):
        counts = [len(_fields(ln, sep)) for _, ln in tail]
        modal = max(set(counts), key=counts.count)
        if sep is None or (modal > 1 and 2 * counts.count(modal) > len(counts)):
            return sep, modal
    raise AssertionError('unreachable: white space always decides')


def _fields(line: str, sep: Optional[str]):
    if sep is None:
        return line.split()
    return [f.strip() for f in next(csv.reader([line], delimiter=sep))]


_DECIMAL_COMMA = re.compile(r'[+-]?\d*,\d+(?:[eE][+-]?\d+)?')
_DECIMAL_POINT = re.compile(r'[+-]?\d*\.\d+(?:[eE][+-]?\d+)?')


def _numbers(fields, decimal_comma: bool):
    """Return the fields as floats, or None when one is not a number."""
    try:
        return [float(f.replace(',', '.') if decimal_comma else f) for f in fields]
    except ValueError:
        return None


def _load_text(path: Path) -> Dict[str, np.ndarray]:
    # Hand-written rather than numpy.loadtxt / csv.Sniffer: DAQ exports put names, units and
    # metadata lines above the samples and use ';' with decimal commas, and an error must name
    # the offending line of the file (loadtxt skips a fixed count; the sniffer takes digits
    # for separators on numeric tables).
    text = path.read_text(encoding='utf-8-sig', errors='replace')
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith(('#', '%'))]
    if not lines:
        raise RecordingError(f'{path}: empty text table (no lines besides comments)')
    sep, n_cols = _layout(lines)
    # A decimal comma only where ',' cannot separate fields and the file writes no decimal
    # point (one convention per file; looked for in the leading lines).
    head = [f for _, ln in lines[:200] for f in _fields(ln, sep)]
    decimal_comma = (sep != ',' and any(_DECIMAL_COMMA.fullmatch(f) for f in head)
                     and not any(_DECIMAL_POINT.fullmatch(f) for f in head))
    # The samples start at the first all-numeric row with one field per column; rows above
    # it are header rows (a numeric metadata line such as a lone sample rate among them).
    first = len(lines)
    leading = []
    for k, (_, ln) in enumerate(lines):
        fields = _fields(ln, sep)
        if len(fields) == n_cols and _numbers(fields, decimal_comma) is not None:
            first = k
            break
        leading.append(fields)
    names = next((f for f in leading if len(f) == n_cols), None)
    if first == len(lines) and names is None:
        raise RecordingError(f'{path}: no header row with one name per column and no samples')
    header = ([h.strip().strip('"') for h in names] if names is not None
              else [str(i) for i in range(n_cols)])
    body = lines[first:]
    texts = [ln.replace(',', '.') if decimal_comma else ln for _, ln in body]
    rows = list(csv.reader(texts, delimiter=sep)) if sep else [t.split() for t in texts]
    try:
        data = np.array(rows, dtype=np.float64).reshape(len(rows), n_cols)
    except ValueError as err:
        # name the first bad line (the bulk conversion cannot say which)
        for (line_no, line), fields in zip(body, rows):
            if len(fields) != n_cols:
                raise RecordingError(f'{path}: line {line_no} has {len(fields)} fields, the '
                                     f'table {n_cols} columns') from err
            if _numbers(fields, False) is None:
                raise RecordingError(f'{path}: non-numeric value on line {line_no}: '
                                     f'{line!r}') from err
        raise RecordingError(f'{path}: cannot read the text table: {err}') from err
    return {h: data[:, i] for i, h in enumerate(header)}


def _load_json(path: Path) -> Dict[str, np.ndarray]:
    try:
        doc = json.loads(path.read_text())
    except ValueError as err:
        raise RecordingError(f'{path}: invalid JSON: {err}') from err
    if not isinstance(doc, dict):
        raise RecordingError(f'{path}: expected a JSON object of arrays')
    return _with_dotted_fields(doc, lambda v: v.items() if isinstance(v, dict) else ())


def _load_mat(path: Path) -> Dict:
    import scipy.io
    from scipy.io.matlab import MatReadError
    from scipy.io.matlab import matfile_version
    try:
        if matfile_version(str(path))[0] == 2:
            return _load_mat73(path)
        return _with_dotted_fields(scipy.io.loadmat(str(path)), _struct_fields)
    except (MatReadError, IndexError, TypeError, EOFError) as err:
        # scipy's header parser fails on garbage with these rather than MatReadError
        detail = str(err) or type(err).__name__
        raise RecordingError(f'{path}: cannot read MAT file: {detail}') from err


def _with_dotted_fields(contents: Dict, fields) -> Dict:
    """
    Return ``contents`` plus every nested field as a channel ``outer.inner`` (``a.b.c``).

    ``fields(value)`` gives the ``(name, value)`` pairs inside a value (none for an array):
    the keys of a JSON object, the fields of a MATLAB struct.
    """
    out = dict(contents)
    todo = [(k, v) for k, v in contents.items() if not k.startswith('__')]
    while todo:
        name, value = todo.pop()
        for key, sub in fields(value):
            out[f'{name}.{key}'] = sub
            todo.append((f'{name}.{key}', sub))
    return out


def _struct_fields(value):
    """Fields of a (1 x 1) struct as ``scipy.io.loadmat`` gives it (a record array), else ()."""
    if isinstance(value, np.ndarray) and value.dtype.names and value.size == 1:
        return [(field, value.reshape(-1)[0][field]) for field in value.dtype.names]
    return ()


#: MATLAB classes of real numeric arrays (``MATLAB_class`` attribute of a v7.3 dataset).
_MAT_NUMERIC = ('double', 'single', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32',
                'int64', 'uint64', 'logical')


def _load_mat73(path: Path) -> Dict[str, np.ndarray]:
    """
    Read the real numeric arrays of a MATLAB v7.3 (HDF5) file, named as in MATLAB.

    MATLAB stores arrays column-major, so each dataset is transposed back to MATLAB's shape
    (an ``n x 1`` vector or ``n x k`` table of samples).  Struct fields are named
    ``struct.field``; strings, cells, sparse and complex arrays are not channels and are
    left out.
    """
    try:
        import h5py
    except ImportError as err:
        raise RecordingError(f'{path}: a MATLAB v7.3 (HDF5) file needs h5py '
                             f'(pip install h5py)') from err
    out: Dict[str, np.ndarray] = {}

    def visit(name, obj):
        if not isinstance(obj, h5py.Dataset) or name.startswith('#'):
            return
        cls = obj.attrs.get('MATLAB_class', b'')
        cls = cls.decode() if isinstance(cls, bytes) else str(cls)
        if cls in _MAT_NUMERIC and obj.dtype.kind in 'biuf' and 'MATLAB_sparse' not in obj.attrs:
            out[name.replace('/', '.')] = np.asarray(obj[()]).T

    try:
        with h5py.File(path, 'r') as fh:
            fh.visititems(visit)
    except OSError as err:
        raise RecordingError(f'{path}: cannot read MATLAB v7.3 (HDF5) file: {err}') from err
    return out


def _load(path: Path) -> Dict:
    suffix = path.suffix.lower()
    try:
        if suffix in TEXT_SUFFIXES:
            return _load_text(path)
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
        if arr.ndim == 2 and arr.shape[0] < arr.shape[1]:
            # channels stored as rows (channels x samples): time runs along the longer axis,
            # since no recording holds fewer samples than channels
            arr = arr.T
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
        ``.csv``/``.txt``/``.tsv``, ``.mat``, ``.npz`` or ``.json`` file.
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
