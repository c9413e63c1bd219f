# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Exception hierarchy shared by every part of the package.

Every error raised on purpose is a :class:`WheelForceError`; subclasses that describe a bad
value also derive from the matching builtin so generic callers can catch ``ValueError``.
Messages name the file / topic / channel / sample at fault.  The CLI turns any
``WheelForceError`` into exit code 1 with the message on stderr and no traceback.
"""


class WheelForceError(Exception):
    """Base class of all errors raised on purpose by wheel_force_estimator."""


class ShapeError(WheelForceError, ValueError):
    """An array has the wrong number of dimensions, channels or samples."""


class NonFiniteError(WheelForceError, ValueError):
    """An input contains NaN or infinity (the channel and sample index are named)."""


class InsufficientDataError(WheelForceError, ValueError):
    """Too few samples for the requested operation (e.g. shorter than one Welch segment)."""


class ConfigError(WheelForceError, ValueError):
    """A configuration value or parameter is invalid."""


class ModelFileError(WheelForceError):
    """A model file cannot be read, is not a valid model, or does not match the data."""


class BagError(WheelForceError):
    """A recording cannot be read or its content is inconsistent (missing topic, gaps, ...)."""


class SimulationError(WheelForceError):
    """The vehicle simulator was given an invalid configuration or diverged."""


class DiagnosisError(WheelForceError):
    """The sim-vs-real diagnosis cannot be run on the given data."""


class RecordingError(WheelForceError, ValueError):
    """A generic recording (DAQ export) cannot be read or does not match its declared channels."""
