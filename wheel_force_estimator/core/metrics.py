# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Prediction quality as durability engineers judge it: relative RMSE and the paper's rubric.

The RMSE of the paper is ``100 * RMS(prediction - target) / RMS(target)`` in percent.  Both
signals are mean-removed first, so a static offset (the static wheel load, which the model adds
back from its fit) never counts as error.  The 1 Hz high-pass variant is the paper's choice for
events dominated by road input, where low-frequency drift would otherwise dominate.
"""
from collections.abc import Mapping
from typing import Dict, Optional, Sequence

import numpy as np
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filter_design import butter_sos
from wheel_force_estimator.core.filter_design import butter_sos_zi
from wheel_force_estimator.core.validation import as_signals
from wheel_force_estimator.core.validation import positive_float

#: Rubric levels, best first (paper, Table 2).
RUBRIC_LEVELS = ('perfect', 'great', 'good', 'bad', 'not_qualified')
#: Exclusive upper RMSE bounds [%] of the first four levels; >= 100 % is 'not_qualified'.
RUBRIC_UPPER_PCT = (25.0, 50.0, 75.0, 100.0)

# A target whose mean-removed RMS is below this fraction of its peak magnitude is constant to
# rounding (float64 mean removal leaves ~1e-16 relative), so a relative error is meaningless.
_CONSTANT_RTOL = 1e-12
_HIGHPASS_ORDER = 4


def _checked_pair(target, prediction, channels: Optional[Sequence[str]]):
    t = as_signals(target, 'RMSE target', channels=channels)
    p = as_signals(prediction, 'RMSE prediction', channels=channels)
    if p.shape != t.shape:
        raise ShapeError(
            f'RMSE: prediction shape {p.shape} differs from target shape {t.shape}')
    return t, p


def _relative_rms_pct(t: np.ndarray, p: np.ndarray, scale: np.ndarray,
                      channels: Optional[Sequence[str]], what: str) -> np.ndarray:
    t = t - t.mean(axis=1, keepdims=True)
    p = p - p.mean(axis=1, keepdims=True)
    rms_target = np.sqrt(np.mean(t * t, axis=1))
    constant = rms_target <= _CONSTANT_RTOL * scale
    if constant.any():
        ch = int(np.flatnonzero(constant)[0])
        label = channels[ch] if channels is not None else f'channel {ch}'
        raise InsufficientDataError(
            f'{what}: target {label} has zero RMS after mean removal (constant signal), so '
            f'the relative error is undefined')
    err = p - t
    return 100.0 * np.sqrt(np.mean(err * err, axis=1)) / rms_target


def rmse_pct(target, prediction, channels: Optional[Sequence[str]] = None) -> np.ndarray:
    """
    Return the relative RMS error per channel, both signals mean-removed.

    Parameters
    ----------
    target : array_like, shape (n_ch, n)
        Measured signals [any unit].
    prediction : array_like, shape (n_ch, n)
        Predicted signals [same unit], time-aligned with ``target``.
    channels : sequence of str, optional
        Channel names for error messages (length ``n_ch``).

    Returns
    -------
    numpy.ndarray, shape (n_ch,)
        ``100 * RMS(p - mean(p) - t + mean(t)) / RMS(t - mean(t))`` [%].

    Raises
    ------
    ShapeError
        Shapes differ or do not match ``channels``.
    InsufficientDataError
        No samples, or a target channel is constant (named).
    NonFiniteError
        NaN or infinity in either signal.

    """
    t, p = _checked_pair(target, prediction, channels)
    return _relative_rms_pct(t, p, np.abs(t).max(axis=1), channels, 'RMSE')


def highpass(x, fs_hz, cutoff_hz=1.0, name: str = 'high-pass input') -> np.ndarray:
    """
    Apply the zero-phase Butterworth high-pass used by :func:`rmse_hp_pct`.

    A 4th-order Butterworth high-pass (second-order sections) run forward and backward with
    ``scipy.signal.sosfiltfilt``: no phase shift, magnitude squared, so -6 dB at the cutoff.
    Edges use scipy's odd extension over ``padlen = 15`` samples; transients of about
    ``1 / cutoff_hz`` seconds remain at each end.

    Parameters
    ----------
    x : array_like, shape (n_ch, n)
        Signals [any unit], time last.
    fs_hz : float
        Sample rate [Hz].
    cutoff_hz : float
        Cutoff, ``0 < cutoff_hz < fs_hz / 2`` [Hz].
    name : str
        What ``x`` is, for error messages.

    Returns
    -------
    numpy.ndarray, shape (n_ch, n), float64
        High-passed signals [same unit].

    Raises
    ------
    InsufficientDataError
        Not more than ``padlen`` samples.
    NonFiniteError
        NaN or infinity in ``x``.
    ShapeError
        ``x`` is not 1-D or 2-D.
    ConfigError
        ``fs_hz`` or ``cutoff_hz`` out of range.

    """
    fs = positive_float(fs_hz, 'fs_hz')
    cutoff = positive_float(cutoff_hz, 'cutoff_hz')
    if cutoff >= fs / 2.0:
        raise ConfigError(f'cutoff_hz must be below fs/2 = {fs / 2.0} Hz, got {cutoff_hz!r}')
    sos = butter_sos(_HIGHPASS_ORDER, cutoff, 'highpass', fs)
    padlen = 3 * (2 * sos.shape[0] + 1)
    sig = as_signals(x, name, min_samples=padlen + 1)
    return _sosfiltfilt(sos, butter_sos_zi(_HIGHPASS_ORDER, cutoff, 'highpass', fs), sig,
                        padlen)


def _sosfiltfilt(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """
    ``scipy.signal.sosfiltfilt(sos, x, axis=1, padlen=padlen)`` with its ``zi`` given.

    scipy derives ``sosfilt_zi(sos)`` anew on every call; the diagnosis high-passes thousands
    of candidate columns with one design, where that was a quarter of the high-pass time.
    The steps are scipy's (odd extension, forward pass from the first sample's step state,
    backward pass from the last output's), tested equal to it.
    """
    left = 2.0 * x[:, :1] - x[:, padlen:0:-1]
    right = 2.0 * x[:, -1:] - x[:, -2:-padlen - 2:-1]
    ext = np.concatenate([left, x, right], axis=1)
    state = zi[:, np.newaxis, :]
    y, _ = scipy.signal.sosfilt(sos, ext, axis=1, zi=state * ext[np.newaxis, :, :1])
    y, _ = scipy.signal.sosfilt(sos, y[:, ::-1], axis=1, zi=state * y[np.newaxis, :, -1:])
    return y[:, ::-1][:, padlen:-padlen]


def rmse_hp_pct(target, prediction, fs_hz, cutoff_hz=1.0,
                channels: Optional[Sequence[str]] = None) -> np.ndarray:
    """
    Return the relative RMS error per channel after :func:`highpass` of both signals.

    Parameters
    ----------
    target : array_like, shape (n_ch, n)
        Measured signals [any unit].
    prediction : array_like, shape (n_ch, n)
        Predicted signals [same unit], time-aligned with ``target``.
    fs_hz : float
        Sample rate [Hz].
    cutoff_hz : float
        High-pass cutoff, ``0 < cutoff_hz < fs_hz / 2`` [Hz].
    channels : sequence of str, optional
        Channel names for error messages (length ``n_ch``).

    Returns
    -------
    numpy.ndarray, shape (n_ch,)
        Relative RMSE of the high-passed signals [%].

    Raises
    ------
    ShapeError
        Shapes differ or do not match ``channels``.
    InsufficientDataError
        Not more than 15 samples, or a high-passed target channel is zero (named).
    NonFiniteError
        NaN or infinity in either signal.
    ConfigError
        ``fs_hz`` or ``cutoff_hz`` out of range.

    """
    t, p = _checked_pair(target, prediction, channels)
    t_hp = highpass(t, fs_hz, cutoff_hz, 'high-pass RMSE target')
    p_hp = highpass(p, fs_hz, cutoff_hz, 'high-pass RMSE prediction')
    return _relative_rms_pct(t_hp, p_hp, np.abs(t).max(axis=1), channels,
                             f'{float(cutoff_hz):g} Hz high-pass RMSE')


def rubric(pct) -> str:
    """
    Classify one relative RMSE with the paper's rubric.

    Parameters
    ----------
    pct : float
        Relative RMSE [%], >= 0.

    Returns
    -------
    str
        'perfect' (< 25), 'great' (25 to < 50), 'good' (50 to < 75), 'bad' (75 to < 100) or
        'not_qualified' (>= 100, including infinity).

    Raises
    ------
    NonFiniteError
        ``pct`` is NaN.
    ConfigError
        ``pct`` is negative or not a number.

    """
    try:
        value = float(pct)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'RMSE must be a number, got {pct!r}') from err
    if np.isnan(value):
        raise NonFiniteError('RMSE is NaN; no rubric level applies')
    if value < 0.0:
        raise ConfigError(f'RMSE must be >= 0 %, got {value}')
    return RUBRIC_LEVELS[int(np.searchsorted(RUBRIC_UPPER_PCT, value, side='right'))]


def rubric_counts(pcts) -> Dict[str, int]:
    """
    Count how many RMSE values fall in each rubric level.

    Parameters
    ----------
    pcts : array_like or mapping of name to float
        Relative RMSE values [%] (a mapping's values are used).

    Returns
    -------
    dict of str to int
        Count per level, keys in :data:`RUBRIC_LEVELS` order (levels with no value give 0).

    Raises
    ------
    NonFiniteError
        A value is NaN.
    ConfigError
        A value is negative or not a number.

    """
    values = list(pcts.values()) if isinstance(pcts, Mapping) else np.ravel(pcts).tolist()
    counts = dict.fromkeys(RUBRIC_LEVELS, 0)
    for value in values:
        counts[rubric(value)] += 1
    return counts
