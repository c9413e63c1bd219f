# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The choice of the model ``--out-model`` writes, and its before / real_linear / after figures.

Candidates (:func:`candidate_builder`, those that exist for the run): the reference FRF plus
the findings' terms (``sim_frf+physics`` / ``model+physics``, strengths refitted on the
training data), the real-data FRF plus the terms fitted jointly
(``real_frf+physics``, :func:`written.backfitted_model`), the reference unchanged
(``sim_frf`` / ``model``) and the real-data linear model (``real_linear``, a plain ``fit``);
each candidate with terms twice, its force laws bounded to the force they added where they
were fitted (:func:`written.bounded_terms`) and unbounded.

They are judged on data none of them was fitted on - the gate half of the holdout
(:func:`_held_out`; each bounded / unbounded pair first reduced to one on the held-out blocks
of the training recordings pooled with the gate half, :func:`_one_twin_each`) or, without
one, held-out blocks of the training recordings (:func:`_cross_validated`,
:mod:`diagnosis.crossval`) - and per group of linked channels
(:func:`linked_channels`) the rule :func:`crossval.pick_rows` writes the best candidate no
worse than the plain fit, nor than the model it adds terms to, in either figure; the rows
are combined by :func:`combine`.  Every score runs through ``core.predict.predict_forces``,
the path ``evaluate``, ``predict`` and the node take.
"""
from dataclasses import replace
from typing import Dict, List, Mapping, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.model_rows import compatible
from wheel_force_estimator.core.model_rows import compose_rows
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.spindle import component_groups
from wheel_force_estimator.diagnosis.crossval import cut
from wheel_force_estimator.diagnosis.crossval import FIGURES
from wheel_force_estimator.diagnosis.crossval import fixed_figures
from wheel_force_estimator.diagnosis.crossval import held_out_pieces
from wheel_force_estimator.diagnosis.crossval import held_out_scores
from wheel_force_estimator.diagnosis.crossval import pick_rows
from wheel_force_estimator.diagnosis.crossval import training_folds
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.holdout import evaluate_figures
from wheel_force_estimator.diagnosis.holdout import figures_of
from wheel_force_estimator.diagnosis.holdout import holdout_gate
from wheel_force_estimator.diagnosis.holdout import METRIC
from wheel_force_estimator.diagnosis.holdout import scored_pieces
from wheel_force_estimator.diagnosis.holdout import split_holdout
from wheel_force_estimator.diagnosis.prepared import prepare
from wheel_force_estimator.diagnosis.reference import FrfReference
from wheel_force_estimator.diagnosis.result import figure_keys
from wheel_force_estimator.diagnosis.result import FitComparison
from wheel_force_estimator.diagnosis.written import backfitted_model
from wheel_force_estimator.diagnosis.written import backfitted_models
from wheel_force_estimator.diagnosis.written import bounded_terms
from wheel_force_estimator.diagnosis.written import gate_dynamic
from wheel_force_estimator.diagnosis.written import has_joint_step
from wheel_force_estimator.diagnosis.written import is_dynamic
from wheel_force_estimator.diagnosis.written import term_dicts


def linked_channels(candidates: Mapping[str, object], channels: Sequence[str]) -> List[List[str]]:
    """
    Return the groups of output channels that must come from one model.

    Linked are the channels a physics term spans or couples.
    A term's parameters are shared by all its channels, and a load-state term reads the
    prediction of its partner outputs, so those channels are linked (union over every
    candidate's terms); every other channel stands alone.
    """
    parent = {c: c for c in channels}

    def root(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c
    for model in candidates.values():
        for term in model.physics_terms:
            linked = [c for c in tuple(term.channels) + tuple(term.partners) if c in parent]
            for c in linked[1:]:
                parent[root(c)] = root(linked[0])
    groups: Dict[str, List[str]] = {}
    for c in channels:
        groups.setdefault(root(c), []).append(c)
    return list(groups.values())


def choice_groups(candidates: Mapping[str, object], channels: Sequence[str],
                  fixed: Sequence[str] = ()) -> List[List[str]]:
    """
    Return the groups of channels that take their row from one candidate.

    The channels a term links (:func:`linked_channels`), and the channels no term touches
    grouped per wheel force component (:func:`core.spindle.component_groups`: the four
    corners' ``fy`` rows choose together, as ``fit`` chooses their input set together); a
    channel of ``fixed`` (it takes the plain fit without a vote) and any channel that is not
    ``{corner}_{component}`` stand alone.

    Why the plain rows of a component choose together: the real-data rows were designed for
    the four corners together, and one row's blocks of a minute-long record are a learning
    curve more than a verdict.  Simulator, damper asymmetry, seed 7, 1-minute course: every
    block of ``lf_fy`` alone preferred the simulation's row (by 2 to 95 points, the block of
    the only figure-8 most), the row a new recording of the course found 4 points worse
    unfiltered (17 against 13 %) and 5 high-passed; the four ``fy`` rows' mean preferred the
    plain fit's rows in a block, and the new recording found those better on all four.
    """
    touched = touched_channels(candidates)
    component = {channels[o]: k for k, rows in enumerate(component_groups(channels))
                 for o in rows}
    groups, merged = [], {}
    for group in linked_channels(candidates, channels):
        if len(group) > 1 or group[0] in touched or group[0] in fixed:
            groups.append(group)
            continue
        key = component[group[0]]
        if key not in merged:
            merged[key] = []
            groups.append(merged[key])
        merged[key].extend(group)
    return groups


def combine(candidates: Mapping[str, object], pick: Mapping[str, str],
            channels: Sequence[str]) -> Tuple[object, str, str]:
    """
    Return ``(model, fit.model, note)``: each channel's row (and its terms) from ``pick``.

    Every output row of the FRF is its own fit (:mod:`core.model_rows`), so no channel needs
    to take the model another channel prefers: a finding on the vertical channels may be best
    served by the real-data FRF with its terms while the lateral channels keep another
    model's rows.  A term comes along with the rows of the candidate it belongs to.  One
    candidate picked everywhere: that candidate whole.  Rows that cannot be combined (other
    resolutions): the real-data linear model whole, never worse than itself, and ``note``
    says why.
    """
    names = list(candidates)
    if len(set(pick.values())) < 2:
        name = next(iter(pick.values()))
        return candidates[name], public_name(name), ''
    models = [candidates[n] for n in names]
    ok, why = compatible(models)
    if not ok:
        return (candidates['real_linear'], 'real_linear',
                f'rows not combined per channel ({why}): the plain fit is written whole')
    terms = [t.to_dict() for n in names for t in candidates[n].physics_terms
             if all(pick[c] == n for c in t.channels)]
    base = max(names, key=lambda n: sum(v == n for v in pick.values()))
    fit = dict(candidates[base].fit)
    fit['rows_from'] = {c: public_name(n) for c, n in pick.items()}
    model = compose_rows(models, [names.index(pick[c]) for c in channels], terms, fit)
    return model, PER_CHANNEL, ''


def written_rows(pick: Mapping[str, str], choice: str, notes: List[str]) -> Dict[str, str]:
    """
    Return ``fit.rows_from`` of the written model (public names), noting the joint strengths.

    ``choice`` is :func:`combine`'s ``fit.model``: rows only for a per-channel model.
    """
    joint = [c for c, n in pick.items() if n.startswith(JOINT)]
    if joint:
        notes.append('Backfit strengths: the joint least-squares step, chosen over the '
                     'alternation on held-out data, for ' + ', '.join(joint) + '.')
    free = [c for c, n in pick.items() if n.endswith(UNBOUNDED)]
    if free:
        notes.append('Unbounded terms: the force laws extrapolate beyond the force they added '
                     'on the training recordings, chosen over the bounded laws on held-out '
                     'data, for ' + ', '.join(free) + '.')
    return {c: public_name(n) for c, n in pick.items()} if choice == PER_CHANNEL else {}


def public_name(name: str) -> str:
    """Return the ``fit.model`` / ``fit.rows_from`` name of candidate ``name``."""
    name = name.removesuffix(UNBOUNDED)
    return 'real_frf+physics' if name == JOINT else name


#: ``fit.model`` of the reference written unchanged, per diagnosis mode.
UNCHANGED = {'sim': 'sim_frf', 'model': 'model', 'linear': 'real_linear'}
#: ``fit.model`` of a model combined per channel (``fit.rows_from`` names each row's source).
PER_CHANNEL = 'per_channel'
#: ``fit.model`` of the reference FRF plus the findings' terms, per mode.
AUGMENTED = {'sim': 'sim_frf+physics', 'model': 'model+physics', 'linear': 'real_frf+physics'}
#: The real-data FRF plus the terms from the joint least-squares strengths: a candidate of its
#: own, written (and reported) as ``real_frf+physics`` with a note.
JOINT = 'real_frf+physics (joint strengths)'
#: Suffix of a candidate whose terms keep their force laws beyond the training range
#: (:func:`candidate_builder`); written and reported under the name without it, with a note.
UNBOUNDED = ' (unbounded)'


def _reference_with_terms(with_terms, recordings, ref_model, real_fit, hp, skip):
    """
    Return the reference FRF plus the findings' terms, their strengths fitted on ``recordings``.

    The terms' shapes come from the selection; their strengths are refitted on the records
    given (the training blocks of a fold) with the reference FRF kept, so the candidate is
    judged on blocks none of its strengths saw.  A reference that carries physics of its own
    (a ``--model`` written by a diagnosis) keeps the selection's strengths.
    """
    if ref_model.physics:
        return ref_model.with_physics(list(ref_model.physics) + term_dicts(
            t for f in with_terms for t in f.terms))
    return backfitted_model(with_terms, recordings, ref_model, real_fit, hp, skip,
                            iterations=0)[0]


def candidate_builder(findings, ref_model, mode: str, real_fit, hp: float, skip: int):
    """
    Return ``build(recordings, linear=None, reference=None, only=None) -> {name: FrfModel}``.

    The candidates fitted on ``recordings`` (``reference``: the reference FRF to use instead
    of ``ref_model``, e.g. one fitted on the simulation's training blocks; ``only``: the
    names, without :data:`UNBOUNDED`, of the candidates to build, all when None).

    In order of preference on a tie: the reference FRF plus the findings' terms, the real-data
    FRF plus the terms fitted jointly (:func:`backfitted_model`), the same from the joint
    least-squares strengths (:data:`JOINT`, when :func:`written.has_joint_step`), the
    reference unchanged, the real-data linear model (``linear``, or
    ``real_fit(recordings)``), then each candidate whose terms :func:`bounded_terms` bounded
    again with its force laws unbounded (``name`` + :data:`UNBOUNDED`: a stop the training
    records never pressed as hard as a new one does is only right unbounded, a law fed by a
    wild linear prediction only bounded, and only held-out data can tell which case this
    is).  Without a finding that carries terms, the reference unchanged and the linear only;
    without a reference FRF, the real-data ones.
    """
    with_terms = [f for f in findings if f.terms]
    joint = bool(with_terms) and has_joint_step(with_terms)

    def build(recordings, linear=None, reference=None, only=None):
        wanted = (lambda name: True) if only is None else only.__contains__
        ref = ref_model if reference is None else reference
        if linear is None and any(wanted(n) for n in ('real_frf+physics', JOINT, 'real_linear')):
            linear = real_fit(recordings)
        out = {}
        if with_terms and ref is not None and mode != 'linear' and wanted(AUGMENTED[mode]):
            out[AUGMENTED[mode]] = _reference_with_terms(with_terms, recordings, ref,
                                                         real_fit, hp, skip)
        # the alternation and the joint start share their first fit (one call)
        starts = [False] * bool(with_terms and wanted('real_frf+physics'))
        starts += [True] * bool(joint and wanted(JOINT))
        fitted = backfitted_models(with_terms, recordings, linear, real_fit, hp, skip,
                                   starts=starts) if starts else {}
        if False in fitted:
            out['real_frf+physics'] = fitted[False][0]
        if True in fitted:
            out[JOINT] = fitted[True][0]
        if ref is not None and mode != 'linear' and wanted(UNCHANGED[mode]):
            out[UNCHANGED[mode]] = ref
        if wanted('real_linear'):
            out['real_linear'] = linear
        # every term fitted here held within the force it added on the records it was
        # fitted on (the reference's own terms, a --model's, stay as they are), and the same
        # candidate with its laws unbounded after it: the held-out blocks choose
        own = ref.physics_terms if ref is not None else ()
        bounded = {name: bounded_terms(model, recordings, own) for name, model in out.items()}
        return {**bounded, **{name + UNBOUNDED: model for name, model in out.items()
                              if bounded[name] is not model}}
    return build


def _bases(candidates) -> Dict[str, str]:
    """Return candidate -> the candidate it adds terms to (both present)."""
    pairs = [(AUGMENTED[m], UNCHANGED[m]) for m in ('sim', 'model')]
    pairs += [('real_frf+physics', 'real_linear'), (JOINT, 'real_frf+physics')]
    pairs += [(n + UNBOUNDED, b) for n, b in pairs]
    # a base of which only the unbounded twin is left (:func:`_one_twin_each`) stands in
    pairs += [(n, b + UNBOUNDED) for n, b in pairs if b not in candidates]
    return {n: b for n, b in pairs if n in candidates and b in candidates}


def touched_channels(candidates) -> set:
    """Channels some candidate's physics term acts on."""
    return {c for m in candidates.values() for t in m.physics_terms for c in t.channels}


def plain_names(candidates) -> List[str]:
    """Candidates without physics terms."""
    return [n for n, m in candidates.items() if not m.physics]


def _figures_of_pick(scores, pick, figure) -> Dict[str, float]:
    return {c: scores[name][figure][c] for c, name in pick.items()}


def _comparison(before, real_lin, after, data, metric, **kwargs) -> FitComparison:
    """Return a :class:`FitComparison` of both-figure scores (None: no figures)."""
    figures = {}
    for name, scores in (('before', before), ('real_linear', real_lin), ('after', after)):
        if scores is not None:
            figures.update(figure_keys(name, scores))
    return FitComparison(before[metric] if before else {}, after[metric] if after else {},
                         data, real_lin[metric] if real_lin else None,
                         1.0 if metric == 'rmse_hp1_pct' else 0.0, figures=figures, **kwargs)


def _fold_reference(sim, sim_fit, fold: int):
    """Return the reference refitted on the simulation without its block ``fold``, or None."""
    if not sim or sim_fit is None:
        return None
    try:
        return sim_fit(cut(sim, training_folds(sim)[fold][0]))
    except DiagnosisError:
        return None  # the simulation too short for its folds: its full fit stands


def _cross_validated(findings, real, reference, ref_model, mode, channels, real_fit,
                     lin_model, hp, skip, notes, sim=(), sim_fit=None):
    """
    Choose and score the written model on held-out blocks of the training recordings.

    The candidates of :func:`candidate_builder` are fitted on the other blocks of each fold
    and scored on the held-out ones (:mod:`diagnosis.crossval`); per linked group the best
    one no worse than the real-data linear model in either figure is written, refitted on all
    training recordings.  Records too short for the folds: the real-data linear model is
    written (``fit.data`` ``'too_short'``, a note says why).
    """
    metric = METRIC[real[0].input_quantity]
    with_terms = [t for f in findings for t in f.terms]
    if lin_model is None:
        # no real-data model at all: the reference (and its terms) is all there is
        if ref_model is None:
            return findings, _comparison(None, None, None, 'too_short', metric,
                                         notes=tuple(notes)), None
        model = ref_model.with_physics(list(ref_model.physics) + term_dicts(with_terms))
        name = AUGMENTED[mode] if with_terms else UNCHANGED[mode]
        return findings, _comparison(None, None, None, 'too_short', metric, model=name,
                                     notes=tuple(notes)), model
    build = candidate_builder(findings, ref_model, mode, real_fit, hp, skip)
    folds = training_folds(real)

    def fold_build(recordings, fold):
        return build(recordings, reference=_fold_reference(sim, sim_fit, fold))
    try:
        scores, blocks = held_out_scores(fold_build, real, folds)
    except DiagnosisError as err:
        lengths = ', '.join(f'{r.name} ({r.n_samples / r.fs_hz:.1f} s)' for r in real)
        notes.append(f'training recordings too short to hold out blocks of a quarter each: '
                     f'{lengths} ({err}); the plain fit on the real data is written, the '
                     f'findings are named only')
        return findings, _comparison(None, None, None, 'too_short', metric,
                                     model='real_linear', notes=tuple(notes)), lin_model
    final = build(real, lin_model)
    pick = pick_rows(scores, choice_groups(final, channels), touched_channels(final),
                     'real_linear', metric, plain_names(final), bases=_bases(final),
                     blocks=blocks)
    model, choice, note = combine(final, pick, channels)
    if note:
        notes.append(note)
        pick = dict.fromkeys(channels, 'real_linear')
    rows_from = written_rows(pick, choice, notes)
    after = {fig: _figures_of_pick(scores, pick, fig) for fig in FIGURES}
    if ref_model is not None:
        before = scores[UNCHANGED[mode]]
    else:
        before = fixed_figures(reference.predict, real, folds)
    fit = _comparison(before, scores['real_linear'], after, 'cross_validation', metric,
                      model=choice, notes=tuple(notes), rows_from=rows_from)
    return findings, fit, model


def compare(findings, real, reference, mode, holdout, channels, sources, partners,
            config, real_fit, lin_model, motion_channels=(), notes=(), sim=(), sim_fit=None):
    """
    Choose the written model, score before / real_linear / after in both figures.

    ``mode`` is ``'sim'``, ``'model'`` or ``'linear'`` (reference fitted on ``real``);
    ``real_fit(recordings) -> FrfModel`` fits with the design of ``wheel-force fit``;
    ``lin_model`` is ``real_fit(real)`` (None when the records cannot be fitted; ``notes``
    says why).  Without ``holdout`` the candidates are judged on held-out blocks of ``real``
    (:func:`_cross_validated`); with one, on its gate half, and the terms that make the gate
    half worse leave the model (their findings stay named: the holdout judges models, not
    names).  ``motion_channels`` are the channels of motion findings (see
    :func:`crossval.pick_rows`' ``fixed``); ``sim`` the simulation recordings and
    ``sim_fit(recordings) -> FrfModel`` the reference's fit on them (refitted per fold).
    Returns ``(findings, FitComparison, written
    model or None)``.
    """
    rec0 = real[0]
    hp = config.selection.highpass_hz
    skip = settle_samples(rec0.fs_hz, rec0.input_quantity, config.features)
    ref_model = reference.model if isinstance(reference, FrfReference) else None
    notes = list(notes)
    if not holdout:
        return _cross_validated(findings, real, reference, ref_model, mode, channels,
                                real_fit, lin_model, hp, skip, notes, sim, sim_fit)
    return _held_out(findings, real, reference, ref_model, mode, holdout, channels, sources,
                     partners, config, real_fit, lin_model, motion_channels, hp, skip, notes)


def _gated(findings, real, reference, holdout, split, channels, sources, partners, config,
           real_fit, lin_model, hp, skip, notes):
    """
    Strip the terms the gate half finds harmful (:func:`holdout.holdout_gate`).

    Returns ``(findings in their order, rejection lines)``.
    """
    metric = METRIC[real[0].input_quantity]
    # Terms inside the structure were fitted with the FIR refitted around them (their linear
    # part partialled out, :mod:`finders.structure`): added to the reference as it is, they
    # would count that part twice, so the gate judges them on the refitted model.
    dynamic = [f for f in findings if is_dynamic(f)]
    static = [f for f in findings if not is_dynamic(f)]
    gate_prep = prepare(split.whole, reference, sources, partners, config)
    masks = split.gate_masks(gate_prep.spans)
    if masks is not None and not any(m.any() for m in masks):
        notes.append('holdout too short: its gate half lies within the filter settling '
                     'time, no finding was gated')
        return static + dynamic, ()
    static, gated = holdout_gate(static, gate_prep, channels, hp, masks)
    if dynamic and lin_model is not None:
        dynamic, gated_dynamic = gate_dynamic(dynamic, real, lin_model, real_fit,
                                              split.gate_half, metric, hp, skip)
        gated = tuple(gated) + tuple(gated_dynamic)
    return static + dynamic, tuple(gated)


def _held_out(findings, real, reference, ref_model, mode, holdout, channels, sources,
              partners, config, real_fit, lin_model, motion_channels, hp, skip, notes):
    """Gate, choose on the gate half and score on the report half of the holdout."""
    metric = METRIC[real[0].input_quantity]
    split = split_holdout(holdout)
    findings, gated = _gated(findings, real, reference, holdout, split, channels, sources,
                             partners, config, real_fit, lin_model, hp, skip, notes)
    with_terms = [f for f in findings if f.terms]
    gate = split.gate_half
    build = None
    if lin_model is not None:
        build = candidate_builder(findings, ref_model, mode, real_fit, hp, skip)
        candidates = build(real, lin_model)
    elif ref_model is not None:
        terms = term_dicts(t for f in with_terms for t in f.terms)
        candidates = {AUGMENTED[mode] if terms else UNCHANGED[mode]:
                      ref_model.with_physics(list(ref_model.physics) + terms)}
    else:
        candidates = {}
    # each candidate predicted on the gate half once: the twins' choice and the gate's share it
    gate_pieces = {n: scored_pieces(lambda r, m=m: predict_forces(m, r.inputs), gate.records,
                                    gate.masks)
                   for n, m in candidates.items()} if len(candidates) > 1 else {}
    if build is not None:
        candidates = _one_twin_each(candidates, gate_pieces, build, real, metric, notes)
    named = sorted({c for f in with_terms for c in f.channels}) or list(motion_channels)
    gate_scores, model, choice, rows_from = {}, None, '', {}
    if len(candidates) == 1:
        choice, model = next(iter(candidates.items()))
    elif candidates:
        scores = {n: figures_of(gate_pieces[n], gate.records[0]) for n in candidates}
        gate_scores = {n: float(np.mean([s[metric][c] for c in named or channels]))
                       for n, s in scores.items()}
        pick = pick_rows(scores, choice_groups(candidates, channels, motion_channels),
                         touched_channels(candidates), 'real_linear', metric,
                         plain_names(candidates), fixed=motion_channels,
                         bases=_bases(candidates))
        model, choice, note = combine(candidates, pick, channels)
        if note:
            notes.append(note)
            pick = dict.fromkeys(channels, 'real_linear')
        rows_from = written_rows(pick, choice, notes)
    shown = split.report_half
    before = evaluate_figures(reference.predict, shown.records, shown.masks)
    real_lin = (evaluate_figures(lambda r: predict_forces(lin_model, r.inputs), shown.records,
                                 shown.masks) if lin_model is not None else None)
    after = (evaluate_figures(lambda r: predict_forces(model, r.inputs), shown.records,
                              shown.masks) if model is not None else before)
    findings = [replace(f, rmse_after_pct={c: after[metric][c] for c in f.channels})
                for f in findings]
    fit = _comparison(before, real_lin, after, 'holdout', metric, model=choice,
                      report_on=split.report_on, gate=gate_scores, notes=tuple(notes),
                      gated=gated, rows_from=rows_from)
    return findings, fit, model


def _one_twin_each(candidates, gate_pieces, build, real, metric: str, notes: List[str]):
    """
    Return ``candidates`` with one law of each bounded / unbounded pair: all held-out data's.

    With ``--holdout`` the gate half chooses among the candidates; but the twins differ only
    where a term's force leaves the range it took on the training recordings, which the gate
    half may never do (the rig with a bump stop, seed 0: its gate half scored the twins
    7.8007 against 7.8007 %, its report half, pressed harder, 10.02 against 7.59 %).  The
    held-out blocks of the training recordings (:func:`crossval.training_folds`, each fold's
    twins bounded to its own training blocks) do hold such motion, so each pair is judged on
    them pooled with the gate half (``gate_pieces``: each candidate's
    :func:`holdout.scored_pieces` there), by the mean of ``metric`` over the channels its
    terms act on; the unbounded law must be better, the bounded one stays on a tie.  Records
    too short for the folds: the gate half alone judges.  ``notes`` gets one line per pair.
    """
    pairs = [(n, n + UNBOUNDED) for n in candidates if n + UNBOUNDED in candidates]
    if not pairs:
        return candidates

    def fold_build(recordings, _fold):
        fold = build(recordings, only={b for b, _ in pairs})
        # a fold whose terms stayed within their range has no twin: the same law
        return {name: fold.get(name, fold[bounded])
                for bounded, free in pairs for name in (bounded, free)}
    pooled = 'the held-out blocks of the training recordings and the gate half'
    try:
        blocks = held_out_pieces(fold_build, real, training_folds(real))
    except DiagnosisError as err:
        pooled = f'the gate half alone (training recordings too short for folds: {err})'
        blocks = {}
    drop = set()
    for bounded, free in pairs:
        channels = sorted({c for t in candidates[free].physics_terms for c in t.channels})
        score = {}
        for name in (bounded, free):
            pieces = gate_pieces[name] + [p for fold in blocks.get(name, ()) for p in fold]
            figure = figures_of(pieces, real[0])[metric]
            score[name] = float(np.mean([figure[c] for c in channels]))
        drop.add(bounded if score[free] < score[bounded] else free)
        notes.append(f'{bounded}: force laws '
                     f'{"unbounded" if bounded in drop else "bounded"} ({metric} over '
                     f'{", ".join(channels)}: {score[free]:.3f} % unbounded vs '
                     f'{score[bounded]:.3f} % bounded on {pooled}).')
    return {n: m for n, m in candidates.items() if n not in drop}
