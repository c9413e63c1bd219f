# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Plain-language sentences for findings, rejections and the summary."""
from typing import Dict, List, Mapping, Sequence

from wheel_force_estimator.diagnosis.candidates import Candidate
from wheel_force_estimator.diagnosis.candidates import describe_shape


def channel_list(channels: Sequence[str]) -> str:
    """``['lf_fz', 'rf_fz']`` -> ``'LF/RF Fz'`` (vehicle names), else comma-joined."""
    parts = [c.rpartition('_f') for c in channels]
    if all(sep and len(axis) == 1 for _, sep, axis in parts) and \
            len({axis for _, _, axis in parts}) == 1:
        return '/'.join(p[0].upper() for p in parts) + f' F{parts[0][2]}'
    return ', '.join(channels)


def evidence(hyp: Candidate, channels: Sequence[str], params: Mapping[str, float],
             gain: float, null: float, ratios: Mapping[str, Dict[str, float]],
             causal: bool) -> str:
    """One paragraph: what, shape, strength on held-out data, null, where it shows."""
    text = (f'{channel_list(channels)}: {hyp.describe}; {describe_shape(hyp.physics, params)}. '
            f'Explains {gain:.0%} of the residual on held-out time blocks; the same candidate '
            f'on time-shifted features explains at most {max(null, 0.0):.1%}.')
    shows = [f'{c} {r[hyp.regime]:.1f}x' for c, r in ratios.items() if hyp.regime in r]
    if shows:
        text += f' Residual RMS in "{hyp.regime}" relative to its average: {", ".join(shows)}.'
    if not causal:
        text += (' The force leads the acceleration, which a causal stage cannot apply: '
                 'shift the force stamps instead (not added to the model).')
    return text


def rejection(channel: str, rejected) -> str:
    """Why the best remaining candidate of a channel was not accepted."""
    choice, nulls, reason = rejected
    return f'{channel}: best remaining candidate {choice.hypothesis.physics} {reason}'


def summary(findings, fit, rejected: Sequence[str]) -> List[str]:
    """Plain-language lines, one per finding, or why nothing was found."""
    lines = []
    where = 'on holdout' if fit.data == 'holdout' else 'on held-out blocks'
    for f in findings:
        after = f.rmse_after_pct or fit.after
        rmse = ', '.join(f'{c} {fit.before[c]:.1f} % -> {after[c]:.1f} %'
                         for c in f.channels if c in fit.before)
        hyp_text = f.evidence.split(';')[0].split(': ', 1)[-1]
        lines.append(f'{channel_list(f.channels)}: {hyp_text}, '
                     f'{describe_shape(f.physics, f.parameters)}; explains '
                     f'{f.explained_fraction:.0%} of the residual; RMSE {rmse} {where}')
    if not findings:
        lines.append('No physics beyond noise found: no candidate explains enough of the '
                     'residual on held-out data, and clearly more than it does on unrelated '
                     '(time-shifted) features, beyond the tolerance of a linear rate (see '
                     '"rejected").')
    if fit.model:
        lines.append(f'Written model: {fit.model}' + (
            ' (chosen on the gate half of the holdout; mean RMSE over the named channels: '
            + ', '.join(f'{k} {v:.2f} %' for k, v in fit.gate.items()) + ')'
            if fit.gate else '') + '.')
        if fit.rows_from:
            by_source: dict = {}
            for c, n in fit.rows_from.items():
                by_source.setdefault(n, []).append(c)
            on = ('the gate half of the holdout' if fit.data == 'holdout'
                  else 'held-out blocks of the training recordings')
            lines.append(f'Rows of the written model, chosen per group of channels on {on} '
                         "(a term's channels together; a wheel force component's corners "
                         'without a term together): ' + '; '.join(
                             f'{n} for {channel_list(cs)}' for n, cs in by_source.items())
                         + '.')
    if fit.real_linear is not None and findings:
        affected = sorted({c for f in findings if f.terms for c in f.channels})
        beaten = [c for c in affected if fit.after[c] < fit.real_linear[c]]
        if affected:
            lines.append(f'Written model vs the best linear model fitted on the real data '
                         f'(a plain `wheel-force fit`): better on {len(beaten)} of '
                         f'{len(affected)} modelled channels {where}.')
    if fit.report_on:
        lines.append('Reported figures = `wheel-force evaluate` of each model on: '
                     + ', '.join(fit.report_on) + f' ({fit.metric}).')
    lines.extend(fit.notes)
    return lines
