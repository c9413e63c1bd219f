# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Butterworth designs, computed once per (order, corner, kind, rate).

``scipy.signal.butter`` builds poles, zeros and sections from scratch on every call (~0.6 ms);
the diagnosis asks for the same few high- and low-passes thousands of times per run (every
candidate column is high-passed like the residual), where the design cost more than the
filtering.  Callers get copies (a few bytes: scipy's Cython filters need writable
coefficients), so no caller can change another's filter.
"""
import functools
from typing import Tuple, Union

import numpy as np
from scipy import signal

Corner = Union[float, Tuple[float, float]]


@functools.lru_cache(maxsize=256)
def _sos(order, corner_hz, btype, fs_hz):
    return signal.butter(order, corner_hz, btype=btype, fs=fs_hz, output='sos')


@functools.lru_cache(maxsize=256)
def _ba(order, corner_hz, btype, fs_hz):
    return signal.butter(order, corner_hz, btype=btype, fs=fs_hz)


def butter_sos(order: int, corner_hz: Corner, btype: str, fs_hz: float) -> np.ndarray:
    """Return ``scipy.signal.butter(order, corner_hz, btype, fs=fs_hz, output='sos')``."""
    return _sos(int(order), corner_hz, btype, float(fs_hz)).copy()


def butter_ba(order: int, corner_hz: Corner, btype: str,
              fs_hz: float) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``scipy.signal.butter(order, corner_hz, btype, fs=fs_hz)`` as ``(b, a)``."""
    b, a = _ba(int(order), corner_hz, btype, float(fs_hz))
    return b.copy(), a.copy()


@functools.lru_cache(maxsize=256)
def _sos_zi(order, corner_hz, btype, fs_hz):
    return signal.sosfilt_zi(_sos(order, corner_hz, btype, fs_hz))


def butter_sos_zi(order: int, corner_hz: Corner, btype: str, fs_hz: float) -> np.ndarray:
    """Return ``scipy.signal.sosfilt_zi`` of :func:`butter_sos` (step-response initial state)."""
    return _sos_zi(int(order), corner_hz, btype, float(fs_hz)).copy()
