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

A named coupling carries its parameters into the model: one ``anti_roll_bar`` term per axle in
the load state, ``+g/2 (F_l - F_r)`` on the left ``Fz`` and ``-g/2 (F_l - F_r)`` on the right,
``F`` the linear force prediction low-passed at a corner from :data:`ROLL_LOWPASS_HZ` (a bar
the simulation leaves out changes the axle's share of the roll moment, so its left-right load
difference is ``1 + g`` times the predicted one below the roll mode).  ``g`` is the least-
squares gain of the simulation's residual on that basis (both high-passed like the metric),
evaluated by the same :class:`core.physics.PhysicsStage` that ``predict`` and the node run;
the corner is the one that explains most on held-out time blocks (two-fold cross-validation
on alternate blocks), and the term is attached only when it explains anything there.  A rate
in N/m on the relative *wheel* displacement (the motion-state ``anti_roll_bar`` kind) does not
carry over: the bar acts on the suspension deflection, wheel minus body, and body roll is not
measured (on the concealed simulator case it made the holdout Fz 2.6 points worse).
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator import AXLES
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis.result import Finding


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


#: Corners [Hz] tried for the low-passed load state of the roll coupling.
ROLL_LOWPASS_HZ = (0.5, 1.0, 2.0, 4.0, 8.0)


def axle_term(left: str, right: str, gain: float, lowpass_hz: float,
              input_quantity: str = 'acceleration', input_channels=None) -> PhysicsTerm:
    """
    Return the load-state ``anti_roll_bar`` term of one axle (its two Fz channels).

    The load state reads no input; its sources are the ``{corner}_az`` channels, or the
    first of ``input_channels`` when those are absent.
    """
    sources = tuple(c.replace('_fz', '_az') for c in (left, right))
    if input_channels is not None and not set(sources) <= set(input_channels):
        sources = (input_channels[0],) * 2
    return PhysicsTerm('anti_roll_bar', (left, right), {'gain': gain}, sources=sources,
                       partners=(right, left), input_quantity=input_quantity, state='load',
                       state_lowpass_hz=lowpass_hz)


def fit_axle_gain(recordings: Sequence, sim_reference, left: str, right: str, skip: int,
                  highpass_hz: float, block_s: float = 4.0) -> Tuple[float, float, float, float]:
    """
    Least-squares roll-coupling gain of one axle on the simulation's residual.

    Returns
    -------
    gain : float
        ``g`` of :func:`core.physics.load_roll_force`, fitted on all samples.
    lowpass_hz : float
        Load-state corner from :data:`ROLL_LOWPASS_HZ` with the best cross-validated fit.
    explained : float
        Fraction of the axle's residual sum of squares the term removes (in sample).
    cv_explained : float
        The same, two-fold cross-validated on alternate ``block_s`` blocks (gain fitted on
        one half, scored on the other): <= 0 when the term does not carry over.

    """
    best = None
    for fc in ROLL_LOWPASS_HZ:
        unit = axle_term(left, right, 1.0, fc, recordings[0].input_quantity,
                         recordings[0].input_channels)
        sums = np.zeros((2, 3))  # per fold: basis.resid, basis.basis, resid.resid
        for rec in recordings:
            channels = list(rec.output_channels)
            rows = [channels.index(left), channels.index(right)]
            pred = sim_reference.predict(rec)
            basis = (apply_physics([unit], rec.fs_hz, rec.input_channels, channels,
                                   rec.inputs, pred) - pred)[rows]
            resid = (np.asarray(rec.outputs) - pred)[rows]
            if highpass_hz > 0.0:
                basis = highpass(basis, rec.fs_hz, highpass_hz, 'roll coupling basis')
                resid = highpass(resid, rec.fs_hz, highpass_hz, 'roll coupling residual')
            basis, resid = basis[:, skip:], resid[:, skip:]
            fold = (np.arange(basis.shape[1]) // max(int(round(block_s * rec.fs_hz)), 1)) % 2
            for k in (0, 1):
                bk, rk = basis[:, fold == k], resid[:, fold == k]
                sums[k] += (np.sum(bk * rk), np.sum(bk * bk), np.sum(rk * rk))
        num, den, ss = sums.sum(axis=0)
        if den <= 0.0 or ss <= 0.0:
            continue
        removed = 0.0
        for k in (0, 1):
            other = sums[1 - k]
            fitted = other[0] / other[1] if other[1] > 0.0 else 0.0
            removed += 2.0 * fitted * sums[k][0] - fitted ** 2 * sums[k][1]
        gain = num / den
        fit = (float(gain), fc, float(gain * num / ss), float(removed / ss))
        if best is None or fit[3] > best[3]:
            best = fit
    return best if best is not None else (0.0, ROLL_LOWPASS_HZ[0], 0.0, 0.0)


def left_right_coupling(recordings: Sequence, sim_reference, real_reference,
                        channels: Sequence[str], skip: int, highpass_hz: float,
                        config: Optional[CouplingConfig] = None) -> Optional[Finding]:
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

    Returns
    -------
    Finding or None
        An ``anti_roll_bar`` finding on the Fz channels of the axles that pass, with one
        cross-corner term per axle carrying its fitted gain (when it carries over to held-out
        blocks; otherwise the axle has no term).

    """
    config = config or CouplingConfig()
    channels = list(channels)
    pairs = [(f'{lc}_fz', f'{rc}_fz') for lc, rc in AXLES
             if f'{lc}_fz' in channels and f'{rc}_fz' in channels]
    if not pairs:
        return None
    targets, sim_pred, real_pred = _signals(recordings, sim_reference, real_reference, skip,
                                            highpass_hz)
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
    params = {'antisymmetric_explained': anti, 'symmetric_explained': sym}
    terms, parts = _axle_terms(found, recordings, sim_reference, skip, highpass_hz, params)
    detail = '; '.join(f'{lc}/{rc}: {an:.0%} of the left-right difference, {sy:.0%} of the '
                       f'sum' for lc, rc, sy, an in found)
    model = 'modelled as a roll coupling per axle: ' + '; '.join(parts)
    evidence = (f'anti_roll_bar on {", ".join(group)}: a linear FRF refitted on the real data '
                f'explains the anti-symmetric (roll) vertical force the simulation misses but '
                f'not the symmetric (heave) one, so a left-right coupling is left out ({detail})'
                f'; {model}')
    return Finding('anti_roll_bar', group, params, anti, evidence, tuple(terms), max(sym, 0.0))


def _signals(recordings: Sequence, sim_reference, real_reference, skip: int,
             highpass_hz: float) -> Tuple[list, list, list]:
    """Return the forces and both references' predictions per record (high-passed, settled)."""
    targets, sim_pred, real_pred = [], [], []
    for rec in recordings:
        parts = [rec.outputs, sim_reference.predict(rec), real_reference.predict(rec)]
        if highpass_hz > 0.0:
            parts = [highpass(p, rec.fs_hz, highpass_hz, 'coupling signal') for p in parts]
        targets.append(parts[0][:, skip:])
        sim_pred.append(parts[1][:, skip:])
        real_pred.append(parts[2][:, skip:])
    return targets, sim_pred, real_pred


def _axle_terms(found: Sequence[Tuple[str, str, float, float]], recordings: Sequence,
                sim_reference, skip: int, highpass_hz: float,
                params: dict) -> Tuple[list, list]:
    """
    Fit each found axle's roll gain: its terms and descriptions (``params`` gets the gains).

    An axle whose gain does not carry over to held-out blocks has no term.
    """
    terms, parts = [], []
    for left, right, _, _ in found:
        gain, fc, explained, cv = fit_axle_gain(recordings, sim_reference, left, right, skip,
                                                highpass_hz)
        axle = 'front' if left[:2] == AXLES[0][0] else 'rear'
        params[f'{axle}_roll_gain'] = gain
        if cv > 0.0:
            params[f'{axle}_roll_lowpass_hz'] = fc
            parts.append(f'{left[:2]}/{right[:2]} {100 * gain:+.1f} % of the predicted '
                         f'left-right load difference below {fc:g} Hz ({explained:.0%} of the '
                         f'axle residual, {cv:.0%} on held-out blocks)')
            terms.append(axle_term(left, right, gain, fc, recordings[0].input_quantity,
                                   recordings[0].input_channels))
        else:
            parts.append(f'{left[:2]}/{right[:2]}: no term (a gain on the predicted left-right '
                         f'load difference explains {cv:.0%} of held-out blocks)')
    return terms, parts
