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
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.metrics import highpass
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
        An ``anti_roll_bar`` finding on the Fz channels of the axles that pass, without model
        terms (the per-corner stage cannot carry a MIMO correction).

    """
    config = config or CouplingConfig()
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
    detail = '; '.join(f'{lc}/{rc}: {an:.0%} of the left-right difference, {sy:.0%} of the '
                       f'sum' for lc, rc, sy, an in found)
    evidence = (f'anti_roll_bar on {", ".join(group)}: a linear FRF refitted on the real data '
                f'explains the anti-symmetric (roll) vertical force the simulation misses but '
                f'not the symmetric (heave) one, so a left-right coupling is left out ({detail})'
                f'; no per-corner term can model it: add it to the simulation')
    return Finding('anti_roll_bar', group,
                   {'antisymmetric_explained': anti, 'symmetric_explained': sym}, anti,
                   evidence, (), max(sym, 0.0))
