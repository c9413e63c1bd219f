# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The differentiator low-pass of displacement / velocity inputs: two corners, the holdout chooses.

Velocity from a displacement input (and every feature of a velocity input) goes through a
2nd-order low-pass, by default at ``fs / 8`` (:class:`features.FeatureConfig`).  At 25 Hz on
a 256 Hz rig it lags 30 degrees, which smears a force that flips with the velocity (friction,
damper asymmetry); but a lagged velocity can also stand in for a hysteretic state (the real
MR damper).  No rule tells the two apart, so the diagnosis runs at both corners and the gate
half of the holdout keeps the better written model (:func:`with_sharper_corner`).
"""
from dataclasses import replace
from typing import Callable, Optional

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.spectra import power_quantile_hz
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.holdout import METRIC
from wheel_force_estimator.diagnosis.holdout import split_holdout
from wheel_force_estimator.diagnosis.written import mean_score

#: Phase lag [deg] the sharper differentiator low-pass may leave at the top of the band that
#: carries the coherent velocity power (see :func:`sharper_lowpass_hz`).
SHARP_LAG_DEG = 5.0
#: Fraction of the coherent velocity power below the frequency the lag is judged at.
SHARP_POWER_FRACTION = 0.99
#: Highest corner as a fraction of the sample rate (the feature filters need it < fs / 2).
SHARP_MAX_FRACTION = 0.4


def _butter2_ratio(lag_deg: float) -> float:
    """Return ``f / fc`` at which a 2nd-order Butterworth low-pass lags by ``lag_deg``."""
    # tan(phi) = sqrt(2) r / (1 - r^2)  ->  tan(phi) r^2 + sqrt(2) r - tan(phi) = 0
    t = np.tan(np.radians(lag_deg))
    return float((-np.sqrt(2.0) + np.sqrt(2.0 + 4.0 * t * t)) / (2.0 * t))


def sharper_lowpass_hz(recordings, config: FeatureConfig) -> Optional[float]:
    """
    Return a differentiator low-pass corner sharper than ``fs / 8``, or None.

    The corner leaves at most :data:`SHARP_LAG_DEG` of lag at the frequency below which
    :data:`SHARP_POWER_FRACTION` of the *coherent* velocity power lies (velocity power
    spectrum times the largest input-output coherence, pooled over the records, largest over
    the inputs, so a noise floor that no output follows does not push the corner up),
    clamped to ``[fs / 8, 0.4 fs]``.

    Returns None for acceleration inputs (nothing is differentiated), when the corner is set
    explicitly, or when the sharper corner would not be above the default one.
    """
    from scipy import signal
    rec0 = recordings[0]
    quantity, fs = rec0.input_quantity, float(rec0.fs_hz)
    if quantity == 'acceleration' or config.lowpass_hz > 0.0:
        return None
    default = config.resolved(fs, quantity)[1]
    order_in = ('displacement', 'velocity').index(quantity)
    top = 0.0
    # one Welch grid for all records (the shortest record sets it)
    nperseg = int(min(1024, max(8, min(rec.inputs.shape[1] for rec in recordings) // 4)))
    for i in range(rec0.inputs.shape[0]):
        power = 0.0
        for rec in recordings:
            x = np.asarray(rec.inputs[i], dtype=np.float64)
            f, pxx = signal.welch(x, fs, nperseg=nperseg)
            coh = np.max([signal.coherence(x, y, fs, nperseg=nperseg)[1]
                          for y in np.asarray(rec.outputs, dtype=np.float64)], axis=0)
            power = power + pxx * (2.0 * np.pi * f) ** (2 * (1 - order_in)) * coh
        here = power_quantile_hz(f, power, SHARP_POWER_FRACTION)
        top = top if here is None else max(top, here)
    corner = min(top / _butter2_ratio(SHARP_LAG_DEG), SHARP_MAX_FRACTION * fs)
    return corner if corner > default else None


def with_sharper_corner(result, diagnose_once: Callable, real, holdout, config):
    """
    Return ``result`` or the diagnosis at the sharper corner, whichever the gate prefers.

    ``diagnose_once(config) -> DiagnosisResult`` diagnoses with fixed corners; ``result`` is
    its answer at ``config`` (the default corner).  When :func:`sharper_lowpass_hz` offers a
    corner, the diagnosis runs again there and the gate half of the holdout keeps the written
    model with the lower mean RMSE over all outputs (a tie keeps the default); without a
    holdout the cross-validated RMSE after the terms (``fit.after``, held-out time blocks of
    the real records) decides.  A note in ``fit.notes`` and the summary says which corner
    was kept, both scores and what the other corner named; when the second run cannot be
    made (``DiagnosisError``) the first stands and the note says why.
    """
    sharp = sharper_lowpass_hz(real, config.features)
    if sharp is None:
        return result
    try:
        other = diagnose_once(replace(config, features=replace(config.features,
                                                               lowpass_hz=sharp)))
    except DiagnosisError as err:
        return _noted(result, f'Differentiator low-pass {sharp:.3g} Hz not tried: {err}')
    if other.model is None:
        return result
    rec0 = real[0]
    channels = rec0.output_channels
    default = config.features.resolved(rec0.fs_hz, rec0.input_quantity)[1]
    if holdout:
        gate = split_holdout(holdout).gate_half
        metric = METRIC[rec0.input_quantity]
        scores = [mean_score(r.model, gate, channels, metric)[0] for r in (result, other)]
        judge = 'the gate half of the holdout'
    elif result.fit.after and other.fit.after:
        # no holdout: the cross-validated RMSE of the written model (held-out time blocks)
        scores = [float(np.mean([r.fit.after[c] for c in channels])) for r in (result, other)]
        judge = 'the cross-validation blocks (no holdout)'
    else:
        return _noted(result, f'Differentiator low-pass {sharp:.3g} Hz not tried: no held-out '
                              f'figures to judge it on')
    # Without terms at either corner the written models are the same linear fit: nothing to
    # choose (their scores differ only by the samples each corner's settle time leaves out).
    sharper_wins = scores[1] < scores[0] and bool(result.terms or other.terms)
    keep, lost = (other, result) if sharper_wins else (result, other)
    corners = (default, sharp) if keep is result else (sharp, default)
    named = [f.physics for f in keep.findings]
    other_named = [f.physics for f in lost.findings]
    return _noted(keep, (
        f'Differentiator low-pass: {corners[0]:.3g} Hz kept over {corners[1]:.3g} Hz '
        f'(default fs/8 = {default:.3g} Hz; sharper = {SHARP_LAG_DEG:g} deg lag at the top of '
        f'the coherent velocity band), chosen on {judge}: mean RMSE over all outputs '
        f'{min(scores):.2f} % vs {max(scores):.2f} %'
        + (f'; with {corners[1]:.3g} Hz it named {", ".join(other_named) or "nothing"}'
           if other_named != named else '') + '.'))


def _noted(result, note: str):
    """Return ``result`` with ``note`` appended to its fit notes and its summary."""
    return replace(result, fit=replace(result.fit, notes=result.fit.notes + (note,)),
                   summary=result.summary + (note,))
