# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Generic recordings (text tables, MAT, NPZ, JSON) as the diagnosis sees them.

The reader and the ``NAME:QUANTITY:UNIT`` role specs live in :mod:`wheel_force_estimator.daqio`
(shared with ``fit`` and ``evaluate``); this façade turns its records into
:class:`MotionRecording` and its :class:`RecordingError` into :class:`DiagnosisError` with the
same message, so callers of the diagnosis catch one error type.
"""
from typing import Sequence

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.errors import RecordingError
from wheel_force_estimator.daqio import ChannelSpec
from wheel_force_estimator.daqio import DaqRecording
from wheel_force_estimator.daqio import INPUT_QUANTITIES
from wheel_force_estimator.daqio import parse_spec as _parse_spec
from wheel_force_estimator.daqio import read_daq
from wheel_force_estimator.daqio import UNITS
from wheel_force_estimator.diagnosis.recording import MotionRecording

__all__ = ['ChannelSpec', 'INPUT_QUANTITIES', 'UNITS', 'load_generic', 'motion_recording',
           'parse_spec']


def parse_spec(text: str, role: str) -> ChannelSpec:
    """
    Parse ``NAME:QUANTITY:UNIT`` for ``role`` ``'input'`` or ``'output'``.

    Raises
    ------
    DiagnosisError
        Malformed spec, a quantity not allowed for the role, or an unknown unit.

    """
    try:
        return _parse_spec(text, role)
    except RecordingError as err:
        raise DiagnosisError(*err.args) from err


def motion_recording(rec: DaqRecording) -> MotionRecording:
    """Return a generic recording as a :class:`MotionRecording` (same arrays, SI units)."""
    return MotionRecording(
        name=rec.path, fs_hz=rec.fs_hz, inputs=rec.inputs, outputs=rec.outputs,
        input_channels=rec.input_channels, output_channels=rec.output_channels,
        input_quantity=rec.input_quantity)


def load_generic(path, inputs: Sequence[ChannelSpec], outputs: Sequence[ChannelSpec],
                 fs_hz: float) -> MotionRecording:
    """
    Read one generic recording into a :class:`MotionRecording` (SI units).

    Parameters
    ----------
    path : str or os.PathLike
        ``.csv``/``.txt``/``.tsv``, ``.mat``, ``.npz`` or ``.json`` file.
    inputs, outputs : sequence of ChannelSpec
        Declared motion and force channels (:func:`parse_spec`).
    fs_hz : float
        Sample rate [Hz].

    Raises
    ------
    DiagnosisError
        Unreadable file, missing channel, mixed input quantities, unequal lengths,
        non-finite values.

    """
    try:
        return motion_recording(read_daq(path, inputs, outputs, fs_hz))
    except RecordingError as err:
        raise DiagnosisError(*err.args) from err
