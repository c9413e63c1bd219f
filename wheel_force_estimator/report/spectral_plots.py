# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
PNG plots against frequency: coherence, FRF and conditioning of a model; ASD of an evaluation.

In the style of the paper's figures.  The conventions shared by all report plots (pure
functions, no ``pyplot``, inputs validated before drawing) are stated in
:mod:`wheel_force_estimator.report.figures`.

Layout convention: channels named ``{corner}_{quantity}`` (``lf_fx`` ...) are drawn on a grid
with one row per corner and one column per quantity (4 x 3 for the 12 forces); any other
names (generic recordings) fill rows of three.  Units come from vehicle channel names or are
passed in (``units``, ``input_unit``), so any channel count and naming works.
"""
from pathlib import Path
from typing import Optional, Sequence, Tuple

from matplotlib.figure import Figure
import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.report.figures import as_axis
from wheel_force_estimator.report.figures import channel_label
from wheel_force_estimator.report.figures import channel_unit
from wheel_force_estimator.report.figures import channel_units
from wheel_force_estimator.report.figures import check_non_negative
from wheel_force_estimator.report.figures import COLOR_ERROR
from wheel_force_estimator.report.figures import COLOR_FRF
from wheel_force_estimator.report.figures import COLOR_ORDINARY
from wheel_force_estimator.report.figures import COLOR_PREDICTION
from wheel_force_estimator.report.figures import COLOR_TARGET
from wheel_force_estimator.report.figures import DPI
from wheel_force_estimator.report.figures import png_path
from wheel_force_estimator.report.figures import ratio_unit
from wheel_force_estimator.report.figures import save_figure
from wheel_force_estimator.report.tables import check_names
from wheel_force_estimator.report.tables import check_values

# Lowest decade shown on spectral plots: 100 dB below the peak is far below any error that
# matters and keeps a near-zero DC bin from squashing the interesting range.
_SPECTRUM_DYNAMIC_RANGE = 1e-10


# ---------------------------------------------------------------- layout helpers
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
    out = png_path(path)
    names = check_names(output_channels, 'output_channels')
    f = as_axis(f_hz, 'f_hz')
    multiple = check_values(coherence_multiple, 'coherence_multiple', (f.size, len(names)))
    ordinary = None if coherence_ordinary_diag is None else check_values(
        coherence_ordinary_diag, 'coherence_ordinary_diag', (f.size, len(names)))
    f_end = _f_max(f, f_max_hz)
    fig, axes, cells, n_rows = _grid_figure(names, 4.2, 2.3, 'Coherence: inputs -> outputs '
                                            '(values below 0.5: FRF not trusted)')
    for i, (ax, (row, col)) in enumerate(zip(axes, cells)):
        ax.plot(f, multiple[:, i], color=COLOR_PREDICTION, lw=1.0, label='multiple (all inputs)')
        if ordinary is not None:
            ax.plot(f, ordinary[:, i], color=COLOR_ORDINARY, lw=0.8, alpha=0.9,
                    label='ordinary (same-axis input)')
        ax.axhline(0.5, color='0.4', ls='--', lw=0.8, label='0.5 threshold')
        ax.set_ylim(0.0, 1.05)
        ax.set_xlim(f[0], f_end)
        ax.set_title(channel_label(names[i]), fontsize=10)
        ax.grid(alpha=0.3)
        if row == n_rows - 1:
            ax.set_xlabel('frequency [Hz]')
        if col == 0:
            ax.set_ylabel('coherence [-]')
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc='outside lower center', ncols=len(labels))
    return save_figure(fig, out)


def same_axis_pairs(inputs: Sequence[str], outputs: Sequence[str]) -> list:
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
    out = png_path(path)
    inputs = check_names(input_channels, 'input_channels')
    outputs = check_names(output_channels, 'output_channels')
    f = as_axis(f_hz, 'f_hz')
    frf = check_values(h, 'h', (f.size, len(outputs), len(inputs)), dtype=np.complex128)
    f_end = _f_max(f, f_max_hz)
    pairs = same_axis_pairs(inputs, outputs)
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
            _frf_lines(ax_mag, ax_ph, f, frf[:, o, i], colours[corner], corner.upper())
            unit = f'{channel_unit(outputs[o])}/({channel_unit(inputs[i])})'
        ax_mag.set_yscale('log')
        _frf_axes(ax_mag, ax_ph, f'{q.capitalize()} / a{q[1:]}', unit, f[0], f_end)
    return save_figure(fig, out)


def _frf_lines(ax_mag, ax_ph, f, h_line, colour, label) -> None:
    """Draw one FRF's magnitude and phase (phase line broken at the +-180 deg wraps)."""
    ax_mag.plot(f, np.abs(h_line), color=colour, lw=1.0, label=label)
    phase = np.angle(h_line, deg=True)
    # Break the line at +-180 wraps instead of drawing a vertical stroke across.
    wraps = np.nonzero(np.abs(np.diff(phase)) > 180.0)[0] + 1
    ax_ph.plot(np.insert(f, wraps, np.nan), np.insert(phase, wraps, np.nan), color=colour,
               lw=0.8)


def _frf_axes(ax_mag, ax_ph, title, unit, f_start, f_end) -> None:
    """Title, labels, grids and limits of a magnitude / phase pair of FRF axes."""
    ax_mag.set_title(title, fontsize=11)
    ax_mag.set_ylabel(f'|H| [{unit}]')
    ax_mag.grid(alpha=0.3, which='both')
    ax_mag.legend(fontsize=8, loc='best')
    ax_ph.set_ylim(-190.0, 190.0)
    ax_ph.set_yticks([-180, -90, 0, 90, 180])
    ax_ph.set_ylabel('phase [deg]')
    ax_ph.set_xlabel('frequency [Hz]')
    ax_ph.set_xlim(f_start, f_end)
    ax_ph.grid(alpha=0.3)


def plot_frf_matrix(path, f_hz, h, input_channels: Sequence[str],
                    output_channels: Sequence[str], input_unit: str = 'm/s^2',
                    output_unit: str = 'N', f_max_hz: Optional[float] = None,
                    max_inputs: int = 6) -> Path:
    """
    Magnitude and phase of the FRF from every input to every output, any channel names.

    For models whose channels do not follow the vehicle naming (generic recordings): one
    column per output (rows of three), the inputs overlaid.  With more than ``max_inputs``
    inputs only the ``max_inputs`` with the largest RMS gain to that output are drawn (all
    inputs share one quantity, so their gains compare).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    f_hz : array_like, shape (nf,)
        Frequency vector [Hz].
    h : array_like, complex, shape (nf, n_out, n_in)
        FRF matrix [output_unit / input_unit].
    input_channels, output_channels : sequence of str
        Channel names.
    input_unit, output_unit : str
        Units of the inputs (e.g. ``m``) and outputs (``N``), for the axis label.
    f_max_hz : float, optional
        Upper frequency limit of the plot [Hz].
    max_inputs : int
        Most inputs drawn per output (>= 1).

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    inputs = check_names(input_channels, 'input_channels')
    outputs = check_names(output_channels, 'output_channels')
    f = as_axis(f_hz, 'f_hz')
    frf = check_values(h, 'h', (f.size, len(outputs), len(inputs)), dtype=np.complex128)
    f_end = _f_max(f, f_max_hz)
    if max_inputs < 1:
        raise ConfigError(f'max_inputs must be >= 1, got {max_inputs!r}')
    n_cols = min(3, len(outputs))
    n_blocks = -(-len(outputs) // n_cols)
    fig = Figure(figsize=(4.6 * n_cols + 0.6, 4.4 * n_blocks + 0.8), dpi=DPI,
                 layout='constrained')
    gs = fig.add_gridspec(2 * n_blocks, n_cols, height_ratios=(2.0, 1.0) * n_blocks)
    fig.suptitle('FRF: inputs -> outputs, magnitude and phase', fontsize=13)
    unit = ratio_unit(output_unit, input_unit)
    for o, name in enumerate(outputs):
        block, col = divmod(o, n_cols)
        ax_mag = fig.add_subplot(gs[2 * block, col])
        ax_ph = fig.add_subplot(gs[2 * block + 1, col], sharex=ax_mag)
        rms = np.sqrt(np.mean(np.abs(frf[:, o, :]) ** 2, axis=0))
        for i in sorted(np.argsort(rms)[::-1][:max_inputs]):
            _frf_lines(ax_mag, ax_ph, f, frf[:, o, i], f'C{i % 10}', inputs[i])
        if np.any(rms > 0):
            ax_mag.set_yscale('log')
        _frf_axes(ax_mag, ax_ph, name, unit, f[0], f_end)
        ax_mag.tick_params(labelbottom=False)
    return save_figure(fig, out)


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
    out = png_path(path)
    f = as_axis(f_hz, 'f_hz')
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
    return save_figure(fig, out)


# ---------------------------------------------------------------- evaluation plots
def plot_asd(path, f_hz, asd_target, asd_prediction, asd_error, channels: Sequence[str],
             frf_mag=None, units: Optional[Sequence[str]] = None,
             frf_unit: Optional[str] = None) -> Path:
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
    units : sequence of str, optional
        Unit of each channel (e.g. ``N``); default from vehicle channel names.
    frf_unit : str, optional
        Unit of ``frf_mag`` (e.g. ``N/m``); default ``{unit}/(m/s²)``.

    Returns
    -------
    Path

    Raises
    ------
    ShapeError, NonFiniteError, ConfigError

    """
    out = png_path(path)
    names = check_names(channels, 'channels')
    f = as_axis(f_hz, 'f_hz')
    shape = (len(names), f.size)
    spectra = [check_values(asd_target, 'asd_target', shape),
               check_values(asd_prediction, 'asd_prediction', shape),
               check_values(asd_error, 'asd_error', shape)]
    frf = None if frf_mag is None else check_values(frf_mag, 'frf_mag', shape)
    unit_of = channel_units(names, units)
    for arr, n in zip(spectra + ([] if frf is None else [frf]),
                      ('asd_target', 'asd_prediction', 'asd_error', 'frf_mag')):
        check_non_negative(arr, n, names)
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
        ax.set_title(channel_label(names[k]), fontsize=10)
        ax.grid(alpha=0.3, which='major')
        if row == n_rows - 1:
            ax.set_xlabel('frequency [Hz]')
        if col == 0:
            ax.set_ylabel(f'ASD [{_squared(unit_of[k])}/Hz]')
        if frf is not None:
            twin = ax.twinx()
            twin_handles = twin.plot(f, frf[k], color=COLOR_FRF, lw=0.8, ls='--',
                                     label='|FRF| same axis (right axis)')
            twin.set_yscale('log')
            twin.tick_params(axis='y', colors=COLOR_FRF, labelsize=7)
            if col == n_cols - 1:
                gain = frf_unit or ratio_unit(unit_of[k], 'm/s^2')
                twin.set_ylabel(f'|H| [{gain}]', color=COLOR_FRF)
    handles, labels = axes[0].get_legend_handles_labels()
    handles += twin_handles
    labels += [h.get_label() for h in twin_handles]
    fig.legend(handles, labels, loc='outside lower center', ncols=len(labels))
    return save_figure(fig, out)
