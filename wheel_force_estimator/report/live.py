# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Offline vs live: the side-by-side table and the accuracy-against-look-ahead plot.

Used by ``evaluate --causal`` and the fit report, so an engineer can choose the look-ahead
(latency) knowing what it costs.  Directions are the force axes of vehicle channels
(``*_fx`` -> x ...); other channel names form one group, ``all``.
"""
from pathlib import Path
from typing import Dict, Sequence

from matplotlib.figure import Figure
import numpy as np

from wheel_force_estimator.report.figures import DPI
from wheel_force_estimator.report.figures import png_path
from wheel_force_estimator.report.figures import save_figure


def direction_groups(channels: Sequence[str]) -> Dict[str, np.ndarray]:
    """Return channel indices per force direction (``x``, ``y``, ``z``; else ``all``)."""
    groups = {}
    for axis in 'xyz':
        idx = [k for k, c in enumerate(channels) if c.endswith(f'_f{axis}')]
        if idx:
            groups[axis] = np.asarray(idx)
    return groups or {'all': np.arange(len(channels))}


def direction_means(channels: Sequence[str], values) -> Dict[str, float]:
    """Return the mean of ``values`` (one per channel) per direction group."""
    v = np.asarray(values, dtype=np.float64)
    return {name: float(np.mean(v[idx])) for name, idx in direction_groups(channels).items()}


def _fmt(value: float, spec: str) -> str:
    return format(value, spec) if np.isfinite(value) else 'n/a'


def comparison_table(offline, live, label: str, markdown: bool = False) -> str:
    """
    Return RMSE % (unfiltered, 1 Hz HP) and damage ratio per channel, offline | live.

    Parameters
    ----------
    offline, live : Evaluation
        Evaluations of the same data (same channels) by the two-sided and the live filter.
    label : str
        What the live column is (e.g. ``live 51 ms``).
    markdown : bool
        Markdown table instead of aligned text.

    """
    head = ('channel', 'RMSE % offline', f'RMSE % {label}', 'HP1 % offline',
            f'HP1 % {label}', 'damage ratio offline', f'damage ratio {label}')
    rows = []
    r_off, r_live = offline.damage_ratio, live.damage_ratio
    for k, name in enumerate(offline.channels):
        rows.append((name, _fmt(offline.rmse_pct[k], '.1f'), _fmt(live.rmse_pct[k], '.1f'),
                     _fmt(offline.rmse_hp1_pct[k], '.1f'), _fmt(live.rmse_hp1_pct[k], '.1f'),
                     _fmt(r_off[k], '.2f'), _fmt(r_live[k], '.2f')))
    for axis, idx in direction_groups(offline.channels).items():
        rows.append((f'mean {axis}', f'{np.mean(offline.rmse_pct[idx]):.1f}',
                     f'{np.mean(live.rmse_pct[idx]):.1f}',
                     f'{np.mean(offline.rmse_hp1_pct[idx]):.1f}',
                     f'{np.mean(live.rmse_hp1_pct[idx]):.1f}', '', ''))
    if markdown:
        lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
        lines += ['| ' + ' | '.join(r) + ' |' for r in rows]
        return '\n'.join(lines)
    widths = [max(len(h), *(len(r[c]) for r in rows)) for c, h in enumerate(head)]
    fmt = '  '.join(f'{{:>{w}}}' if c else f'{{:<{w}}}' for c, w in enumerate(widths))
    return '\n'.join([fmt.format(*head)] + [fmt.format(*r) for r in rows])


def plot_accuracy_vs_look_ahead(path, look_ahead_s, rmse_by_group: Dict[str, Sequence[float]],
                                offline_by_group: Dict[str, float], title: str = '') -> Path:
    """
    Plot mean RMSE % per direction against the live look-ahead, offline as dashed lines.

    Parameters
    ----------
    path : str or Path
        PNG to write (its directory must exist).
    look_ahead_s : sequence of float
        Look-aheads of the live estimators [s].
    rmse_by_group : dict
        Mean RMSE % per direction, one value per look-ahead.
    offline_by_group : dict
        Mean RMSE % of the two-sided offline filter per direction.
    title : str
        Figure title.

    Returns
    -------
    pathlib.Path

    """
    out = png_path(path)
    order = np.argsort(np.asarray(look_ahead_s, dtype=float))
    ms = 1e3 * np.asarray(look_ahead_s, dtype=float)[order]
    fig = Figure(figsize=(7.0, 4.2), dpi=DPI)
    ax = fig.add_subplot(1, 1, 1)
    colors = {'x': '#1f77b4', 'y': '#2ca02c', 'z': '#d62728', 'all': '#222222'}
    for name, values in rmse_by_group.items():
        color = colors.get(name, '#7f7f7f')
        ax.plot(ms, np.asarray(values, dtype=float)[order], 'o-', color=color,
                label=f'{name}: live')
        if name in offline_by_group:
            ax.axhline(offline_by_group[name], color=color, linestyle='--', linewidth=1.0,
                       label=f'{name}: offline (two-sided)')
    ax.set_xlabel('look-ahead [ms] (latency = look-ahead + block + compute)')
    ax.set_ylabel('mean RMSE % (unfiltered)')
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    ax.set_title(title or 'Accuracy against look-ahead')
    fig.tight_layout()
    return save_figure(fig, out)


def comparison_json(cmp, fs_hz: float) -> dict:
    """Return the ``live`` and ``look_ahead_sweep`` entries of ``evaluate --json``."""
    ch = cmp.offline.channels
    return {
        'live': {'look_ahead_samples': cmp.look_ahead_samples,
                 'look_ahead_s': cmp.look_ahead_samples / fs_hz, 'estimator': cmp.live_kind,
                 'channels': cmp.live.to_json()['channels']},
        'look_ahead_sweep': [
            {'look_ahead_s': s, 'estimator': kind,
             'rmse_pct_mean': direction_means(ch, ev.rmse_pct),
             'rmse_hp1_pct_mean': direction_means(ch, ev.rmse_hp1_pct)}
            for s, kind, ev in cmp.sweep],
        'offline_rmse_pct_mean': direction_means(ch, cmp.offline.rmse_pct),
    }


def comparison_text(cmp, fs_hz: float) -> str:
    """Return the terminal side-by-side table and the sweep."""
    ms = 1e3 * cmp.look_ahead_samples / fs_hz
    lines = [f'offline (two-sided) vs live ({cmp.live_kind}, look-ahead {ms:.1f} ms):',
             comparison_table(cmp.offline, cmp.live, f'live {ms:.0f} ms'), '',
             'mean RMSE % per direction against look-ahead:']
    offline = direction_means(cmp.offline.channels, cmp.offline.rmse_pct)
    lines.append('  offline two-sided: ' + '  '.join(f'{k} {v:.1f}' for k, v in offline.items()))
    for s, kind, ev in cmp.sweep:
        means = direction_means(ev.channels, ev.rmse_pct)
        lines.append(f'  {1e3 * s:6.1f} ms ({kind}): '
                     + '  '.join(f'{k} {v:.1f}' for k, v in means.items()))
    return '\n'.join(lines)


def report_section(out, directory, cmp, fs_hz: float, data: str) -> None:
    """Append the offline-vs-live section (table + look-ahead plot) to a report."""
    ms = 1e3 * cmp.look_ahead_samples / fs_hz
    out.heading('Offline vs live', 2)
    out.paragraph(f'{data}. Live = what the node publishes: the {cmp.live_kind} at a '
                  f'look-ahead of {cmp.look_ahead_samples} samples ({ms:.1f} ms); offline = the '
                  f'two-sided FIR of `predict`.')
    out.table(comparison_table(cmp.offline, cmp.live, f'live {ms:.0f} ms', markdown=True))
    ch = cmp.offline.channels
    groups: dict = {}
    for _, _, ev in cmp.sweep:
        for k, v in direction_means(ch, ev.rmse_pct).items():
            groups.setdefault(k, []).append(v)
    kinds = sorted({kind for _, kind, _ in cmp.sweep})
    out.image(plot_accuracy_vs_look_ahead(
        Path(directory) / 'accuracy_vs_look_ahead.png', [s for s, _, _ in cmp.sweep], groups,
        direction_means(ch, cmp.offline.rmse_pct), title=f'{" / ".join(kinds)}: accuracy '
        f'against look-ahead'), 'Mean RMSE % per direction against look-ahead (live) and '
        'the offline two-sided filter (dashed)')
