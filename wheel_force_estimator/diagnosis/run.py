# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The diagnosis's settings and the helpers its stages use (:mod:`diagnosis.pipeline`).

- :class:`DiagnosisConfig`: every setting of a diagnosis;
- :func:`reference_of`, :func:`real_linear_fit`: the reference and the one real-data linear fit
  of the run (``fit``'s design);
- :func:`coupling_finding`: the left-right coupling test, like with like;
- :class:`Builder`: per-channel findings with shared parameters per axis;
- :func:`ranked`: the ranking of the findings.

The stages themselves run in :func:`diagnosis.pipeline.diagnose_once`.
"""
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
from typing import Dict, List, Optional, Sequence

import numpy as np

from wheel_force_estimator import AXLES
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.agreement import AgreementConfig
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.candidates import HARDENINGS
from wheel_force_estimator.diagnosis.candidates import LINEAR_COMPANIONS
from wheel_force_estimator.diagnosis.candidates import term_parameters
from wheel_force_estimator.diagnosis.coupling import CouplingConfig
from wheel_force_estimator.diagnosis.coupling import left_right_coupling
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.features import motion_features
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.hardening import hardening_winner
from wheel_force_estimator.diagnosis.locate import regime_ratios
from wheel_force_estimator.diagnosis.motion import MotionConfig
from wheel_force_estimator.diagnosis.omissions import OmissionConfig
from wheel_force_estimator.diagnosis.prepared import axis
from wheel_force_estimator.diagnosis.prepared import group_pieces
from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.recording import check_compatible
from wheel_force_estimator.diagnosis.reference import FrfReference
from wheel_force_estimator.diagnosis.reference import RegressionReference
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.diagnosis.selection import SelectionConfig
from wheel_force_estimator.diagnosis.selection import Selector


@dataclass(frozen=True)
class DiagnosisConfig:
    """
    Settings of a diagnosis.

    Attributes
    ----------
    features : FeatureConfig
        Feature filter corners (stored in the fitted terms).
    selection : SelectionConfig
        Cross-validation and acceptance rules.
    linear : str
        Reference fitted on simulation recordings: ``'frf'`` (the product's MIMO FRF),
        ``'regression'`` (per-channel ``F0 + k x + c v + m a``) or ``'auto'`` (FRF for
        acceleration inputs).
    fit : object
        ``core.pipeline.FitConfig`` for FRF fits.  None: the design ``wheel-force fit`` uses
        without a params file (:func:`core.design.product_fit_config`), for the simulation's
        FRF and every fit on the real data alike: what ``wheel-force diagnose`` runs, so a
        benchmark of the library measures the diagnosis users get.
    fit_fallback : bool
        Real-data fits may fall back to one resolution for records shorter than the long
        Welch segment, as ``wheel-force fit`` does for generic recordings (the CLI passes
        False for bags and when the long segment was chosen explicitly).
    long_window_fallback : bool or None
        Real-data fits may fall back to one resolution when the records hold no more windows
        of the long segment than inputs, as ``wheel-force fit`` does for bags and generic
        recordings (the CLI passes False when the long segment was chosen explicitly);
        None = as ``fit_fallback``.
    segment_fallback : bool
        Real-data fits may shorten the Welch segment when the records hold no more windows
        than inputs, as ``wheel-force fit`` does for generic recordings (the CLI passes False
        for bags and when the segment length was chosen explicitly).
    choose_resolution : bool
        Real-data fits choose their Welch segment by blocked cross-validation
        (:mod:`core.resolution`), as ``wheel-force fit`` does for generic recordings whose
        segment length was not chosen (the CLI passes True for those; off by default here,
        where a car's 12 x 12 records would pay for it on every refit).
    merge_ratio : float
        A physics found on several channels becomes one shared-parameter finding when the
        shared fit removes at least this fraction of what the per-channel fits remove.
    range_ratio : float
        Largest ratio of real to simulated input RMS (per channel) still called overlapping.
    residual_highpass_hz : float or None
        Zero-phase high-pass of residuals before locating, fitting and scoring (the paper's
        1 Hz RMSE for road events); None = 1 Hz for an FRF reference (which cannot follow
        quasi-static load transfer), none for a linear-law reference.
    agreement : AgreementConfig
        When the corners of an axis that agree on a candidate name it together
        (:mod:`diagnosis.agreement`; against a simulation or a model only).
    progress : bool
        Show a tqdm bar on stderr, when it is a terminal, for the search over inputs
        (:mod:`diagnosis.sources`; minutes for a dozen unnamed inputs).
    motion, coupling, omissions : MotionConfig, CouplingConfig, OmissionConfig
        Settings of the motion findings (clip, tyre lift-off), the left-right coupling test
        and the linear-omission search.

    """

    features: FeatureConfig = field(default_factory=FeatureConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    linear: str = 'auto'
    fit: object = None
    fit_fallback: bool = True
    long_window_fallback: Optional[bool] = None
    segment_fallback: bool = True
    choose_resolution: bool = False
    merge_ratio: float = 0.85
    range_ratio: float = 10.0
    residual_highpass_hz: Optional[float] = None
    agreement: AgreementConfig = field(default_factory=AgreementConfig)
    progress: bool = False
    motion: MotionConfig = field(default_factory=MotionConfig)
    coupling: CouplingConfig = field(default_factory=CouplingConfig)
    omissions: OmissionConfig = field(default_factory=OmissionConfig)

    def __post_init__(self):
        if self.linear not in ('auto', 'frf', 'regression'):
            raise ConfigError(f'linear must be auto, frf or regression, got {self.linear!r}')
        if not 0.0 < self.merge_ratio <= 1.0 or not self.range_ratio > 1.0:
            raise ConfigError('merge_ratio must be in (0, 1] and range_ratio > 1')


def fit_linear(recordings, config, name, rec0):
    """Fit the linear reference on simulation recordings (``config.linear``)."""
    kind = config.linear
    if kind == 'auto':
        kind = 'frf' if rec0.input_quantity == 'acceleration' else 'regression'
    if kind == 'frf':
        return FrfReference.fit(recordings, name, config.fit)
    return RegressionReference.fit(recordings, config.features, name)


def real_linear_fit(recordings, config, name='real'):
    """
    Fit the best linear dynamic model on real recordings: ``wheel-force fit``'s design.

    Each output's design chosen by blocked cross-validation as ``fit`` chooses it, so
    ``fit.real_linear`` is what ``evaluate`` gives for the model ``fit`` writes; the held-out
    blocks and the joint fits with terms refit that design (:meth:`FrfReference.refit`).
    """
    return FrfReference.fit(recordings, name, config.fit, config.fit_fallback,
                            config.segment_fallback, config.choose_resolution,
                            config.long_window_fallback, cross_validate=True,
                            progress=config.progress)


def coupling_finding(real, reference, channels, config, hp):
    """
    Return the left-right coupling finding (anti-roll bar), or None.

    The comparison is like with like: the real records fitted with the simulation FRF's own
    design (not the design ``fit``'s search chooses for the real car), so the two FRFs
    differ by the data alone.  Real records too short for that design: no coupling test.
    """
    try:
        real_frf = FrfReference(reference.refit(real), 'real (simulation design)')
    except DiagnosisError:
        return None
    rec0 = real[0]
    return left_right_coupling(real, reference, real_frf, channels,
                               settle_samples(rec0.fs_hz, rec0.input_quantity,
                                              config.features), hp, config.coupling)


def reference_of(real, sim_or_model, config):
    """Return ``(reference, companions, mode, sim recordings)``."""
    from wheel_force_estimator.core.model import FrfModel
    if sim_or_model is None:
        return (real_linear_fit(real, config, 'real (linear fit)'),
                tuple(BY_NAME[n] for n in LINEAR_COMPANIONS), 'linear', ())
    if isinstance(sim_or_model, (FrfReference, RegressionReference)):
        return sim_or_model, (), 'model', ()
    if isinstance(sim_or_model, FrfModel):
        return FrfReference(sim_or_model, 'model'), (), 'model', ()
    rec0 = real[0]
    sim = tuple(sim_or_model)
    check_compatible(sim, 'sim')
    check_compatible((rec0,) + sim, 'real and sim')
    _check_overlap(real, sim, config)
    return fit_linear(sim, config, 'sim', rec0), (), 'sim', sim


def _check_overlap(real, sim, config):
    """Refuse a simulation whose operating range does not overlap the real one."""
    def stats(recs):
        rms, lo, hi = [], [], []
        for rec in recs:
            acc = motion_features(rec.inputs, rec.fs_hz, rec.input_quantity,
                                  config.features)['acceleration']
            rms.append(np.sqrt(np.mean(acc ** 2, axis=1)))
            lo.append(rec.inputs.min(axis=1))
            hi.append(rec.inputs.max(axis=1))
        return np.mean(rms, axis=0), np.min(lo, axis=0), np.max(hi, axis=0)
    r_rms, r_lo, r_hi = stats(real)
    s_rms, s_lo, s_hi = stats(sim)
    for i, name in enumerate(real[0].input_channels):
        ratio = max(r_rms[i], s_rms[i]) / max(min(r_rms[i], s_rms[i]), 1e-300)
        if ratio > config.range_ratio or r_hi[i] < s_lo[i] or s_hi[i] < r_lo[i]:
            raise DiagnosisError(
                f'operating ranges do not overlap on {name}: real {r_lo[i]:.4g}..'
                f'{r_hi[i]:.4g} (dynamic RMS {r_rms[i]:.4g}), sim {s_lo[i]:.4g}..{s_hi[i]:.4g} '
                f'(dynamic RMS {s_rms[i]:.4g}); a diagnosis needs the simulation driven like '
                f'the real system')


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


def without_duplicates(findings, structural):
    """
    Drop per-channel findings of a physics a whole-vehicle finding names on the same channels.

    Both would carry a term for the same effect on the same channels (a roll bar as a
    per-channel displacement-difference stiffness and as the cross-corner load term), so
    the model would count it twice, and the holdout gate, judging each on top of the
    other, finds either harmful.  The whole-vehicle form is kept: it passed a test across
    all corners.
    """
    named = [(f.physics, set(f.channels)) for f in structural]
    return [f for f in findings
            if not any(f.physics == p and set(f.channels) & c for p, c in named)]


def ranked(findings, prep, channels, hp, fs_hz, structural=(), pooled=None):
    """
    Order findings: effects seen in the raw inputs first, then by the residual they explain.

    Findings of the whole-vehicle FRF comparisons (``structural``: ids of a left-right
    coupling, a wrong mass or spring rate) come before the per-channel ones: they passed a
    test across all corners and their side effects on other channels are often picked up
    per channel by a stand-in candidate (a missing roll bar as lateral "damping").  That test
    names a physics, so every finding of that physics ranks with it: the holdout gate may
    later keep the per-channel finding of the same physics and drop the whole-vehicle one,
    and the name the whole-vehicle test supports must not fall behind a stand-in then.

    A physics' weight is the sum over its findings of the explained fraction times the
    squared relative residual of the channels (the drop of RMSE squared), so an effect found
    on four corners outranks one found on a single corner; competing hardenings are settled
    by :func:`hardening.hardening_winner`.
    """
    rel = {}
    for o, c in enumerate(channels):
        t = [x[o][np.newaxis] for x in prep.targets]
        r = [x[o][np.newaxis] - p[o][np.newaxis] for x, p in zip(prep.targets, prep.predictions)]
        if hp > 0.0:
            t = [highpass(x, fs_hz, hp, 'ranking target') for x in t]
            r = [highpass(x, fs_hz, hp, 'ranking residual') for x in r]
        ts = sum(float(np.sum(x ** 2)) for x in t)
        rel[c] = sum(float(np.sum(x ** 2)) for x in r) / ts if ts > 0.0 else 0.0

    def weight(f):
        return max(f.explained_fraction, 0.0) * sum(rel.get(c, 0.0) for c in f.channels)
    total: Dict[str, float] = {}
    for f in findings:
        total[f.physics] = total.get(f.physics, 0.0) + weight(f)
    winner = hardening_winner(findings, pooled) if pooled is not None else None
    if winner is not None:
        total[winner] = max(v for k, v in total.items()
                            if k in HARDENINGS) * (1.0 + 1e-9) + 1e-300
    structural = set(structural)
    first = {f.physics for f in findings if id(f) in structural}
    return sorted(findings, key=lambda f: (not BY_NAME[f.physics].priority,
                                           f.physics not in first,
                                           -total[f.physics], -weight(f)))


def is_simulation(sim_or_model) -> bool:
    """Return True when ``sim_or_model`` is simulation recordings (not None, not a model)."""
    from wheel_force_estimator.core.model import FrfModel
    return sim_or_model is not None and not isinstance(
        sim_or_model, (FrfModel, FrfReference, RegressionReference))
