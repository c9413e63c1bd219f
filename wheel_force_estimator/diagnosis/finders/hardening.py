# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The pooled hardening finder: which kind of stiffening one car's axis shows.

Per-channel selection sees one corner at a time.  A symmetric hardening spring that shows on
one corner more than on the others can win there as a rebound or bump stop.  One car has one
spring law on all corners, so against a simulation the kinds compete on the pooled channels
of the axes where any hardening was named, with shared parameters (``run.pooled``: held-out
gain of one candidate fitted on several channels at once, :func:`selection.pooled_gain`).
When a kind no channel selected explains :data:`HARDENING_SWITCH` times what the best selected
kind explains there and beats its own time-shifted null (the acceptance rule of
:mod:`finders.acceptance` with that floor), :func:`find` names it on those channels, and it
supersedes the per-channel hardenings, its stand-ins on single corners
(:mod:`finders.reconcile`).

:func:`hardening_winner` is the same comparison for the ranking, among the kinds named.
"""
from dataclasses import replace
from typing import Callable, Optional, Sequence

from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import HARDENINGS
from wheel_force_estimator.diagnosis.finders.acceptance import rejection
from wheel_force_estimator.diagnosis.finders.per_channel import builder
from wheel_force_estimator.diagnosis.prepared import axis
from wheel_force_estimator.diagnosis.selection import pooled_selector

#: A hardening no channel selected replaces the ones selected when, pooled over their axis,
#: it explains this many times more than the best of them.
HARDENING_SWITCH = 1.3

Pooled = Callable[[Sequence[str], str], float]


def _scores(pooled: Pooled, group, names) -> dict:
    """Per kind: (best pooled gain over its motion and load forms, that key)."""
    return {n: max((pooled(group, k), k) for k in (n, f'{n}:load')) for n in names}


def _hardenings(findings) -> list:
    return [f for f in findings if f.physics in HARDENINGS and f.terms]


def hardening_winner(findings, pooled: Pooled) -> Optional[str]:
    """
    Return the hardening that best explains all channels where any was found.

    Only when two or more kinds were found: per-corner selections may call the same
    stiffening a cubic spring on three corners and a rebound stop on the fourth.
    """
    hard = _hardenings(findings)
    if len({f.physics for f in hard}) < 2:
        return None
    group = sorted({c for f in hard for c in f.channels})
    scores = _scores(pooled, group, {f.physics for f in hard})
    return max(scores, key=lambda n: scores[n][0])


def find(run, found) -> list:
    """
    Return a kind of hardening no channel selected, when it clearly fits the axis better.

    All kinds are fitted with shared parameters on every channel of the axes where a
    hardening was found (``found``: the findings so far).  Against a simulation only.
    """
    hard = _hardenings(found)
    if run.mode != 'sim' or not hard:
        return []
    axes = {axis(c) for f in hard for c in f.channels}
    group = [c for c in run.channels if axis(c) in axes]
    scores = _scores(run.pooled, group, HARDENINGS)
    named = {f.physics for f in hard}
    best_named = max(named, key=lambda n: scores[n][0])
    winner = max(HARDENINGS, key=lambda n: scores[n][0])
    gain, key = scores[winner]
    rules = run.config.selection
    floor = HARDENING_SWITCH * max(scores[best_named][0], 0.0)
    if winner in named or rejection(rules, gain, min_gain=floor) is not None:
        return []
    selector = pooled_selector(run.prep, run.sim_prep, run.channels, group, run.config)
    null = max(selector.null_gains(BY_KEY[key]))
    if rejection(rules, gain, null, min_gain=floor) is not None:
        return []
    shape, gain, coef, _ = selector.fit_single(BY_KEY[key])
    finding = builder(run).pooled_finding(key, group, shape, coef, gain, null)
    return [replace(finding, evidence=finding.evidence + (
        f'; fitted with shared parameters on {text.channel_list(group)} it explains '
        f'{gain:.1%} of the held-out residual, {best_named.replace("_", " ")} (selected per '
        f'channel) {scores[best_named][0]:.1%}'))]
