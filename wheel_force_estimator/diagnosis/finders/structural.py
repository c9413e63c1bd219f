# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The structural finder: whole-vehicle comparisons of the real and the simulated FRF.

Only against a simulation's FRF.  Two comparisons across all corners name what no corner
shows alone (:func:`find`):

- a missing left-right coupling, an anti-roll bar (:mod:`diagnosis.coupling`), compared like
  with like: the real records fitted with the simulation FRF's own design;
- a wrong sprung mass or spring rate (:mod:`diagnosis.omissions`).  A spring-rate error and
  a hardening both make the real FRF look stiffer, so the spring rate is named only when a
  load-proportional term, fitted with shared parameters on the vertical channels, explains
  :data:`LINEAR_OVER_HARDENING` times what the best hardening candidate (or any physics found
  on those channels) explains there: the acceptance rule of :mod:`finders.acceptance` with
  that rival's gain as its floor.

Their findings supersede what the finders before them named of the same effect on their
channels (:mod:`finders.reconcile`): they passed a test across all corners.
"""
from dataclasses import replace

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import LINEAR_COMPANIONS
from wheel_force_estimator.diagnosis.candidates import STIFFENING
from wheel_force_estimator.diagnosis.coupling import left_right_coupling
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.finders.acceptance import rejection
from wheel_force_estimator.diagnosis.omissions import linear_omissions
from wheel_force_estimator.diagnosis.reference import FrfReference

#: A linear spring-rate error must explain this many times what the best hardening explains.
LINEAR_OVER_HARDENING = 1.3


def find(run, found) -> list:
    """
    Return the left-right coupling and the linear omissions (against a simulation's FRF).

    ``found`` are the findings so far: any physics found on the vertical channels competes
    with a spring-rate error.
    """
    if run.mode != 'sim' or run.reference.kind != 'frf':
        return []
    coupling = coupling_finding(run.real, run.reference, run.channels, run.config, run.hp)
    return ([coupling] if coupling is not None else []) + omissions(run, found)


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


def omissions(run, found) -> list:
    """Return the wrong sprung mass / spring rate :mod:`diagnosis.omissions` names."""
    rec0, config = run.real[0], run.config
    skip = settle_samples(rec0.fs_hz, rec0.input_quantity, config.features)
    filters = config.features.resolved(rec0.fs_hz, rec0.input_quantity)
    extra = linear_omissions(run.real, run.sim, run.reference, run.channels, skip, run.hp,
                             run.sources, rec0.input_quantity, filters, config.omissions)
    kept = []
    for f in extra:
        if f.physics == 'stiffness_error':
            f = _beats_hardening(f, run, found)
        if f is not None:
            kept.append(f)
    return kept


def _beats_hardening(finding, run, found):
    """Return the spring-rate finding with its pooled evidence, or None when it loses."""
    group = list(finding.channels)
    linear = run.pooled(group, 'stiffness_error:load')
    # Any per-channel physics found on these channels competes too (a friction also adds
    # body-band force in phase with the load).
    rivals = set(STIFFENING) | {
        t.key
        for g in found for t in g.terms
        if t.physics not in LINEAR_COMPANIONS and set(t.channels) & set(group)}
    hardening = max(run.pooled(group, k) for k in sorted(rivals & set(BY_KEY)))
    floor = LINEAR_OVER_HARDENING * max(hardening, 0.0)
    if rejection(run.config.selection, linear, min_gain=floor) is not None:
        return None
    return replace(finding, evidence=finding.evidence + (
        f'; pooled over these channels it explains {linear:.1%} of the held-out '
        f'residual, the best hardening candidate {hardening:.1%}'),
        explained_fraction=linear, null_fraction=max(hardening, 0.0))
