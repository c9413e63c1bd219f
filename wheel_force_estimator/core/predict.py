# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Force prediction from spindle accelerations: one streaming object for node and offline.

:class:`Predictor` is the only prediction code path.  The live node feeds it blocks as they
arrive; :func:`predict_forces` feeds a whole recording and flushes the filter's look-ahead.

Signal path per block::

    accel [m/s²] - static_accel  ->  filter  ->  + static_force  ->  physics terms

Which filter (one rule, :func:`select_filter`, shared by the node and ``predict --causal``):
no ``causal_delay_samples`` (or the model's full look-ahead) -> the two-sided offline FIR;
a look-ahead the model carries a live estimator for -> that causal estimator
(:mod:`.live_estimator`, streamed by :class:`.causal_filter.CausalFilter`); a model without
any live estimator (schema 1, or fitted without) -> the offline FIR cut to that look-ahead,
with :attr:`Predictor.fallback` saying so; a model with live estimators, but not for that
look-ahead -> :class:`ConfigError` naming the look-aheads it has.  Nothing is substituted
silently.

Start and end: the filter starts at the fit-time rest state (as if the car had been standing
at its mean specific force before the first sample; low-coherence bands, where a step would be
amplified, are faded out of the FRF at fit time).  Holding the *first sample* instead was
measured worse: one noisy sample times the quasi-static gain leaves an error lasting the whole
FIR length.  :meth:`Predictor.flush` fills the look-ahead with the mean of the last
``delay_samples`` inputs held constant (a local, noise-averaged state, not a step to rest).
No recorded sample is changed, added or dropped.  The output stream lags the input by
``delay_samples`` (the FIR look-ahead): output sample ``j`` is the estimate for input sample
``j - delay_samples``.  Physics terms read from motion features are faded in after every
(re)start while the feature filters settle (:func:`.physics.settle_weight`), counted from the
first recorded sample (the stage's first ``delay_samples`` inputs are the rest level).

A model whose inputs end with the traction/braking and/or cornering split (issue 29) may be
given its inputs without those rows: :func:`predict_forces` and :func:`iter_forces` derive
them from the accelerations of the segment (:func:`.derived.specific_force_parts`, as the bag
reader does).
"""
from typing import Iterator, Optional

import numpy as np

from wheel_force_estimator.core.causal_filter import CausalFilter
from wheel_force_estimator.core.derived import accel_derived_count
from wheel_force_estimator.core.derived import specific_force_parts
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import with_delay
from wheel_force_estimator.core.lag import LeadDrop
from wheel_force_estimator.core.live_estimator import find_live
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


def check_look_ahead(model: FrfModel, causal_delay_samples: Optional[int] = None):
    """
    Apply the one look-ahead rule without building a filter.

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    causal_delay_samples : int, optional
        Look-ahead [samples]; ``None`` = the full two-sided offline filter.

    Returns
    -------
    (str, CausalEstimator or None, str or None)
        ``'offline'``, ``'live'`` or ``'cut'``; the live estimator for ``'live'``; the fallback
        message for ``'cut'`` (the model has no live estimator).

    Raises
    ------
    ConfigError
        Negative look-ahead; a look-ahead the model's live estimators were not fitted for
        (the available ones and a refit hint named); without live estimators, a look-ahead
        beyond the offline FIR's.

    """
    fs = model.fs_hz
    if causal_delay_samples is None or int(causal_delay_samples) == model.fir_delay_samples:
        return 'offline', None, None
    delay = int(causal_delay_samples)
    if delay < 0:
        raise ConfigError(f'look-ahead {causal_delay_samples} samples must be >= 0')
    live = find_live(model.live, delay)
    if live is not None:
        return 'live', live, None
    if model.live:
        have = ', '.join(f'{e.look_ahead_samples} ({1e3 * e.look_ahead_samples / fs:.1f} ms)'
                         for e in model.live)
        raise ConfigError(
            f'the model has live estimators for look-aheads of {have} samples, not for '
            f'{delay} samples ({1e3 * delay / fs:.1f} ms); use one of those or refit with '
            f'`wheel-force fit --live-look-ahead-s {delay / fs:g}`')
    if delay > model.fir_delay_samples:
        raise ConfigError(
            f'causal delay {causal_delay_samples} samples must be within '
            f"[0, {model.fir_delay_samples}] (the model's look-ahead)")
    message = (f'the model has no live (causal) estimator (schema 1 or fitted without one): '
               f'using the offline FIR cut to {delay} samples ({1e3 * delay / fs:.1f} ms) of '
               f'look-ahead, which loses accuracy; refit with `wheel-force fit` to get the '
               f'causal estimator')
    return 'cut', None, message


def select_filter(model: FrfModel, causal_delay_samples: Optional[int] = None):
    """
    Return the filter engine for a look-ahead and why it is not the designed one.

    Built by the one rule :func:`check_look_ahead` (see the module notes).

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    causal_delay_samples : int, optional
        Look-ahead [samples]; ``None`` = the full two-sided offline filter.

    Returns
    -------
    (engine, str or None)
        An :class:`OverlapAddFilter` or :class:`CausalFilter`, and ``None`` or the fallback
        message (the offline FIR cut, because the model has no live estimator).

    Raises
    ------
    ConfigError
        As :func:`check_look_ahead`.

    """
    kind, live, message = check_look_ahead(model, causal_delay_samples)
    if kind == 'live':
        return CausalFilter(live, model.fs_hz), None
    full = FirFilter(np.asarray(model.fir_taps), model.fir_delay_samples, model.fs_hz)
    if kind == 'offline':
        return OverlapAddFilter(full), None
    return OverlapAddFilter(with_delay(full, int(causal_delay_samples))), message


class Predictor:
    """
    Streaming force estimator for one model (linear filter + optional physics terms).

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    causal_delay_samples : int, optional
        Look-ahead [samples].  ``None`` keeps the model's full two-sided filter (best
        accuracy, latency ``model.fir_delay_samples / fs``); a smaller value selects the
        model's live estimator for that look-ahead (see :func:`select_filter`).

    Attributes
    ----------
    fallback : str or None
        Why the filter is the cut offline FIR instead of a live estimator (model without
        one), for the node's warning and ``predict --causal``; ``None`` otherwise.

    Raises
    ------
    ConfigError
        As :func:`select_filter`.

    """

    def __init__(self, model: FrfModel, causal_delay_samples: Optional[int] = None):
        self.model = model
        self._filter, self.fallback = select_filter(model, causal_delay_samples)
        self._static_accel = np.asarray(model.static_accel_mps2, dtype=np.float64)
        self._static_force = np.asarray(model.static_force_n, dtype=np.float64)[:, None]
        self._physics = None
        self._accel_delay = None
        self._recent = np.empty((len(model.input_channels), 0))
        if model.physics:
            from wheel_force_estimator.core.physics import PhysicsStage
            # The stage reads the inputs delayed like the FIR's output: the first
            # delay_samples it sees are the rest level, before the record.
            self._physics = PhysicsStage(model.physics_terms, model.fs_hz, model.input_channels,
                                         model.output_channels,
                                         lead_samples=self.delay_samples)
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


def model_inputs(model: FrfModel, accel_mps2) -> np.ndarray:
    """
    Return one gap-free segment's inputs to ``model``, checked.

    As given, or, for a model whose inputs end with the splits (traction/braking, cornering)
    given without those rows, with the splits derived from the segment's accelerations at
    the model's sample rate.

    Raises
    ------
    ShapeError
        Wrong channel count.
    NonFiniteError
        NaN or infinity in the input.

    """
    channels = tuple(model.input_channels)
    n_split = accel_derived_count(channels)
    if n_split and np.ndim(accel_mps2) == 2 \
            and np.shape(accel_mps2)[0] == len(channels) - n_split:
        x = as_signals(accel_mps2, 'accelerations', channels[:-n_split], min_samples=0)
        return np.concatenate([x, specific_force_parts(x, model.fs_hz, channels[-n_split:])])
    return as_signals(accel_mps2, 'accelerations', channels, min_samples=0)


def predict_forces(model: FrfModel, accel_mps2, causal_delay_samples: Optional[int] = None,
                   block_size: Optional[int] = None) -> np.ndarray:
    """
    Predict the forces of one contiguous recording, time-aligned with the input.

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    accel_mps2 : array_like, shape (n_inputs, n)
        Specific force [m/s²] of one gap-free segment (a split model: with or without the
        split's two rows, see the module notes).
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
    x = model_inputs(model, accel_mps2)
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
    x = model_inputs(model, accel_mps2)
    predictor = Predictor(model, causal_delay_samples)
    if block_size is None:
        block_size = predictor.efficient_block
    if block_size < 1:
        raise ShapeError(f'block_size must be >= 1, got {block_size}')
    lead = LeadDrop(predictor.delay_samples)

    def stream():
        for i in range(0, x.shape[1], block_size):
            yield predictor.process(x[:, i:i + block_size])
        yield predictor.flush()  # only after the last block: the look-ahead is drained

    for block in stream():
        block = lead(block)
        if block.shape[1]:
            yield block
