# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The per-channel finder: every candidate channel by channel, shared parameters per axis.

:func:`select` runs the greedy cross-validated selection (:class:`selection.Selector`) on
each output channel against its time-shifted-feature null, with the acceptance rule of
:mod:`finders.acceptance`; with coherence pairing the selection also chooses each output's
source input (:mod:`diagnosis.sources`).  :func:`find` turns the accepted candidates into
findings: one candidate accepted on several channels of an axis is refitted with shared
parameters over the axis, then per axle, then per channel, the widest grouping that keeps
``merge_ratio`` of what the single-channel fits removed (:class:`Builder`).  A linear law
fitted on the real data itself carries refitted linear companions, attached to each channel's
first finding.
"""
from dataclasses import replace
from typing import Dict, List, Sequence

from wheel_force_estimator import AXLES
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.candidates import HYPOTHESES
from wheel_force_estimator.diagnosis.candidates import term_parameters
from wheel_force_estimator.diagnosis.features import paired_by_coherence
from wheel_force_estimator.diagnosis.locate import regime_ratios
from wheel_force_estimator.diagnosis.prepared import axis
from wheel_force_estimator.diagnosis.prepared import group_pieces
from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.diagnosis.selection import Selector
from wheel_force_estimator.diagnosis.sources import sources_by_selection


def candidates(run) -> list:
    """Return the candidates the selection tries."""
    skip_names = {h.physics for h in run.companions}
    # Without --sim/--model the reference is the MIMO FIR fitted on these very records: a
    # delay, a rate or a left-right coupling of the motion lies in its span, so what such a
    # candidate "explains" is the FIR's estimation error (measured: a delay explained 51 % of
    # a linear sine rig's residual), not missing physics.
    return [h for h in HYPOTHESES if h.physics not in skip_names
            and not (run.mode == 'linear' and h.lti)]


def select(run) -> None:
    """
    Run the per-channel selection into ``run.outcomes``; with coherence pairing, pair by it.

    The selection's choice of sources re-prepares the run (``run.prepare``) when it differs
    from the coherence pairing.
    """
    tried = candidates(run)
    for o, ch in enumerate(run.channels):
        sim_pieces = pieces(run.sim_prep, o, ch) if run.sim_prep else None
        run.outcomes[ch] = Selector(pieces(run.prep, o, ch), run.config.selection,
                                    run.companions, sim_pieces).run(tried)
    if paired_by_coherence(run.channels, run.real[0].input_channels):
        chosen = sources_by_selection(run.prep, run.sim_prep, run.reference, run.sources,
                                      run.outcomes, run.config, run.companions, tried)
        if chosen != run.sources:
            run.prepare(chosen)


def find(run, found=()) -> List[Finding]:
    """Return the findings of the candidates :func:`select` accepted (``found`` unused)."""
    return builder(run).findings()


def builder(run) -> 'Builder':
    """Return the run's finding maker."""
    return Builder(run.prep, run.outcomes, run.channels, run.sources, run.partners,
                   run.config, run.companions, run.sim_prep)


def _contribution(hyp, shape, coef, ctx):
    return coef * hyp.basis(ctx, shape)


def _groups(channels: Sequence[str]) -> List[List[List[str]]]:
    """Ways to share parameters, widest first: all channels of an axis, axles, singles."""
    options = [[list(channels)]]
    front = [c for c in channels if c[:2] in AXLES[0]]
    rear = [c for c in channels if c[:2] in AXLES[1]]
    if front and rear and len(front) + len(rear) == len(channels):
        options.append([front, rear])
    if len(channels) > 1:
        options.append([[c] for c in channels])
    return options


class Builder:
    """Turns per-channel selections into findings with shared parameters and model terms."""

    def __init__(self, prep, outcomes, channels, sources, partners, config, companions,
                 sim_prep=None):
        self.prep, self.outcomes, self.channels = prep, outcomes, channels
        self.sim_prep = sim_prep
        self.sources, self.partners = sources, partners
        self.config, self.companions = config, companions
        rec0 = prep.recordings[0]
        self.fs_hz, self.quantity = rec0.fs_hz, rec0.input_quantity
        self.hp, self.lp = config.features.resolved(self.fs_hz, self.quantity)

    def _cleaned_pieces(self, channel, key):
        """Pieces of ``channel`` with its other accepted terms and companions removed."""
        o = self.channels.index(channel)
        outcome = self.outcomes[channel]
        cleaned = pieces(self.prep, o, channel)
        for p in cleaned:
            for a in outcome.accepted:
                if a.hypothesis.key != key:
                    p.residual = p.residual - _contribution(a.hypothesis, a.shape,
                                                            a.coefficient, p.ctx)
            for name, coef in outcome.companions.items():
                p.residual = p.residual - _contribution(BY_NAME[name], {}, coef, p.ctx)
        return cleaned

    def _shared(self, key, group):
        """Pooled fit over ``group``: (shape, gain, coefficient, sse drop)."""
        real = [p for c in group for p in self._cleaned_pieces(c, key)]
        sim_pieces = (None if self.sim_prep is None
                      else group_pieces(self.sim_prep, self.channels, group))
        sel = Selector(real, self.config.selection, (), sim_pieces)
        shape, gain, coef, base = sel.fit_single(BY_KEY[key])
        return shape, gain, coef, gain * base

    def findings(self) -> List[Finding]:
        """Return one finding per accepted candidate and channel group, priority first."""
        by_key: Dict[str, List[str]] = {}
        for ch in self.channels:
            for a in self.outcomes[ch].accepted:
                by_key.setdefault(a.hypothesis.key, []).append(ch)
        found = []
        for key, chans in by_key.items():
            axes: Dict[str, List[str]] = {}
            for c in chans:
                axes.setdefault(axis(c), []).append(c)
            for group in axes.values():
                found.extend(self._group_findings(key, group))
        found.sort(key=lambda f: (not BY_NAME[f.physics].priority, -f.explained_fraction))
        return self._with_companions(found)

    def _accepted(self, channel, key):
        return next(a for a in self.outcomes[channel].accepted if a.hypothesis.key == key)

    def _group_findings(self, key, group) -> List[Finding]:
        singles = {c: self._accepted(c, key) for c in group}
        for option in _groups(group):
            if all(len(g) == 1 for g in option):
                return [self._finding(key, [c], a.shape, a.coefficient, a.gain,
                                      max(a.null_gains)) for c, a in singles.items()]
            shared = [self._shared(key, g) for g in option]
            ok = all(drop >= self.config.merge_ratio * sum(
                singles[c].gain * singles[c].sse_before for c in g)
                for g, (_, _, _, drop) in zip(option, shared))
            if ok:
                return [self._finding(key, g, shape, coef, gain,
                                      max(max(singles[c].null_gains) for c in g))
                        for g, (shape, gain, coef, _) in zip(option, shared)]
        return []

    def pooled_finding(self, key, group, shape, coef, gain, null) -> Finding:
        """Return a finding of ``key`` fitted with shared parameters on ``group``."""
        return self._finding(key, list(group), shape, coef, gain, null)

    def _finding(self, key, group, shape, coef, gain, null) -> Finding:
        hyp = BY_KEY[key]
        physics = hyp.physics
        params = term_parameters(hyp, shape, coef, self.fs_hz)
        idx = [self.channels.index(c) for c in group]
        causal = not (physics == 'time_delay' and params['delay_s'] < 0.0)
        terms = ()
        if causal:
            terms = (PhysicsTerm(
                physics=physics, channels=tuple(group), parameters=params,
                sources=tuple(self.sources[i] for i in idx),
                partners=tuple(self.partners[i] for i in idx) if physics == 'anti_roll_bar'
                else (), input_quantity=self.quantity, highpass_hz=self.hp,
                lowpass_hz=self.lp, state=hyp.state,
                state_lowpass_hz=shape.get('state_lowpass_hz', 0.0)),)
        ratios = {}
        for c in group:
            o = self.channels.index(c)
            residuals = [p.residual for p in pieces(self.prep, o, c)]
            ratios[c] = dict(regime_ratios(residuals, [ctx[o] for ctx in self.prep.contexts]))
        evidence = text.evidence(hyp, group, params, gain, null, ratios, causal)
        return Finding(physics, tuple(group), params, gain, evidence, terms, null)

    def _with_companions(self, found: List[Finding]) -> List[Finding]:
        """Attach each channel's refitted linear companions to its first finding."""
        if not self.companions:
            return found
        done = set()
        out = []
        for f in found:
            extra = []
            for c in f.channels:
                if c in done:
                    continue
                done.add(c)
                i = self.channels.index(c)
                for name, coef in self.outcomes[c].companions.items():
                    params = BY_NAME[name].parameters({}, coef)
                    extra.append(PhysicsTerm(name, (c,), params, sources=(self.sources[i],),
                                             input_quantity=self.quantity,
                                             highpass_hz=self.hp, lowpass_hz=self.lp))
            out.append(replace(f, terms=f.terms + tuple(extra)))
        return out
