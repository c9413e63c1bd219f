# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Cached Butterworth designs: the same coefficients as scipy, and no shared state."""
import numpy as np
from scipy import signal

from wheel_force_estimator.core.filter_design import butter_ba
from wheel_force_estimator.core.filter_design import butter_sos


def test_designs_equal_scipy_and_callers_cannot_change_each_others():
    sos = butter_sos(4, 1.0, 'highpass', 512.0)
    np.testing.assert_array_equal(sos, signal.butter(4, 1.0, 'highpass', fs=512.0,
                                                     output='sos'))
    sos[:] = 0.0  # a caller scribbling on its copy
    np.testing.assert_array_equal(butter_sos(4, 1.0, 'highpass', 512.0),
                                  signal.butter(4, 1.0, 'highpass', fs=512.0, output='sos'))
    b, a = butter_ba(1, 4.0, 'lowpass', 100.0)
    b_ref, a_ref = signal.butter(1, 4.0, fs=100.0)
    np.testing.assert_array_equal(b, b_ref)
    np.testing.assert_array_equal(a, a_ref)
    band = butter_sos(4, (2.0, 8.0), 'bandpass', 100.0)
    np.testing.assert_array_equal(band, signal.butter(4, (2.0, 8.0), 'bandpass', fs=100.0,
                                                      output='sos'))
