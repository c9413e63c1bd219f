# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The records a diagnosis works on: reference prediction, targets and features, settling removed.

:func:`prepare` runs the reference over every recording once; :func:`pieces` cuts one output
channel out of it for the selection (:class:`diagnosis.selection.Piece`).
"""
from dataclasses import dataclass
from dataclasses import replace
import math
from typing import List, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis.blocks import Piece
from wheel_force_estimator.diagnosis.features import channel_contexts
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.recording import MotionRecording


@dataclass
class Prepared:
    """
    Reference prediction and features of the real recordings, settling time removed.

    ``spans[i] = (start, stop)``: the samples of record ``i`` kept in ``targets``,
    ``predictions`` and ``contexts`` (``full_predictions`` cover the whole record).
    """

    recordings: Tuple[MotionRecording, ...]
    targets: List[np.ndarray]
    predictions: List[np.ndarray]
    contexts: list
    starts_s: List[float]
    full_predictions: List[np.ndarray]
    spans: List[Tuple[int, int]]


def edge_samples(reference) -> int:
    """
    Return the samples at each end of a record where the reference's FIR reaches beyond it.

    A two-sided FIR of look-ahead ``d`` needs ``d`` samples before and after each output; at
    the ends of a record the predictor fills them with the static level, a transient that
    says nothing about the physics (largest on sine tests, whose FRF is undetermined between
    the tested frequencies).  The residual the diagnosis analyses leaves them out (at most a
    quarter of a record at each end, see :func:`prepare`); reported figures (``evaluate``)
    keep every sample.
    """
    model = getattr(reference, 'model', None)
    return int(getattr(model, 'fir_delay_samples', 0) or 0)


def _remedy(recordings, reference, settle: int, config) -> str:
    """
    Return what would let records too short for the feature filters through (error text).

    The integrators of velocity or acceleration inputs settle in ``3 / highpass_hz``; a
    higher corner settles sooner but loses the motion below it, so the corner that would fit
    the shortest record is said with that cost, beside the remedies that keep the motion
    (longer runs, or a displacement channel, whose features need no integration).
    """
    corner_hz = 0.0
    for rec in recordings:
        edge = min(edge_samples(reference), rec.n_samples // 4)
        # prepare keeps n - edge - max(settle, edge) > min_block samples: the most settling
        # a record allows, and whether any corner can help (not when the FIR edges alone
        # leave too little)
        room = rec.n_samples - edge - config.selection.min_block_samples - 1
        if rec.input_quantity == 'displacement' or settle <= edge or room <= edge:
            return ''
        corner_hz = max(corner_hz, 3.0 * rec.fs_hz / room)
    if corner_hz >= 0.25 * recordings[0].fs_hz:
        return ''
    step = 10.0 ** (math.floor(math.log10(corner_hz)) - 1)
    corner_hz = math.ceil(corner_hz / step) * step      # 2 digits, rounded up: it must fit
    return (f'; a higher integrator corner (--highpass-hz {corner_hz:.2g} or above, now '
            f'{config.features.highpass_hz:g} Hz) would fit every record, but the integrated '
            f'motion then loses what lies below it: longer runs or a displacement input keep '
            f'it')


def prepare(recordings, reference, sources, partners, config,
            predictions=None) -> Prepared:
    """
    Predict every recording with ``reference`` and build its channel features.

    ``predictions`` (one ``(n_out, n)`` array per recording, e.g. an earlier
    ``Prepared.full_predictions`` of the same reference) skips the prediction.

    Raises
    ------
    DiagnosisError
        A recording too short for the feature filters to settle (name and duration given).

    """
    rec0 = recordings[0]
    settle = settle_samples(rec0.fs_hz, rec0.input_quantity, config.features)
    prep = Prepared(tuple(recordings), [], [], [], [], [], [])
    for i, rec in enumerate(recordings):
        # A FIR as long as the record (the two-resolution fit on a short record) may not
        # take more than half of it: the transient is largest right at the ends.
        edge = min(edge_samples(reference), rec.n_samples // 4)
        skip = max(settle, edge)
        stop = rec.n_samples - edge
        if stop - skip <= config.selection.min_block_samples:
            raise DiagnosisError(
                f'{rec.name}: {rec.n_samples} samples ({rec.duration_s:.2f} s); the feature '
                f'filters need {skip / rec.fs_hz:.2f} s to settle and the reference FIR '
                f'{edge / rec.fs_hz:.2f} s at each end, too little data remains'
                + _remedy(recordings, reference, settle, config))
        pred = reference.predict(rec) if predictions is None else predictions[i]
        ctxs = channel_contexts(rec.inputs, rec.input_channels, rec.fs_hz, rec.input_quantity,
                                pred, sources, partners, config.features)
        prep.targets.append(np.asarray(rec.outputs)[:, skip:stop])
        prep.predictions.append(pred[:, skip:stop])
        prep.contexts.append([trim(c, skip, stop) for c in ctxs])
        prep.starts_s.append(rec.start_s + skip / rec.fs_hz)
        prep.full_predictions.append(pred)
        prep.spans.append((skip, stop))
    return prep


def axis(channel: str) -> str:
    """Return the force axis of a vehicle channel (``lf_fz`` -> ``z``), else the name itself."""
    corner, sep, name = channel.rpartition('_f')
    return name if sep else channel


def trim(ctx, skip, stop=None):
    """Return ``ctx`` without its first ``skip`` samples (and from ``stop`` on)."""
    return replace(ctx, **{k: (None if getattr(ctx, k) is None else getattr(ctx, k)[skip:stop])
                           for k in ('disp', 'vel', 'acc', 'level', 'load', 'partner_disp')})


def pieces(prep: Prepared, o: int, channel: str) -> List[Piece]:
    """Return output ``o`` (named ``channel``) of every record as selection pieces."""
    return [Piece(prep.contexts[i][o], prep.targets[i][o] - prep.predictions[i][o],
                  prep.targets[i][o], i, channel, prep.recordings[i].name)
            for i in range(len(prep.recordings))]


def group_pieces(prep: Prepared, channels: Sequence[str], group) -> List[Piece]:
    """Return the pieces of every channel in ``group`` (positions in ``channels``), pooled."""
    return [p for c in group for p in pieces(prep, channels.index(c), c)]
