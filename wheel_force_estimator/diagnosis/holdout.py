# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Holdout comparisons of a diagnosis: RMSE per channel, the augmented model, the holdout gate.

``prep`` arguments are the prepared records of :mod:`diagnosis.run` (``recordings``,
``targets``, ``predictions`` and ``full_predictions`` of the reference, settling removed).
"""
from dataclasses import replace
from typing import Dict, List

import numpy as np

from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.diagnosis import text


def rmse_by_channel(targets, predictions, channels, highpass_hz=0.0,
                    fs_hz=1.0) -> Dict[str, float]:
    """RMSE % per channel over records (each record high-passed on its own first)."""
    if highpass_hz > 0.0:
        targets = [highpass(t, fs_hz, highpass_hz, 'RMSE target') for t in targets]
        predictions = [highpass(p, fs_hz, highpass_hz, 'RMSE prediction') for p in predictions]
    t = np.concatenate(targets, axis=1)
    p = np.concatenate(predictions, axis=1)
    return dict(zip(channels, (float(v) for v in rmse_pct(t, p, channels))))


def augmented(prep, terms) -> List[np.ndarray]:
    """Return the reference prediction plus the physics stage, over the trimmed records."""
    out = []
    for rec, pred, target in zip(prep.recordings, prep.full_predictions, prep.targets):
        y = apply_physics(terms, rec.fs_hz, rec.input_channels, rec.output_channels,
                          rec.inputs, pred, rest_inputs=rec.inputs.mean(axis=1))
        out.append(y[:, -target.shape[1]:])
    return out


def contributions(prep, findings, hp: float) -> List[List[np.ndarray]]:
    """Per finding, per record: the force its terms add (high-passed like the metric)."""
    out = []
    for f in findings:
        per_rec = []
        for y, pred in zip(augmented(prep, f.terms), prep.predictions):
            d = y - pred
            if hp > 0.0 and np.any(d):
                d = highpass(d, prep.recordings[0].fs_hz, hp, 'term contribution')
            per_rec.append(d)
        out.append(per_rec)
    return out


def refitted(findings, fit_prep, eval_prep, hp: float) -> List[np.ndarray]:
    """
    Prediction of ``eval_prep``'s reference plus the findings' terms, strengths refitted.

    One strength factor per finding (its shapes kept) is fitted by least squares on the
    residual of ``fit_prep`` (channels weighted by their force RMS, like the RMSE %), so the
    named physics are judged on top of *this* reference (the best linear fit on real data).
    """
    findings = [f for f in findings if f.terms]
    preds = [p.copy() for p in eval_prep.predictions]
    if not findings:
        return preds
    fs_hz = fit_prep.recordings[0].fs_hz
    cols = contributions(fit_prep, findings, hp)
    a_rows, b_rows = [], []
    for i, (y, p) in enumerate(zip(fit_prep.targets, fit_prep.predictions)):
        r = y - p
        t = y
        if hp > 0.0:
            r = highpass(r, fs_hz, hp, 'refit residual')
            t = highpass(y, fs_hz, hp, 'refit target')
        w = 1.0 / np.maximum(np.sqrt(np.mean(t ** 2, axis=1, keepdims=True)), 1e-300)
        a_rows.append(np.stack([(c[i] * w).ravel() for c in cols], axis=1))
        b_rows.append((r * w).ravel())
    beta, *_ = np.linalg.lstsq(np.concatenate(a_rows), np.concatenate(b_rows), rcond=None)
    for k, f in enumerate(findings):
        for i, (y, pred) in enumerate(zip(augmented(eval_prep, f.terms),
                                          eval_prep.predictions)):
            preds[i] = preds[i] + beta[k] * (y - pred)
    return preds


#: Largest rise of the holdout RMSE [points of %] a finding's terms may cause (mean over its
#: channels, the other findings kept) before it is dropped.
MAX_HOLDOUT_HARM_PCT = 0.05


def holdout_gate(findings, hold, before, channels, hp, fs_hz):
    """
    Drop findings whose terms make the holdout worse (backward elimination).

    A finding is dropped when it raises the holdout RMSE by more than
    :data:`MAX_HOLDOUT_HARM_PCT` points on average over its channels (its parameters are
    shared, so it stands or falls on all of them); the most harmful goes first.

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
        return rmse_by_channel(hold.targets, augmented(hold, terms), channels, hp, fs_hz)
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
    kept = [replace(f, rmse_after_pct={c: full[c] for c in f.channels}) for f in kept]
    if companions and any(f.terms for f in kept):
        i = next(i for i, f in enumerate(kept) if f.terms)
        kept[i] = replace(kept[i], terms=kept[i].terms + tuple(companions))
    return kept, gated
