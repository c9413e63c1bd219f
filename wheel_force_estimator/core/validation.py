# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Argument checks shared by the numeric core: reject, never repair."""
from typing import Optional, Sequence, Tuple, Type

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError


def as_signals(x, name: str, channels: Optional[Sequence[str]] = None,
               min_samples: int = 1) -> np.ndarray:
    """
    Return ``x`` as a finite float64 array of shape ``(n_channels, n_samples)``.

    Parameters
    ----------
    x : array_like, shape (n_channels, n_samples) or (n_samples,)
        Signals, time last.  A 1-D input is one channel.
    name : str
        What ``x`` is, used in error messages (e.g. ``'inputs of recording run1'``).
    channels : sequence of str, optional
        Channel names; when given, the channel count must match and a non-finite value is
        reported by channel name.
    min_samples : int
        Minimum number of samples required.

    Returns
    -------
    numpy.ndarray, shape (n_channels, n_samples), float64

    Raises
    ------
    ShapeError
        Wrong number of dimensions or channels.
    InsufficientDataError
        Fewer than ``min_samples`` samples.
    NonFiniteError
        A NaN or infinite value (first offending channel and sample named).

    """
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[np.newaxis, :]
    if arr.ndim != 2:
        raise ShapeError(
            f'{name}: expected shape (n_channels, n_samples), got {arr.shape}')
    if channels is not None and arr.shape[0] != len(channels):
        raise ShapeError(
            f'{name}: expected {len(channels)} channels {list(channels)}, got {arr.shape[0]}')
    if arr.shape[1] < min_samples:
        raise InsufficientDataError(
            f'{name}: {arr.shape[1]} samples, at least {min_samples} required')
    finite = np.isfinite(arr)
    if not finite.all():
        ch, idx = np.argwhere(~finite)[0]
        label = channels[ch] if channels is not None else f'channel {ch}'
        raise NonFiniteError(
            f'{name}: non-finite value {arr[ch, idx]!r} in {label} at sample {idx}')
    return arr


def positive_float(value, name: str) -> float:
    """
    Return ``value`` as a float after checking it is finite and > 0.

    Raises
    ------
    ConfigError
        When ``value`` is not a finite number > 0.

    """
    try:
        v = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'{name} must be a number, got {value!r}') from err
    if not np.isfinite(v) or v <= 0.0:
        raise ConfigError(f'{name} must be finite and > 0, got {value!r}')
    return v


def paired_signals(inputs, outputs, input_channels: Sequence[str],
                   output_channels: Sequence[str], name: str, error: Type[Exception],
                   min_samples: int = 1) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return one record's inputs and outputs as read-only signals of one common length.

    Parameters
    ----------
    inputs, outputs : array_like, shape (n_in, n) and (n_out, n)
        Signals, time last (checked by :func:`as_signals` against the channel names).
    input_channels, output_channels : sequence of str
        Row names.
    name : str
        The record, for messages.
    error : type
        Exception raised for unequal lengths or too few samples (the caller's domain error).
    min_samples : int
        Fewest samples accepted.

    Raises
    ------
    ShapeError, NonFiniteError
        From :func:`as_signals`.
    error
        Inputs and outputs differ in length, or hold fewer than ``min_samples`` samples.

    """
    x = as_signals(inputs, f'inputs of {name}', tuple(input_channels), min_samples=0)
    y = as_signals(outputs, f'outputs of {name}', tuple(output_channels), min_samples=0)
    if x.shape[1] != y.shape[1]:
        raise error(f'{name}: {x.shape[1]} input samples but {y.shape[1]} output samples')
    if x.shape[1] < min_samples:
        raise error(f'{name}: no samples' if x.shape[1] == 0 else
                    f'{name}: {x.shape[1]} samples, at least {min_samples} required')
    x.setflags(write=False)
    y.setflags(write=False)
    return x, y


def freeze_paired_record(record, label: str, quantities: Sequence[str],
                         error: Type[Exception]) -> None:
    """
    Validate a frozen motion record's common fields and store them read-only, in place.

    ``record`` is a frozen dataclass with ``fs_hz`` [Hz], ``inputs``, ``outputs``,
    ``input_channels``, ``output_channels`` and ``input_quantity`` (a recording read from a
    DAQ file, a segment the diagnosis works on); called from its ``__post_init__``.

    Parameters
    ----------
    record : dataclass instance
        The record; its fields are replaced by the validated values.
    label : str
        The record (file or segment name), for messages.
    quantities : sequence of str
        Accepted input quantities.
    error : type
        The caller's domain error, raised for every problem found here (chained).

    Raises
    ------
    error
        Sample rate not finite and > 0, unknown input quantity, unequal lengths, no samples.
    ShapeError, NonFiniteError
        From :func:`as_signals` (wrong shapes, NaN or inf in the signals).

    """
    try:
        fs = positive_float(record.fs_hz, f'{label}: sample rate')
    except ConfigError as err:
        raise error(*err.args) from err
    if record.input_quantity not in quantities:
        raise error(f'{label}: input quantity {record.input_quantity!r} is not one of '
                    f'{list(quantities)}')
    x, y = paired_signals(record.inputs, record.outputs, record.input_channels,
                          record.output_channels, label, error)
    for field, value in (('fs_hz', fs), ('inputs', x), ('outputs', y),
                         ('input_channels', tuple(record.input_channels)),
                         ('output_channels', tuple(record.output_channels))):
        object.__setattr__(record, field, value)


def read_only_array(value, dtype) -> np.ndarray:
    """
    Return ``value`` as a read-only array of ``dtype``, shared when that is already safe.

    A plain C-contiguous array that is already of ``dtype``, read-only, and whose every base
    is a read-only array too (so no numpy object can write its memory) is returned itself;
    anything else is copied (C order) and the copy made read-only.  Rebuilding a frozen model
    or filter from another's arrays therefore keeps the same array objects, and caches keyed
    on them (the tap spectra of :mod:`wheel_force_estimator.core.overlap_add`) keep serving
    them.

    Parameters
    ----------
    value : array_like
        The values.
    dtype : numpy dtype
        The dtype of the result.

    Returns
    -------
    numpy.ndarray
        Read-only array of ``dtype``, equal to ``value``.

    Raises
    ------
    TypeError, ValueError
        ``value`` is not convertible to ``dtype`` (numpy's errors, unchanged).

    """
    if type(value) is np.ndarray and value.dtype == np.dtype(dtype) \
            and value.flags.c_contiguous:
        base = value
        while isinstance(base, np.ndarray) and not base.flags.writeable:
            base = base.base
        if base is None:
            return value
    arr = np.array(value, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr
