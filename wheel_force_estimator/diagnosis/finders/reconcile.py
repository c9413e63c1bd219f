# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
How the finders' findings combine: the two rules, in one place.

**Later finders supersede.**  The finders run in the order of :data:`pipeline.FINDERS`
(per channel, agreement, inside the structure, structural, pooled hardening), each seeing the
findings so far.  A later finder tests an effect on more evidence than an earlier one (across
all corners, or pooled over an axis), so its finding replaces what the earlier finders named
of the same effect on its channels (:func:`supersedes`): the same physics on any shared
channel (a roll bar named per channel and across the axle would be modelled twice), or, for
a wrong spring rate or a kind of hardening fitted on a whole axis, any hardening on channels
within its own (a per-corner hardening is its stand-in on a single corner).  Earlier findings
stay in their order; the new ones follow in theirs.

**Motion findings are reported once per physics.**  The motion finder reads the recordings,
not the residual, and its findings carry no terms, so they take no part in the ranking or
the choice of model (only their channels do).  At the report they come first; where the
residual finders named the same physics, that finding (with its term and held-out figures)
stands for both, with the motion finding's evidence and time windows (:func:`merge_motion`).
"""
from dataclasses import replace
from typing import List, Sequence

from wheel_force_estimator.diagnosis.candidates import HARDENINGS
from wheel_force_estimator.diagnosis.result import Finding


def supersedes(new: Finding, old: Finding) -> bool:
    """Return True when ``new`` (a later finder's) names the effect ``old`` names."""
    if new.physics == old.physics and set(new.channels) & set(old.channels):
        return True
    return (old.physics in HARDENINGS and new.physics in HARDENINGS + ('stiffness_error',)
            and set(old.channels) <= set(new.channels))


def reconcile(found: Sequence[Finding], new: Sequence[Finding]) -> List[Finding]:
    """Return ``found`` without what ``new`` supersedes, followed by ``new``."""
    return [f for f in found if not any(supersedes(n, f) for n in new)] + list(new)


def merge_motion(findings: Sequence[Finding], motion: Sequence[Finding]) -> List[Finding]:
    """
    Put motion findings first; one already named by the residual ranking keeps its term.

    A physics named both ways stays one finding: the ranked one (with its term and holdout
    figures), given the motion finding's time windows and evidence.
    """
    out = list(findings)
    first = []
    for m in motion:
        same = [k for k, f in enumerate(out) if f.physics == m.physics]
        if same:
            k = same[0]
            out[k] = replace(out[k], evidence=out[k].evidence + ' | ' + m.evidence,
                             time_windows_s=m.time_windows_s)
        else:
            first.append(m)
    return first + out
