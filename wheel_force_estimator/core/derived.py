# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Derived inputs: the wheel spin acceleration from the recorded spin rate (issue 33).

A model does not take the spin *rate* itself: it holds the vehicle speed (tens of rad/s
changing over tens of seconds), whose power leaks through the Welch window's side lobes into
every frequency line and buries the spin dynamics there (measured: the held-out 1 Hz
high-passed RMSE of ``Fy`` tripled with the rate as an input).  Its time derivative, the spin
acceleration, is what the physics needs (``My`` = tyre moment - outboard spin inertia x spin
acceleration) and has no such slow content.

The derivative is taken per gap-free segment on the sample stamps with second-order central
differences inside and one-sided differences at the two ends (``numpy.gradient``): nothing is
filled in, a gap is never differentiated across (the same gap rules as every other channel:
segments end at gaps).
"""
import numpy as np

from wheel_force_estimator.core.errors import ShapeError


def spin_acceleration(spin_radps, stamp_ns) -> np.ndarray:
    """
    Return the spin acceleration of one gap-free segment.

    Parameters
    ----------
    spin_radps : numpy.ndarray, shape (n_ch, n)
        Spin rates [rad/s].
    stamp_ns : numpy.ndarray, shape (n,), int64
        Their stamps [ns], strictly increasing, ``n >= 2``.

    Returns
    -------
    numpy.ndarray, shape (n_ch, n)
        d(spin)/dt [rad/s²].

    Raises
    ------
    ShapeError
        Fewer than 2 samples or mismatched shapes.

    """
    spin = np.asarray(spin_radps, dtype=np.float64)
    stamps = np.asarray(stamp_ns, dtype=np.int64)
    if spin.ndim != 2 or stamps.ndim != 1 or spin.shape[1] != stamps.size or stamps.size < 2:
        raise ShapeError(f'spin_acceleration: spin {spin.shape} and stamps {stamps.shape}: '
                         'need (n_ch, n) and (n,) with n >= 2')
    t_s = (stamps - stamps[0]) * 1e-9
    return np.gradient(spin, t_s, axis=1)
