# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Which model to write without a holdout: blocked cross-validation on the training recordings.

Without ``--holdout`` nothing unseen can judge the candidates, so the real training recordings
are cut into the contiguous blocks ``wheel-force fit`` cross-validates its resolution on
(:func:`core.resolution.fold_bounds`: ``N_FOLDS`` blocks per record).  Fold ``k`` fits every
candidate on the records without their block ``k`` (the pieces before and after, each a
gap-free record of its own, as ``fit`` joins recordings) - and a simulation's FRF on the
simulation without its block ``k``, so the reference is not judged with more data behind it
than the real-data FIR it competes with - and predicts each whole record; the
held-out blocks are cut out of that prediction as ``evaluate --samples`` cuts them and scored
together over all folds, in both figures ``evaluate`` reports (unfiltered and 1 Hz
high-passed).  Held-out samples are whole blocks, never interleaved samples: a FIR fitted on
every other sample would see the neighbours of each scored one.

The rule (:func:`pick_rows`), per group of linked channels
(:func:`choice.linked_channels`): a candidate is eligible when it is no worse than the
real-data linear model (a plain ``fit``) in *either* figure, mean over the group, over all
held-out blocks together and in every block on its own (:func:`held_out_scores`), and no
worse than the model it adds terms to over all blocks; the eligible one with the lowest
figure of the diagnosis' metric is written.  So the written model is never worse than the
plain fit on held-out data; where the terms do not pay, the plain fit is written and the
finding stays named with its description.
"""
from dataclasses import replace
from types import MappingProxyType
from typing import Callable, Dict, List, Mapping, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.resolution import fold_bounds
from wheel_force_estimator.core.sample_ranges import runs
from wheel_force_estimator.diagnosis.holdout import figures_of
from wheel_force_estimator.diagnosis.holdout import scored_pieces

#: Contiguous blocks per training record (as ``fit``'s resolution cross-validation).
N_FOLDS = 4
#: The two figures ``evaluate`` reports (keys of :func:`holdout.figures_of`).
FIGURES = ('rmse_pct', 'rmse_hp1_pct')


def training_folds(records: Sequence, n_folds: int = N_FOLDS
                   ) -> List[Tuple[List[np.ndarray], List[np.ndarray]]]:
    """
    Return the folds of blocked cross-validation: per fold ``(train masks, held-out masks)``.

    Parameters
    ----------
    records : sequence of MotionRecording
        The training recordings (each gap-free).
    n_folds : int
        Contiguous blocks per record; fold ``k`` holds out block ``k`` of every record.

    Returns
    -------
    list of (list of numpy.ndarray, list of numpy.ndarray)
        One boolean sample mask per record for the samples fitted on and those held out
        (complements of each other).

    """
    folds = []
    for k in range(n_folds):
        held = []
        for rec in records:
            a, b = fold_bounds(rec.n_samples, n_folds, k)
            mask = np.zeros(rec.n_samples, dtype=bool)
            mask[a:b] = True
            held.append(mask)
        folds.append(([~m for m in held], held))
    return folds


def cut(records: Sequence, masks: Sequence[np.ndarray]) -> List:
    """Return the runs of True samples of each record's mask, each a record of its own."""
    out = []
    for rec, mask in zip(records, masks):
        for a, b in runs(mask):
            out.append(replace(rec, name=f'{rec.name}[{a}..{b}]',
                               inputs=rec.inputs[:, a:b], outputs=rec.outputs[:, a:b],
                               start_s=rec.start_s + a / rec.fs_hz,
                               events=tuple(e for e in rec.events
                                            if a <= (e[0] - rec.start_s) * rec.fs_hz < b)))
    return out


def held_out_figures(build: Callable[[Sequence], Mapping[str, object]], records: Sequence,
                     folds) -> Dict[str, Dict[str, Dict[str, float]]]:
    """
    Score every candidate on the held-out blocks of all folds.

    Parameters
    ----------
    build : callable
        ``build(training records, fold index) -> {name: FrfModel}``: the candidates fitted
        on the records given (the same names in every fold); may raise ``DiagnosisError``.
    records : sequence of MotionRecording
        The training recordings.
    folds : list
        :func:`training_folds` of ``records``.

    Returns
    -------
    dict
        ``{name: {figure: {channel: RMSE %}}}`` for the figures of :data:`FIGURES`, each over
        the held-out pieces of every fold together.

    """
    return held_out_scores(build, records, folds)[0]


def held_out_scores(build: Callable[[Sequence], Mapping[str, object]], records: Sequence,
                    folds) -> Tuple[Dict[str, Dict[str, Dict[str, float]]],
                                    Dict[str, List[Dict[str, Dict[str, float]]]]]:
    """
    Return :func:`held_out_figures` and the same figures per fold (``{name: [per fold]}``).

    Each fold's figures are those of its own held-out block, scored by its own models.
    """
    pieces = held_out_pieces(build, records, folds)
    return ({name: figures_of([p for fold in per_fold for p in fold], records[0])
             for name, per_fold in pieces.items()},
            {name: [figures_of(fold, records[0]) for fold in per_fold]
             for name, per_fold in pieces.items()})


def held_out_pieces(build: Callable[[Sequence], Mapping[str, object]], records: Sequence,
                    folds) -> Dict[str, List[List]]:
    """
    Return ``{name: [pieces of fold k]}``: each fold's candidates on its held-out block.

    ``build`` and ``folds`` as for :func:`held_out_figures`; the pieces
    (:func:`holdout.scored_pieces`, cut as ``evaluate --samples`` cuts them) are what
    :func:`holdout.figures_of` scores, alone or pooled with other held-out data.
    """
    pieces: Dict[str, List[List]] = {}
    for k, (train, held) in enumerate(folds):
        for name, model in build(cut(records, train), k).items():
            pieces.setdefault(name, []).append(
                scored_pieces(lambda r, m=model: predict_forces(m, r.inputs), records, held))
    return pieces


def fixed_figures(predict: Callable, records: Sequence, folds) -> Dict[str, Dict[str, float]]:
    """Return both figures of a model fitted on none of ``records``, on the held-out blocks."""
    pieces = [p for _, held in folds for p in scored_pieces(predict, records, held)]
    return figures_of(pieces, records[0])


def _group_mean(scores, figure: str, group: Sequence[str]) -> float:
    return float(np.mean([scores[figure][c] for c in group]))


def _no_worse(scores, blocks, group: Sequence[str], name: str, than: str,
              every_block: bool = False) -> bool:
    """Return whether ``name`` is no worse than ``than`` on ``group`` in either figure."""
    tables = [(scores[name], scores[than])]
    if every_block and name in blocks and than in blocks:
        tables += list(zip(blocks[name], blocks[than]))
    return all(_group_mean(a, fig, group) <= _group_mean(b, fig, group)
               for a, b in tables for fig in FIGURES)


def pick_rows(scores: Mapping[str, Mapping[str, Mapping[str, float]]],
              groups: Sequence[Sequence[str]], touched, baseline: str, metric: str,
              plain: Sequence[str], fixed: Sequence[str] = (),
              bases: Mapping[str, str] = MappingProxyType({}),
              blocks: Mapping[str, Sequence] = MappingProxyType({})) -> Dict[str, str]:
    """
    Return ``{channel: candidate}``: per group, the best candidate no worse than the baseline.

    Parameters
    ----------
    scores : mapping
        :func:`held_out_figures` of the candidates (in order of preference on a tie).
    groups : sequence of sequence of str
        Channels that must come from one candidate.
    touched : set of str
        Channels a physics term acts on or reads; a group without one chooses among
        ``plain`` (models without terms) only.
    baseline : str
        The real-data linear model: a candidate worse than it in either figure (mean over
        the group) is not eligible.
    metric : str
        The figure of :data:`FIGURES` the eligible candidates are ranked by.
    plain : sequence of str
        The candidates without terms.
    bases : mapping str -> str
        Candidate -> the candidate it adds terms to (``sim_frf+physics`` -> ``sim_frf``): a
        candidate with terms must also be no worse than its own base in either figure, or
        the terms did not pay (the training blocks fit the real-data FIR on less data than
        the written one, so the plain fit alone is a lenient bar for the reference's terms).
    blocks : mapping str -> sequence of mapping
        Per candidate, the figures of each held-out block (:func:`held_out_scores`): when
        given, a candidate replaces the baseline only if it is no worse than it in either
        figure in every block as well.  Pooled squares let one block decide: on 1-minute
        records the block of a road event no other block holds is one the FIRs fitted
        without it extrapolate to (a quasi-static load transfer: 300-700 % unfiltered for
        the real-data FIR there, 10-16 % on the other blocks), so the pooled figure chose
        the simulation's rows where a new recording of the whole course found them 50 %
        worse unfiltered.
    fixed : sequence of str
        Channels that take the baseline without a vote when no term touches them: where a
        clipped accelerometer or a tyre in the air was found, the reference's rows were
        fitted on motion the real car does not make (simulator, 3 seeds: a deciding half
        took the simulation's rows for one Fz and the report half found them 0.05 and 0.01
        points worse).

    """
    names = list(scores)
    pick: Dict[str, str] = {}
    for group in groups:
        pool = names if touched.intersection(group) else [n for n in names if n in plain]
        if not touched.intersection(group) and set(group) <= set(fixed):
            pool = [baseline]
        eligible = [n for n in pool
                    if _no_worse(scores, blocks, group, n, baseline, every_block=True)
                    and (n not in bases or _no_worse(scores, blocks, group, n, bases[n]))]
        best = min(eligible or [baseline],
                   key=lambda n: (_group_mean(scores[n], metric, group), names.index(n)))
        pick.update(dict.fromkeys(group, best))
    return pick
