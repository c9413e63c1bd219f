# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
PNG plots of an evaluation in the time and durability domains.

Time histories (target, prediction, error), pseudo damage ratio, relative damage spectrum
and the RMSE rubric map, in the style of the paper's figures.  The conventions shared by
all report plots (pure functions, no ``pyplot``, inputs validated before drawing) are
stated in :mod:`wheel_force_estimator.report.figures`.
"""
from pathlib import Path
from typing import Optional, Sequence, Tuple

from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch
import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.report.figures import as_axis
from wheel_force_estimator.report.figures import channel_label
from wheel_force_estimator.report.figures import channel_units
from wheel_force_estimator.report.figures import check_non_negative
from wheel_force_estimator.report.figures import COLOR_ERROR
from wheel_force_estimator.report.figures import COLOR_PREDICTION
from wheel_force_estimator.report.figures import COLOR_TARGET
from wheel_force_estimator.report.figures import DPI
from wheel_force_estimator.report.figures import png_path
from wheel_force_estimator.report.figures import RUBRIC_COLORS
from wheel_force_estimator.report.figures import RUBRIC_TEXT_COLOURS
from wheel_force_estimator.report.figures import save_figure
from wheel_force_estimator.report.tables import check_names
from wheel_force_estimator.report.tables import check_values
from wheel_force_estimator.report.tables import DAMAGE_RATIO_GOOD
from wheel_force_estimator.report.tables import rubric_index
from wheel_force_estimator.report.tables import RUBRIC_NAMES
from wheel_force_estimator.report.tables import RUBRIC_RANGES

# Time histories longer than this many points per axes are drawn as a min/max envelope.
_MAX_LINE_POINTS = 4000


def _envelope(t: np.ndarray, y: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Min/max per bucket of a long record: what the rasteriser shows anyway, peaks kept."""
    if t.size <= _MAX_LINE_POINTS:
        return t, y
    starts = np.linspace(0, t.size, _MAX_LINE_POINTS // 2, endpoint=False).astype(np.intp)
    lo = np.minimum.reduceat(y, starts)
    hi = np.maximum.reduceat(y, starts)
    return np.repeat(t[starts], 2), np.column_stack([lo, hi]).ravel()


def plot_time_overlay(path, t_s, target, prediction, channels: Sequence[str],
                      window_s: Optional[Tuple[float, float]] = None, title: str = '',
                      units: Optional[Sequence[str]] = None) -> Path:
    """
    Target, prediction and error time histories, one stacked axes per channel (Figure 8).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    t_s : array_like, shape (n,)
        Time [s], strictly increasing.
    target, prediction : array_like, shape (n_ch, n)
        Measured and predicted signals (units from ``units`` or the channel names).
    channels : sequence of str
        Channel names.
    window_s : (float, float), optional
        Zoom window ``(start, end)`` [s]; only samples inside it are drawn.
    title : str
        Figure title (e.g. the recording or event name).
    units : sequence of str, optional
        Unit of each channel (e.g. ``N``); default from vehicle channel names.

    Returns
    -------
    Path

    Notes
    -----
    The error is drawn as prediction - target.  Records longer than a few thousand points are
    drawn as a min/max envelope per pixel column, so peaks stay visible and drawing stays fast.

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    names = check_names(channels, 'channels')
    t = as_axis(t_s, 't_s')
    y_true = check_values(target, 'target', (len(names), t.size))
    y_pred = check_values(prediction, 'prediction', (len(names), t.size))
    unit_of = channel_units(names, units)
    if window_s is not None:
        start, end = (float(v) for v in window_s)
        keep = (t >= start) & (t <= end)
        if not start < end or np.count_nonzero(keep) < 2:
            raise ConfigError(f'window_s={tuple(window_s)}: needs start < end and at least '
                              f'2 samples inside the record {t[0]:.3f}-{t[-1]:.3f} s')
        t, y_true, y_pred = t[keep], y_true[:, keep], y_pred[:, keep]
    n_ch = len(names)
    fig = Figure(figsize=(13.0, 1.45 * n_ch + 1.3), dpi=DPI, layout='constrained')
    axes = fig.subplots(n_ch, 1, sharex=True, squeeze=False)[:, 0]
    # Prediction slightly transparent so the target shows where the two coincide.
    series = ((y_true, COLOR_TARGET, 0.8, 1.0, 'target'),
              (y_pred, COLOR_PREDICTION, 0.7, 0.8, 'prediction'),
              (y_pred - y_true, COLOR_ERROR, 0.6, 0.9, 'error (prediction - target)'))
    for k, ax in enumerate(axes):
        for values, colour, lw, alpha, label in series:
            ax.plot(*_envelope(t, values[k]), color=colour, lw=lw, alpha=alpha, label=label)
        ax.set_ylabel(f'{channel_label(names[k])}\n[{unit_of[k]}]', fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel('time [s]')
    axes[-1].set_xlim(t[0], t[-1])
    span = f'{t[0]:.2f}-{t[-1]:.2f} s'
    fig.suptitle(f'{title}  ({span})' if title else f'Target vs prediction ({span})',
                 fontsize=13)
    handles, labels = axes[0].get_legend_handles_labels()
    # Below the axes: an 'outside upper' legend collides with the suptitle.
    fig.legend(handles, labels, loc='outside lower center', ncols=3)
    return save_figure(fig, out)


def plot_damage_ratio(path, channels: Sequence[str], ratio) -> Path:
    """
    Prediction / target pseudo damage per channel with the 0.5-2 'good' band shaded.

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    channels : sequence of str
        Channel names.
    ratio : array_like, shape (n_ch,)
        Damage ratio prediction / target [-], >= 0.  A zero ratio (no predicted cycles) is
        marked at the bottom of the log axis.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    names = check_names(channels, 'channels')
    r = check_values(ratio, 'ratio', (len(names),))
    check_non_negative(r, 'ratio', names)
    low, high = DAMAGE_RATIO_GOOD
    positive = r[r > 0]
    y_min = min(0.1, positive.min() / 2.0) if positive.size else 0.1
    # Headroom above the tallest bar for its value label.
    y_max = max(10.0, positive.max() * 4.0) if positive.size else 10.0
    fig = Figure(figsize=(max(7.0, 0.75 * len(names) + 2.0), 4.6), dpi=DPI,
                 layout='constrained')
    ax = fig.add_subplot()
    x = np.arange(len(names))
    inside = (r >= low) & (r <= high)
    colours = np.where(inside, RUBRIC_COLORS[0], RUBRIC_COLORS[4])
    ax.axhspan(low, high, color=RUBRIC_COLORS[1], alpha=0.25)
    ax.axhline(1.0, color='0.3', lw=0.8)
    # Bars start at the bottom of the log axis, so the drawn height is r - y_min.
    ax.bar(x, np.where(r > 0, r - y_min, np.nan), bottom=y_min, color=colours, width=0.65)
    for xi, ri in zip(x, r):
        if ri > 0:
            ax.text(xi, ri * 1.08, f'{ri:.2f}', ha='center', va='bottom', fontsize=8)
        else:
            ax.text(xi, y_min * 1.15, '0\n(no cycles)', ha='center', va='bottom', fontsize=8,
                    color=RUBRIC_COLORS[4])
    ax.set_yscale('log')
    ax.set_ylim(y_min, y_max)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.set_xticks(x, [channel_label(n) for n in names], fontsize=9)
    ax.set_ylabel('damage ratio prediction / target [-]')
    ax.set_title('Pseudo damage ratio per channel', fontsize=12)
    ax.grid(alpha=0.3, axis='y', which='both')
    fig.legend(handles=[Patch(color=RUBRIC_COLORS[1], alpha=0.25,
                              label=f'good band {low:g}-{high:g} (Andrew)'),
                        Patch(color=RUBRIC_COLORS[0], label='inside band'),
                        Patch(color=RUBRIC_COLORS[4], label='outside band')],
               fontsize=8, loc='outside lower center', ncols=3)
    return save_figure(fig, out)


def plot_relative_damage_spectrum(path, channels: Sequence[str], bands_hz, rds_target,
                                  rds_prediction) -> Path:
    """
    Relative damage spectrum: damage per channel and frequency band (paper Figure 13).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    channels : sequence of str
        Channel names.
    bands_hz : array_like, shape (n_bands, 2)
        ``(low, high)`` edges of each band [Hz], low < high.
    rds_target, rds_prediction : array_like, shape (n_ch, n_bands)
        Pseudo damage of each band-passed signal [-], >= 0.  Zero-damage bars are empty.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    names = check_names(channels, 'channels')
    bands = np.asarray(bands_hz, dtype=np.float64)
    if bands.ndim != 2 or bands.shape[1] != 2 or bands.shape[0] < 1:
        raise ShapeError(f'bands_hz: expected shape (n_bands, 2), got {bands.shape}')
    bands = check_values(bands, 'bands_hz', bands.shape)
    if not (bands[:, 0] < bands[:, 1]).all() or (bands < 0).any():
        raise ConfigError(f'bands_hz: every band needs 0 <= low < high, got {bands.tolist()}')
    n_bands = bands.shape[0]
    target = check_values(rds_target, 'rds_target', (len(names), n_bands))
    pred = check_values(rds_prediction, 'rds_prediction', (len(names), n_bands))
    check_non_negative(target, 'rds_target', names)
    check_non_negative(pred, 'rds_prediction', names)
    group = n_bands + 1.0
    centre = np.arange(len(names))[:, np.newaxis] * group + np.arange(n_bands)
    fig = Figure(figsize=(max(9.0, 0.24 * centre.size + 2.0), 5.0), dpi=DPI,
                 layout='constrained')
    ax = fig.add_subplot()
    positive = np.concatenate([target[target > 0], pred[pred > 0]])
    log_scale = positive.size > 0
    bottom = positive.min() / 3.0 if log_scale else 0.0
    for values, dx, colour, label in ((target, -0.2, COLOR_TARGET, 'target'),
                                      (pred, 0.2, COLOR_PREDICTION, 'prediction')):
        heights = np.where(values > 0, values - bottom, np.nan) if log_scale else values
        ax.bar((centre + dx).ravel(), heights.ravel(), bottom=bottom, width=0.4,
               color=colour, label=label)
    for k in range(1, len(names)):
        ax.axvline(k * group - 1.0, color='0.75', lw=0.8)
    if log_scale:
        ax.set_yscale('log')
        ax.set_ylim(bottom, positive.max() * 3.0)
    else:
        ax.text(0.5, 0.5, 'no damage in any band', transform=ax.transAxes, ha='center')
    ax.set_xticks(centre.ravel(), [str(b + 1) for b in range(n_bands)] * len(names),
                  minor=True, fontsize=6)
    ax.set_xticks(centre.mean(axis=1), [channel_label(n) for n in names], fontsize=9)
    ax.tick_params(axis='x', which='major', pad=12, length=0)
    ax.set_xlim(centre.min() - 1.0, centre.max() + 1.0)
    ax.set_ylabel('pseudo damage [-]')
    band_text = ', '.join(f'{b + 1}: {lo:g}-{hi:g} Hz' for b, (lo, hi) in enumerate(bands))
    ax.set_title(f'Relative damage spectrum (bands {band_text})', fontsize=11)
    ax.grid(alpha=0.3, axis='y', which='major')
    ax.legend(fontsize=9, loc='upper right')
    return save_figure(fig, out)


def plot_rmse_colormap(path, events: Sequence[str], channels: Sequence[str], rmse_pct) -> Path:
    """
    RMSE per event and channel coloured by the paper's rubric (Figure 9, Table 2).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    events : sequence of str
        Event names (rows).
    channels : sequence of str
        Channel names (columns).
    rmse_pct : array_like, shape (n_events, n_ch)
        RMSE in percent, >= 0; each cell shows its value.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    ev = check_names(events, 'events')
    names = check_names(channels, 'channels')
    pct = check_values(rmse_pct, 'rmse_pct', (len(ev), len(names)))
    if (pct < 0).any():
        e, c = np.argwhere(pct < 0)[0]
        raise ConfigError(f'rmse_pct: negative value {pct[e, c].item()!r} for event {ev[e]}, '
                          f'channel {names[c]}')
    level = rubric_index(pct)
    width = 2.2 + 0.12 * max(len(e) for e in ev) + 0.78 * len(names)
    fig = Figure(figsize=(width, 1.9 + 0.36 * len(ev)), dpi=DPI, layout='constrained')
    ax = fig.add_subplot()
    ax.imshow(level, cmap=ListedColormap(RUBRIC_COLORS), vmin=-0.5,
              vmax=len(RUBRIC_COLORS) - 0.5, aspect='auto', interpolation='nearest')
    for (e, c), value in np.ndenumerate(pct):
        ax.text(c, e, f'{value:.1f}', ha='center', va='center', fontsize=8,
                color=RUBRIC_TEXT_COLOURS[level[e, c]])
    ax.set_xticks(np.arange(len(names)), [channel_label(n) for n in names], fontsize=9)
    ax.set_yticks(np.arange(len(ev)), list(ev), fontsize=9)
    ax.xaxis.tick_top()
    ax.tick_params(length=0)
    ax.set_xticks(np.arange(len(names) + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(len(ev) + 1) - 0.5, minor=True)
    ax.grid(which='minor', color='white', lw=1.0)
    ax.set_title('RMSE [%] per event and channel', fontsize=12)
    handles = [Patch(color=colour, label=f'{name} ({span})') for colour, name, span
               in zip(RUBRIC_COLORS, RUBRIC_NAMES, RUBRIC_RANGES)]
    fig.legend(handles=handles, loc='outside lower center', ncols=len(handles), fontsize=8)
    return save_figure(fig, out)
