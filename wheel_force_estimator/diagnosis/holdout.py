# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Holdout comparisons of a diagnosis: the gate/report split, scores, the holdout gate.

``prep`` arguments are the prepared records of :mod:`diagnosis.prepared` (``recordings``,
``targets``, ``predictions`` and ``full_predictions`` of the reference, settling removed).

The holdout is split in two (:func:`split_holdout`) so that a user can reproduce every reported
figure with ``wheel-force evaluate``: with two or more holdout files (bags or generic files),
whole files alternate - the 1st, 3rd, ... decide (the gate that drops findings which make unseen
data worse, and the choice of the model ``--out-model`` writes), the 2nd, 4th, ... report.  A
single holdout file is predicted whole and its samples are split: each gap-free segment into
contiguous halves (first half gate, second half report) - or, when the file carries road-event
markers (a proving-ground bag), every event into halves (its first half decides, its second
half reports).  Contiguous halves of a course give the gate the first events only (rough roads)
and the report the rest (manoeuvres): on the simulator the gate then preferred terms and rows
that were 3-9 points worse than the plain fit or the simulation on the report half (a stop
fitted on rough-road engagements firing through a slalom's sustained load, a clip term).
Every reported figure (:func:`evaluate_scores`) is the RMSE ``core.evaluation.evaluate_segments``
reports (its ``rmse_figures``) of the report records predicted through
``core.predict.predict_forces`` - the path ``wheel-force evaluate`` runs - and, for a single
file, of the report samples cut from the whole-record prediction as ``evaluate FILE --samples
A..B,...`` cuts them (``core.evaluation.select_samples``; ``fit.report_on`` prints the
command's arguments), so no reported number comes from data that took part in a decision.
"""
from dataclasses import dataclass
from dataclasses import replace
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.evaluation import EvalSegment
from wheel_force_estimator.core.evaluation import rmse_figures
from wheel_force_estimator.core.evaluation import select_samples
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.sample_ranges import format_ranges
from wheel_force_estimator.core.sample_ranges import runs
from wheel_force_estimator.diagnosis import text
from wheel_force_estimator.diagnosis.recording import MotionRecording


@dataclass(frozen=True)
class Scored:
    """
    Records and the samples of each that are scored (``masks`` None: every sample).

    Attributes
    ----------
    records : tuple of MotionRecording
        Whole records (or cut halves).
    masks : tuple of numpy.ndarray of bool, optional
        Per record, the samples scored.

    """

    records: Tuple[MotionRecording, ...]
    masks: Optional[Tuple[np.ndarray, ...]] = None


@dataclass(frozen=True)
class HoldoutSplit:
    """
    The holdout cut into the half that decides and the half that reports.

    Attributes
    ----------
    gate, report : tuple of MotionRecording
        Records of each half.
    report_on : tuple of str
        What ``wheel-force evaluate`` must be given to reproduce the reported figures (files,
        or ``FILE --samples A..B,...`` for a single holdout file).
    whole : tuple of MotionRecording
        The records the gate's features are computed on (whole records, so their filters
        settle before the gate half starts).
    gate_samples, report_samples : tuple of numpy.ndarray of bool, optional
        Per record (a single holdout file), the samples of each half; None: every sample of
        the half's records (two or more files).

    """

    gate: Tuple[MotionRecording, ...]
    report: Tuple[MotionRecording, ...]
    report_on: Tuple[str, ...]
    whole: Tuple[MotionRecording, ...] = ()
    gate_samples: Optional[Tuple[np.ndarray, ...]] = None
    report_samples: Optional[Tuple[np.ndarray, ...]] = None

    @property
    def gate_half(self) -> Scored:
        """Return the deciding records and their scored samples."""
        return Scored(self.gate, self.gate_samples)

    @property
    def report_half(self) -> Scored:
        """Return the reporting records and their scored samples."""
        return Scored(self.report, self.report_samples)

    def gate_masks(self, spans) -> Optional[List[np.ndarray]]:
        """Masks of the gate samples over prepared spans of :attr:`whole` (None = all)."""
        if self.gate_samples is None:
            return None
        return [m[a:b] for m, (a, b) in zip(self.gate_samples, spans)]


def source_file(rec: MotionRecording) -> str:
    """Return the file a record came from (bag segments are named ``PATH#i``)."""
    path, sep, index = rec.name.rpartition('#')
    return path if sep and index.isdigit() else rec.name


def _event_spans(rec: MotionRecording) -> List[Tuple[int, int]]:
    """
    Return the sample spans of the road events in ``rec`` (before the first: a span too).

    Event starts outside the record are left out; spans shorter than 2 samples are merged
    into the one before (they cannot be halved).
    """
    starts = sorted({int(round((t - rec.start_s) * rec.fs_hz)) for t, _ in rec.events})
    cuts = [0] + [s for s in starts if 0 < s < rec.n_samples] + [rec.n_samples]
    spans = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if spans and b - a < 2:
            spans[-1] = (spans[-1][0], b)
        elif b > a:
            spans.append((a, b))
    return spans


#: Separates a ``fit.report_on`` entry's file from its report samples.
SAMPLES_OPTION = ' --samples '


def evaluate_arguments(report_on: str) -> List[str]:
    """Return the ``wheel-force evaluate`` arguments of a ``fit.report_on`` entry."""
    path, sep, samples = report_on.partition(SAMPLES_OPTION)
    return [path, SAMPLES_OPTION.strip(), samples] if sep else [path]


def split_holdout(holdout: Sequence[MotionRecording]) -> HoldoutSplit:
    """
    Split holdout records into gate and report halves (see the module notes).

    Whole files alternate when there are two or more (1st, 3rd, ... gate; 2nd, 4th, ...
    report); a single file with road-event markers is cut per event (first half of each
    event gate, second half report: sample masks over whole records); any other single file
    into contiguous halves per segment.
    """
    files = list(dict.fromkeys(source_file(r) for r in holdout))
    if len(files) >= 2:
        report_files = files[1::2]
        gate = tuple(r for r in holdout if source_file(r) not in report_files)
        report = tuple(r for r in holdout if source_file(r) in report_files)
        return HoldoutSplit(gate, report, tuple(report_files), gate)
    whole = tuple(holdout)
    per_event = any(len(_event_spans(r)) >= 2 for r in holdout)
    gate_masks = []
    for rec in whole:
        gate_mask = np.zeros(rec.n_samples, dtype=bool)
        for a, b in (_event_spans(rec) if per_event else [(0, rec.n_samples)]):
            gate_mask[a:a + (b - a) // 2] = True
        gate_masks.append(gate_mask)
    report_masks = tuple(~m for m in gate_masks)
    # evaluate --samples counts the file's samples over its segments in order
    offsets = np.cumsum([0] + [r.n_samples for r in whole[:-1]])
    ranges = [(int(a + o), int(b + o)) for m, o in zip(report_masks, offsets) for a, b in runs(m)]
    report_on = (f'{files[0]}{SAMPLES_OPTION}{format_ranges(ranges)}',)
    return HoldoutSplit(whole, whole, report_on, whole, tuple(gate_masks), report_masks)


#: Metric of the reported figures per input quantity: an acceleration FRF cannot follow
#: quasi-static load (the spindle acceleration of a steady load transfer is ~0), so vehicle
#: figures are the paper's 1 Hz high-passed RMSE; displacement and velocity inputs see the
#: quasi-static motion, and rig tests often run below 1 Hz, so their figures are unfiltered.
METRIC = {'acceleration': 'rmse_hp1_pct', 'velocity': 'rmse_pct', 'displacement': 'rmse_pct'}


def evaluate_scores(predict: Callable[[MotionRecording], np.ndarray],
                    recordings: Sequence[MotionRecording], metric: str,
                    masks: Optional[Sequence[np.ndarray]] = None) -> Dict[str, float]:
    """Return the ``metric`` figures of :func:`evaluate_figures` (RMSE % per channel)."""
    return evaluate_figures(predict, recordings, masks)[metric]


def evaluate_figures(predict: Callable[[MotionRecording], np.ndarray],
                     recordings: Sequence[MotionRecording],
                     masks: Optional[Sequence[np.ndarray]] = None
                     ) -> Dict[str, Dict[str, float]]:
    """
    RMSE % per channel exactly as ``wheel-force evaluate`` computes it for these records.

    Returns ``{'rmse_pct': {channel: %}, 'rmse_hp1_pct': {channel: %}}``: both figures.

    Parameters
    ----------
    predict : callable
        ``predict(recording) -> force [N]`` of the whole record (``predict_forces`` of a
        model for every reported figure).
    recordings : sequence of MotionRecording
        Whole records (no settling removed: ``evaluate`` does not remove any).
    masks : sequence of numpy.ndarray of bool, optional
        Per record, the samples scored (the per-event halves); None: every sample.

    """
    return figures_of(scored_pieces(predict, recordings, masks), recordings[0])


def scored_pieces(predict: Callable[[MotionRecording], np.ndarray],
                  recordings: Sequence[MotionRecording],
                  masks: Optional[Sequence[np.ndarray]] = None) -> List[EvalSegment]:
    """
    Whole records predicted, the masked samples cut out as ``evaluate --samples`` cuts them.

    Each run of True samples of a record's mask becomes a segment of its own (its own
    high-pass); ``masks`` None: every record whole.
    """
    segments = [EvalSegment(np.asarray(r.outputs, dtype=np.float64),
                            np.asarray(predict(r), dtype=np.float64),
                            np.arange(r.n_samples), r.name) for r in recordings]
    if masks is None:
        return segments
    return [piece for seg, m in zip(segments, masks) for piece in select_samples([seg], runs(m))]


def figures_of(segments: Sequence[EvalSegment], rec0: MotionRecording
               ) -> Dict[str, Dict[str, float]]:
    """Both RMSE figures per channel over ``segments`` (``rec0`` names rate and channels)."""
    # evaluate's own RMSE function (core.evaluation.rmse_figures): the same figures without
    # the damage, spectra and events evaluate_segments also computes (~10 % of a diagnosis).
    raw, hp = rmse_figures([s.target_n for s in segments], [s.prediction_n for s in segments],
                           rec0.fs_hz, rec0.output_channels)
    return {name: dict(zip(rec0.output_channels, (float(v) for v in values)))
            for name, values in (('rmse_pct', raw), ('rmse_hp1_pct', hp))}


def _with_terms(prep, terms) -> List[np.ndarray]:
    """Return the reference prediction plus the physics stage, full records."""
    return [apply_physics(terms, rec.fs_hz, rec.input_channels, rec.output_channels,
                          rec.inputs, pred, rest_inputs=rec.inputs.mean(axis=1))
            for rec, pred in zip(prep.recordings, prep.full_predictions)]


def augmented(prep, terms) -> List[np.ndarray]:
    """Return the reference prediction plus the physics stage, over the trimmed records."""
    return [y[:, a:b] for y, (a, b) in zip(_with_terms(prep, terms), prep.spans)]


#: Largest rise of the holdout RMSE [points of %] a finding's terms may cause (mean over its
#: channels, the other findings kept) before they leave the model.
MAX_HOLDOUT_HARM_PCT = 0.05


def holdout_gate(findings, hold, channels, hp, mask):
    """
    Strip the terms of findings that make the holdout worse (backward elimination).

    Judged on the samples of ``mask`` (all when None) of ``hold``, the gate half of
    :func:`split_holdout`, by the scorer of every reported figure (:func:`figures_of` of the
    pieces; 1 Hz high-passed when ``hp`` > 0).  A finding's terms are stripped when they
    raise the RMSE by more than :data:`MAX_HOLDOUT_HARM_PCT` points on average over its
    channels (its parameters are shared, so it stands or falls on all of them); the most
    harmful goes first.

    A term that fits the real recordings but makes unseen data worse does not go into the
    model; the finding stays named (the holdout judges models, not names: what is named does
    not depend on whether a holdout is given) and the line goes under ``rejected``.  Every
    finding is returned, in order.  Linear companions were refitted jointly with all
    terms of their channel, so they stay in every model compared (and end up on the first
    finding kept).  Returns ``(kept, rejection lines)``.
    """
    metric = 'rmse_hp1_pct' if hp > 0.0 else 'rmse_pct'
    companions = [t for f in findings for t in f.terms if t.physics != f.physics]
    kept = [replace(f, terms=tuple(t for t in f.terms if t.physics == f.physics))
            for f in findings]
    gated = []

    def score(items):
        terms = [t for g in items for t in g.terms]
        terms += companions if terms else []
        # the scorer of every reported figure: pieces cut first, each high-passed alone
        segments = [EvalSegment(t, p, np.arange(t.shape[1]), r.name) for t, p, r in zip(
            hold.targets, augmented(hold, terms), hold.recordings)]
        if mask is not None:
            segments = [piece for seg, m in zip(segments, mask)
                        for piece in select_samples([seg], runs(m))]
        return figures_of(segments, hold.recordings[0])[metric]
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
                     f'data but its term worsens the holdout RMSE of ' + ', '.join(
                         f'{c} ({undo[c]:.1f} % -> {full[c]:.1f} %)' for c in worst.channels)
                     + '; named, its term not written')
        kept = [replace(g, terms=()) if g is worst else g for g in kept]
    if companions and any(f.terms for f in kept):
        i = next(i for i, f in enumerate(kept) if f.terms)
        kept[i] = replace(kept[i], terms=kept[i].terms + tuple(companions))
    return kept, gated
