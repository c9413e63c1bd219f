# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The fit report's design section: every candidate's held-out score, and the choice."""
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np


def _label(cand: dict) -> str:
    """Return a short label of a candidate (its family and the settings it uses)."""
    parts = [cand['inputs']] if 'inputs' in cand else []
    parts.append(cand['family'])
    if 'segment_length' in cand:
        parts.append(f'seg {cand["segment_length"]} lreg {cand["long_regularisation"]:g}')
    if 'ls_regularisation' in cand:
        parts.append(f'ridge {cand["ls_regularisation"]:g} '
                     f'D {1e3 * cand["ls_look_ahead_s"]:.0f} ms')
    if 'crossover_hz' in cand:
        parts.append(f'x {cand["crossover_hz"]:g} Hz')
    return ' '.join(parts)


def design_tables(design: dict, output_channels) -> tuple:
    """
    Return the markdown tables of the chosen design and of every candidate.

    Parameters
    ----------
    design : dict
        The model's ``fit.design`` (``method == 'blocked_cross_validation'``).
    output_channels : sequence of str
        Output names, in model order.

    Returns
    -------
    (str, str)
        Per-output choice table, per-candidate table (mean held-out RMSE % over outputs).

    """
    sets = [s['name'] for s in design.get('input_sets') or ()]
    rows = ['| output | design | held-out RMSE % | 1 Hz HP % | live ridge | live inputs |'
            + ''.join(f' {n} % |' for n in sets),
            '|---|---|---|---|---|---|' + '---|' * len(sets)]
    for name in output_channels:
        r = design['rows'][name]
        per = r.get('input_sets') or {}
        rows.append(f'| {name} | {_label(r)} | {r["cv_rmse_pct"]:.1f} | '
                    f'{r["cv_rmse_hp1_pct"]:.1f} | {r["live_regularisation"]:g} | '
                    f'{r.get("live_inputs", "-")} |'
                    + ''.join(f' {per[n]["cv_rmse_pct"]:.1f} / {per[n]["cv_rmse_hp1_pct"]:.1f} |'
                              for n in sets if n in per))
    cands = ['| candidate | mean held-out RMSE % | mean 1 Hz HP % | chosen for |',
             '|---|---|---|---|']
    for c in design['candidates']:
        label = _label(c)
        chosen = [n for n in output_channels if _label(design['rows'][n]) == label]
        cands.append(f'| {label} | {np.mean(c["cv_rmse_pct"]):.1f} | '
                     f'{np.mean(c["cv_rmse_hp1_pct"]):.1f} | {", ".join(chosen) or "-"} |')
    return '\n'.join(rows), '\n'.join(cands)


def plot_design_scores(path, design: dict, output_channels) -> Path:
    """
    Plot every candidate's held-out RMSE per output, the chosen one marked (PNG).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    design : dict
        The model's ``fit.design``.
    output_channels : sequence of str
        Output names.

    Returns
    -------
    Path

    """
    out = Path(path)
    fig = Figure(figsize=(10, 6.5), layout='constrained')
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 1, sharex=True)
    x = np.arange(len(output_channels))
    for ax, key, title in ((axes[0], 'cv_rmse_pct', 'unfiltered'),
                           (axes[1], 'cv_rmse_hp1_pct', '1 Hz high-passed')):
        for c in design['candidates']:
            ax.plot(x, c[key], '.', color='0.6', ms=5)
        chosen = [design['rows'][n][key] for n in output_channels]
        ax.plot(x, chosen, 'o', color='C3', ms=7, label='chosen per output')
        ax.plot([], [], '.', color='0.6', label='candidates')
        ax.set_ylabel(f'held-out RMSE % ({title})')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='upper right', fontsize=8)
    axes[1].set_xticks(x, list(output_channels), rotation=45, fontsize=8)
    fig.suptitle(f'Design by blocked cross-validation ({design["n_blocks"]} blocks)')
    fig.savefig(out, dpi=100)
    return out
