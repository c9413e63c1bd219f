# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Sim-vs-real diagnosis: residual location, physics candidates, cross-validated selection.

``diagnose(real, sim_or_model, holdout, config)`` is the entry point; recordings are
:class:`MotionRecording` (from bags via ``recording.from_bag_recording`` or from text tables /
MAT / NPZ / JSON via ``generic.load_generic``).
"""
from wheel_force_estimator.diagnosis.pipeline import diagnose
from wheel_force_estimator.diagnosis.recording import MotionRecording
from wheel_force_estimator.diagnosis.result import DiagnosisResult
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.diagnosis.run import DiagnosisConfig

__all__ = ['DiagnosisConfig', 'DiagnosisResult', 'Finding', 'MotionRecording', 'diagnose']
