# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Which stiffening explains the vertical residual: a kind of hardening, or a linear rate error.

Per-channel selection sees one corner at a time.  A symmetric hardening spring that shows on
one corner more than on the others can win there as a rebound or bump stop, and a wrong spring
rate looks like a hardening whose load is always large.  One car has one spring law on all
corners, so the kinds compete on the pooled channels of an axis with shared parameters
(:func:`pooled_gain`: held-out gain of one candidate fitted on several channels at once).
"""
from dataclasses import replace
from typing import Callable, List, Optional, Sequence, Tuple

from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import HARDENINGS
from wheel_force_estimator.diagnosis.candidates import LINEAR_COMPANIONS
from wheel_force_estimator.diagnosis.candidates import STIFFENING
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.omissions import linear_omissions
from wheel_force_estimator.diagnosis.prepared import axis
from wheel_force_estimator.diagnosis.prepared import group_pieces
from wheel_force_estimator.diagnosis.selection import Selector

#: A linear spring-rate error must explain this many times what the best hardening explains.
LINEAR_OVER_HARDENING = 1.3
#: A hardening no channel selected replaces the ones selected when, pooled over their axis,
#: it explains this many times more than the best of them.
HARDENING_SWITCH = 1.3

Pooled = Callable[[Sequence[str], str], float]


def pooled_selector(prep, sim_prep, channels, group, config) -> Selector:
    """Return a :class:`Selector` over the pieces of every channel in ``group``."""
    sim = None if sim_prep is None else group_pieces(sim_prep, channels, group)
    return Selector(group_pieces(prep, channels, group), config.selection, (), sim)


def pooled_gain(prep, sim_prep, channels, group, key, config) -> float:
    """Held-out gain of one candidate fitted with shared parameters over ``group``."""
    return pooled_selector(prep, sim_prep, channels, group, config).fit_single(BY_KEY[key])[1]


def _scores(pooled: Pooled, group, names) -> dict:
    """Per kind: (best pooled gain over its motion and load forms, that key)."""
    return {n: max((pooled(group, k), k) for k in (n, f'{n}:load')) for n in names}


def hardening_winner(findings, pooled: Pooled) -> Optional[str]:
    """
    Return the hardening that best explains all channels where any was found.

    Only when two or more kinds were found: per-corner selections may call the same
    stiffening a cubic spring on three corners and a rebound stop on the fourth.
    """
    hard = [f for f in findings if f.physics in HARDENINGS and f.terms]
    if len({f.physics for f in hard}) < 2:
        return None
    group = sorted({c for f in hard for c in f.channels})
    scores = _scores(pooled, group, {f.physics for f in hard})
    return max(scores, key=lambda n: scores[n][0])


def settle_hardening(findings, builder, prep, sim_prep, channels, config,
                     pooled: Pooled) -> List:
    """
    Replace per-channel hardenings by a kind no channel selected when it clearly fits better.

    All kinds are fitted with shared parameters on every channel of the axes where a
    hardening was found.  When the best of them was not selected anywhere, explains
    :data:`HARDENING_SWITCH` times what the best selected kind explains and beats its own
    time-shifted null by the selection's ``null_factor``, it becomes one finding on those
    channels and the selected hardenings (its stand-ins on single corners) are dropped.
    ``pooled(group, key)`` is :func:`pooled_gain` on these records (memoised by the caller).
    """
    hard = [f for f in findings if f.physics in HARDENINGS and f.terms]
    if not hard:
        return findings
    axes = {axis(c) for f in hard for c in f.channels}
    group = [c for c in channels if axis(c) in axes]
    scores = _scores(pooled, group, HARDENINGS)
    found = {f.physics for f in hard}
    best_found = max(found, key=lambda n: scores[n][0])
    winner = max(HARDENINGS, key=lambda n: scores[n][0])
    gain, key = scores[winner]
    if winner in found or gain < HARDENING_SWITCH * max(scores[best_found][0], 0.0):
        return findings
    selector = pooled_selector(prep, sim_prep, channels, group, config)
    null = max(selector.null_gains(BY_KEY[key]))
    if gain <= config.selection.null_factor * max(null, 0.0):
        return findings
    shape, gain, coef, _ = selector.fit_single(BY_KEY[key])
    finding = builder.pooled_finding(key, group, shape, coef, gain, null)
    finding = replace(finding, evidence=finding.evidence + (
        f'; fitted with shared parameters on {text.channel_list(group)} it explains '
        f'{gain:.1%} of the held-out residual, {best_found.replace("_", " ")} (selected per '
        f'channel) {scores[best_found][0]:.1%}'))
    return [f for f in findings if f not in hard] + [finding]


def add_omissions(findings, real, sim, reference, channels, sources, config,
                  pooled: Pooled) -> Tuple[List, List]:
    """
    Return ``(findings, omissions)``: a wrong sprung mass / spring rate found by :mod:`omissions`.

    A spring-rate error and a hardening both make the real FRF look stiffer; the linear one is
    named only when a load-proportional term explains clearly more of the pooled vertical
    residual than the best hardening candidate (or physics found on those channels), and then
    replaces the hardening findings of those channels (they were its linearisation).
    ``pooled(group, key)`` is :func:`pooled_gain` on the real / sim records (memoised).
    """
    rec0 = real[0]
    skip = settle_samples(rec0.fs_hz, rec0.input_quantity, config.features)
    filters = config.features.resolved(rec0.fs_hz, rec0.input_quantity)
    hp = config.selection.highpass_hz
    extra = linear_omissions(real, sim, reference, channels, skip, hp, sources,
                             rec0.input_quantity, filters, config.omissions)
    kept = []
    for f in extra:
        if f.physics == 'stiffness_error':
            group = list(f.channels)
            linear = pooled(group, 'stiffness_error:load')
            # Any per-channel physics found on these channels competes too (a friction
            # also adds body-band force in phase with the load).
            rivals = set(STIFFENING) | {
                t.key
                for g in findings for t in g.terms
                if t.physics not in LINEAR_COMPANIONS and set(t.channels) & set(group)}
            hardening = max(pooled(group, k) for k in sorted(rivals & set(BY_KEY)))
            if linear < LINEAR_OVER_HARDENING * max(hardening, 0.0):
                continue
            f = replace(f, evidence=f.evidence + (
                f'; pooled over these channels it explains {linear:.1%} of the held-out '
                f'residual, the best hardening candidate {hardening:.1%}'),
                explained_fraction=linear, null_fraction=max(hardening, 0.0))
            findings = [g for g in findings if not (
                g.physics in HARDENINGS and set(g.channels) <= set(group))]
        kept.append(f)
    return findings, kept
