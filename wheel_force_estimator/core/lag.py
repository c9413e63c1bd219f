# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The output-lag drop: map a lagged filter stream back onto its input samples.

A :class:`~wheel_force_estimator.core.predict.Predictor` with look-ahead ``delay`` returns, as
output sample ``j`` (counted from its last reset), the estimate for input sample
``j - delay``.  The first ``delay`` outputs after a reset therefore estimate nothing that was
received and are dropped; every later output belongs to one input sample, in order.  Offline
``predict`` (``iter_forces``) and the live stream both drop through :class:`LeadDrop`.
"""
import numpy as np


class LeadDrop:
    """
    Drop the first ``delay_samples`` columns of a stream of blocks.

    Parameters
    ----------
    delay_samples : int
        Lag of the filter output behind its input [samples], >= 0.

    Raises
    ------
    ValueError
        On a negative delay.

    """

    def __init__(self, delay_samples: int):
        if delay_samples < 0:
            raise ValueError(f'delay_samples must be >= 0, got {delay_samples}')
        self._delay = int(delay_samples)
        self._left = self._delay

    def reset(self) -> None:
        """Start again: the filter was reset, its next ``delay`` outputs are dropped."""
        self._left = self._delay

    def __call__(self, y: np.ndarray) -> np.ndarray:
        """
        Return the columns of the next filter output block that estimate input samples.

        Parameters
        ----------
        y : numpy.ndarray, shape (n_outputs, m)
            Next block of the lagged filter output.

        Returns
        -------
        numpy.ndarray, shape (n_outputs, m - dropped)
            A view of ``y`` without the columns still inside the lead.

        """
        drop = min(self._left, y.shape[1])
        self._left -= drop
        return y[:, drop:]
