# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The offline path: predict and evaluate whole recordings with a model.

``wheel-force predict``/``evaluate`` and the fleet tasks (``fleet.task``) call these, so a bag
is predicted and scored the same way whoever asks (the fleet's ``damage`` is exactly
``evaluate``'s ``damage_prediction`` for the same bag and model).  ``compare`` puts the
live (causal) estimate beside the offline one for ``evaluate --causal`` and the fit report.
"""
import dataclasses
from pathlib import Path
from typing import Callable, List, Optional, Tuple


def input_storage(path) -> str:
    """Return the storage plugin of a rosbag2 directory, ``mcap`` for anything else."""
    meta = Path(path) / 'metadata.yaml'
    if meta.is_file() and 'sqlite3' in meta.read_text():
        return 'sqlite3'
    return 'mcap'


def bag_extras(model, where: str, with_wft: bool = True):
    """
    Return the reader's ``extras`` a bag must carry for ``model`` (core.spindle's rule).

    The moments are read only with the WFT topics (``evaluate``, fleet bags with them).
    """
    from wheel_force_estimator.core.spindle import spindle_layout
    extras = spindle_layout(model, where).extras
    return tuple(e for e in extras if with_wft or e != 'moments')


def split_loads(loads):
    """Return ``(force_n (12, n), torque_nm (12, n) or None)`` of a model's outputs."""
    from wheel_force_estimator import OUTPUT_CHANNELS
    n = len(OUTPUT_CHANNELS)
    return loads[:n], (loads[n:2 * n] if loads.shape[0] > n else None)


def predict_recording(model, recording, causal_delay_samples=None):
    """
    Predict every segment of ``recording``; return a list of ``(stamp_ns, loads)``.

    The model's declared inputs are taken from the segments (``Segment.signals``: the
    accelerations, then the angular rates and spin when the model has them); ``loads`` has
    every output of the model: the forces, then the moments if it has them (core.spindle).
    """
    from wheel_force_estimator.core.predict import predict_forces
    return [(seg.stamp_ns, predict_forces(model, seg.signals(model.input_channels, model.fs_hz),
                                          causal_delay_samples))
            for seg in recording.segments]


def stream_recording(model, recording, causal_delay_samples=None):
    """
    Return the stamps and the forces of every segment as one stream of blocks.

    The forces are computed while the bag is written (:class:`..bagio.blocks.SignalBlocks`),
    one block ahead in a worker thread, so an hour of forces is never held whole.
    """
    import numpy as np

    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.bagio.blocks import SignalBlocks
    from wheel_force_estimator.core.predict import iter_forces

    segments = recording.segments
    stamps = (segments[0].stamp_ns if len(segments) == 1
              else np.concatenate([seg.stamp_ns for seg in segments]))

    def blocks():
        n = len(OUTPUT_CHANNELS)  # the forces; moments, if any, follow (core.spindle)
        for seg in segments:
            for block in iter_forces(model, seg.signals(model.input_channels, model.fs_hz),
                                     causal_delay_samples):
                yield block[:n]
    return stamps, SignalBlocks(OUTPUT_CHANNELS, stamps.size, prefetched(blocks()))


def prefetched(items):
    """
    Yield ``items`` while a worker thread already computes the next one.

    FFTs, matrix products and large copies release the GIL, so filtering overlaps the bag
    writing.
    """
    from concurrent.futures import ThreadPoolExecutor

    it = iter(items)
    done = object()
    with ThreadPoolExecutor(max_workers=1) as pool:
        ahead = pool.submit(next, it, done)
        while True:
            item = ahead.result()
            if item is done:
                return
            ahead = pool.submit(next, it, done)
            yield item


def evaluate_recordings(model, recordings, sn_slope, causal_delay_samples=None, ranges=None,
                        sn_slope_moment=None):
    """
    Predict and evaluate bag recordings; return ``(Evaluation, segments)``.

    Every output of the model is scored (the moments too, against the recorded
    ``wrench.torque``, with ``sn_slope_moment``).  ``ranges`` (``--samples``, one
    recording) keeps only those samples of the prediction.
    """
    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments

    segments, events = [], []
    for rec in recordings:
        segments.extend(selected([
            EvalSegment(seg.signals(model.output_channels), pred, stamps, f'{rec.path}#{i}')
            for i, ((stamps, pred), seg) in enumerate(
                zip(predict_recording(model, rec, causal_delay_samples), rec.segments))],
            ranges, rec.path))
        events.extend(rec.events)
    events.sort()
    evaluation = evaluate_segments(segments, model.fs_hz, model.output_channels, sn_slope,
                                   events=events, sn_slope_moment=sn_slope_moment)
    return evaluation, segments


def evaluate_generic(model, recordings, sn_slope, causal_delay_samples=None, ranges=None):
    """Predict and evaluate generic recordings (``DaqRecording``); return the same pair."""
    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments
    from wheel_force_estimator.core.predict import predict_forces

    segments = [piece for rec in recordings for piece in selected(
        [EvalSegment(rec.outputs, predict_forces(model, rec.inputs, causal_delay_samples),
                     rec.stamp_ns(), rec.path)], ranges, rec.path)]
    evaluation = evaluate_segments(segments, model.fs_hz, model.output_channels, sn_slope)
    return evaluation, segments


def selected(segments, ranges, path):
    """
    Return ``segments`` cut to ``ranges`` (``--samples``; None: all of them).

    Raises
    ------
    RecordingError
        A range ends after the recording's last aligned sample (the file named).

    """
    if ranges is None:
        return segments
    from wheel_force_estimator.core.errors import RecordingError
    from wheel_force_estimator.core.evaluation import select_samples
    try:
        return select_samples(segments, ranges)
    except ValueError as err:
        raise RecordingError(f'{path}: --samples {err}') from err


@dataclasses.dataclass(frozen=True)
class LiveComparison:
    """Offline and live evaluations of the same data, plus the look-ahead sweep."""

    offline: object
    live: object
    look_ahead_samples: int
    live_kind: str
    sweep: Tuple[Tuple[float, str, object], ...]   # (look-ahead [s], kind, Evaluation)


def _kind(model, delay: int) -> str:
    from wheel_force_estimator.core.live_estimator import find_live
    return 'live estimator' if find_live(model.live, delay) is not None else 'cut offline FIR'


def compare(model, evaluate: Callable[[Optional[int]], object], delay: int,
            offline=None) -> LiveComparison:
    """
    Evaluate offline, live at ``delay`` and every stored look-ahead (``evaluate(delay)``).

    A model without live estimators is swept with the cut offline FIR at the standard
    look-aheads it can cut to (and labelled so).
    """
    from wheel_force_estimator.core.live_estimator import look_ahead_samples
    from wheel_force_estimator.core.live_estimator import SWEEP_LOOK_AHEADS_S
    offline = evaluate(None) if offline is None else offline
    if model.live:
        delays = sorted(e.look_ahead_samples for e in model.live)
    else:
        delays = sorted({look_ahead_samples(s, model.fs_hz) for s in SWEEP_LOOK_AHEADS_S}
                        | {delay})
        delays = [d for d in delays if d <= model.fir_delay_samples]
    results = {d: evaluate(d) for d in delays}
    live = results[delay] if delay in results else evaluate(delay)
    sweep = tuple((d / model.fs_hz, _kind(model, d), results[d]) for d in delays)
    return LiveComparison(offline, live, delay, _kind(model, delay), sweep)


def training_evaluator(model, segments: List, sn_slope: float = 5.0):
    """Return ``evaluate(delay)`` over fit training segments (no stamps: from 0 at fs)."""
    import numpy as np

    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments
    from wheel_force_estimator.core.predict import predict_forces

    def evaluate(delay):
        evs = [EvalSegment(s.force_n, predict_forces(model, s.accel_mps2, delay),
                           (np.arange(s.force_n.shape[1]) * (1e9 / model.fs_hz)).astype(
                               np.int64), s.source) for s in segments]
        return evaluate_segments(evs, model.fs_hz, model.output_channels, sn_slope)
    return evaluate
