# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
PNG plots of a fitted model and of an evaluation, in the style of the paper's figures.

Pure functions: numpy arrays and channel names in, one PNG written, its ``Path`` returned.
Figures are built with :class:`matplotlib.figure.Figure` directly (Agg canvas on save), never
through ``pyplot``, so there is no global figure state and no GUI backend is touched.

Inputs are validated before anything is drawn: a shape that does not match the channel list
raises :class:`ShapeError` and a NaN / infinity raises :class:`NonFiniteError`, both naming the
argument, because a plot of bad data misleads the person reading it.

Layout convention: channels named ``{corner}_{quantity}`` (``lf_fx`` ...) are drawn on a grid
with one row per corner and one column per quantity (4 x 3 for the 12 forces).
"""
from pathlib import Path
from typing import Optional, Sequence, Tuple

from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch
import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.report.tables import check_names
from wheel_force_estimator.report.tables import check_values
from wheel_force_estimator.report.tables import DAMAGE_RATIO_GOOD
from wheel_force_estimator.report.tables import rubric_index
from wheel_force_estimator.report.tables import RUBRIC_NAMES
from wheel_force_estimator.report.tables import RUBRIC_RANGES

DPI = 150
COLOR_TARGET = '#222222'
COLOR_PREDICTION = '#1f77b4'
COLOR_ERROR = '#d62728'
COLOR_FRF = '#2ca02c'
COLOR_ORDINARY = '#ff7f0e'
# Green (perfect) to red (not qualified), like the paper's Figure 9 colour map.
RUBRIC_COLORS = ('#1a9850', '#91cf60', '#fee08b', '#fc8d59', '#d73027')
_RUBRIC_TEXT = ('white', 'black', 'black', 'black', 'white')
# Time histories longer than this many points per axes are drawn as a min/max envelope.
_MAX_LINE_POINTS = 4000
# Lowest decade shown on spectral plots: 100 dB below the peak is far below any error that
# matters and keeps a near-zero DC bin from squashing the interesting range.
_SPECTRUM_DYNAMIC_RANGE = 1e-10


# ---------------------------------------------------------------- validation / helpers
def _png_path(path) -> Path:
    out = Path(path)
    if out.suffix.lower() != '.png':
        raise ConfigError(f'plot path {out}: must end in .png')
    if not out.parent.is_dir():
        raise ConfigError(f'plot path {out}: directory {out.parent} does not exist')
    if out.is_dir():
        raise ConfigError(f'plot path {out}: is a directory')
    return out


def _axis(values, name: str, min_len: int = 2) -> np.ndarray:
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


def _non_negative(arr: np.ndarray, name: str, channels: Sequence[str]) -> None:
    if (arr < 0).any():
        idx = np.argwhere(arr < 0)[0]
        raise ConfigError(f'{name}: negative value {arr[tuple(idx)].item()!r} for channel '
                          f'{channels[idx[0]]}')


def _label(channel: str) -> str:
    """Return 'lf_fx' as 'LF Fx', the paper's spelling."""
    corner, sep, rest = channel.partition('_')
    return f'{corner.upper()} {rest.capitalize()}' if sep else channel


def _unit(channel: str) -> str:
    quantity = channel.partition('_')[2][:1]
    return {'f': 'N', 'm': 'N·m', 'a': 'm/s²'}.get(quantity, '-')


def _squared(unit: str) -> str:
    return f'{unit}²' if unit.isalpha() else f'({unit})²'


def _grid(channels: Sequence[str]) -> Tuple[int, int, list]:
    """Return (rows, cols, [(row, col)] per channel): one row per corner when names allow."""
    groups = []
    for ch in channels:
        prefix = ch.partition('_')[0]
        if prefix not in groups:
            groups.append(prefix)
    if len(groups) < len(channels):
        cols = dict.fromkeys(groups, 0)
        cells = []
        for ch in channels:
            g = ch.partition('_')[0]
            cells.append((groups.index(g), cols[g]))
            cols[g] += 1
        return len(groups), max(cols.values()), cells
    n_cols = min(3, len(channels))
    n_rows = -(-len(channels) // n_cols)
    return n_rows, n_cols, [divmod(i, n_cols) for i in range(len(channels))]


def _grid_figure(channels: Sequence[str], cell_w: float, cell_h: float, title: str):
    n_rows, n_cols, cells = _grid(channels)
    fig = Figure(figsize=(cell_w * n_cols + 0.6, cell_h * n_rows + 1.0), dpi=DPI,
                 layout='constrained')
    gs = fig.add_gridspec(n_rows, n_cols)
    axes, first = [], None
    for row, col in cells:
        ax = fig.add_subplot(gs[row, col], sharex=first)
        first = first or ax
        axes.append(ax)
    fig.suptitle(title, fontsize=13)
    return fig, axes, cells, n_rows


def _f_max(f: np.ndarray, f_max_hz: Optional[float]) -> float:
    if f_max_hz is None:
        return float(f[-1])
    value = float(f_max_hz)
    if not (np.isfinite(value) and value > f[0]):
        raise ConfigError(f'f_max_hz={f_max_hz}: must be finite and exceed the first '
                          f'frequency {f[0]} Hz')
    return value


def _spectrum_floor(ax, *arrays: np.ndarray) -> None:
    values = np.concatenate([a.ravel() for a in arrays])
    positive = values[values > 0]
    if positive.size:
        top = positive.max()
        ax.set_ylim(max(positive.min(), top * _SPECTRUM_DYNAMIC_RANGE) / 2.0, top * 2.0)


def _envelope(t: np.ndarray, y: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Min/max per bucket of a long record: what the rasteriser shows anyway, peaks kept."""
    if t.size <= _MAX_LINE_POINTS:
        return t, y
    starts = np.linspace(0, t.size, _MAX_LINE_POINTS // 2, endpoint=False).astype(np.intp)
    lo = np.minimum.reduceat(y, starts)
    hi = np.maximum.reduceat(y, starts)
    return np.repeat(t[starts], 2), np.column_stack([lo, hi]).ravel()


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, format='png', dpi=DPI)
    return path


# ---------------------------------------------------------------- model plots
def plot_coherence(path, f_hz, coherence_multiple, coherence_ordinary_diag,
                   output_channels: Sequence[str], f_max_hz: Optional[float] = None) -> Path:
    """
    Multiple and same-axis ordinary coherence per output channel (paper Figure 6).

    Parameters
    ----------
    path : str or Path
        PNG file to write (its directory must exist).
    f_hz : array_like, shape (nf,)
        Frequency vector [Hz], strictly increasing.
    coherence_multiple : array_like, shape (nf, n_out)
        Multiple coherence of each output with all inputs [-].
    coherence_ordinary_diag : array_like, shape (nf, n_out) or None
        Ordinary coherence of each output with its same-axis input (lf_ax -> lf_fx) [-].
    output_channels : sequence of str
        Output channel names.
    f_max_hz : float, optional
        Upper frequency limit of the plot [Hz].

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = _png_path(path)
    names = check_names(output_channels, 'output_channels')
    f = _axis(f_hz, 'f_hz')
    multiple = check_values(coherence_multiple, 'coherence_multiple', (f.size, len(names)))
    ordinary = None if coherence_ordinary_diag is None else check_values(
        coherence_ordinary_diag, 'coherence_ordinary_diag', (f.size, len(names)))
    f_end = _f_max(f, f_max_hz)
    fig, axes, cells, n_rows = _grid_figure(names, 4.2, 2.3, 'Coherence: accelerations -> '
                                            'wheel forces (values below 0.5: FRF not trusted)')
    for i, (ax, (row, col)) in enumerate(zip(axes, cells)):
        ax.plot(f, multiple[:, i], color=COLOR_PREDICTION, lw=1.0, label='multiple (all inputs)')
        if ordinary is not None:
            ax.plot(f, ordinary[:, i], color=COLOR_ORDINARY, lw=0.8, alpha=0.9,
                    label='ordinary (same-axis input)')
        ax.axhline(0.5, color='0.4', ls='--', lw=0.8, label='0.5 threshold')
        ax.set_ylim(0.0, 1.05)
        ax.set_xlim(f[0], f_end)
        ax.set_title(_label(names[i]), fontsize=10)
        ax.grid(alpha=0.3)
        if row == n_rows - 1:
            ax.set_xlabel('frequency [Hz]')
        if col == 0:
            ax.set_ylabel('coherence [-]')
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc='outside lower center', ncols=len(labels))
    return _save(fig, out)


def _same_axis_pairs(inputs: Sequence[str], outputs: Sequence[str]) -> list:
    """(out_index, in_index) for lf_fx <- lf_ax style pairs, in output order."""
    pairs = []
    for o, name in enumerate(outputs):
        corner, _, quantity = name.partition('_')
        partner = f'{corner}_a{quantity[1:]}'
        if quantity.startswith('f') and partner in inputs:
            pairs.append((o, inputs.index(partner)))
    return pairs


def plot_frf_diagonal(path, f_hz, h, input_channels: Sequence[str],
                      output_channels: Sequence[str], f_max_hz: Optional[float] = None) -> Path:
    """
    Magnitude and phase of each corner's same-axis FRF (paper Figure 7).

    One column per axis (x, y, z); the four corners are overlaid so their resonances compare
    directly.  Magnitude on a log scale, phase wrapped to +-180 degrees.

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    f_hz : array_like, shape (nf,)
        Frequency vector [Hz].
    h : array_like, complex, shape (nf, n_out, n_in)
        FRF matrix, output force per input acceleration [N/(m/s²)].
    input_channels, output_channels : sequence of str
        Channel names; outputs ``{corner}_f{axis}`` are paired with inputs ``{corner}_a{axis}``.
    f_max_hz : float, optional
        Upper frequency limit of the plot [Hz].

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError
        ConfigError when no same-axis pair exists in the channel names.

    """
    out = _png_path(path)
    inputs = check_names(input_channels, 'input_channels')
    outputs = check_names(output_channels, 'output_channels')
    f = _axis(f_hz, 'f_hz')
    frf = check_values(h, 'h', (f.size, len(outputs), len(inputs)), dtype=np.complex128)
    f_end = _f_max(f, f_max_hz)
    pairs = _same_axis_pairs(inputs, outputs)
    if not pairs:
        raise ConfigError('output_channels: no output {corner}_f{axis} has a same-axis input '
                          f'{{corner}}_a{{axis}} in input_channels {list(inputs)}')
    quantities = []
    for o, _ in pairs:
        q = outputs[o].partition('_')[2]
        if q not in quantities:
            quantities.append(q)
    corners = [outputs[o].partition('_')[0] for o, _ in pairs]
    colours = {c: f'C{k}' for k, c in enumerate(dict.fromkeys(corners))}
    fig = Figure(figsize=(4.6 * len(quantities) + 0.6, 6.6), dpi=DPI, layout='constrained')
    gs = fig.add_gridspec(2, len(quantities), height_ratios=(2.0, 1.0))
    fig.suptitle('FRF diagonal: same-axis spindle acceleration -> wheel force', fontsize=13)
    mag_axes = []
    for k, q in enumerate(quantities):
        ax_mag = fig.add_subplot(gs[0, k], sharex=mag_axes[0] if mag_axes else None)
        ax_ph = fig.add_subplot(gs[1, k], sharex=ax_mag)
        mag_axes.append(ax_mag)
        for o, i in pairs:
            if outputs[o].partition('_')[2] != q:
                continue
            corner = outputs[o].partition('_')[0]
            ax_mag.plot(f, np.abs(frf[:, o, i]), color=colours[corner], lw=1.0,
                        label=corner.upper())
            phase = np.angle(frf[:, o, i], deg=True)
            # Break the line at +-180 wraps instead of drawing a vertical stroke across.
            wraps = np.nonzero(np.abs(np.diff(phase)) > 180.0)[0] + 1
            ax_ph.plot(np.insert(f, wraps, np.nan), np.insert(phase, wraps, np.nan),
                       color=colours[corner], lw=0.8)
            unit = f'{_unit(outputs[o])}/({_unit(inputs[i])})'
        ax_mag.set_yscale('log')
        ax_mag.set_title(f'{q.capitalize()} / a{q[1:]}', fontsize=11)
        ax_mag.set_ylabel(f'|H| [{unit}]')
        ax_mag.grid(alpha=0.3, which='both')
        ax_mag.legend(fontsize=8, loc='best')
        ax_ph.set_ylim(-190.0, 190.0)
        ax_ph.set_yticks([-180, -90, 0, 90, 180])
        ax_ph.set_ylabel('phase [deg]')
        ax_ph.set_xlabel('frequency [Hz]')
        ax_ph.set_xlim(f[0], f_end)
        ax_ph.grid(alpha=0.3)
    return _save(fig, out)


def plot_condition_number(path, f_hz, cond) -> Path:
    """
    Condition number of the input cross-spectral matrix Sxx versus frequency (log scale).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    f_hz : array_like, shape (nf,)
        Frequency vector [Hz].
    cond : array_like, shape (nf,)
        2-norm condition number of Sxx(f) [-], > 0.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = _png_path(path)
    f = _axis(f_hz, 'f_hz')
    c = check_values(cond, 'cond', (f.size,))
    if (c <= 0).any():
        raise ConfigError(f'cond: non-positive value {c[c <= 0][0].item()!r} at index '
                          f'{int(np.argmax(c <= 0))}')
    fig = Figure(figsize=(9.0, 4.2), dpi=DPI, layout='constrained')
    ax = fig.add_subplot()
    ax.semilogy(f, c, color=COLOR_PREDICTION, lw=1.0)
    ax.set_xlim(f[0], f[-1])
    ax.set_xlabel('frequency [Hz]')
    ax.set_ylabel('cond(Sxx) [-]')
    ax.set_title('Condition number of the input cross-spectral matrix '
                 '(high: inputs nearly dependent, FRF ill-posed)', fontsize=11)
    ax.grid(alpha=0.3, which='both')
    return _save(fig, out)


# ---------------------------------------------------------------- evaluation plots
def plot_time_overlay(path, t_s, target, prediction, channels: Sequence[str],
                      window_s: Optional[Tuple[float, float]] = None, title: str = '') -> Path:
    """
    Target, prediction and error time histories, one stacked axes per channel (Figure 8).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    t_s : array_like, shape (n,)
        Time [s], strictly increasing.
    target, prediction : array_like, shape (n_ch, n)
        Measured and predicted signals (units from the channel names: N, N·m, m/s²).
    channels : sequence of str
        Channel names.
    window_s : (float, float), optional
        Zoom window ``(start, end)`` [s]; only samples inside it are drawn.
    title : str
        Figure title (e.g. the recording or event name).

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
    out = _png_path(path)
    names = check_names(channels, 'channels')
    t = _axis(t_s, 't_s')
    y_true = check_values(target, 'target', (len(names), t.size))
    y_pred = check_values(prediction, 'prediction', (len(names), t.size))
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
        ax.set_ylabel(f'{_label(names[k])}\n[{_unit(names[k])}]', fontsize=9)
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
    return _save(fig, out)


def plot_asd(path, f_hz, asd_target, asd_prediction, asd_error, channels: Sequence[str],
             frf_mag=None) -> Path:
    """
    Auto spectral density of target, prediction and error per channel (Figures 10-12).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    f_hz : array_like, shape (nf,)
        Frequency vector [Hz].
    asd_target, asd_prediction, asd_error : array_like, shape (n_ch, nf)
        One-sided ASD [unit²/Hz, e.g. N²/Hz], >= 0.
    channels : sequence of str
        Channel names.
    frf_mag : array_like, shape (n_ch, nf), optional
        Magnitude of each channel's same-axis FRF, drawn on a twin log axis, so error bands can
        be matched with resonances and anti-resonances.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = _png_path(path)
    names = check_names(channels, 'channels')
    f = _axis(f_hz, 'f_hz')
    shape = (len(names), f.size)
    spectra = [check_values(asd_target, 'asd_target', shape),
               check_values(asd_prediction, 'asd_prediction', shape),
               check_values(asd_error, 'asd_error', shape)]
    frf = None if frf_mag is None else check_values(frf_mag, 'frf_mag', shape)
    for arr, n in zip(spectra + ([] if frf is None else [frf]),
                      ('asd_target', 'asd_prediction', 'asd_error', 'frf_mag')):
        _non_negative(arr, n, names)
    fig, axes, cells, n_rows = _grid_figure(names, 4.4, 2.6,
                                            'Auto spectral density: target, prediction, error')
    n_cols = max(col for _, col in cells) + 1
    styles = ((COLOR_TARGET, 1.0, 'target'), (COLOR_PREDICTION, 0.9, 'prediction'),
              (COLOR_ERROR, 0.9, 'error'))
    twin_handles = []
    for k, (ax, (row, col)) in enumerate(zip(axes, cells)):
        for arr, (colour, lw, label) in zip(spectra, styles):
            ax.plot(f, arr[k], color=colour, lw=lw, label=label)
        ax.set_yscale('log')
        _spectrum_floor(ax, *(arr[k] for arr in spectra))
        ax.set_xlim(f[0], f[-1])
        ax.set_title(_label(names[k]), fontsize=10)
        ax.grid(alpha=0.3, which='major')
        if row == n_rows - 1:
            ax.set_xlabel('frequency [Hz]')
        if col == 0:
            ax.set_ylabel(f'ASD [{_squared(_unit(names[k]))}/Hz]')
        if frf is not None:
            twin = ax.twinx()
            twin_handles = twin.plot(f, frf[k], color=COLOR_FRF, lw=0.8, ls='--',
                                     label='|FRF| same axis (right axis)')
            twin.set_yscale('log')
            twin.tick_params(axis='y', colors=COLOR_FRF, labelsize=7)
            if col == n_cols - 1:
                twin.set_ylabel(f'|H| [{_unit(names[k])}/(m/s²)]', color=COLOR_FRF)
    handles, labels = axes[0].get_legend_handles_labels()
    handles += twin_handles
    labels += [h.get_label() for h in twin_handles]
    fig.legend(handles, labels, loc='outside lower center', ncols=len(labels))
    return _save(fig, out)


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
    out = _png_path(path)
    names = check_names(channels, 'channels')
    r = check_values(ratio, 'ratio', (len(names),))
    _non_negative(r, 'ratio', names)
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
    ax.set_xticks(x, [_label(n) for n in names], fontsize=9)
    ax.set_ylabel('damage ratio prediction / target [-]')
    ax.set_title('Pseudo damage ratio per channel', fontsize=12)
    ax.grid(alpha=0.3, axis='y', which='both')
    fig.legend(handles=[Patch(color=RUBRIC_COLORS[1], alpha=0.25,
                              label=f'good band {low:g}-{high:g} (Andrew)'),
                        Patch(color=RUBRIC_COLORS[0], label='inside band'),
                        Patch(color=RUBRIC_COLORS[4], label='outside band')],
               fontsize=8, loc='outside lower center', ncols=3)
    return _save(fig, out)


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
    out = _png_path(path)
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
    _non_negative(target, 'rds_target', names)
    _non_negative(pred, 'rds_prediction', names)
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
    ax.set_xticks(centre.mean(axis=1), [_label(n) for n in names], fontsize=9)
    ax.tick_params(axis='x', which='major', pad=12, length=0)
    ax.set_xlim(centre.min() - 1.0, centre.max() + 1.0)
    ax.set_ylabel('pseudo damage [-]')
    band_text = ', '.join(f'{b + 1}: {lo:g}-{hi:g} Hz' for b, (lo, hi) in enumerate(bands))
    ax.set_title(f'Relative damage spectrum (bands {band_text})', fontsize=11)
    ax.grid(alpha=0.3, axis='y', which='major')
    ax.legend(fontsize=9, loc='upper right')
    return _save(fig, out)


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
    out = _png_path(path)
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
                color=_RUBRIC_TEXT[level[e, c]])
    ax.set_xticks(np.arange(len(names)), [_label(n) for n in names], fontsize=9)
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
    return _save(fig, out)
