# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Tables and plots of a fleet run (``wheel-force fleet``): what the terminal and report.md show.

- Percentile table: damage per hour of the 50/90/95/99 % customer per channel, and with a
  reference the repeats of the proving-ground schedule that equal that customer over the
  target hours (formula in :mod:`wheel_force_estimator.fleet.summary`).
- Ranked bags: severity = geometric mean over channels of the bag's damage per hour divided
  by the fleet median of that channel (1.0 = a median customer; 2.0 = twice the damage rate
  on a typical channel).  Channels where the median is 0 are left out of the mean.
- Plots: the distribution of damage per hour per channel (empirical cumulative fraction of
  bags on a log axis) with the percentile lines and the reference's own rate; the relative
  damage spectrum of the fleet vs the reference (share of each band in the band sum).
"""
import math
from pathlib import Path
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.report.figures import channel_label
from wheel_force_estimator.report.figures import COLOR_ERROR
from wheel_force_estimator.report.figures import COLOR_PREDICTION
from wheel_force_estimator.report.figures import COLOR_TARGET
from wheel_force_estimator.report.figures import save_figure
from wheel_force_estimator.report.tables import render

_PCT_COLORS = {'50': '#2ca02c', '90': '#ff7f0e', '95': COLOR_ERROR, '99': '#9467bd'}


def _sci(value: Optional[float]) -> str:
    return '-' if value is None else f'{value:.3g}'


def severity(rates: dict, median: dict) -> float:
    """Return the geometric mean over channels of ``rates[c] / median[c]`` (median > 0)."""
    logs = [math.log(max(rates[c], 1e-300) / m) for c, m in median.items() if m > 0]
    return math.exp(sum(logs) / len(logs)) if logs else float('nan')


def ranked(outcome) -> List[Tuple[float, object]]:
    """Return ``(severity, result)`` of the ok bags, most severe first."""
    pct = outcome.document['percentiles']
    if pct is None:
        return []
    rows = [(severity(r.damage_per_hour, pct['50']), r) for r in outcome.results if r.ok]
    return sorted(rows, key=lambda x: -x[0])


def percentile_table(outcome, markdown: bool = False) -> str:
    """Return the per-channel percentile (and proving-ground repeats) table."""
    doc = outcome.document
    pct = doc['percentiles']
    if pct is None:
        return 'no bag finished: no percentiles'
    channels = list(pct['50'])
    ref = doc['reference']
    header = ['channel'] + [f'P{p} dmg/h' for p in pct]
    if ref is not None:
        header += ['ref dmg/pass'] + [f'P{p} repeats' for p in pct]
    rows = []
    for c in channels:
        row = [c] + [_sci(pct[p][c]) for p in pct]
        if ref is not None:
            reps = ref['repeats_for_target']
            row += [_sci(ref['damage'][c])] + [_sci(reps[p][c]) for p in pct]
        rows.append(row)
    return render(header, rows, [False] + [True] * (len(header) - 1), markdown=markdown)


def ranked_table(outcome, markdown: bool = False, limit: Optional[int] = None) -> str:
    """Return the bags ranked by severity (worst first), then the failed ones."""
    rows = []
    for rank, (sev, r) in enumerate(ranked(outcome), start=1):
        worst = max(r.damage_per_hour, key=lambda c: r.damage_per_hour[c]
                    / max(outcome.document['percentiles']['50'][c], 1e-300))
        rows.append([str(rank), r.bag_id, f'{r.duration_s:.0f}', f'{sev:.2f}', worst,
                     'ok'])
    if limit is not None:
        rows = rows[:limit]
    for r in outcome.results:
        if not r.ok:
            rows.append(['-', r.bag_id, '-', '-', '-', f'failed: {r.error}'])
    header = ['rank', 'bag', 'duration s', 'severity', 'worst channel', 'status']
    return render(header, rows, [True, False, True, True, False, False], markdown=markdown)


def fleet_text(outcome) -> str:
    """Return the terminal summary of a fleet run."""
    doc = outcome.document
    n_ok, n_failed = doc['n_ok'], doc['n_failed']
    hours = sum(r.duration_s for r in outcome.results if r.ok) / 3600.0
    parts = [f'fleet: {n_ok} bag(s) ok ({hours:.2f} h), {n_failed} failed; pseudo damage '
             f'per hour (S-N slope k = {doc["sn_slope"]:g})']
    if doc['reference'] is not None:
        ref = doc['reference']
        parts.append(f'reference: {len(ref["path"])} bag(s), {ref["duration_s"]:.0f} s per '
                     f'pass; repeats = P-th percentile damage per hour x '
                     f'{ref["target_hours"]:g} h / damage of one pass')
    elif doc.get('reference_error'):
        parts.append(f'reference failed: {doc["reference_error"]}')
    parts.append(percentile_table(outcome))
    parts.append('bags by severity (damage per hour / fleet median, geometric mean over '
                 'channels):')
    parts.append(ranked_table(outcome, limit=20))
    return '\n'.join(parts)


def plot_damage_rate_distribution(path, outcome) -> Path:
    """
    Plot each channel's damage per hour over the bags with percentile lines.

    The x axis is the damage per hour divided by the fleet median of the channel (log
    scale), so every panel reads the same way: 1 = the median customer, 2 = twice its
    damage rate; the median's absolute value is in the panel title.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter
    from matplotlib.ticker import LogLocator
    from matplotlib.ticker import NullFormatter
    doc = outcome.document
    ok = [r for r in outcome.results if r.ok]
    median = doc['percentiles']['50']
    channels = list(median)
    ncols = 3
    nrows = math.ceil(len(channels) / ncols)
    fig = Figure(figsize=(4.2 * ncols, 2.7 * nrows), layout='constrained')
    ref = doc['reference']
    for i, c in enumerate(channels):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        ax.set_title(f'{channel_label(c)} (median {median[c]:.3g} N^k/h)', fontsize=9)
        ax.tick_params(labelsize=7)
        if median[c] <= 0:
            ax.text(0.5, 0.5, 'no damage', ha='center', va='center', transform=ax.transAxes)
            continue
        rates = np.sort([r.damage_per_hour[c] for r in ok]) / median[c]
        frac = np.arange(1, rates.size + 1) / rates.size
        positive = rates > 0
        ax.step(rates[positive], frac[positive], where='post', color=COLOR_PREDICTION,
                label='bags')
        ax.plot(rates[positive], frac[positive], 'o', ms=3, color=COLOR_PREDICTION)
        lines = [rates[positive].min(), rates.max()]
        for p, row in doc['percentiles'].items():
            ax.axvline(row[c] / median[c], color=_PCT_COLORS.get(p, 'grey'), lw=1, ls='--',
                       label=f'P{p}')
        if ref is not None and ref['damage'][c] > 0:
            ref_rate = ref['damage'][c] * 3600.0 / ref['duration_s'] / median[c]
            ax.axvline(ref_rate, color=COLOR_TARGET, lw=1.5, label='reference')
            lines.append(ref_rate)
        lo, hi = min(lines), max(lines)
        ax.set_xscale('log')
        ax.set_xlim(min(lo / 1.2, 0.5), max(hi * 1.2, 2.0))
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f'{v:g}'))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(0, 1.05)
        if i % ncols == 0:
            ax.set_ylabel('fraction of bags', fontsize=8)
        if i >= len(channels) - ncols:
            ax.set_xlabel('damage per hour / fleet median', fontsize=8)
        if i == 0:
            ax.legend(fontsize=6, loc='lower right')
    fig.suptitle('Damage rate distribution over the fleet (percentile lines dashed, '
                 'reference solid)')
    return save_figure(fig, Path(path))


def plot_rds_fleet_vs_reference(path, outcome) -> Path:
    """Plot the share of each band in the damage, fleet vs reference, per channel."""
    from matplotlib.figure import Figure
    doc = outcome.document
    fleet = doc['relative_damage_spectrum']
    ref = doc['reference']
    channels = list(fleet['fraction'])
    bands = fleet['bands_hz']
    ncols = 3
    nrows = math.ceil(len(channels) / ncols)
    fig = Figure(figsize=(4.2 * ncols, 2.6 * nrows), layout='constrained')
    x = np.arange(len(bands))
    width = 0.4 if ref is not None else 0.8
    labels = [f'{lo:g}-{hi:g}' for lo, hi in bands]
    for i, c in enumerate(channels):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        ax.bar(x - (width / 2 if ref is not None else 0), fleet['fraction'][c], width,
               color=COLOR_PREDICTION, label='fleet')
        if ref is not None:
            ax.bar(x + width / 2, ref['relative_damage_spectrum']['fraction'][c], width,
                   color=COLOR_TARGET, label='reference')
        ax.set_xticks(x, labels, fontsize=6)
        ax.set_title(channel_label(c), fontsize=9)
        ax.set_ylim(0, 1)
        ax.tick_params(labelsize=7)
        if i % ncols == 0:
            ax.set_ylabel('share of damage', fontsize=8)
        if i >= len(channels) - ncols:
            ax.set_xlabel('band [Hz]', fontsize=8)
        if i == 0:
            ax.legend(fontsize=6)
    fig.suptitle('Relative damage spectrum: fleet vs proving-ground reference')
    return save_figure(fig, Path(path))


def write_fleet_report(out_dir, outcome) -> Path:
    """Write ``report.md`` with the tables and both plots; return its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = outcome.document
    lines = ['# Fleet damage', '',
             f'{doc["n_ok"]} bag(s) ok, {doc["n_failed"]} failed; model `{doc["model"]}`, '
             f'S-N slope k = {doc["sn_slope"]:g}.  Damage per hour = pseudo damage of the '
             f'predicted force / bag duration.', '']
    if doc['reference'] is not None:
        ref = doc['reference']
        lines += [f'Reference schedule: {", ".join(f"`{p}`" for p in ref["path"])} '
                  f'({ref["duration_s"]:.0f} s per pass).  **Repeats** of the schedule that '
                  f'equal the P-th percentile customer over {ref["target_hours"]:g} h: '
                  f'`repeats_P = d_P x {ref["target_hours"]:g} h / D_pass`.', '']
    lines += ['## Percentiles per channel', '', percentile_table(outcome, markdown=True), '']
    plots = _sections(out, outcome)
    for title, png in plots:
        lines += [f'## {title}', '', f'![{title}]({png.name})', '']
    lines += ['## Bags by severity', '',
              'Severity: damage per hour / fleet median per channel, geometric mean over '
              'channels (1 = a median customer).', '', ranked_table(outcome, markdown=True),
              '']
    report = out / 'report.md'
    report.write_text('\n'.join(lines))
    return report


def _sections(out: Path, outcome) -> Sequence[Tuple[str, Path]]:
    if outcome.document['percentiles'] is None:
        return ()
    return (('Damage rate distribution',
             plot_damage_rate_distribution(out / 'damage_rate_distribution.png', outcome)),
            ('Relative damage spectrum, fleet vs reference',
             plot_rds_fleet_vs_reference(out / 'relative_damage_spectrum_fleet.png',
                                         outcome)))
