# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the offline subcommands: config files, progress, recordings."""
from pathlib import Path
import sys
from typing import Iterable, Optional

from wheel_force_estimator.core.errors import ConfigError
import yaml

FIT_SECTION = 'wheel_force_fit'
_FIT_KEYS = {
    'segment_length': int, 'overlap': float, 'window': str, 'detrend': str,
    'estimator': str, 'regularisation': float, 'f_min_hz': float, 'f_max_hz': float,
    'coherence_floor': float, 'long_segment_length': int, 'crossover_hz': float,
    'long_regularisation': float,
}
# What `wheel-force fit` uses when neither the params file nor the command line says
# otherwise (the library's FitConfig() keeps the single-resolution paper method): the
# two-resolution fit measured better on held-out simulated data on every Fz and most Fx/Fy
# channels (bench/bench_accuracy.py, README).
CLI_FIT_DEFAULTS = {'long_segment_length': 8192, 'crossover_hz': 2.0,
                    'long_regularisation': 1e-2}


def default_config_path() -> Optional[Path]:
    """Return the packaged ``config/wheel_force.yaml`` (source tree or ament share dir)."""
    here = Path(__file__).resolve().parents[2] / 'config' / 'wheel_force.yaml'
    if here.is_file():
        return here
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('wheel_force_estimator'))
    except (ImportError, LookupError, ValueError):
        return None
    cfg = share / 'config' / 'wheel_force.yaml'
    return cfg if cfg.is_file() else None


def load_fit_config(path=None, **overrides):
    """
    Return the :class:`FitConfig` from the params YAML's ``wheel_force_fit`` section.

    Parameters
    ----------
    path : str or os.PathLike, optional
        Params file; ``None`` uses the built-in defaults.
    **overrides
        Values from the command line (``None`` values are ignored).

    Raises
    ------
    ConfigError
        Unreadable file, unknown key or a value of the wrong type (file and key named).

    """
    from wheel_force_estimator.core.pipeline import FitConfig
    values = dict(CLI_FIT_DEFAULTS)
    if path is not None:
        try:
            doc = yaml.safe_load(Path(path).read_text()) or {}
        except (OSError, yaml.YAMLError) as err:
            raise ConfigError(f'{path}: cannot read params file: {err}') from err
        section = (doc.get(FIT_SECTION) or {}).get('ros__parameters') or {}
        for key, value in section.items():
            if key not in _FIT_KEYS:
                raise ConfigError(f'{path}: unknown key {FIT_SECTION}.{key} '
                                  f'(known: {", ".join(sorted(_FIT_KEYS))})')
            try:
                values[key] = _FIT_KEYS[key](value)
            except (TypeError, ValueError) as err:
                raise ConfigError(f'{path}: {FIT_SECTION}.{key} = {value!r} is not a '
                                  f'{_FIT_KEYS[key].__name__}') from err
    values.update({k: v for k, v in overrides.items() if v is not None})
    if values.get('f_max_hz') == 0.0:
        values['f_max_hz'] = None
    try:
        return FitConfig(**values)
    except ConfigError as err:
        raise ConfigError(f'{path or "defaults"}: {err}') from err


def progress(iterable: Iterable, desc: str, total: Optional[int] = None):
    """Wrap ``iterable`` in a tqdm bar when stderr is a terminal, else return it unchanged."""
    if not sys.stderr.isatty():
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, unit='file', leave=False)


def read_recordings(paths, topics, require_wft: bool, expected_fs_hz: Optional[float] = None):
    """
    Read every recording (with a progress bar); return a list of ``Recording``.

    Raises
    ------
    BagError
        From the reader, naming the file and topic at fault; also when the recordings do not
        share one sample rate.

    """
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.core.errors import BagError
    recordings = []
    for path in progress(paths, 'reading', total=len(paths)):
        recordings.append(read_recording(path, topics, require_wft=require_wft,
                                         expected_fs_hz=expected_fs_hz))
    rates = [r.fs_hz for r in recordings]
    if rates and max(rates) > min(rates) * (1 + 1e-3):
        detail = ', '.join(f'{r.path}: {r.fs_hz:g} Hz' for r in recordings)
        raise BagError(f'recordings have different sample rates ({detail}); nothing is '
                       f'resampled — fit them separately')
    return recordings


def nominal_fs_hz(recordings) -> float:
    """Return the common sample rate of already-checked recordings [Hz]."""
    return float(recordings[0].fs_hz)
