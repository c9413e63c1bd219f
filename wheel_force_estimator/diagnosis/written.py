# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Fitting the written model's candidates: the real-data FRF with the findings' terms.

- :func:`backfitted_model`: the FRF fitted on the real recordings with the design of
  ``wheel-force fit`` plus the findings' terms, fitted jointly by backfitting (the
  ``real_frf+physics`` candidate, and the strengths of ``sim_frf+physics``);
- :func:`partialled`: the Frisch-Waugh-Lovell step (a column minus what the linear design
  predicts of it);
- :func:`has_joint_step`: whether the joint least-squares strengths are a candidate of
  their own;
- :func:`gate_dynamic`: the gate half of a holdout on terms inside the structure;
- :func:`bounded_terms`: each term held within the force it added where it was fitted;
- :func:`with_live_estimators`: the written model's live estimators for the node.

Which candidate is written is :mod:`diagnosis.choice`'s.
"""
from dataclasses import replace
from typing import Callable, Dict, List, Sequence, Tuple

import numpy as np
import scipy.optimize

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.predict import model_inputs
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.diagnosis.holdout import evaluate_scores
from wheel_force_estimator.diagnosis.holdout import MAX_HOLDOUT_HARM_PCT
from wheel_force_estimator.diagnosis.holdout import Scored


def _predictions(model, recordings) -> List[np.ndarray]:
    return [predict_forces(model, r.inputs) for r in recordings]


def term_dicts(terms) -> List[dict]:
    return [t.to_dict() for t in terms]


def bounded_terms(model, recordings: Sequence, keep: Sequence = ()):
    """
    Return ``model`` with each term's force bounded to what it added on ``recordings``.

    A term's force law is fitted where the recordings took it; fed a motion or a load they
    never reached, a progressive law extrapolates without bound.  Measured (simulator, seed
    6, rebound stop, 2-minute records): the real-data FIR fitted on three quarters of the
    record predicted the last quarter's ``lr_fz`` down to -7 kN where it stayed above 1.6
    kN, and the load-driven stop term turned that into -209 kN (5090 % RMSE on the block, 450
    % for the FIR alone), so the held-out blocks could not see the terms' gain (8 % at 1 Hz
    high-pass on a new recording of the course).  The bound is the least and greatest force
    the term added on ``recordings`` per channel (:attr:`PhysicsTerm.force_range_n`); beyond
    them it holds the edge.  Terms that already carry a bound, and the terms of ``keep`` (a
    ``--model``'s own, fitted on other recordings), are left as they are.  Each term is
    evaluated alone on the linear prediction, which is what it reads in the stage, so the
    bounds are exact on ``recordings``.  Whether the bound is written is the held-out data's
    choice: :func:`choice.candidate_builder` offers each bounded candidate unbounded too.
    """
    terms = model.physics_terms
    if all(t.force_range_n or t in keep for t in terms):
        return model
    linear = _predictions(model.with_physics([]), recordings)
    rows = {c: i for i, c in enumerate(model.output_channels)}
    out = []
    for term in terms:
        if not (term.force_range_n or term in keep):
            added = _units(model, [[term]], recordings, linear)[0]
            index = [rows[c] for c in term.channels]
            term = replace(term, force_range_n=tuple(
                (min(float(a[o].min()) for a in added), max(float(a[o].max()) for a in added))
                for o in index))
        out.append(term)
    return model.with_physics(term_dicts(out))


def _units(model, groups, recordings, base) -> List[List[np.ndarray]]:
    """Per term group, per record: the force the group adds to ``model`` (Predictor path)."""
    return [[y - b for y, b in zip(_predictions(model.with_physics(term_dicts(g)), recordings),
                                   base)] for g in groups]


def _figure_views(x: np.ndarray, fs_hz: float, hp: float, skip: int,
                  what: str) -> List[np.ndarray]:
    """
    Return ``x`` (n_out, n) after ``skip`` as each figure of ``evaluate`` sees it.

    Unfiltered (``rmse_pct``): mean-removed; when ``hp`` > 0 also high-passed at ``hp``
    (``rmse_hp1_pct``).  A term's strength is fitted on both: on the high-passed figure
    alone a term that fixes the dynamics could spoil the quasi-static band it also carries
    (an asymmetric damper's slow jacking force), which the unfiltered figure scores.
    """
    tail = x[:, skip:]
    views = [tail - tail.mean(axis=1, keepdims=True)]
    if hp > 0.0:
        views.append(highpass(x, fs_hz, hp, what)[:, skip:] if np.any(x) else tail)
    return views


def _figure_weights(y: np.ndarray, fs_hz: float, hp: float, skip: int) -> List[np.ndarray]:
    """Per figure of :func:`_figure_views`: (n_out, 1) weights 1 / RMS of each force there."""
    return [1.0 / np.maximum(np.sqrt(np.mean(v ** 2, axis=1, keepdims=True)), 1e-300)
            for v in _figure_views(y, fs_hz, hp, skip, 'refit target')]


def _strengths(units, free, recordings, base, hp: float, skip: int) -> np.ndarray:
    """
    Non-negative least-squares strength per group (fixed groups at 1) on the residual.

    The criterion is the sum over both figures of ``evaluate`` (:func:`_figure_views`) of
    the squared relative error: channels weighted by their force RMS in that figure (like
    the RMSE %), the first ``skip`` samples of each record (filter settling) left out.
    """
    beta = np.ones(len(units))
    idx = [i for i, f in enumerate(free) if f]
    if not idx:
        return beta
    a_rows, b_rows = [], []
    for k, (rec, pred) in enumerate(zip(recordings, base)):
        if rec.n_samples <= skip:
            continue  # a piece within its filters' settling time holds no sample to fit
        y = np.asarray(rec.outputs, dtype=np.float64)
        r = y - pred - sum((units[i][k] for i, f in enumerate(free) if not f),
                           np.zeros_like(pred))
        fs = rec.fs_hz
        cols = [_figure_views(units[i][k], fs, hp, skip, 'term contribution') for i in idx]
        for v, (rv, w) in enumerate(zip(_figure_views(r, fs, hp, skip, 'refit residual'),
                                        _figure_weights(y, fs, hp, skip))):
            a_rows.append(np.stack([(c[v] * w).ravel() for c in cols], axis=1))
            b_rows.append((rv * w).ravel())
    if not a_rows:
        return beta  # every piece within its settling time: the strengths found stand
    q, rr = np.linalg.qr(np.concatenate(a_rows))
    sol, _ = scipy.optimize.nnls(rr, q.T @ np.concatenate(b_rows))
    beta[idx] = sol
    return beta


def _weighted_sse(units, beta, recordings, base, hp: float, skip: int) -> float:
    """Residual sum of squares the strength fit minimises (both figures, weights, skip)."""
    total = 0.0
    for k, (rec, pred) in enumerate(zip(recordings, base)):
        if rec.n_samples <= skip:
            continue
        y = np.asarray(rec.outputs, dtype=np.float64)
        r = y - pred - sum((b * u[k] for b, u in zip(beta, units)), np.zeros_like(pred))
        for rv, w in zip(_figure_views(r, rec.fs_hz, hp, skip, 'refit residual'),
                         _figure_weights(y, rec.fs_hz, hp, skip)):
            total += float(np.sum((rv * w) ** 2))
    return total


def _joint_eligible(group) -> bool:
    """Return True when a strength group gets the joint step: motion state, free strength."""
    return all(t.state == 'motion' and t.kind.strength is not None and not t.response_taps
               for t in group)


def partialled(columns: Sequence[np.ndarray], recordings: Sequence,
               refit: Callable[[Sequence], object]) -> List[np.ndarray]:
    """
    Return ``columns[k]`` minus what the linear design predicts of them (Frisch-Waugh-Lovell).

    ``columns[k]`` (n_cols, n) are outputs over record ``k`` of ``recordings``; ``refit`` fits
    the linear design on records whose outputs they are (H1 fits each output row on its
    own, so this is the column-by-column refit in one pass).  What is left is the part of
    each column no linear model of the inputs can explain: the regressor of a joint
    least-squares fit of the FIR with the column.  The one home of the step, for the
    backfit's joint strengths (:func:`_partialled_fit`) and the search inside the structure
    (:mod:`diagnosis.finders.structure`).
    """
    names = tuple(f'column {j}' for j in range(np.shape(columns[0])[0]))
    fitted = refit([replace(rec, outputs=c, output_channels=names)
                    for rec, c in zip(recordings, columns)])
    return [c - p for c, p in zip(columns, _predictions(fitted, recordings))]


def _partialled_fit(groups, free, units, real, base, refit, hp: float, skip: int):
    """
    Strengths and FRF of the joint least-squares fit in one step (Frisch-Waugh-Lovell).

    The H1 fit is linear in the output, so the FRF refitted on ``y - sum(beta * u)`` predicts
    ``pred(y) - sum(beta * pred(u))``: the joint residual is ``(y - pred(y)) -
    sum(beta * (u - pred(u)))``, where ``pred(u)`` is what the linear design predicts of a
    group's force fitted as if it were the output.  Regressing the linear residual on those
    *partialled* forces gives the joint strengths at once.  The alternation converges like
    ``rho**(2 k)``, ``rho`` the correlation of a term with the linear inputs: a cubic of a
    Gaussian displacement correlates 0.77 with it, a Coulomb force 0.80 with the velocity,
    so two refits leave the strength about a third short (measured on a force-driven
    Duffing rig: cubic stiffness fitted at half its value).  Exact for terms of the inputs
    (motion state), so only their groups are partialled; a load-state term reads the FIR's
    prediction, so its force moves with every refit and the step is not exact: there the
    alternation alone stays (measured: partialled load-state backlash terms of a simulated
    car fitted better but held out worse, 50.71 vs 50.58 %).  Judged like the alternation
    by the weighted residual.  Returns ``(sse, model, beta)``.
    """
    if not any(_joint_eligible(g) for g in groups):
        return np.inf, None, None
    regressors = []
    for i, g_units in enumerate(units):
        if not _joint_eligible(groups[i]) or not any(np.any(u) for u in g_units):
            regressors.append(g_units)
            continue
        regressors.append(partialled(g_units, real, refit))
    beta = _strengths(regressors, free, real, base, hp, skip)
    model, base, units = _refit_around(groups, beta, units, real, refit)
    return _weighted_sse(units, beta, real, base, hp, skip), model, beta


def _refit_around(groups, beta, units, real, refit):
    """
    Refit the FRF on the real forces minus the groups' force at ``beta``.

    Returns ``(model, its predictions, the groups' unit forces on it)``.
    """
    added = [sum((b * u[k] for b, u in zip(beta, units)), np.zeros_like(units[0][k]))
             for k in range(len(real))]
    model = refit([replace(rec, outputs=np.asarray(rec.outputs) - a)
                   for rec, a in zip(real, added)])
    base = _predictions(model, real)
    return model, base, _units(model, groups, real, base)


def _one_channel(term, channel: str):
    """Return ``term`` acting on ``channel`` alone (same parameters and source)."""
    i = term.channels.index(channel)
    return replace(term, channels=(channel,), sources=(term.sources[i],))


def _strength_groups(findings) -> List[tuple]:
    """
    Return the term groups that get one strength each in the backfit.

    A finding whose terms all scale (a strength parameter) and act on each channel alone (no
    partner) gets one group per channel: its shape was fitted with shared parameters, but
    the same law does not have the same size everywhere (a hardening read through the load
    of a front and a rear corner differs by the cube of their spring-rate ratio).  Any
    other finding is one group.
    """
    groups = []
    for f in findings:
        if not f.terms:
            continue
        terms = tuple(f.terms)
        split = all(t.kind.strength is not None and not t.kind.needs_partner for t in terms)
        channels = list(dict.fromkeys(c for t in terms for c in t.channels))
        if split and len(channels) > 1:
            groups.extend(tuple(_one_channel(t, c) for t in terms if c in t.channels)
                          for c in channels)
        else:
            groups.append(terms)
    return groups


def backfitted_model(findings, real: Sequence, linear_model,
                     refit: Callable[[Sequence], object], hp: float, skip: int,
                     iterations: int = 2, joint: bool = False):
    """Return :func:`backfitted_models` from the one start ``joint`` names."""
    return backfitted_models(findings, real, linear_model, refit, hp, skip, iterations,
                             (joint,))[joint]


def backfitted_models(findings, real: Sequence, linear_model,
                      refit: Callable[[Sequence], object], hp: float, skip: int,
                      iterations: int = 2, starts: Sequence[bool] = (False, True)):
    """
    Fit the best linear FRF on the real data and the findings' strengths jointly.

    A linear FRF fitted on the real forces absorbs the linearised part of a nonlinear
    effect; adding the terms as they were fitted against another reference counts that part
    twice.  Backfitting removes it: the strengths (one non-negative factor per group of
    :func:`_strength_groups` - per channel of a finding whose terms scale and act channel by
    channel, else per finding - shapes kept) are fitted on the residual of the FRF, the FRF
    is refitted on the real forces minus the terms' force, up to ``iterations`` times
    (stopping when the weighted residual no longer falls: the best pair is kept).  Terms
    whose physics has no strength parameter keep their strength; a group whose factor comes
    out 0 leaves the model.

    ``findings`` (those without terms are ignored) were found on ``real`` (MotionRecording);
    ``linear_model`` is ``refit(real)``, where ``refit(recordings) -> FrfModel`` has the
    design of ``wheel-force fit``.  ``hp`` is the high-pass of the second figure the
    strengths are fitted on [Hz] (0 = the unfiltered figure alone; :func:`_figure_views`),
    ``skip`` the samples left out at the start of each record (feature filter settling),
    ``iterations`` the FRF refits.  ``starts`` are the starts to fit from: False, the
    strengths fitted on the first residual; True (``joint``), the joint least-squares
    strengths of the motion-state groups (:func:`_partialled_fit`) when they fit the real
    data better than the first residual fit, the alternation's shrunken strengths otherwise.
    Both starts share the residual fit, and one alternation when the joint start is the
    residual one.

    Returns
    -------
    dict bool -> (FrfModel, tuple of float)
        Per start, the model with the scaled terms and the factor of every group.

    """
    groups = _strength_groups(findings)
    if not groups:
        return dict.fromkeys(starts, (linear_model, ()))
    free = _free_groups(groups)
    model = linear_model
    base = _predictions(model, real)
    units = _units(model, groups, real, base)
    beta = _strengths(units, free, real, base, hp, skip)
    first = (_weighted_sse(units, beta, real, base, hp, skip), model, beta)
    shared, out = None, {}  # the alternation from the first start, for both starts
    for joint in starts:
        best = first
        if joint:
            best = min(first, _partialled_fit(groups, free, units, real, base, refit, hp,
                                              skip), key=lambda item: item[0])
        if best is first:
            shared = shared or _alternate(first, groups, free, units, real, refit, hp, skip,
                                          iterations)
            best = shared
        else:
            best = _alternate(best, groups, free, units, real, refit, hp, skip, iterations)
        _, model, beta = best
        out[joint] = (model.with_physics(term_dicts(_scaled_terms(groups, free, beta))),
                      tuple(float(b) for b in beta))
    return out


def _free_groups(groups) -> List[bool]:
    """
    Return per group whether its strength is fitted here.

    A term inside the structure (response FIR) comes with its strength already fitted at
    the fixed point of the FIR refitted around it (:meth:`dynamic._Channel.refined`); a
    strength refitted here against the plain FIR's load would shrink it (measured: factor
    0.28, held-out 16.8 % where the refits alone reach 12.7 %), so only the FIR is refitted.
    A physics without a strength parameter keeps its strength.
    """
    return [all(t.kind.strength is not None and not t.response_taps for t in g)
            for g in groups]


def _alternate(best: tuple, groups, free: Sequence[bool], units, real: Sequence, refit,
               hp: float, skip: int, iterations: int) -> tuple:
    """
    Refit the FIR around the terms and the strengths on its residual, ``iterations`` times.

    ``best``: ``(weighted SSE, model, strengths)`` to start from; returns the best triple.
    """
    _, _, beta = best
    for _ in range(iterations):
        model, base, units = _refit_around(groups, beta, units, real, refit)
        beta = _strengths(units, free, real, base, hp, skip)
        sse = _weighted_sse(units, beta, real, base, hp, skip)
        if not sse < best[0]:
            # The joint fit stopped improving on its own data: a load-state term reads the
            # FIR's prediction, so refitting the FIR moves the term it was refitted around,
            # and the alternation can run away (measured on a rig: strength 18 -> 349 ->
            # 6908).  Keep the best pair found.
            break
        best = (sse, model, beta)
    return best


def _scaled_terms(groups, free: Sequence[bool], beta) -> list:
    """Return the groups' terms at their strengths (a free group at 0 leaves the model)."""
    terms = []
    for g, f, b in zip(groups, free, beta):
        if f and b > 0.0:
            terms.extend(t.scaled(b) for t in g)
        elif not f:
            terms.extend(g)
    return terms


def mean_score(model, half: Scored, channels, metric: str) -> Tuple[float, Dict[str, float]]:
    """Mean RMSE % of ``model`` over ``channels`` (and all channels) on the scored ``half``."""
    scores = evaluate_scores(lambda r: predict_forces(model, r.inputs), half.records, metric,
                             half.masks)
    return float(np.mean([scores[c] for c in channels])), scores


def has_joint_step(findings) -> bool:
    """
    Return True when the joint least-squares strengths are a candidate of their own.

    The joint strengths (:func:`_partialled_fit`, ``backfitted_model(joint=True)``) are the
    fixed point the alternation's two refits approach from below; with a strong effect that
    is what unseen data want (a force-driven Duffing rig: 20.1 -> 17.3 %), with a concealed
    one (below the noise) the alternation's shrinkage generalises better (synthetic pairs:
    `cubic_stiffness` and `coulomb_friction` lost to the plain fit in 3 of 6 cases with the
    joint strengths).  So both are candidates of the written model and held-out data choose
    (:mod:`diagnosis.choice`); only motion-state groups with a free strength have the step.
    """
    return any(_joint_eligible(g) for g in _strength_groups(findings))


def is_dynamic(finding) -> bool:
    """Return True for a finding inside the structure (a term with a response FIR)."""
    return any(t.response_taps for t in finding.terms)


def gate_dynamic(dynamic, real, lin_model, real_fit, gate, metric, hp, skip):
    """
    Strip the terms of dynamic findings that harm the gate half with the FIR refitted around them.

    The rule of :func:`holdout.holdout_gate` (a rise of the mean RMSE over the finding's
    channels above ``MAX_HOLDOUT_HARM_PCT`` drops it), judged on the real-data FIR refitted
    jointly with the finding (:func:`backfitted_model`) against that FIR alone; a harmful
    finding stays named without its term.  Returns ``(findings, rejection lines)``.
    """
    kept, gated = [], []
    for f in dynamic:
        model, _ = backfitted_model([f], real, lin_model, real_fit, hp, skip)
        with_f = mean_score(model, gate, f.channels, metric)[1]
        without = mean_score(lin_model, gate, f.channels, metric)[1]
        harm = float(np.mean([with_f[c] - without[c] for c in f.channels]))
        if harm > MAX_HOLDOUT_HARM_PCT:
            gated.append(f'{", ".join(f.channels)}: {f.physics} (inside the structure) fitted '
                         f'the real data but worsens the holdout RMSE of ' + ', '.join(
                             f'{c} ({without[c]:.1f} % -> {with_f[c]:.1f} %)'
                             for c in f.channels) + '; named, its term not written')
            kept.append(replace(f, terms=()))
        else:
            kept.append(f)
    return kept, gated


def _linear_part_correlations(model, recordings: Sequence, max_lag: int):
    """
    Return the correlations of ``model``'s inputs with the real forces minus its terms' force.

    A model with the traction/braking split gets it derived from each record's accelerations.
    """
    from wheel_force_estimator.core.correlations import CorrelationAccumulator
    linear = model.with_physics(())
    corr = CorrelationAccumulator(len(model.input_channels), len(model.output_channels),
                                  max_lag)
    for rec in recordings:
        inputs = model_inputs(model, np.asarray(rec.inputs, dtype=np.float64))
        target = np.asarray(rec.outputs, dtype=np.float64)
        if model.physics:
            target = target - (predict_forces(model, inputs) - predict_forces(linear, inputs))
        corr.add(inputs, target)
    return corr.result(model.fs_hz)


def with_live_estimators(model, recordings: Sequence, design, real_fit=None):
    """
    Return ``model`` with live (causal) estimators designed as ``fit`` designs them.

    The estimators are fitted on the real recordings (inputs -> forces, the causal
    least-squares FIR of :mod:`core.live_estimator`), minus the force the model's physics
    terms add there: the terms act on top of the live estimate as they do on the offline one,
    and the linear part of a ``real_frf+physics`` row was fitted the same way.  For rows
    taken from the simulation's FRF this makes the live estimate the real data's causal
    estimate rather than a causal copy of the simulation's map; measured on a 1-minute
    simulated pair (damper asymmetry, 50 ms look-ahead, holdout, 1 Hz high-passed): live
    44.2 % mean RMSE against 30.2 % offline for the written model (a plain `fit` on the same
    data: 46.1 % live, 33.2 % offline).  Designing on the written model's own offline
    prediction instead gave 53.3 % (its FIR ends, 8 s at each end of the record, had to be
    left out).

    Each row's live input set and ridge are the ones the real-data linear fit's
    cross-validation chose (``real_fit``, as ``fit`` writes them: :func:`core.search.chosen_live`);
    they were scored on the real forces without the terms, at the search's look-ahead (the
    default 50 ms).  Without a cross-validated ``real_fit`` (records too short to search, a
    fit on other inputs) every row gets ``design``'s ridge on every input.

    Parameters
    ----------
    model : FrfModel
        The model to write.
    recordings : sequence of MotionRecording
        The real training recordings (the inputs the car gives the node).
    design : LiveDesign
        Look-aheads (configured one first) and filter design.
    real_fit : DesignedFit, optional
        The run's real-data linear fit (``DiagnosisResult.real_fit``).

    Raises
    ------
    DiagnosisError
        The recordings are too short for the design's correlation lags.

    """
    from wheel_force_estimator.core.errors import WheelForceError
    from wheel_force_estimator.core.normal_equations import design_live
    from wheel_force_estimator.core.search import chosen_live
    from wheel_force_estimator.core.search import max_lag
    fs = model.fs_hz
    chosen = getattr(real_fit, 'chosen', None)
    if chosen is not None and tuple(real_fit.model.input_channels) != tuple(
            model.input_channels):
        chosen = None
    corr = _linear_part_correlations(
        model, recordings, design.max_lag(fs) if chosen is None else max_lag(design, fs))
    try:
        if chosen is None:
            live = design_live(corr, design)
        else:
            live = chosen_live(corr, chosen.choice, design, len(model.input_channels))
    except WheelForceError as err:
        raise DiagnosisError(f'cannot design the live estimators of the written model: '
                             f'{err}') from err
    return replace(model, live=live)
