# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Named physics terms added to a linear force-from-motion model: features and the stage.

The terms themselves (:class:`PhysicsTerm`, typed parameters, the :data:`TERM_KINDS`
registry) live in :mod:`core.physics_terms`, the force laws in :mod:`core.physics_laws`; both
are re-exported here, so ``core.physics`` stays the one import for users of the terms.
:class:`PhysicsStage` evaluates a set of terms causally, block by block, so the live node,
``predict`` and the diagnosis that fitted the terms all see the same numbers (chunked ==
batch, bit for bit).

Features come from the recorded input by causal IIR filters ``s**k * HP(s) * LP(s)``
(bilinear transform): integration from acceleration needs a high-pass (order 3, so a constant
gravity offset gives exactly zero displacement), differentiation from displacement needs a
low-pass.  The three features of one channel share the same HP and LP, so velocity is the exact
derivative of displacement.  Filter states start in steady state for the first sample, which
keeps a constant offset (gravity) from ringing through the integrators; the motion before the
first sample is still unknown, so a term that reads the features is faded in over the filters'
settle time after every (re)start (:func:`settle_weight`; terms that read only the force
prediction start at once).
"""
import math
from typing import Dict, Sequence

import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filter_design import butter_ba
from wheel_force_estimator.core.physics_laws import *  # noqa: F401,F403  (re-export)
from wheel_force_estimator.core.physics_laws import clip_indicator
from wheel_force_estimator.core.physics_laws import load_rate
from wheel_force_estimator.core.physics_laws import play_operator
from wheel_force_estimator.core.physics_laws import QUANTITIES
from wheel_force_estimator.core.physics_params import TermParams  # noqa: F401
from wheel_force_estimator.core.physics_terms import default_source  # noqa: F401
from wheel_force_estimator.core.physics_terms import LOAD_PARAMETERS  # noqa: F401
from wheel_force_estimator.core.physics_terms import MAX_RESPONSE_TAPS  # noqa: F401
from wheel_force_estimator.core.physics_terms import PARAMETERS  # noqa: F401
from wheel_force_estimator.core.physics_terms import PhysicsTerm
from wheel_force_estimator.core.physics_terms import term_kind  # noqa: F401
from wheel_force_estimator.core.physics_terms import TERM_KINDS  # noqa: F401
from wheel_force_estimator.core.validation import as_signals


# --- features -----------------------------------------------------------------------------------

def feature_filters(fs_hz: float, input_quantity: str, highpass_hz: float,
                    lowpass_hz: float) -> Dict[str, np.ndarray]:
    """
    Second-order sections from the recorded quantity to each feature.

    Returns
    -------
    dict
        ``{'displacement': sos, 'velocity': sos, 'acceleration': sos}``.

    Raises
    ------
    ConfigError
        Unknown quantity, or a corner missing / at or above Nyquist when it is needed.

    """
    if input_quantity not in QUANTITIES:
        raise ConfigError(f'input_quantity must be one of {list(QUANTITIES)}')
    order_in = QUANTITIES.index(input_quantity)
    n_hp = order_in + 1 if order_in > 0 else 0
    n_lp = 2 if order_in < 2 else (2 if lowpass_hz > 0.0 else 0)
    for corner, needed, name in ((highpass_hz, n_hp, 'highpass_hz'),
                                 (lowpass_hz, n_lp, 'lowpass_hz')):
        if needed and not 0.0 < corner < 0.5 * fs_hz:
            raise ConfigError(f'{name}={corner} must be in (0, {0.5 * fs_hz}) Hz for '
                              f'{input_quantity} inputs at {fs_hz} Hz')
    poles, gain, n_zero = np.zeros(0, complex), 1.0, n_hp
    if n_hp:
        _, p, k = signal.butter(n_hp, 2 * np.pi * highpass_hz, 'highpass', analog=True,
                                output='zpk')
        poles, gain = np.concatenate([poles, p]), gain * k
    if n_lp:
        _, p, k = signal.butter(n_lp, 2 * np.pi * lowpass_hz, 'lowpass', analog=True,
                                output='zpk')
        poles, gain = np.concatenate([poles, p]), gain * k
    out = {}
    for order_out, name in enumerate(QUANTITIES):
        zeros = np.zeros(n_zero + order_out - order_in)
        z, p, k = signal.bilinear_zpk(zeros, poles, gain, fs_hz)
        out[name] = signal.zpk2sos(z, p, k) if p.size else np.array([[k, 0, 0, 1, 0, 0.0]])
    return out


class FeatureBank:
    """Causal streaming features (displacement, velocity, acceleration) of some channels."""

    def __init__(self, fs_hz: float, input_quantity: str, highpass_hz: float,
                 lowpass_hz: float, n_channels: int):
        self.sos = feature_filters(fs_hz, input_quantity, highpass_hz, lowpass_hz)
        self._zi_unit = {k: signal.sosfilt_zi(s) for k, s in self.sos.items()}
        self.n_channels = n_channels
        self._zi = None

    def reset(self):
        """Forget the filter state (the next block restarts in steady state)."""
        self._zi = None

    def process(self, x: np.ndarray, rest=None) -> Dict[str, np.ndarray]:
        """
        Return ``{'displacement'|'velocity'|'acceleration': (n_ch, n)}`` for block ``x``.

        A fresh bank starts in steady state for a constant input equal to ``rest``
        (per channel) or, when None, to the first sample.
        """
        if x.shape[1] == 0:
            return {k: np.zeros_like(x) for k in self.sos}
        if self._zi is None:
            level = x[:, 0] if rest is None else np.asarray(rest, dtype=np.float64)
            self._zi = {k: z[:, np.newaxis, :] * level[np.newaxis, :, np.newaxis]
                        for k, z in self._zi_unit.items()}
        out = {}
        for key, sos in self.sos.items():
            out[key], self._zi[key] = signal.sosfilt(sos, x, axis=-1, zi=self._zi[key])
        return out


def settle_samples(fs_hz: float, highpass_hz: float, lowpass_hz: float) -> int:
    """
    Return the samples the feature filters need to settle after a (re)start.

    An integrator high-pass at ``f`` rings for about ``3 / f`` seconds after the record
    starts (a differentiator low-pass for about ``3 / f_lp``): the filters cannot know the
    motion before the first sample.
    """
    settle_s = max(3.0 / highpass_hz if highpass_hz else 0.0,
                   3.0 / lowpass_hz if lowpass_hz else 0.0)
    return int(math.ceil(settle_s * fs_hz))


def settle_weight(start: int, n: int, n_settle: int) -> np.ndarray:
    """
    Weight (n,) of a term's force for samples ``start .. start + n - 1`` after a (re)start.

    0 for the first half of ``n_settle`` samples, a raised cosine to 1 over the second half,
    then 1.  The feature filters cannot know the motion before the first sample: an
    integrator high-pass of order ``q`` answers the unknown initial state with a transient
    decaying like ``t**(q-1) exp(-2 pi f t)``, as large as 100x the displacement for a 0.2 Hz
    double integration of a 6 m/s**2 acceleration, and a hardening law cubes it (measured
    10^5 x the rig's force on a 60 s record).  Half the settle time later it is below 0.3 %
    of its size, so the term is faded in from there; until then the linear prediction stands
    alone.  The diagnosis leaves the same samples out when it fits the terms.
    """
    k = start + np.arange(n, dtype=np.float64)
    if n_settle <= 0:
        return np.ones(n)
    half = 0.5 * n_settle
    ramp = 0.5 - 0.5 * np.cos(np.pi * (k - half) / half)
    return np.where(k < half, 0.0, np.where(k < n_settle, ramp, 1.0))


# --- the streaming stage ------------------------------------------------------------------------

class TermView:
    """
    What a term's force law reads for one output channel of one block.

    ``disp``, ``vel``, ``acc`` are the features of the source input channel, ``partner_disp``
    the displacement of the partner channel (anti-roll bar), ``force`` the linear prediction
    of the output channel (static force included).  The methods keep their state in the stage
    under this (term, channel) key, so a split record gives the same numbers.
    """

    def __init__(self, stage, key, term, feat, s, partner, o, x, f, delayed):
        self._stage, self._key, self._term = stage, key, term
        self._feat, self._s, self._partner, self._o = feat, s, partner, o
        self._x, self._delayed, self._f = x, delayed, f
        self.force = f[o]

    @property
    def disp(self) -> np.ndarray:
        """Displacement of the source channel [m]."""
        return self._feat['displacement'][self._s]

    @property
    def vel(self) -> np.ndarray:
        """Velocity of the source channel [m/s]."""
        return self._feat['velocity'][self._s]

    @property
    def acc(self) -> np.ndarray:
        """Dynamic acceleration of the source channel [m/s**2]."""
        return self._feat['acceleration'][self._s]

    @property
    def partner_disp(self) -> np.ndarray:
        """Displacement of the partner channel [m]."""
        return self._feat['displacement'][self._partner]

    def load(self, partner: bool = False) -> np.ndarray:
        """
        First-order low-pass of the channel's force at the term's ``state_lowpass_hz``.

        ``partner``: of the partner output channel instead (load-state coupling).
        """
        force = self._f[self._partner] if partner else self.force
        key = self._key + (partner,)
        b, a = butter_ba(1, float(self._term.state_lowpass_hz), 'lowpass',
                         float(self._stage.fs_hz))
        zi = self._stage._load_zi.get(key)
        if zi is None:
            zi = signal.lfilter_zi(b, a) * force[0]
        y, self._stage._load_zi[key] = signal.lfilter(b, a, force, zi=zi)
        return y

    def load_rate(self) -> np.ndarray:
        """
        Return the rate of :meth:`load` [N/s].

        Backward difference, the last state of the previous block carried over (the first
        sample of a run has rate 0).  Call it instead of :meth:`load`, not as well: both
        advance the same low-pass state.
        """
        y = self.load()
        key = self._key + ('rate',)
        prev = self._stage._rate_prev.get(key, y[0])
        self._stage._rate_prev[key] = y[-1]
        return load_rate(y, self._stage.fs_hz, prev)

    def delayed(self, delay_s: float) -> np.ndarray:
        """Return the channel's force ``delay_s`` ago (held at its first value at the start)."""
        return delayed_signal(self._delayed[self._o], delay_s * self._stage.fs_hz,
                              self._stage._max_delay)

    def play(self, gap_m: float) -> np.ndarray:
        """Play operator of half-width ``gap_m`` on the displacement, state carried over."""
        disp = self.disp
        y = play_operator(disp, gap_m, self._stage._play.get(self._key, disp[0]))
        self._stage._play[self._key] = y[-1]
        return y

    def clip_feature(self, limit: float, integration: int) -> np.ndarray:
        """Clip indicator of the source, ``integration`` orders below the recorded quantity."""
        stage, n_term = self._stage, self._key[0]
        if n_term not in stage._clip_banks:
            stage._clip_banks[n_term] = (FeatureBank(stage.fs_hz, *self._term.filter_key,
                                                     n_channels=self._x.shape[0]), {})
        bank, cache = stage._clip_banks[n_term]
        if cache.get('block') is not self._x:
            feats = bank.process(clip_indicator(self._x, limit), np.zeros(self._x.shape[0]))
            cache.update(block=self._x, feats=feats)
        order = QUANTITIES.index(self._term.input_quantity) - int(integration)
        return cache['feats'][QUANTITIES[order]][self._s]


class PhysicsStage:
    """
    Add named physics terms to a linear force prediction, causally and block by block.

    Parameters
    ----------
    terms : sequence of PhysicsTerm
    fs_hz : float
        Sample rate [Hz].
    input_channels : sequence of str
        Names of the rows of the input blocks (recorded quantity of each term, usually
        acceleration in m/s**2, gravity included).
    output_channels : sequence of str
        Names of the rows of the force blocks.
    rest_inputs : array_like, shape (n_inputs,), optional
        Input level the feature filters are at rest with before the first block (e.g. the
        fit-time mean acceleration); default: the first sample.
    lead_samples : int
        Samples at the start of every run (after construction or :meth:`reset`) that come
        before the record (a predictor's delay line holding the rest level): feature terms
        are faded in from the first sample after them (:func:`settle_weight`).

    Raises
    ------
    ConfigError
        A term names a channel that is not there.

    """

    def __init__(self, terms: Sequence[PhysicsTerm], fs_hz: float,
                 input_channels: Sequence[str], output_channels: Sequence[str],
                 rest_inputs=None, lead_samples: int = 0):
        self.terms = tuple(terms)
        self._lead = int(lead_samples)
        self.fs_hz = float(fs_hz)
        self.input_channels = tuple(input_channels)
        self.output_channels = tuple(output_channels)
        in_idx = {c: i for i, c in enumerate(self.input_channels)}
        out_idx = {c: i for i, c in enumerate(self.output_channels)}
        self._plan = []
        banks = {}
        self._max_delay = 0
        for term in self.terms:
            for name in term.channels:
                if name not in out_idx:
                    raise ConfigError(f'{term.physics}: output channel {name!r} not in '
                                      f'{list(self.output_channels)}')
            partner_idx = out_idx if term.partners_are_outputs else in_idx
            for name in term.partners:
                if name not in partner_idx:
                    raise ConfigError(f'{term.physics}: partner channel {name!r} not in '
                                      f'{list(partner_idx)}')
            for name in term.sources:
                if name not in in_idx:
                    raise ConfigError(f'{term.physics}: input channel {name!r} not in '
                                      f'{list(self.input_channels)}')
            kind = term.kind
            if kind.history_samples is not None:
                self._max_delay = max(self._max_delay,
                                      kind.history_samples(term.params, self.fs_hz))
            key = term.filter_key
            if key not in banks:
                banks[key] = FeatureBank(self.fs_hz, *key, n_channels=len(self.input_channels))
            settle = (settle_samples(self.fs_hz, term.highpass_hz, term.lowpass_hz)
                      if kind.state == 'motion' and kind.reads_features else 0)
            self._plan.append((term, kind, settle, [out_idx[c] for c in term.channels],
                               [in_idx[c] for c in term.sources],
                               [partner_idx[c] for c in term.partners]))
        self._banks = banks
        self._rest = None
        if rest_inputs is not None:
            self._rest = as_signals(np.asarray(rest_inputs, dtype=np.float64)[:, np.newaxis],
                                    'physics stage rest inputs', self.input_channels)[:, 0]
        self.reset()

    def reset(self):
        """Forget all state (filters, play operators, force history)."""
        for bank in self._banks.values():
            bank.reset()
        self._n_seen = -self._lead
        self._clip_banks = {}
        self._load_zi = {}
        self._rate_prev = {}
        self._response_zi = {}
        self._play = {}
        self._history = None

    def process(self, accel_block_mps2, force_block_n) -> np.ndarray:
        """
        Return ``force_block_n`` plus the force of every term for this block.

        Parameters
        ----------
        accel_block_mps2 : array_like, shape (n_inputs, n)
            Recorded inputs, time-aligned with the force block.
        force_block_n : array_like, shape (n_outputs, n)
            Linear prediction INCLUDING the static force [N].

        Returns
        -------
        numpy.ndarray, shape (n_outputs, n)

        Raises
        ------
        ShapeError
            Channel counts differ from the configuration or the blocks differ in length.

        """
        x = as_signals(accel_block_mps2, 'physics stage input', self.input_channels, 0)
        f = as_signals(force_block_n, 'physics stage force', self.output_channels, 0)
        if x.shape[1] != f.shape[1]:
            raise ShapeError(f'physics stage: input block has {x.shape[1]} samples, force '
                             f'block {f.shape[1]}')
        if not self._plan or x.shape[1] == 0:
            return f.copy()
        feats = {key: bank.process(x, self._rest) for key, bank in self._banks.items()}
        delayed = self._delay_line(f)
        out = f.copy()
        n = x.shape[1]
        for n_term, (term, kind, settle, outs, srcs, partners) in enumerate(self._plan):
            feat = feats[term.filter_key]
            weight = (settle_weight(self._n_seen, n, settle)
                      if self._n_seen < settle else None)
            for j, (o, s) in enumerate(zip(outs, srcs)):
                view = TermView(self, (n_term, j), term, feat, s,
                                partners[j] if partners else None, o, x, f, delayed)
                added = kind.force(term.params, view)
                if weight is not None:
                    added = added * weight
                if term.response_taps:
                    added = self._response(term.response_taps, (n_term, j), added)
                if term.force_range_n:
                    # held at the edge of what the fit saw, not extrapolated (see PhysicsTerm)
                    added = np.clip(added, *term.force_range_n[j])
                out[o] += added
        self._n_seen += n
        return out

    def _response(self, taps, key, added):
        """
        Return the term's force through its causal response FIR, state carried over.

        Zero before the first sample: the term adds no force before the run starts.
        """
        zi = self._response_zi.get(key)
        if zi is None:
            zi = np.zeros(len(taps) - 1)
        if len(taps) == 1:
            return taps[0] * added
        y, self._response_zi[key] = signal.lfilter(taps, (1.0,), added, zi=zi)
        return y

    def _delay_line(self, f):
        if not self._max_delay:
            return None
        if self._history is None:
            # Before the first sample the force is held at its first value (batch == stream).
            self._history = np.repeat(f[:, :1], self._max_delay, axis=1)
        ext = np.concatenate([self._history, f], axis=1)
        self._history = ext[:, -self._max_delay:]
        return ext


def delayed_signal(extended, delay_samples: float, n_history: int) -> np.ndarray:
    """
    ``y[n] = x[n - d]`` by linear interpolation from a record with ``n_history`` past samples.

    ``extended`` holds ``n_history`` samples of history followed by the block.
    """
    whole = int(math.floor(delay_samples))
    frac = delay_samples - whole
    n = extended.size - n_history
    start = n_history - whole
    a = extended[start:start + n]
    b = extended[start - 1:start - 1 + n] if frac > 0.0 else a
    return (1.0 - frac) * a + frac * b


def apply_physics(terms: Sequence[PhysicsTerm], fs_hz: float, input_channels: Sequence[str],
                  output_channels: Sequence[str], inputs, force_n,
                  rest_inputs=None) -> np.ndarray:
    """Batch form of :class:`PhysicsStage` (a fresh stage over the whole record)."""
    stage = PhysicsStage(terms, fs_hz, input_channels, output_channels, rest_inputs)
    return stage.process(inputs, force_n)
