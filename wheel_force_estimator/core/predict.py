# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Force prediction from spindle accelerations: one streaming object for node and offline.

:class:`Predictor` is the only prediction code path.  The live node feeds it blocks as they
arrive; :func:`predict_forces` feeds a whole recording and flushes the filter's look-ahead.

Signal path per block::

    accel [m/s²] - static_accel  ->  FIR (overlap-add)  ->  + static_force  ->  physics terms

Start and end: the filter starts at the fit-time rest state (as if the car had been standing
at its mean specific force before the first sample; low-coherence bands, where a step would be
amplified, are faded out of the FRF at fit time).  Holding the *first sample* instead was
measured worse: one noisy sample times the quasi-static gain leaves an error lasting the whole
FIR length.  :meth:`Predictor.flush` fills the look-ahead with the mean of the last
``delay_samples`` inputs held constant (a local, noise-averaged state, not a step to rest).
No recorded sample is changed, added or dropped.  The output stream lags the input by
``delay_samples`` (the FIR look-ahead): output sample ``j`` is the estimate for input sample
``j - delay_samples``.
"""
from typing import Iterator, Optional

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import with_delay
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.overlap_add import OverlapAddFilter
from wheel_force_estimator.core.validation import as_signals


class _DelayLine:
    """Integer delay of a multichannel stream, started at a constant state."""

    def __init__(self, initial: np.ndarray, delay_samples: int):
        self._buf = np.repeat(initial[:, None], delay_samples, axis=1)

    def reset(self, initial: np.ndarray):
        self._buf = np.repeat(initial[:, None], self._buf.shape[1], axis=1)

    def process(self, x: np.ndarray) -> np.ndarray:
        joined = np.concatenate([self._buf, x], axis=1)
        m = x.shape[1]
        out, self._buf = joined[:, :m], joined[:, m:]
        return out


class Predictor:
    """
    Streaming force estimator for one model (linear FIR + optional physics terms).

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    causal_delay_samples : int, optional
        Look-ahead kept by the FIR [samples].  ``None`` keeps the model's full two-sided
        filter (best accuracy, latency ``model.fir_delay_samples / fs``); a smaller value
        truncates the acausal part of the impulse response (lower latency).

    Raises
    ------
    ConfigError
        When ``causal_delay_samples`` is negative or exceeds the model's look-ahead.

    """

    def __init__(self, model: FrfModel, causal_delay_samples: Optional[int] = None):
        self.model = model
        fir = FirFilter(np.asarray(model.fir_taps), model.fir_delay_samples, model.fs_hz)
        if causal_delay_samples is not None:
            delay = int(causal_delay_samples)
            if delay < 0 or delay > model.fir_delay_samples:
                raise ConfigError(
                    f'causal delay {causal_delay_samples} samples must be within '
                    f"[0, {model.fir_delay_samples}] (the model's look-ahead)")
            if delay != model.fir_delay_samples:
                fir = with_delay(fir, delay)
        self.fir = fir
        self._filter = OverlapAddFilter(fir)
        self._static_accel = np.asarray(model.static_accel_mps2, dtype=np.float64)
        self._static_force = np.asarray(model.static_force_n, dtype=np.float64)[:, None]
        self._physics = None
        self._accel_delay = None
        self._recent = np.empty((len(model.input_channels), 0))
        if model.physics:
            from wheel_force_estimator.core.physics import PhysicsStage
            self._physics = PhysicsStage(model.physics_terms, model.fs_hz, model.input_channels,
                                         model.output_channels)
            self._accel_delay = _DelayLine(self._static_accel, self.delay_samples)

    @property
    def delay_samples(self) -> int:
        """Return the lag of the output stream behind the input stream [samples]."""
        return int(self._filter.delay_samples)

    @property
    def efficient_block(self) -> int:
        """Return the cheapest long block length [samples] (see the filter's)."""
        return int(self._filter.efficient_block)

    @property
    def n_inputs(self) -> int:
        """Return the number of input channels."""
        return len(self.model.input_channels)

    def reset(self):
        """Forget all state (after a gap or a stamp jump); the next block starts afresh."""
        self._filter.reset()
        self._recent = np.empty((len(self.model.input_channels), 0))
        if self._physics is not None:
            self._physics.reset()
            self._accel_delay.reset(self._static_accel)

    def process(self, accel_mps2) -> np.ndarray:
        """
        Filter one block of accelerations.

        Parameters
        ----------
        accel_mps2 : array_like, shape (n_inputs, m)
            Specific force [m/s²], any ``m >= 0``.

        Returns
        -------
        numpy.ndarray, shape (n_outputs, m)
            Force [N] (static + dynamic + physics), lagged by :attr:`delay_samples`.

        Raises
        ------
        ShapeError
            Wrong channel count.
        NonFiniteError
            NaN or infinity in the block.

        """
        x = as_signals(accel_mps2, 'accelerations', self.model.input_channels, min_samples=0)
        if x.shape[1] == 0:
            return np.empty((len(self.model.output_channels), 0))
        keep = max(self.delay_samples, 1)
        self._recent = np.concatenate([self._recent[:, -keep:], x[:, -keep:]], axis=1)[:, -keep:]
        y = self._filter.process(x - self._static_accel[:, None]) + self._static_force
        if self._physics is not None:
            y = self._physics.process(self._accel_delay.process(x), y)
        return y

    def flush(self) -> np.ndarray:
        """
        Return the last :attr:`delay_samples` outputs (end of a record or before a gap).

        The look-ahead is filled with the mean of the last ``delay_samples`` inputs held
        constant, not with recorded data; the last samples of a record carry the FIR's edge
        effect.  Nothing is returned when no sample was processed since the last reset.
        """
        if self._recent.shape[1] == 0:
            return np.empty((len(self.model.output_channels), 0))
        held = self._recent.mean(axis=1, keepdims=True)
        return self.process(np.repeat(held, self.delay_samples, axis=1))


def predict_forces(model: FrfModel, accel_mps2, causal_delay_samples: Optional[int] = None,
                   block_size: Optional[int] = None) -> np.ndarray:
    """
    Predict the forces of one contiguous recording, time-aligned with the input.

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    accel_mps2 : array_like, shape (n_inputs, n)
        Specific force [m/s²] of one gap-free segment.
    causal_delay_samples : int, optional
        As for :class:`Predictor`.
    block_size : int, optional
        Samples per call to the streaming filter (affects speed and memory, and the result
        only by FFT rounding); default as for :func:`iter_forces`.

    Returns
    -------
    numpy.ndarray, shape (n_outputs, n)
        Force [N]; sample ``k`` estimates input sample ``k``.

    Raises
    ------
    ShapeError
        Wrong channel count.
    NonFiniteError
        NaN or infinity in the input.

    """
    x = as_signals(accel_mps2, 'accelerations', model.input_channels, min_samples=0)
    # Filled in place (no list of blocks to join): a long record needs one output array.
    y = np.empty((len(model.output_channels), x.shape[1]))
    done = 0
    for block in iter_forces(model, x, causal_delay_samples, block_size):
        y[:, done:done + block.shape[1]] = block
        done += block.shape[1]
    return y


def iter_forces(model: FrfModel, accel_mps2, causal_delay_samples: Optional[int] = None,
                block_size: Optional[int] = None) -> Iterator[np.ndarray]:
    """
    Yield the forces of one contiguous recording block by block, time-aligned with the input.

    The blocks, concatenated, are exactly :func:`predict_forces`' result (same code path);
    a consumer can write each block away before the next is computed, so a long recording
    never needs its whole force array in memory.

    Parameters
    ----------
    model, accel_mps2, causal_delay_samples
        As for :func:`predict_forces`.
    block_size : int, optional
        Samples per filter call; default :attr:`Predictor.efficient_block` (a whole batch of
        FFT segments, ~230 k samples for 8192 taps: little memory, one FFT length).

    Yields
    ------
    numpy.ndarray, shape (n_outputs, m)
        Forces [N] of the next ``m >= 1`` input samples, in order.

    Raises
    ------
    ShapeError
        Wrong channel count or block size.
    NonFiniteError
        NaN or infinity in the input (checked before the first block).

    """
    x = as_signals(accel_mps2, 'accelerations', model.input_channels, min_samples=0)
    predictor = Predictor(model, causal_delay_samples)
    if block_size is None:
        block_size = predictor.efficient_block
    if block_size < 1:
        raise ShapeError(f'block_size must be >= 1, got {block_size}')
    # Stream sample j estimates input sample j - delay: the first `delay` outputs are dropped.
    skip = predictor.delay_samples

    def stream():
        for i in range(0, x.shape[1], block_size):
            yield predictor.process(x[:, i:i + block_size])
        yield predictor.flush()  # only after the last block: the look-ahead is drained

    for block in stream():
        drop = min(skip, block.shape[1])
        skip -= drop
        if block.shape[1] > drop:
            yield block[:, drop:]
