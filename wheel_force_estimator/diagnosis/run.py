# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The diagnosis's settings and the helpers its stages use (:mod:`diagnosis.pipeline`).

- :class:`DiagnosisConfig`: every setting of a diagnosis;
- :func:`reference_of`, :func:`real_linear_fit`: the reference and the one real-data linear fit
  of the run (``fit``'s design);
- :func:`ranked`: the ranking of the findings;
- :func:`is_simulation`: whether the run has simulation recordings.

The stages themselves run in :func:`diagnosis.pipeline.diagnose_once`.
"""
from dataclasses import dataclass
from dataclasses import field
from typing import Dict, Optional, Tuple

import numpy as np

from wheel_force_estimator.core.derived import ACCEL_DERIVED_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.candidates import HARDENINGS
from wheel_force_estimator.diagnosis.candidates import LINEAR_COMPANIONS
from wheel_force_estimator.diagnosis.coupling import CouplingConfig
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.features import motion_features
from wheel_force_estimator.diagnosis.finders.agreement import AgreementConfig
from wheel_force_estimator.diagnosis.finders.hardening import hardening_winner
from wheel_force_estimator.diagnosis.finders.motion import MotionConfig
from wheel_force_estimator.diagnosis.omissions import OmissionConfig
from wheel_force_estimator.diagnosis.recording import check_compatible
from wheel_force_estimator.diagnosis.reference import FrfReference
from wheel_force_estimator.diagnosis.reference import RegressionReference
from wheel_force_estimator.diagnosis.selection import SelectionConfig


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
    derived : tuple of str
        Real-data fits of the 12 spindle accelerations also offer every output row these
        inputs derived from them (:func:`reference.with_split`; default: the traction/braking
        and the cornering splits), as ``wheel-force fit`` does (its params key ``inputs``: the
        CLI passes none for ``inputs: []``, and only the listed splits for a list); the
        simulation's FRF, the features and the finders keep the 12 accelerations.  Measured
        on a damper-asymmetry pair (seed 7, issue 30): without the traction/braking split the
        model written without ``--holdout`` scored 19.3 % on a held-out bag where a plain
        ``fit`` scored 13.9 %.
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
        (:mod:`finders.agreement`; against a simulation or a model only).
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
    derived: Tuple[str, ...] = ACCEL_DERIVED_CHANNELS
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
                            progress=config.progress, derived=config.derived)


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
