# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
One fleet task: a bag's path in, its :class:`.result.BagResult` out.

The task runs in a Dask worker process and reads everything itself (bag, model, params file)
from a filesystem the workers share, so no array travels through the scheduler.  It uses the
commands' own paths, nothing copied: ``predict``'s per-segment prediction
(``offline.predict_recording`` = ``core.predict.iter_forces`` block by block), and, when
the bag carries the WFT topics, ``evaluate``'s evaluation (``offline.evaluate_recordings``);
damage and relative damage spectrum come from ``core.evaluation.damage_figures``, the rule
``evaluate`` applies.  So ``damage`` is exactly ``evaluate``'s ``damage_prediction``.

Memory per task: the bag's accelerations and the predicted forces of its segments
(2 × 12 × 8 bytes per sample, ~0.35 GB for an hour at 512 Hz) plus the reader's buffers; the
relative damage spectrum's zero-phase band filters need each segment's whole force history.
"""
import contextlib
import dataclasses
import functools
import os
from pathlib import Path
import shutil
from typing import Optional
import uuid

import numpy as np

from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.fleet.discover import BagRef
from wheel_force_estimator.fleet.result import BagResult
from wheel_force_estimator.fleet.result import failed
from wheel_force_estimator.fleet.result import SECONDS_PER_HOUR
from wheel_force_estimator.fleet.result import STATUS_OK

#: Where ``--write-forces`` bags go inside ``--out`` (one per bag, named by its bag id).
FORCES_DIR = 'forces'
_PARTIAL_DIR = '.partial'


@dataclasses.dataclass(frozen=True)
class FleetSettings:
    """
    What every task of one run shares (small: it is sent with each task).

    Attributes
    ----------
    model_path : str
        Model file (.npz), readable by every worker.
    model_sha256 : str
        Hash of the model file (the result-store key; a cached model is reused per worker).
    sn_slope : float
        Basquin exponent ``k`` of the pseudo damage [-].
    config_path : str or None
        Params file with the topic names.
    forces_dir : str or None
        Directory for the predicted-force bags (``--write-forces``), or None.
    sn_slope_moment : float or None
        Basquin exponent of the wheel moments (None: ``sn_slope``).

    """

    model_path: str
    model_sha256: str
    sn_slope: float
    config_path: Optional[str] = None
    forces_dir: Optional[str] = None
    sn_slope_moment: Optional[float] = None

    def __post_init__(self):
        """Check the Basquin exponent."""
        if not (np.isfinite(self.sn_slope) and self.sn_slope > 0):
            raise ValueError(f'sn_slope must be finite and > 0, got {self.sn_slope!r}')
        if self.sn_slope_moment is not None and not (
                np.isfinite(self.sn_slope_moment) and self.sn_slope_moment > 0):
            raise ValueError(f'sn_slope_moment must be finite and > 0, got '
                             f'{self.sn_slope_moment!r}')

    def key(self) -> dict:
        """Return what a stored result depends on besides the bag (JSON-able)."""
        key = {'model_sha256': self.model_sha256, 'sn_slope': self.sn_slope,
               'config': _config_text(self.config_path),
               'write_forces': self.forces_dir is not None}
        if self.sn_slope_moment is not None:  # stores of earlier runs keep their keys
            key['sn_slope_moment'] = self.sn_slope_moment
        return key


def _config_text(path: Optional[str]) -> Optional[str]:
    return None if path is None else Path(path).read_text()


@functools.lru_cache(maxsize=4)
def _model(path: str, sha256: str):
    from wheel_force_estimator.core.model import load_model
    return load_model(path)


@functools.lru_cache(maxsize=4)
def _topics(config_path: Optional[str]):
    from wheel_force_estimator.bagio import load_topic_config
    return load_topic_config(config_path)


def has_topics(path, names) -> bool:
    """
    Return whether the bag lists every topic in ``names``.

    An unreadable bag gives False here; reading it then reports what is wrong.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.highlevel import AnyReaderError

    from wheel_force_estimator.bagio.reader import jazzy_typestore
    try:
        with AnyReader([Path(path)], default_typestore=jazzy_typestore()) as reader:
            present = set(reader.topics)
    except (AnyReaderError, OSError, ValueError):
        return False
    return set(names) <= present


def process_bag(ref: BagRef, settings: FleetSettings) -> BagResult:
    """
    Predict one bag's forces and return its damage figures.

    Errors raised on purpose (a corrupt bag, a missing topic, a rate the model was not
    fitted at: see ``bagio.read_recording``) become a ``failed`` result naming the fault;
    anything else is a bug and propagates (the run marks the bag failed with its type).

    Parameters
    ----------
    ref : BagRef
        The bag.
    settings : FleetSettings
        Model, pseudo damage and output settings of the run.

    Returns
    -------
    BagResult

    """
    try:
        return _process(ref, settings)
    except WheelForceError as err:
        return failed(ref.path, ref.bag_id, str(err))


def _process(ref: BagRef, settings: FleetSettings) -> BagResult:
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.core.evaluation import channel_sn_slopes
    from wheel_force_estimator.core.evaluation import damage_figures
    from wheel_force_estimator.core.fatigue import damage_bands_hz
    from wheel_force_estimator.offline import bag_extras
    from wheel_force_estimator.offline import evaluate_recordings
    from wheel_force_estimator.offline import predict_recording

    model = _model(settings.model_path, settings.model_sha256)
    topics = _topics(settings.config_path)
    with_wft = has_topics(ref.path, topics.wft_topics)
    recording = read_recording(ref.path, topics, require_wft=with_wft,
                               expected_fs_hz=model.fs_hz,
                               extras=bag_extras(model, str(ref.path), with_wft))
    channels = tuple(model.output_channels)
    rmse = rmse_hp1 = None
    if with_wft:
        evaluation, segments = evaluate_recordings(model, [recording], settings.sn_slope,
                                                   sn_slope_moment=settings.sn_slope_moment)
        stamps = [s.stamp_ns for s in segments]
        forces = [s.prediction_n for s in segments]
        damage, rds, bands = (evaluation.damage_prediction, evaluation.rds_prediction,
                              evaluation.bands_hz)
        rmse = dict(zip(channels, map(float, evaluation.rmse_pct)))
        rmse_hp1 = dict(zip(channels, map(float, evaluation.rmse_hp1_pct)))
    else:
        stamps, forces = zip(*predict_recording(model, recording))
        bands = tuple(tuple(b) for b in damage_bands_hz(model.fs_hz))
        damage, rds = damage_figures(forces, model.fs_hz, channel_sn_slopes(
            channels, settings.sn_slope, settings.sn_slope_moment), bands)
    duration_s = recording.n_used / recording.fs_hz
    written = None
    if settings.forces_dir is not None:
        written = str(_write_forces(ref, settings.forces_dir, topics, stamps, forces))
    events = tuple(dict.fromkeys(name for _, name in recording.events))
    return BagResult(
        path=ref.path, bag_id=ref.bag_id, status=STATUS_OK, duration_s=float(duration_s),
        damage=dict(zip(channels, map(float, damage))),
        damage_per_hour={c: float(d) * SECONDS_PER_HOUR / duration_s
                         for c, d in zip(channels, damage)},
        rds={c: tuple(map(float, row)) for c, row in zip(channels, rds)},
        bands_hz=tuple((float(lo), float(hi)) for lo, hi in bands), events=events,
        rmse_pct=rmse, rmse_hp1_pct=rmse_hp1, forces=written)


def _write_forces(ref: BagRef, forces_dir: str, topics, stamps, forces) -> Path:
    """
    Write the predicted forces as ``predict`` does, then move the bag into place.

    The bag is written under ``.partial`` and renamed when complete, so an interrupted task
    never leaves a half-written bag under its final name; one left from an interrupted run
    is replaced.
    """
    from wheel_force_estimator.bagio import write_recording
    from wheel_force_estimator.offline import input_storage
    from wheel_force_estimator.offline import split_loads

    final = Path(forces_dir) / ref.bag_id
    scratch = Path(forces_dir) / _PARTIAL_DIR / uuid.uuid4().hex
    scratch.mkdir(parents=True)
    try:
        force, torque = split_loads(np.concatenate(forces, axis=1))
        write_recording(scratch / final.name, np.concatenate(stamps), force_n=force,
                        topics=topics, storage=input_storage(ref.path), output=True,
                        compression='zstd', torque_nm=torque)
        final.parent.mkdir(parents=True, exist_ok=True)
        if final.exists():
            shutil.rmtree(final)
        os.replace(scratch / final.name, final)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    with contextlib.suppress(OSError):  # still in use by another task: left to that one
        scratch.parent.rmdir()
    return final
