# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Holdout comparisons of a diagnosis: RMSE per channel, the augmented model, the holdout gate.

``prep`` arguments are the prepared records of :mod:`diagnosis.prepared` (``recordings``,
``targets``, ``predictions`` and ``full_predictions`` of the reference, settling removed).

The holdout recordings are cut into alternate time blocks (:func:`alternate_blocks`): the
gate that drops findings which make unseen data worse decides on one half, and every
before/after figure is computed on the other half only, so no reported number comes from
data that took part in a decision.
"""
from dataclasses import replace
from typing import Dict, List

import numpy as np

from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.diagnosis import text


#: Length of the alternate holdout blocks (gate / report) [s].
HOLDOUT_BLOCK_S = 4.0


def alternate_blocks(prep, fs_hz: float, block_s: float = HOLDOUT_BLOCK_S):
    """
    Return ``(gate, report)``: per record, boolean sample masks of alternate time blocks.

    A record is cut into ``max(2, n // block)`` equal blocks; even blocks go to the gate,
    odd ones to the report (so every record contributes to both).
    """
    gate, report = [], []
    for target in prep.targets:
        n = target.shape[1]
        n_blocks = max(2, n // max(int(round(block_s * fs_hz)), 1))
        block = (np.arange(n) * n_blocks) // n
        gate.append(block % 2 == 0)
        report.append(block % 2 == 1)
    return gate, report


def rmse_by_channel(targets, predictions, channels, highpass_hz=0.0, fs_hz=1.0,
                    masks=None) -> Dict[str, float]:
    """
    RMSE % per channel over records (each record high-passed on its own first).

    ``masks`` (one boolean sample mask per record) restricts the comparison to those samples,
    after the high-pass.
    """
    if highpass_hz > 0.0:
        targets = [highpass(t, fs_hz, highpass_hz, 'RMSE target') for t in targets]
        predictions = [highpass(p, fs_hz, highpass_hz, 'RMSE prediction') for p in predictions]
    if masks is not None:
        targets = [t[:, m] for t, m in zip(targets, masks)]
        predictions = [p[:, m] for p, m in zip(predictions, masks)]
    t = np.concatenate(targets, axis=1)
    p = np.concatenate(predictions, axis=1)
    return dict(zip(channels, (float(v) for v in rmse_pct(t, p, channels))))


def _with_terms(prep, terms) -> List[np.ndarray]:
    """Return the reference prediction plus the physics stage, full records."""
    return [apply_physics(terms, rec.fs_hz, rec.input_channels, rec.output_channels,
                          rec.inputs, pred, rest_inputs=rec.inputs.mean(axis=1))
            for rec, pred in zip(prep.recordings, prep.full_predictions)]


def augmented(prep, terms) -> List[np.ndarray]:
    """Return the reference prediction plus the physics stage, over the trimmed records."""
    return [y[:, -target.shape[1]:] for y, target in zip(_with_terms(prep, terms), prep.targets)]


def _unit_forces(findings, prep) -> List[List[np.ndarray]]:
    """Per finding, per record: the force its terms add to the prediction (full records)."""
    return [[y - pred for y, pred in zip(_with_terms(prep, f.terms), prep.full_predictions)]
            for f in findings]


def _strengths(units, prep, hp: float) -> np.ndarray:
    """
    Least-squares strength factor per finding on the residual of ``prep``'s reference.

    ``units`` are the findings' :func:`_unit_forces` on ``prep``.  Channels are weighted by
    their force RMS (like the RMSE %); residual and contributions are high-passed like the
    metric.
    """
    fs_hz = prep.recordings[0].fs_hz
    a_rows, b_rows = [], []
    for i, (y, p) in enumerate(zip(prep.targets, prep.predictions)):
        cols = [u[i][:, -y.shape[1]:] for u in units]
        r = y - p
        t = y
        if hp > 0.0:
            cols = [highpass(c, fs_hz, hp, 'term contribution') if np.any(c) else c
                    for c in cols]
            r = highpass(r, fs_hz, hp, 'refit residual')
            t = highpass(y, fs_hz, hp, 'refit target')
        w = 1.0 / np.maximum(np.sqrt(np.mean(t ** 2, axis=1, keepdims=True)), 1e-300)
        a_rows.append(np.stack([(c * w).ravel() for c in cols], axis=1))
        b_rows.append((r * w).ravel())
    beta, *_ = np.linalg.lstsq(np.concatenate(a_rows), np.concatenate(b_rows), rcond=None)
    return beta


def _added_force(units, beta, prep) -> List[np.ndarray]:
    """Per record of ``prep``: the force the findings add with strengths ``beta`` (full)."""
    return [sum((b * u[i] for b, u in zip(beta, units)), np.zeros_like(pred))
            for i, pred in enumerate(prep.full_predictions)]


def backfitted(findings, real, holdout, reference, fit_linear, prepare, hp: float,
               iterations: int = 2):
    """
    Fit the best linear FRF on the real data and the findings' strengths jointly.

    A linear FRF fitted on the real forces absorbs the linearised part of a nonlinear effect;
    fitting the terms on its residual then counts that part twice.  Backfitting removes it:
    the FRF is refitted on the real forces minus the terms' force, the strengths (one factor
    per finding, shapes kept) on the residual of that FRF, ``iterations`` times.  The result
    is an FRF plus physics terms, like any augmented model.

    Parameters
    ----------
    findings : sequence of Finding
        Findings with terms (others are ignored).
    real, holdout : sequence of MotionRecording
        Recordings to fit on / to predict.
    reference : object
        The linear fit on ``real`` as recorded (the starting point).
    fit_linear : callable
        ``fit_linear(recordings) -> reference`` (the best linear fit on real data).
    prepare : callable
        ``prepare(recordings, reference) -> Prepared``.
    hp : float
        High-pass of the strength fit [Hz] (0 = none).
    iterations : int
        FRF refits after the first.

    Returns
    -------
    (targets, predictions) : lists of numpy.ndarray
        Of the prepared holdout records (settling removed).

    """
    findings = [f for f in findings if f.terms]
    real_prep = prepare(real, reference)
    units = _unit_forces(findings, real_prep)
    beta = _strengths(units, real_prep, hp) if findings else np.zeros(0)
    for _ in range(iterations if findings else 0):
        added = _added_force(units, beta, real_prep)
        corrected = [replace(rec, outputs=np.asarray(rec.outputs) - a)
                     for rec, a in zip(real, added)]
        reference = fit_linear(corrected)
        real_prep = prepare(real, reference)
        units = _unit_forces(findings, real_prep)
        beta = _strengths(units, real_prep, hp)
    hold_prep = prepare(holdout, reference)
    added = _added_force(_unit_forces(findings, hold_prep), beta, hold_prep)
    preds = [p + a[:, -p.shape[1]:] for p, a in zip(hold_prep.predictions, added)]
    return hold_prep.targets, preds


#: Largest rise of the holdout RMSE [points of %] a finding's terms may cause (mean over its
#: channels, the other findings kept) before it is dropped.
MAX_HOLDOUT_HARM_PCT = 0.05


def holdout_gate(findings, hold, channels, hp, fs_hz, mask):
    """
    Drop findings whose terms make the holdout worse (backward elimination).

    Judged on the samples of ``mask`` only (the gate half of :func:`alternate_blocks`).  A
    finding is dropped when it raises the RMSE by more than :data:`MAX_HOLDOUT_HARM_PCT`
    points on average over its channels (its parameters are shared, so it stands or falls on
    all of them); the most harmful goes first.

    A term that fits the real recordings but makes unseen data worse did not find physics;
    it is reported under ``rejected``.  Linear companions were refitted jointly with all
    terms of their channel, so they stay in every model compared (and end up on the first
    finding kept).  Returns ``(kept, rejection lines)``.
    """
    companions = [t for f in findings for t in f.terms if t.physics != f.physics]
    kept = [replace(f, terms=tuple(t for t in f.terms if t.physics == f.physics))
            for f in findings]
    gated = []

    def score(items):
        terms = [t for g in items for t in g.terms]
        terms += companions if terms else []
        return rmse_by_channel(hold.targets, augmented(hold, terms), channels, hp, fs_hz,
                               mask)
    while True:
        full = score(kept)
        worst, harm = None, MAX_HOLDOUT_HARM_PCT
        for f in (g for g in kept if g.terms):
            without = score([g for g in kept if g is not f])
            # A shared-parameter finding is judged on all its channels together.
            damage = float(np.mean([full[c] - without[c] for c in f.channels]))
            if damage > harm:
                worst, harm, undo = f, damage, without
        if worst is None:
            break
        gated.append(f'{text.channel_list(worst.channels)}: {worst.physics} fitted the real '
                     f'data but worsens the holdout RMSE of ' + ', '.join(
                         f'{c} ({undo[c]:.1f} % -> {full[c]:.1f} %)' for c in worst.channels)
                     + '; not kept')
        kept = [g for g in kept if g is not worst]
    if companions and any(f.terms for f in kept):
        i = next(i for i, f in enumerate(kept) if f.terms)
        kept[i] = replace(kept[i], terms=kept[i].terms + tuple(companions))
    return kept, gated
