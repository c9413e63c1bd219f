# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The linear prediction a diagnosis starts from ("what the simulation can explain").

- :class:`FrfReference`: the product's MIMO FRF model (any declared input quantity), fitted
  on the simulation's recordings (``--sim``), loaded (``--model``), or - without either -
  fitted on the real recordings themselves with the design of ``wheel-force fit``.
- :class:`RegressionReference`: a per-channel linear force-from-motion law
  ``F = F0 + k x + c v + m a`` on the same band-limited features the physics terms use, only
  on request (``--linear regression`` with ``--sim``) and as a benchmark baseline; never the
  default reference.
"""
from typing import Optional, Sequence

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.features import motion_features
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.recording import MotionRecording


def splittable(rec: MotionRecording) -> bool:
    """Return True for a recording of exactly the 12 spindle accelerations (package order)."""
    return rec.input_channels == INPUT_CHANNELS and rec.input_quantity == 'acceleration'


def with_split(rec: MotionRecording, derived: Sequence[str]) -> np.ndarray:
    """
    Return the 12 accelerations of ``rec`` with the inputs ``derived`` from them below.

    ``derived``: the traction/braking and cornering splits, by name.  Derived per record, as
    ``predict`` derives them per gap-free segment (:func:`core.predict.model_inputs`), so a
    model fitted on these rows predicts the same record from its 12 accelerations alone.
    """
    from wheel_force_estimator.core.derived import specific_force_parts
    x = np.asarray(rec.inputs, dtype=np.float64)
    return np.concatenate([x, specific_force_parts(x, rec.fs_hz, derived)])


def training_segments(recordings: Sequence[MotionRecording], derived: Sequence[str]) -> tuple:
    """
    Return the fit's training segments of ``recordings`` and their input channel names.

    ``derived``: the inputs derived from the accelerations (:func:`with_split`) below them.
    """
    from wheel_force_estimator.core.pipeline import TrainingSegment
    derived = tuple(derived)
    segments = [TrainingSegment(with_split(r, derived) if derived else r.inputs, r.outputs,
                                r.name) for r in recordings]
    return segments, recordings[0].input_channels + derived


class FrfReference:
    """Predict forces with an :class:`FrfModel` (static force included, physics applied)."""

    kind = 'frf'

    def __init__(self, model, name: str, design=None, fitted=None, derived=()):
        self.model = model
        self.name = name
        #: The model's last inputs, derived here from the recordings' 12 spindle
        #: accelerations (:func:`with_split`) for every (re)fit: the splits, by name.
        self.derived = tuple(derived)
        #: The ``FitConfig`` the model was fitted with (segment chosen), when fitted here.
        self.design = design
        #: The :class:`core.design.DesignedFit` of the model, when fitted here.
        self.fitted = fitted

    @classmethod
    def fit(cls, recordings: Sequence[MotionRecording], name: str, fit_config=None,
            short_record_fallback: bool = False, segment_fallback: bool = False,
            choose_resolution: bool = False, long_window_fallback: Optional[bool] = None,
            cross_validate: bool = False, progress: bool = False, derived=()):
        """
        Fit the FRF on recordings with the product's design (``wheel-force fit``).

        Parameters
        ----------
        recordings : sequence of MotionRecording
            One Welch-averaged segment each.
        name : str
            What they are (``'sim'``, ``'real'``), in messages and the model's ``fit``.
        fit_config : FitConfig, optional
            Settings; None = what ``wheel-force fit`` uses without a params file.
        short_record_fallback : bool
            One resolution when no record holds the long segment (generic recordings).
        segment_fallback : bool
            A shorter Welch segment when the records hold no more windows than inputs.
        choose_resolution : bool
            The Welch segment chosen by blocked cross-validation (:mod:`core.resolution`).
        long_window_fallback : bool or None
            One resolution when the records hold no more long windows than inputs (None =
            as ``short_record_fallback``).
        cross_validate : bool
            Each output's design chosen by blocked cross-validation, as ``wheel-force fit``
            chooses it (the real-data linear model); a simulation's FRF keeps the single
            design the concealed sizes were measured with (:mod:`sim.concealment`).
        progress : bool
            The search's progress bars on a terminal (the library prints nothing by default).
        derived : sequence of str
            Recordings of the 12 spindle accelerations also give these inputs derived from
            them (the splits, :func:`training_segments`), as ``wheel-force fit``; other
            recordings are fitted as they are.

        Raises
        ------
        DiagnosisError
            When the recordings cannot be fitted (too short, singular), with the reason.

        """
        from wheel_force_estimator.core.design import fit_design
        from wheel_force_estimator.core.design import product_fit_config
        config = fit_config or product_fit_config()
        rec0 = recordings[0]
        derived = tuple(derived) if splittable(rec0) else ()
        segments, inputs = training_segments(recordings, derived)
        try:
            fitted = fit_design(segments, rec0.fs_hz, config, inputs,
                                rec0.output_channels, rec0.input_quantity,
                                {'diagnosis': name}, short_record_fallback, segment_fallback,
                                choose_resolution, long_window_fallback,
                                cross_validate=cross_validate, show_progress=progress)
        except WheelForceError as err:
            raise DiagnosisError(f'cannot fit the linear FRF on the {name} recordings: '
                                 f'{err}') from err
        return cls(fitted.model, name, fitted.config, fitted, derived)

    def refit(self, recordings: Sequence[MotionRecording]):
        """
        Return the FrfModel of ``recordings`` fitted with this model's design.

        The settings and, when the design was cross-validated, each output's chosen design
        (:meth:`core.design.DesignedFit.refit`): the held-out blocks and the joint fits with
        physics terms fit what ``fit`` writes without searching again.

        Raises
        ------
        DiagnosisError
            This model was not fitted here, or the recordings are too short for its design.

        """
        if self.fitted is None:
            raise DiagnosisError(f'the {self.name} model was not fitted here: no design to '
                                 f'refit')
        segments = training_segments(recordings, self.derived)[0]
        try:
            return self.fitted.refit(segments, {'diagnosis': self.name})
        except WheelForceError as err:
            raise DiagnosisError(f'cannot fit the linear FRF on the {self.name} recordings: '
                                 f'{err}') from err

    def check(self, rec: MotionRecording):
        """Refuse a recording whose channels, rate or input quantity differ from the model's."""
        from wheel_force_estimator.daqio import quantity_of_unit
        m = self.model
        inputs = tuple(m.input_channels)[:len(m.input_channels) - len(self.derived)]
        if rec.input_channels != inputs or rec.output_channels != m.output_channels:
            raise DiagnosisError(f'{rec.name}: channels {list(rec.input_channels)} -> '
                                 f'{list(rec.output_channels)} differ from those of the '
                                 f'{self.name} model ({list(m.input_channels)} -> '
                                 f'{list(m.output_channels)}); nothing is renamed')
        if abs(rec.fs_hz - m.fs_hz) > 1e-6 * m.fs_hz:
            raise DiagnosisError(f'{rec.name}: sampled at {rec.fs_hz:g} Hz but the {self.name} '
                                 f'model at {m.fs_hz:g} Hz; nothing is resampled')
        unit = m.units.get('input', 'm/s^2')
        if quantity_of_unit(unit) != rec.input_quantity:
            raise DiagnosisError(f'{rec.name}: inputs are {rec.input_quantity} but the '
                                 f'{self.name} model takes {quantity_of_unit(unit) or "unknown"} '
                                 f'({unit})')

    def predict(self, rec: MotionRecording) -> np.ndarray:
        """Total force [N] time-aligned with ``rec`` (the path ``evaluate`` takes)."""
        from wheel_force_estimator.core.predict import predict_forces
        self.check(rec)
        return predict_forces(self.model, rec.inputs)


class RegressionReference:
    """Per-channel ``F = F0 + k x + c v + m a`` fitted by least squares."""

    kind = 'regression'

    def __init__(self, coefficients: np.ndarray, config: FeatureConfig, name: str,
                 input_channels, output_channels, input_quantity: str, fs_hz: float,
                 sources):
        self.coefficients = coefficients
        self.config = config
        self.name = name
        self.input_channels = tuple(input_channels)
        self.output_channels = tuple(output_channels)
        self.input_quantity = input_quantity
        self.fs_hz = fs_hz
        self.sources = tuple(sources)

    @staticmethod
    def _design(rec: MotionRecording, config: FeatureConfig, sources):
        feats = motion_features(rec.inputs, rec.fs_hz, rec.input_quantity, config)
        idx = {c: i for i, c in enumerate(rec.input_channels)}
        cols = []
        for src in sources:
            s = idx[src]
            cols.append(np.stack([np.ones(rec.n_samples), feats['displacement'][s],
                                  feats['velocity'][s], feats['acceleration'][s]], axis=1))
        return cols

    @classmethod
    def fit(cls, recordings: Sequence[MotionRecording], config: FeatureConfig, name: str):
        """Fit on recordings, leaving out each record's filter settling time."""
        rec0 = recordings[0]
        sources, _ = pairing(rec0.output_channels, rec0.input_channels, recordings)
        skip = settle_samples(rec0.fs_hz, rec0.input_quantity, config)
        rows = [[] for _ in sources]
        ys = [[] for _ in sources]
        for rec in recordings:
            if rec.n_samples <= skip + 8:
                raise DiagnosisError(f'{rec.name}: {rec.n_samples} samples, the feature filters '
                                     f'need {skip} to settle')
            for o, design in enumerate(cls._design(rec, config, sources)):
                rows[o].append(design[skip:])
                ys[o].append(rec.outputs[o, skip:])
        coefs = []
        for o in range(len(sources)):
            a, y = np.concatenate(rows[o]), np.concatenate(ys[o])
            scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
            sol, *_ = np.linalg.lstsq(a / scale, y, rcond=None)
            coefs.append(sol / scale)
        return cls(np.array(coefs), config, name, rec0.input_channels, rec0.output_channels,
                   rec0.input_quantity, rec0.fs_hz, sources)

    def predict(self, rec: MotionRecording) -> np.ndarray:
        """Total force [N] time-aligned with ``rec``."""
        if (rec.input_channels, rec.output_channels, rec.input_quantity) != (
                self.input_channels, self.output_channels, self.input_quantity):
            raise DiagnosisError(f'{rec.name}: channels or input quantity differ from the '
                                 f'{self.name} recordings')
        design = self._design(rec, self.config, self.sources)
        return np.stack([d @ c for d, c in zip(design, self.coefficients)])
