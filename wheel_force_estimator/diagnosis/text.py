# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Plain-language sentences for findings, rejections and the summary."""
from typing import Dict, List, Mapping, Sequence

from wheel_force_estimator.diagnosis.hypotheses import describe_shape
from wheel_force_estimator.diagnosis.hypotheses import Hypothesis


def channel_list(channels: Sequence[str]) -> str:
    """``['lf_fz', 'rf_fz']`` -> ``'LF/RF Fz'`` (vehicle names), else comma-joined."""
    parts = [c.rpartition('_f') for c in channels]
    if all(sep and len(axis) == 1 for _, sep, axis in parts) and \
            len({axis for _, _, axis in parts}) == 1:
        return '/'.join(p[0].upper() for p in parts) + f' F{parts[0][2]}'
    return ', '.join(channels)


def evidence(hyp: Hypothesis, channels: Sequence[str], params: Mapping[str, float],
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
    if fit.linear_real is not None and findings:
        beaten = [c for f in findings for c in f.channels
                  if c in fit.after and fit.after[c] < fit.linear_real[c]]
        lines.append(f'Augmented model vs best linear FRF fitted on the real data: better on '
                     f'{len(set(beaten))} of {len({c for f in findings for c in f.channels})} '
                     f'affected channels {where}.')
    if fit.augmented_real is not None and fit.linear_real is not None and findings:
        affected = {c for f in findings if f.terms for c in f.channels}
        beaten = [c for c in affected if fit.augmented_real[c] < fit.linear_real[c]]
        if affected:
            lines.append(f'Best linear FRF fitted on the real data plus the named physics '
                         f'(fitted jointly) vs that FRF alone: better on '
                         f'{len(beaten)} of {len(affected)} modelled channels {where}.')
    return lines
