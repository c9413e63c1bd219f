# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The agreement finder: effects too weak to name on any one corner, named when corners agree.

Per-channel selection (:mod:`diagnosis.selection`) asks a term to explain ``min_gain`` of one
channel's residual.  A small clearance present in every hub bushing explains a few percent on
each corner and is named on none.  When the same candidate ranks first on at least
``min_votes`` channels of one force axis where nothing was accepted, it is fitted once with
shared parameters over those channels and accepted when the pooled term passes the same tests
as a per-channel one (held-out gain over its time-shifted null, RMSE drop, linear-rate
tolerance) with the lower ``min_gain`` of :class:`AgreementConfig`: agreement of independent
corners is evidence one channel cannot give.  The holdout gate still judges the finding.

Against a simulation or a given model only (:func:`find`); the channels it names had nothing
accepted, so its findings never overlap the per-channel ones.
"""
from dataclasses import dataclass
from dataclasses import replace
from typing import Dict, List

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.finders.per_channel import builder
from wheel_force_estimator.diagnosis.prepared import axis
from wheel_force_estimator.diagnosis.selection import pooled_selector


@dataclass(frozen=True)
class AgreementConfig:
    """
    When corners that agree name an effect none of them could name alone.

    Attributes
    ----------
    min_votes : int
        Channels of one axis whose best candidate must be the same (0 = pass off).
    min_gain : float
        Smallest fraction of the pooled residual the shared term must explain on held-out
        blocks (the per-channel rule asks ``SelectionConfig.min_gain``).

    """

    min_votes: int = 2
    min_gain: float = 0.03

    def __post_init__(self):
        if self.min_votes == 1 or self.min_votes < 0 or not 0.0 < self.min_gain < 1.0:
            raise ConfigError('min_votes must be 0 or >= 2 and min_gain in (0, 1)')


def votes(outcomes, channels) -> Dict[tuple, List[str]]:
    """Channels without an accepted term, grouped by (axis, best candidate key)."""
    grouped: Dict[tuple, List[str]] = {}
    for c in channels:
        outcome = outcomes[c]
        if outcome.accepted or not outcome.ranking or not outcome.ranking[0].gain > 0.0:
            continue
        grouped.setdefault((axis(c), outcome.ranking[0].hypothesis.key), []).append(c)
    return grouped


def agreed_findings(outcomes, channels, prep, sim_prep, builder, config,
                    agreement: AgreementConfig) -> list:
    """
    Return findings of candidates that rank first on ``min_votes`` channels of an axis.

    Parameters
    ----------
    outcomes : dict
        Per-channel :class:`selection.Outcome`.
    channels : sequence of str
        Output channels.
    prep, sim_prep : Prepared
        Real (and simulated, or None) records of :mod:`diagnosis.prepared`.
    builder : object
        Has ``pooled_finding(key, group, shape, coef, gain, null)`` (the run's finding maker).
    config : DiagnosisConfig
        Its ``selection`` rules are used with ``agreement.min_gain``.
    agreement : AgreementConfig
        Votes and pooled gain required.

    """
    if agreement.min_votes == 0:
        return []
    rules = replace(config, selection=replace(config.selection, min_gain=agreement.min_gain,
                                              max_terms=1))
    found = []
    channels = list(channels)
    for (_, key), group in votes(outcomes, channels).items():
        if len(group) < agreement.min_votes:
            continue
        outcome = pooled_selector(prep, sim_prep, channels, group, rules).run([BY_KEY[key]])
        if outcome.accepted:
            a = outcome.accepted[0]
            found.append(builder.pooled_finding(key, group, a.shape, a.coefficient, a.gain,
                                                max(a.null_gains)))
    return found


def find(run, found=()) -> list:
    """Return the agreed findings of the run (not against a fit on the real data itself)."""
    if run.mode == 'linear':
        return []
    return agreed_findings(run.outcomes, run.channels, run.prep, run.sim_prep, builder(run),
                           run.config, run.config.agreement)
