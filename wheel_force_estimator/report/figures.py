# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Shared scaffolding of the report's PNG plots: palette, input checks, labels, saving.

Conventions of every report plot, stated once here.

Pure functions: numpy arrays and channel names in, one PNG written, its ``Path`` returned.
Figures are built with :class:`matplotlib.figure.Figure` directly (Agg canvas on save), never
through ``pyplot``, so there is no global figure state and no GUI backend is touched.

Inputs are validated before anything is drawn: a shape that does not match the channel list
raises :class:`ShapeError` and a NaN / infinity raises :class:`NonFiniteError`, both naming the
argument, because a plot of bad data misleads the person reading it.

The plots are in :mod:`wheel_force_estimator.report.spectral_plots` (against frequency)
and :mod:`wheel_force_estimator.report.evaluation_plots` (time histories, damage, RMSE).
"""
from pathlib import Path
from typing import Optional, Sequence

from matplotlib.figure import Figure
import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.report.tables import check_values

DPI = 150
COLOR_TARGET = '#222222'
COLOR_PREDICTION = '#1f77b4'
COLOR_ERROR = '#d62728'
COLOR_FRF = '#2ca02c'
COLOR_ORDINARY = '#ff7f0e'
# Green (perfect) to red (not qualified), like the paper's Figure 9 colour map.
RUBRIC_COLORS = ('#1a9850', '#91cf60', '#fee08b', '#fc8d59', '#d73027')
RUBRIC_TEXT_COLOURS = ('white', 'black', 'black', 'black', 'white')


# ---------------------------------------------------------------- validation / helpers
def png_path(path) -> Path:
    out = Path(path)
    if out.suffix.lower() != '.png':
        raise ConfigError(f'plot path {out}: must end in .png')
    if not out.parent.is_dir():
        raise ConfigError(f'plot path {out}: directory {out.parent} does not exist')
    if out.is_dir():
        raise ConfigError(f'plot path {out}: is a directory')
    return out


def as_axis(values, name: str, min_len: int = 2) -> np.ndarray:
    """Check a 1-D frequency or time vector: finite and strictly increasing."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1 or arr.size < min_len:
        raise ShapeError(f'{name}: expected a 1-D vector of at least {min_len} values, '
                         f'got shape {arr.shape}')
    check_values(arr, name, arr.shape)
    if not (np.diff(arr) > 0).all():
        i = int(np.argmax(np.diff(arr) <= 0)) + 1
        raise ConfigError(f'{name}: not strictly increasing at index {i}')
    return arr


def check_non_negative(arr: np.ndarray, name: str, channels: Sequence[str]) -> None:
    if (arr < 0).any():
        idx = np.argwhere(arr < 0)[0]
        raise ConfigError(f'{name}: negative value {arr[tuple(idx)].item()!r} for channel '
                          f'{channels[idx[0]]}')


def channel_label(channel: str) -> str:
    """Return 'lf_fx' as 'LF Fx', the paper's spelling; other names unchanged."""
    corner, sep, rest = channel.partition('_')
    return f'{corner.upper()} {rest.capitalize()}' if sep and corner in CORNERS else channel


def channel_unit(channel: str) -> str:
    """Return the unit of a vehicle channel from its name ('lf_fx' -> N), '-' if unknown."""
    corner, _, quantity = channel.partition('_')
    if corner not in CORNERS:
        return '-'
    # w: spindle angular rate, spin / spin_accel: wheel spin (six components, issue 33)
    if quantity == 'spin_accel':
        return 'rad/s²'
    return {'f': 'N', 'm': 'N·m', 'a': 'm/s²', 'w': 'rad/s', 's': 'rad/s'}.get(quantity[:1],
                                                                               '-')


def pretty_unit(unit: str) -> str:
    """Return a model-file unit for a plot label ('m/s^2' -> 'm/s²')."""
    return unit.replace('^2', '²').replace('^3', '³')


def ratio_unit(numerator: str, denominator: str) -> str:
    """Return the unit of a gain, e.g. ``N/m`` or ``N/(m/s²)``."""
    den = pretty_unit(denominator)
    return f'{pretty_unit(numerator)}/({den})' if '/' in den else f'{pretty_unit(numerator)}/{den}'


def channel_units(channels: Sequence[str], units: Optional[Sequence[str]]) -> list:
    """
    Return one unit label per channel: ``units`` when given, else from the channel names.

    Raises
    ------
    ShapeError
        ``units`` does not have one entry per channel.

    """
    if units is None:
        return [channel_unit(c) for c in channels]
    units = [pretty_unit(str(u)) for u in units]
    if len(units) != len(channels):
        raise ShapeError(f'units: expected {len(channels)} entries (one per channel), '
                         f'got {len(units)}')
    return units


def save_figure(fig: Figure, path: Path) -> Path:
    fig.savefig(path, format='png', dpi=DPI)
    return path
