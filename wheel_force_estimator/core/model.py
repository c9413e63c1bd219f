# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The fitted model (:class:`FrfModel`) and its file format.

A model file is a single ``.npz`` readable with ``numpy.load(path, allow_pickle=False)``:
numeric arrays plus one JSON string entry ``meta``.  Loading never unpickles anything and every
array is checked for dtype and shape against the channel lists in ``meta`` before a model is
built, so a file from a stranger can at worst be refused with :class:`ModelFileError`.

Arrays (``nf`` frequency lines, ``no`` outputs, ``ni`` inputs, ``nt`` FIR taps):

========================  ==================  ===========================================
``f_hz``                  (nf,) float64       frequency lines [Hz], 0 .. fs/2
``h``                     (nf, no, ni) c128   FRF [N/(m/s²)], ``h[f, out, in]``
``coherence_ordinary``    (nf, no, ni) f64    ordinary coherence per pair [-]
``coherence_multiple``    (nf, no) f64        multiple coherence per output [-]
``cond_sxx``              (nf,) f64           condition number of the input CSD matrix [-]
``fir_taps``              (no, ni, nt) f64    two-sided impulse response [N/(m/s²)]
``static_force_n``        (no,) f64           mean force at fit time, added back [N]
``static_accel_mps2``     (ni,) f64           mean specific force at fit time [m/s²]
``live{D}_fine_taps``     (no, ni, nf) f64    live estimator for look-ahead ``D`` samples
``live{D}_coarse_edges``  (nc + 1,) int64     (schema 2, optional; one set per entry of
``live{D}_coarse_taps``   (no, ni, nc) f64    ``meta.live_estimators``, see
                                              :mod:`.live_estimator`)
========================  ==================  ===========================================

Schema 1 files (no live estimators) still load; the predictor then cuts the offline FIR for
a short look-ahead and says so (:func:`.predict.live_fallback`).  Schema 3 (six components,
issue 33) is schema 2 plus optional per-channel units in ``meta.units`` (``input_channels``,
``output_channels``: lists as long as the channel lists); schema 2 files load unchanged and
every channel of a side then has that side's unit (:func:`.spindle.channel_units`).
"""
import dataclasses
import datetime
import json
import os
from pathlib import Path
import tempfile
from typing import Any, Dict, Mapping, Tuple
import zipfile

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.live_estimator import check_live
from wheel_force_estimator.core.live_estimator import live_arrays
from wheel_force_estimator.core.live_estimator import live_from_contents
from wheel_force_estimator.core.live_estimator import live_meta
from wheel_force_estimator.core.physics_terms import PhysicsTerm
from wheel_force_estimator.core.validation import read_only_array

SCHEMA_VERSION = 3
# Versions this code reads: 1 has no live estimators; 2 has one unit per side (3 may add
# ``units.input_channels`` / ``units.output_channels``: one unit per channel, issue 33).
READABLE_SCHEMA_VERSIONS = (1, 2, 3)

_ARRAYS = ('f_hz', 'h', 'coherence_ordinary', 'coherence_multiple', 'cond_sxx', 'fir_taps',
           'static_force_n', 'static_accel_mps2')
_META_REQUIRED = ('schema_version', 'sample_rate_hz', 'input_channels', 'output_channels',
                  'units', 'estimator', 'fit', 'created', 'fir_delay_samples')


def _frozen_array(value, name: str, dtype, shape: Tuple[int, ...]) -> np.ndarray:
    try:
        arr = read_only_array(value, dtype)
    except (TypeError, ValueError) as err:
        raise ModelFileError(f'model field {name!r}: not convertible to {dtype}') from err
    if arr.shape != shape:
        raise ModelFileError(f'model field {name!r}: expected shape {shape}, got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ModelFileError(f'model field {name!r}: contains NaN or infinity')
    return arr


@dataclasses.dataclass(frozen=True)
class FrfModel:
    """
    A fitted acceleration-to-force model (immutable; arrays are read-only).

    Parameters
    ----------
    fs_hz : float
        Sample rate the model was fitted at [Hz]; data at another rate is refused.
    input_channels, output_channels : tuple of str
        Channel names in array order (DESIGN.md: ``lf_ax`` … / ``lf_fx`` …).
    f_hz : numpy.ndarray, shape (nf,)
        Frequency lines [Hz].
    h : numpy.ndarray, shape (nf, no, ni), complex
        Frequency response function [N/(m/s²)].
    coherence_ordinary : numpy.ndarray, shape (nf, no, ni)
        Ordinary coherence of every input-output pair [-].
    coherence_multiple : numpy.ndarray, shape (nf, no)
        Multiple coherence of every output with all inputs [-].
    cond_sxx : numpy.ndarray, shape (nf,)
        Condition number of the input cross-spectral matrix [-]; singular lines hold the
        cap ``1 / eps`` (about 4.5e15), never ``inf``.
    fir_taps : numpy.ndarray, shape (no, ni, nt)
        Two-sided FIR realisation of ``h`` [N/(m/s²)], lag zero at ``fir_delay_samples``.
    fir_delay_samples : int
        Index of lag zero in ``fir_taps`` (look-ahead of the offline filter) [samples].
    static_force_n : numpy.ndarray, shape (no,)
        Mean force over the fitting data, added to the dynamic prediction [N].
    static_accel_mps2 : numpy.ndarray, shape (ni,)
        Mean specific force over the fitting data (gravity on z) [m/s²].
    estimator : str
        FRF estimator used (``h1``, ``h1_tikhonov``, ``h1_tsvd``).
    fit : dict
        How the model was fitted (recordings, durations, Welch settings, regularisation).
    units : dict
        Units of inputs and outputs.
    created : str
        ISO 8601 creation time (UTC).
    physics : tuple of dict
        Physics terms added by diagnosis (``PhysicsTerm.to_dict()``), applied after the FIR;
        parsed and validated when the model is built (:attr:`physics_terms`); a bad term
        raises :class:`ModelFileError` naming its index, physics and field, or a channel the
        model does not have.
    live : tuple of CausalEstimator
        Live (causal) estimators, one per look-ahead (``fit`` designs them); empty for
        schema 1 files.

    Raises
    ------
    ModelFileError
        When a field has the wrong type, shape or non-finite values.

    """

    fs_hz: float
    input_channels: Tuple[str, ...]
    output_channels: Tuple[str, ...]
    f_hz: np.ndarray
    h: np.ndarray
    coherence_ordinary: np.ndarray
    coherence_multiple: np.ndarray
    cond_sxx: np.ndarray
    fir_taps: np.ndarray
    fir_delay_samples: int
    static_force_n: np.ndarray
    static_accel_mps2: np.ndarray
    estimator: str
    fit: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    units: Mapping[str, str] = dataclasses.field(
        default_factory=lambda: {'input': 'm/s^2', 'output': 'N'})
    created: str = ''
    physics: Tuple[Mapping[str, Any], ...] = ()
    live: Tuple[CausalEstimator, ...] = ()

    def __post_init__(self):
        """Validate every field; convert arrays to read-only copies."""
        fs = float(self.fs_hz)
        if not np.isfinite(fs) or fs <= 0:
            raise ModelFileError(f'model field sample_rate_hz must be > 0, got {self.fs_hz!r}')
        object.__setattr__(self, 'fs_hz', fs)
        for name in ('input_channels', 'output_channels'):
            chans = getattr(self, name)
            if (isinstance(chans, str) or not all(isinstance(c, str) for c in chans)
                    or len(chans) == 0 or len(set(chans)) != len(chans)):
                raise ModelFileError(
                    f'model field {name!r}: expected a list of unique channel names, '
                    f'got {chans!r}')
            object.__setattr__(self, name, tuple(chans))
        ni, no = len(self.input_channels), len(self.output_channels)
        f_hz = np.asarray(self.f_hz)
        if f_hz.ndim != 1 or f_hz.size < 2:
            raise ModelFileError(f"model field 'f_hz': expected 1-D with >= 2 lines, "
                                 f'got shape {f_hz.shape}')
        nf = f_hz.size
        taps = np.asarray(self.fir_taps)
        if taps.ndim != 3:
            raise ModelFileError(f"model field 'fir_taps': expected 3-D, got {taps.shape}")
        nt = taps.shape[2]
        shapes = {'f_hz': (np.float64, (nf,)), 'h': (np.complex128, (nf, no, ni)),
                  'coherence_ordinary': (np.float64, (nf, no, ni)),
                  'coherence_multiple': (np.float64, (nf, no)),
                  'cond_sxx': (np.float64, (nf,)), 'fir_taps': (np.float64, (no, ni, nt)),
                  'static_force_n': (np.float64, (no,)),
                  'static_accel_mps2': (np.float64, (ni,))}
        for name, (dtype, shape) in shapes.items():
            object.__setattr__(self, name, _frozen_array(getattr(self, name), name, dtype, shape))
        if np.any(np.diff(self.f_hz) <= 0) or self.f_hz[0] != 0.0:
            raise ModelFileError("model field 'f_hz': must start at 0 Hz and increase")
        if abs(self.f_hz[-1] - fs / 2) > 1e-6 * fs:
            raise ModelFileError(
                f"model field 'f_hz': last line {self.f_hz[-1]} Hz is not Nyquist "
                f'({fs / 2} Hz) of sample_rate_hz {fs}')
        delay = self.fir_delay_samples
        if isinstance(delay, bool) or not isinstance(delay, (int, np.integer)) \
                or not 0 <= int(delay) < nt:
            raise ModelFileError(
                f"model field 'fir_delay_samples': expected an int in [0, {nt}), got {delay!r}")
        object.__setattr__(self, 'fir_delay_samples', int(delay))
        if not isinstance(self.estimator, str) or not self.estimator:
            raise ModelFileError(f"model field 'estimator': expected a name, "
                                 f'got {self.estimator!r}')
        for name in ('fit', 'units'):
            if not isinstance(getattr(self, name), Mapping):
                raise ModelFileError(f'model field {name!r}: expected an object')
            object.__setattr__(self, name, dict(getattr(self, name)))
        for key, n in (('input_channels', ni), ('output_channels', no)):
            listed = self.units.get(key)
            if listed is not None and (isinstance(listed, str) or len(listed) != n or not all(
                    isinstance(u, str) and u for u in listed)):
                raise ModelFileError(f"model field 'units.{key}': expected {n} unit names, "
                                     f'got {listed!r}')
            if listed is not None:
                self.units[key] = list(listed)
        physics = self.physics
        if isinstance(physics, (str, bytes, Mapping)) or not all(
                isinstance(p, (Mapping, PhysicsTerm)) for p in physics):
            raise ModelFileError("model field 'physics': expected a list of objects")
        terms = []
        for i, item in enumerate(physics):
            if isinstance(item, PhysicsTerm):
                terms.append(item)
                continue
            try:
                terms.append(PhysicsTerm.from_dict(item))
            except ConfigError as err:
                raise ModelFileError(f"model field 'physics': term {i} "
                                     f"({item.get('physics', '?')!s}): {err}") from err
        for i, term in enumerate(terms):
            for name in term.channels:
                if name not in self.output_channels:
                    raise ModelFileError(
                        f"model field 'physics': term {i} ({term.physics}): output channel "
                        f'{name!r} is not one of the model outputs {list(self.output_channels)}')
            partners = () if term.partners_are_outputs else term.partners
            for name in term.partners if term.partners_are_outputs else ():
                if name not in self.output_channels:
                    raise ModelFileError(
                        f"model field 'physics': term {i} ({term.physics}): partner channel "
                        f'{name!r} is not one of the model outputs {list(self.output_channels)}')
            for name in term.sources + partners:
                if name not in self.input_channels:
                    raise ModelFileError(
                        f"model field 'physics': term {i} ({term.physics}): input channel "
                        f'{name!r} is not one of the model inputs {list(self.input_channels)}')
        object.__setattr__(self, 'physics', tuple(
            t.to_dict() if isinstance(t, PhysicsTerm) else dict(t) for t in physics))
        object.__setattr__(self, 'live', check_live(self.live, no, ni))

    @property
    def physics_terms(self) -> Tuple[PhysicsTerm, ...]:
        """Return the ``physics`` section as typed terms (validated when the model was built)."""
        return tuple(PhysicsTerm.from_dict(p) for p in self.physics)

    @property
    def n_taps(self) -> int:
        """Return the number of FIR taps."""
        return int(self.fir_taps.shape[2])

    def with_physics(self, terms) -> 'FrfModel':
        """
        Return a copy carrying the given terms (replacing any present).

        ``terms`` are :class:`PhysicsTerm` objects or their ``to_dict()`` form; they are
        validated like the ``physics`` section of a model file.
        """
        return dataclasses.replace(self, physics=tuple(terms))

    def meta(self) -> Dict[str, Any]:
        """Return the JSON ``meta`` entry of the model file."""
        return {
            'schema_version': SCHEMA_VERSION,
            'sample_rate_hz': self.fs_hz,
            'input_channels': list(self.input_channels),
            'output_channels': list(self.output_channels),
            'units': dict(self.units),
            'estimator': self.estimator,
            'fit': dict(self.fit),
            'created': self.created or datetime.datetime.now(
                datetime.timezone.utc).isoformat(timespec='seconds'),
            'fir_delay_samples': self.fir_delay_samples,
            'physics': [dict(p) for p in self.physics],
            'live_estimators': live_meta(self.live),
        }


def select_outputs(model: FrfModel, channels) -> FrfModel:
    """
    Return ``model`` restricted to the output ``channels`` (in the order given).

    Every output row is its own estimate (FRF, FIR, live estimators), so a subset is exact:
    e.g. the forces of a six-component model, which the force diagnosis works on.

    Raises
    ------
    ModelFileError
        A channel the model does not have.

    """
    missing = [c for c in channels if c not in model.output_channels]
    if missing:
        raise ModelFileError(f'output channel(s) {missing} not in the model '
                             f'{list(model.output_channels)}')
    rows = [model.output_channels.index(c) for c in channels]
    units = dict(model.units)
    if 'output_channels' in units:
        units['output_channels'] = [units['output_channels'][r] for r in rows]
    live = tuple(dataclasses.replace(e, fine_taps=e.fine_taps[rows],
                                     coarse_taps=e.coarse_taps[rows]) for e in model.live)
    return dataclasses.replace(
        model, output_channels=tuple(channels), h=model.h[:, rows],
        coherence_ordinary=model.coherence_ordinary[:, rows],
        coherence_multiple=model.coherence_multiple[:, rows], fir_taps=model.fir_taps[rows],
        static_force_n=model.static_force_n[rows], units=units, live=live,
        physics=tuple(p for p in model.physics if set(p.get('channels', ())) <= set(channels)))


def save_model(model: FrfModel, path) -> Path:
    """
    Write ``model`` to ``path`` (``.npz``) atomically; an existing file is replaced.

    Parameters
    ----------
    model : FrfModel
        The model to write.
    path : str or os.PathLike
        Destination; ``.npz`` is appended when missing (numpy's convention).

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ModelFileError
        When the destination cannot be written or the metadata is not JSON-serialisable.

    """
    path = Path(path)
    if path.suffix != '.npz':
        path = path.with_name(path.name + '.npz')
    try:
        meta = json.dumps(model.meta(), allow_nan=False)
    except (TypeError, ValueError) as err:
        raise ModelFileError(f'{path}: model metadata is not JSON-serialisable: {err}') from err
    arrays = {name: np.asarray(getattr(model, name)) for name in _ARRAYS}
    arrays.update(live_arrays(model.live))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix='.tmp')
        with os.fdopen(fd, 'wb') as fh:
            np.savez(fh, meta=np.array(meta), **arrays)
        os.replace(tmp, path)
    except OSError as err:
        raise ModelFileError(f'{path}: cannot write model file: {err}') from err
    return path


_ZIP_MAGIC = b'PK\x03\x04'


def load_model(path) -> FrfModel:
    """
    Read and validate a model file written by :func:`save_model`.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.npz`` model file.

    Returns
    -------
    FrfModel

    Raises
    ------
    ModelFileError
        Missing or unreadable file, pickled/object content, missing or malformed field, wrong
        schema version, inconsistent shapes (the field is named in the message).

    """
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f'{path}: model file not found')
    try:
        with open(path, 'rb') as f:
            magic = f.read(4)
    except OSError as err:
        raise ModelFileError(f'{path}: cannot read model file ({err})') from err
    if magic != _ZIP_MAGIC:
        # np.load would try to unpickle anything that is not .npy/.npz and say "pickled data"
        raise ModelFileError(f'{path}: not a .npz model file (no zip header; written by '
                             f'`wheel-force fit`?)')
    try:
        with np.load(path, allow_pickle=False) as npz:
            contents = {key: npz[key] for key in npz.files}
    except ValueError as err:
        # numpy refuses object arrays (pickles) when allow_pickle=False
        raise ModelFileError(f'{path}: not a safe model file ({err})') from err
    except (OSError, zipfile.BadZipFile, EOFError) as err:
        raise ModelFileError(f'{path}: not a readable .npz model file ({err})') from err
    return _model_from_contents(contents, path)


def _model_from_contents(contents: Mapping[str, np.ndarray], path: Path) -> FrfModel:
    if 'meta' not in contents:
        raise ModelFileError(f"{path}: model field 'meta' is missing")
    meta_arr = contents['meta']
    if meta_arr.shape != () or meta_arr.dtype.kind != 'U':
        raise ModelFileError(f"{path}: model field 'meta' must be one JSON string")
    try:
        meta = json.loads(str(meta_arr))
    except json.JSONDecodeError as err:
        raise ModelFileError(f"{path}: model field 'meta' is not valid JSON: {err}") from err
    if not isinstance(meta, dict):
        raise ModelFileError(f"{path}: model field 'meta' must be a JSON object")
    for key in _META_REQUIRED:
        if key not in meta:
            raise ModelFileError(f"{path}: model field 'meta.{key}' is missing")
    if meta['schema_version'] not in READABLE_SCHEMA_VERSIONS:
        raise ModelFileError(
            f'{path}: model field \'meta.schema_version\' is {meta["schema_version"]!r}, '
            f'this version reads {list(READABLE_SCHEMA_VERSIONS)}')
    for name in _ARRAYS:
        if name not in contents:
            raise ModelFileError(f'{path}: model field {name!r} is missing')
        kind = contents[name].dtype.kind
        expected = 'c' if name == 'h' else 'f'
        if kind != expected:
            raise ModelFileError(
                f'{path}: model field {name!r} has dtype {contents[name].dtype}, expected '
                f'{"complex" if expected == "c" else "float"}')
    try:
        live = live_from_contents(meta, contents)
        return FrfModel(
            fs_hz=meta['sample_rate_hz'],
            input_channels=tuple(meta['input_channels']),
            output_channels=tuple(meta['output_channels']),
            estimator=meta['estimator'], fit=meta['fit'], units=meta['units'],
            created=meta['created'], fir_delay_samples=meta['fir_delay_samples'],
            physics=tuple(meta.get('physics', ())), live=live,
            **{name: contents[name] for name in _ARRAYS})
    except ModelFileError as err:
        raise ModelFileError(f'{path}: {err}') from err
    except TypeError as err:
        raise ModelFileError(f'{path}: malformed model metadata: {err}') from err
