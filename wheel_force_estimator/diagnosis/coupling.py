# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Left-right coupling left out of the simulation, found by comparing two linear MIMO FRFs.

A missing anti-roll bar is a *linear* omission the per-corner features cannot show (the
spindle IMU does not see body roll), but the MIMO FRF does: an FRF refitted on the real data
predicts the real forces better than the simulation's FRF.  A left-right coupling acts only on
the difference of the two sides of an axle, so the refit helps the anti-symmetric combination
``F_left - F_right`` of an axle's vertical forces and leaves the symmetric one
``F_left + F_right`` (heave) alone.  A wrong spring, damper or mass, a stop or a clearance acts
on each corner by itself and changes both combinations; estimation scatter between two runs
changes mostly the better excited symmetric one.

A named coupling carries its rate into the model: one ``anti_roll_bar`` term per axle,
``+k (x_l - x_r)`` on the left ``Fz`` and ``-k (x_l - x_r)`` on the right, ``x`` the wheel
displacement the physics stage derives from the spindle inputs.  ``k`` [N/m] is the least-
squares rate of the simulation's residual on that basis (both high-passed like the metric),
evaluated by the same :class:`core.physics.PhysicsStage` that ``predict`` and the node run.
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.result import Finding

#: Axles as (left, right) corners.
AXLES = (('lf', 'rf'), ('lr', 'rr'))


@dataclass(frozen=True)
class CouplingConfig:
    """
    Acceptance rule of a left-right coupling finding.

    Attributes
    ----------
    min_antisymmetric : float
        Smallest fraction of the anti-symmetric residual the refit must remove.  Measured on
        120 s simulator records: at most 0.13 between two nominal runs, up to 0.36 for
        per-corner nonlinear effects (asymmetric damping), 0.70-0.77 for the default roll bar.
    ratio : float
        The anti-symmetric fraction must be at least this times the symmetric one.

    """

    min_antisymmetric: float = 0.5
    ratio: float = 3.0


def _fractions(targets, sim_pred, real_pred, a, b):
    """Return the (symmetric, anti-symmetric) residual fractions the refit removes."""
    out = []
    for sign in (1.0, -1.0):
        before = after = 0.0
        for y, ps, pr in zip(targets, sim_pred, real_pred):
            ys = y[a] + sign * y[b]
            before += float(np.sum((ys - ps[a] - sign * ps[b]) ** 2))
            after += float(np.sum((ys - pr[a] - sign * pr[b]) ** 2))
        out.append(1.0 - after / before if before > 0.0 else 0.0)
    return out[0], out[1]


def axle_terms(recordings: Sequence, left: str, right: str, rate_n_per_m: float,
               features: FeatureConfig) -> PhysicsTerm:
    """
    Return the ``anti_roll_bar`` term of one axle (``left``/``right`` are its Fz channels).

    Raises
    ------
    ConfigError
        The recordings lack the ``{corner}_az`` inputs of the two sides.

    """
    rec0 = recordings[0]
    hp, lp = features.resolved(rec0.fs_hz, rec0.input_quantity)
    src = (left.replace('_fz', '_az'), right.replace('_fz', '_az'))
    return PhysicsTerm('anti_roll_bar', (left, right), {'stiffness_n_per_m': rate_n_per_m},
                       sources=src, partners=src[::-1], input_quantity=rec0.input_quantity,
                       highpass_hz=hp, lowpass_hz=lp)


def fit_axle_rate(recordings: Sequence, sim_reference, left: str, right: str, skip: int,
                  highpass_hz: float, features: FeatureConfig) -> Tuple[float, float]:
    """
    Least-squares roll-bar rate of one axle on the simulation's residual.

    Returns
    -------
    rate_n_per_m : float
        ``k`` of :func:`core.physics.anti_roll_bar_force` (0 when the basis is empty).
    explained : float
        Fraction of the axle's residual sum of squares the term removes.

    """
    unit = axle_terms(recordings, left, right, 1.0, features)
    num = den = ss = 0.0
    for rec in recordings:
        channels = list(rec.output_channels)
        rows = [channels.index(left), channels.index(right)]
        zero = np.zeros((len(channels), rec.n_samples))
        basis = apply_physics([unit], rec.fs_hz, rec.input_channels, channels, rec.inputs,
                              zero, rest_inputs=np.mean(rec.inputs, axis=1))[rows]
        resid = (np.asarray(rec.outputs) - sim_reference.predict(rec))[rows]
        if highpass_hz > 0.0:
            basis = highpass(basis, rec.fs_hz, highpass_hz, 'roll bar basis')
            resid = highpass(resid, rec.fs_hz, highpass_hz, 'roll bar residual')
        basis, resid = basis[:, skip:], resid[:, skip:]
        num += float(np.sum(basis * resid))
        den += float(np.sum(basis * basis))
        ss += float(np.sum(resid * resid))
    rate = num / den if den > 0.0 else 0.0
    return rate, (rate * num / ss if ss > 0.0 else 0.0)


def left_right_coupling(recordings: Sequence, sim_reference, real_reference,
                        channels: Sequence[str], skip: int, highpass_hz: float,
                        config: Optional[CouplingConfig] = None,
                        features: Optional[FeatureConfig] = None) -> Optional[Finding]:
    """
    Name a left-right coupling when the real-data FRF explains the anti-symmetric Fz only.

    Parameters
    ----------
    recordings : sequence of MotionRecording
        Real recordings (the ones ``real_reference`` was fitted on).
    sim_reference, real_reference : FrfReference
        FRFs fitted on the simulation and on ``recordings``.
    channels : sequence of str
        Output channel names (vehicle names ``lf_fz`` ... are needed; otherwise None).
    skip : int
        Samples left out at the start of each record (filter settling).
    highpass_hz : float
        Zero-phase high-pass of forces and predictions (0 = none).
    config : CouplingConfig, optional
        Acceptance rule.
    features : FeatureConfig, optional
        Feature filters of the terms (the diagnosis defaults when None).

    Returns
    -------
    Finding or None
        An ``anti_roll_bar`` finding on the Fz channels of the axles that pass, with one
        cross-corner term per axle carrying its fitted rate (when the recordings have the
        ``{corner}_az`` inputs; otherwise without terms).

    """
    config = config or CouplingConfig()
    features = features or FeatureConfig()
    channels = list(channels)
    pairs = [(f'{lc}_fz', f'{rc}_fz') for lc, rc in AXLES
             if f'{lc}_fz' in channels and f'{rc}_fz' in channels]
    if not pairs:
        return None
    targets, sim_pred, real_pred = [], [], []
    for rec in recordings:
        fs_hz = rec.fs_hz
        parts = [rec.outputs, sim_reference.predict(rec), real_reference.predict(rec)]
        if highpass_hz > 0.0:
            parts = [highpass(p, fs_hz, highpass_hz, 'coupling signal') for p in parts]
        targets.append(parts[0][:, skip:])
        sim_pred.append(parts[1][:, skip:])
        real_pred.append(parts[2][:, skip:])
    found: List[Tuple[str, str, float, float]] = []
    for left, right in pairs:
        sym, anti = _fractions(targets, sim_pred, real_pred, channels.index(left),
                               channels.index(right))
        if anti >= config.min_antisymmetric and anti >= config.ratio * max(sym, 0.0):
            found.append((left, right, sym, anti))
    if not found:
        return None
    anti = min(f[3] for f in found)
    sym = max(f[2] for f in found)
    group = tuple(c for f in found for c in f[:2])
    inputs = recordings[0].input_channels
    terms, rates, params = [], [], {'antisymmetric_explained': anti,
                                    'symmetric_explained': sym}
    for left, right, _, _ in found:
        if not all(c.replace('_fz', '_az') in inputs for c in (left, right)):
            continue
        rate, explained = fit_axle_rate(recordings, sim_reference, left, right, skip,
                                        highpass_hz, features)
        axle = 'front' if left.startswith('lf') else 'rear'
        params[f'{axle}_stiffness_n_per_m'] = rate
        rates.append(f'{left[:2]}/{right[:2]} {rate:.4g} N/m ({explained:.0%} of the axle '
                     f'residual)')
        terms.append(axle_terms(recordings, left, right, rate, features))
    detail = '; '.join(f'{lc}/{rc}: {an:.0%} of the left-right difference, {sy:.0%} of the '
                       f'sum' for lc, rc, sy, an in found)
    model = (f'modelled as a cross-corner rate on the relative wheel displacement, '
             f'{", ".join(rates)}' if terms else
             'no cross-corner term without the vertical spindle inputs: add it to the simulation')
    evidence = (f'anti_roll_bar on {", ".join(group)}: a linear FRF refitted on the real data '
                f'explains the anti-symmetric (roll) vertical force the simulation misses but '
                f'not the symmetric (heave) one, so a left-right coupling is left out ({detail})'
                f'; {model}')
    return Finding('anti_roll_bar', group, params, anti, evidence, tuple(terms), max(sym, 0.0))
