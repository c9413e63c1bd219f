# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Diagnosis report: report.md plus the plots that show the effect (matplotlib, Agg)."""
from pathlib import Path
from typing import List, Sequence

import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.features import motion_features
from wheel_force_estimator.diagnosis.features import pairing


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _predictions(result, rec):
    before = result.baseline.predict(rec)
    if result.model is None:
        return before, before
    # The written model through the path `predict` and `evaluate` take.
    return before, predict_forces(result.model, rec.inputs)


def _time_plot(plt, path, rec, o, before, after, windows):
    t = np.arange(rec.n_samples) / rec.fs_hz + rec.start_s
    centre = windows[0][0] if windows else t[rec.n_samples // 2]
    sel = (t >= centre - 1.0) & (t <= centre + 3.0)
    if sel.sum() < 8:
        sel = slice(None)
    fig, ax = plt.subplots(figsize=(10, 4))
    ax.plot(t[sel], rec.outputs[o][sel], 'k', lw=1.2, label='real')
    ax.plot(t[sel], before[o][sel], 'C1', lw=0.9, label='reference (before)')
    ax.plot(t[sel], after[o][sel], 'C2', lw=0.9, label='written model (after)')
    ax.set_xlabel('time [s]')
    ax.set_ylabel(f'{rec.output_channels[o]} [N]')
    ax.set_title(f'{rec.name}: {rec.output_channels[o]}')
    ax.legend(loc='best')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _asd_plot(plt, path, rec, o, before, after):
    n = min(rec.n_samples, int(2 ** np.floor(np.log2(max(16, 4 * rec.fs_hz)))))
    fig, ax = plt.subplots(figsize=(8, 4))
    for label, x, style in (('real force', rec.outputs[o], 'k'),
                            ('residual before', rec.outputs[o] - before[o], 'C1'),
                            ('residual after', rec.outputs[o] - after[o], 'C2')):
        f, p = signal.welch(x, rec.fs_hz, nperseg=n)
        ax.semilogy(f[1:], np.sqrt(p[1:]), style, lw=1, label=label)
    ax.set_xlabel('frequency [Hz]')
    ax.set_ylabel('ASD [N/sqrt(Hz)]')
    ax.set_title(f'{rec.output_channels[o]}: where the residual lives')
    ax.legend(loc='best')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _regime_plot(plt, path, rec, o, before, finding, after=None):
    term = finding.terms[0] if finding.terms else None
    hp = term.highpass_hz if term else FeatureConfig().highpass_hz
    feats = motion_features(rec.inputs, rec.fs_hz, rec.input_quantity, FeatureConfig(hp or 0.2))
    channel = rec.output_channels[o]
    if term is not None and channel in term.channels:
        source = term.sources[term.channels.index(channel)]
    else:
        source = pairing(rec.output_channels, rec.input_channels, (rec,))[0][o]
    s = rec.input_channels.index(source)
    key, label = BY_NAME[finding.physics].plot
    if term is not None and term.response_taps and after is not None:
        # Inside the structure no motion state shows it (the force arrives through the
        # structure's response, with the FIR refitted around it): what the written model
        # adds to the reference is what the residual should follow, on the diagonal.
        key, label = 'added', 'written model minus reference [N]'
    state = {'level': rec.inputs[s], 'load': before[o],
             'added': None if after is None else after[o] - before[o]}.get(key)
    if state is None:
        state = feats[key][s]
    skip = min(rec.n_samples // 4, int(3.0 / (hp or 1.0) * rec.fs_hz)) if hp else 0
    x, r = state[skip:], (rec.outputs[o] - before[o])[skip:]
    r = r - r.mean()
    fig, ax = plt.subplots(figsize=(7, 5))
    step = max(1, x.size // 4000)
    ax.plot(x[::step], r[::step], '.', ms=2, alpha=0.4, color='0.5', label='residual')
    edges = np.quantile(x, np.linspace(0.0, 1.0, 26))
    idx = np.clip(np.searchsorted(edges, x, side='right') - 1, 0, 24)
    centres = [x[idx == i].mean() for i in range(25) if np.any(idx == i)]
    means = [r[idx == i].mean() for i in range(25) if np.any(idx == i)]
    ax.plot(centres, means, 'C3o-', ms=4, label='binned mean')
    ax.set_xlabel(label if key == 'added' else f'{source} {label}')
    ax.set_ylabel(f'{rec.output_channels[o]} residual [N]')
    ax.set_title(f'{finding.physics}: the regime that reveals it')
    ax.legend(loc='best')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_report(directory, result, real: Sequence, holdout: Sequence = ()) -> Path:
    """
    Write ``report.md`` and PNG plots into ``directory``; return the report path.

    Raises
    ------
    DiagnosisError
        When the directory cannot be written.

    """
    out = Path(directory)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise DiagnosisError(f'{out}: cannot create report directory: {err}') from err
    plt = _pyplot()
    rec = (list(holdout) or list(real))[0]
    before, after = _predictions(result, rec)
    channels = list(rec.output_channels)
    focus = [f.channels[0] for f in result.findings] or [result.mismatch[0].channel]
    images: List[str] = []
    for k, ch in enumerate(dict.fromkeys(focus)):
        o = channels.index(ch)
        windows = next((m.time_windows_s for m in result.mismatch if m.channel == ch), ())
        name = f'time_{k}_{_safe(ch)}.png'
        _time_plot(plt, out / name, rec, o, before, after, windows)
        images.append(name)
        name = f'asd_{k}_{_safe(ch)}.png'
        _asd_plot(plt, out / name, rec, o, before, after)
        images.append(name)
    for k, f in enumerate(result.findings):
        name = f'regime_{k}_{f.physics}.png'
        _regime_plot(plt, out / name, rec, channels.index(f.channels[0]), before, f, after)
        images.append(name)
    report = out / 'report.md'
    try:
        report.write_text(_markdown(result, rec, images))
    except OSError as err:
        raise DiagnosisError(f'{report}: cannot write report: {err}') from err
    return report


def _safe(name: str) -> str:
    return ''.join(c if c.isalnum() or c in '-_' else '_' for c in name)


def _markdown(result, rec, images) -> str:
    lines = ['# Sim-vs-real diagnosis', '', f'Reference: {result.reference}', '']
    lines += [f'- {s}' for s in result.summary] + ['']
    lines += ['## Mismatch', '', '| channel | RMSE % | bands [Hz] | time windows [s] | regime |',
              '|---|---|---|---|---|']
    for m in result.mismatch:
        bands = ', '.join(f'{a:.1f}-{b:.1f}' for a, b in m.bands_hz) or '-'
        wins = ', '.join(f'{a:.2f}-{b:.2f}' for a, b in m.time_windows_s) or '-'
        lines.append(f'| {m.channel} | {m.rmse_pct:.1f} | {bands} | {wins} | {m.regime} |')
    lines += ['', '## Findings', '']
    for f in result.findings:
        params = ', '.join(f'{k} = {v:.4g}' for k, v in f.parameters.items())
        lines += [f'### {f.physics} ({", ".join(f.channels)})', '',
                  f'{BY_NAME[f.physics].describe}. Parameters: {params}.', '', f.evidence, '']
    if not result.findings:
        lines += ['None beyond noise.', '']
    lines += ['', '## Not accepted', ''] + [f'- {r}' for r in result.rejected]
    fit = result.fit
    lin = fit.real_linear or {}
    lines += ['', f'## Fit ({fit.data}, {fit.metric}; written model: {fit.model or "none"})',
              '', '| channel | before % | real_linear % | after % |', '|---|---|---|---|']
    for ch, b in fit.before.items():
        lines.append(f'| {ch} | {b:.1f} | '
                     + (f'{lin[ch]:.1f}' if ch in lin else '-') + f' | {fit.after[ch]:.1f} |')
    lines += ['', f'Plots from {rec.name}:', ''] + [f'![{i}]({i})' for i in images]
    return '\n'.join(lines) + '\n'
