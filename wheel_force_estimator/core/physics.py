# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Named physics terms added to a linear force-from-motion model.

A :class:`PhysicsTerm` names one effect of the DESIGN.md vocabulary, the output channels it
adds force to and its parameters.  Each effect is one small pure function of *features* of the
recorded motion (band-limited displacement, velocity and acceleration of the source channel,
the raw recorded level, the linear force prediction).  :class:`PhysicsStage` evaluates a set of
terms causally, block by block, so the live node, ``predict`` and the diagnosis that fitted the
terms all see the same numbers (chunked == batch, bit for bit).

Features come from the recorded input by causal IIR filters ``s**k * HP(s) * LP(s)``
(bilinear transform): integration from acceleration needs a high-pass (order 3, so a constant
gravity offset gives exactly zero displacement), differentiation from displacement needs a
low-pass.  The three features of one channel share the same HP and LP, so velocity is the exact
derivative of displacement.  Filter states start in steady state for the first sample, which
keeps a constant offset (gravity) from ringing through the integrators.
"""
from dataclasses import dataclass
import math
import types
from typing import Dict, Mapping, Sequence, Tuple

import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import as_signals

VOCABULARY = ('bump_stop', 'rebound_stop', 'cubic_stiffness', 'damper_asymmetry',
              'coulomb_friction', 'backlash', 'tire_lift_off', 'anti_roll_bar', 'time_delay',
              'sensor_saturation', 'mass_error', 'stiffness_error', 'damping_error')

#: Parameter names each physics requires (SI units in the names).
PARAMETERS = {
    'bump_stop': ('gap_m', 'stiffness_n_per_m', 'exponent'),
    'rebound_stop': ('gap_m', 'stiffness_n_per_m', 'exponent'),
    'cubic_stiffness': ('stiffness_n_per_m3',),
    'damper_asymmetry': ('compression_minus_rebound_n_s_per_m',),
    'coulomb_friction': ('friction_n', 'velocity_scale_mps'),
    'backlash': ('gap_m', 'stiffness_n_per_m', 'hysteretic'),
    'tire_lift_off': ('threshold_n', 'gain'),
    'anti_roll_bar': ('stiffness_n_per_m',),
    'time_delay': ('delay_s',),
    'sensor_saturation': ('limit', 'force_n', 'integration'),
    'mass_error': ('mass_kg',),
    'stiffness_error': ('stiffness_n_per_m',),
    'damping_error': ('damping_n_s_per_m',),
}

#: Parameter names of the effects that can also be driven by the predicted-load state: the
#: linear force prediction of the channel, low-passed at ``state_lowpass_hz`` (suspension
#: force through ``k / (k + c s)`` tracks the compression that the spindle IMU cannot see).
LOAD_PARAMETERS = {
    'bump_stop': ('threshold_n', 'gain', 'exponent'),
    'rebound_stop': ('threshold_n', 'gain', 'exponent'),
    'cubic_stiffness': ('center_n', 'gain'),
    'backlash': ('center_n', 'threshold_n', 'gain'),
    'mass_error': ('center_n', 'gain'),
    'stiffness_error': ('center_n', 'gain'),
}
STATES = ('motion', 'load')
QUANTITIES = ('displacement', 'velocity', 'acceleration')
#: Load excess at which the ``gain`` of a load-driven progressive stop is the secant gain.
REFERENCE_LOAD_N = 1000.0
#: Depth at which ``stiffness_n_per_m`` of a progressive stop is the secant stiffness.
REFERENCE_DEPTH_M = 0.01


# --- one pure function per vocabulary entry: the force the effect adds [N] -------------------

def bump_stop_force(disp_m, gap_m, stiffness_n_per_m, exponent):
    """
    Progressive stop in compression: ``k * d * (d / 0.01 m)**(p - 1)``, ``d = max(0, x - gap)``.

    ``stiffness_n_per_m`` is the secant stiffness at 10 mm penetration, so it reads in N/m for
    any exponent.
    """
    depth = np.maximum(np.asarray(disp_m) - gap_m, 0.0)
    return stiffness_n_per_m * depth * (depth / REFERENCE_DEPTH_M) ** (exponent - 1.0)


def rebound_stop_force(disp_m, gap_m, stiffness_n_per_m, exponent):
    """Progressive stop in extension (negative displacement); negative force, see bump_stop."""
    return -bump_stop_force(-np.asarray(disp_m), gap_m, stiffness_n_per_m, exponent)


def load_stop_force(load_n, threshold_n, gain, exponent, sign=1.0):
    """
    Progressive stop driven by the predicted load (``sign`` -1: below the threshold).

    ``gain * d * (d / 1000 N)**(p - 1)`` with ``d = max(0, sign * (load - threshold))``,
    negated for ``sign`` -1 (a rebound stop pulls).
    """
    depth = np.maximum(sign * (np.asarray(load_n) - threshold_n), 0.0)
    return sign * gain * depth * (depth / REFERENCE_LOAD_N) ** (exponent - 1.0)


def load_cubic_force(load_n, center_n, gain):
    """Symmetric hardening in the predicted load: ``gain * 1000 N * ((F - F0) / 1000 N)**3``."""
    return gain * REFERENCE_LOAD_N * ((np.asarray(load_n) - center_n) / REFERENCE_LOAD_N) ** 3


def load_backlash_force(load_n, center_n, threshold_n, gain):
    """
    Clearance driven by the predicted load: ``-gain * clip(F - F0, -thr, thr)``.

    The load through a bushing tracks its deflection; a dead zone of ``+-gap`` in a spring of
    rate ``k`` loses ``k * clip(x, -gap, gap)``, i.e. up to ``thr = k * gap`` of force around
    the unloaded point ``F0``.
    """
    return -gain * np.clip(np.asarray(load_n) - center_n, -threshold_n, threshold_n)


def load_linear_force(load_n, center_n, gain):
    """
    Linear omission seen through the predicted load: ``gain * (F - F0)``.

    A wrong sprung mass scales every quasi-static load (``gain`` = relative mass error, load
    low-passed below the body mode); a wrong spring scales the spring part ``k x`` of the
    suspension force, which is the suspension force through ``k / (k + c s)``.
    """
    return gain * (np.asarray(load_n) - center_n)


def cubic_stiffness_force(disp_m, stiffness_n_per_m3):
    """Symmetric hardening ``k3 * x**3``."""
    return stiffness_n_per_m3 * np.asarray(disp_m) ** 3


def damper_asymmetry_force(vel_mps, compression_minus_rebound_n_s_per_m):
    """
    Damping ``c_c`` in compression (v > 0), ``c_r`` in rebound, beyond their mean.

    ``c_c v`` (v > 0) / ``c_r v`` (v < 0) equals ``(c_c + c_r)/2 v + (c_c - c_r)/2 |v|``; the
    linear model carries the first part, this term the second.
    """
    return 0.5 * compression_minus_rebound_n_s_per_m * np.abs(vel_mps)


def coulomb_friction_force(vel_mps, friction_n, velocity_scale_mps):
    """Coulomb friction regularised at low speed: ``F_c * tanh(v / v0)``."""
    return friction_n * np.tanh(np.asarray(vel_mps) / velocity_scale_mps)


def play_operator(disp_m, half_width_m, start_m):
    """
    Backlash (play) operator: ``y[n] = clip(y[n-1], x[n] - b, x[n] + b)``, ``y[-1] = start``.

    Computed as a prefix scan of clamp compositions (a clamp after a clamp is a clamp), so it
    is vectorised and bit-identical for any split of the record.
    """
    x = np.asarray(disp_m, dtype=np.float64)
    lo, hi = x - half_width_m, x + half_width_m
    shift = 1
    while shift < x.size:
        # Compose the clamp over [i-2s+1, i-s] (earlier) with the one over [i-s+1, i] (later).
        new_lo = np.clip(lo[:-shift], lo[shift:], hi[shift:])
        new_hi = np.clip(hi[:-shift], lo[shift:], hi[shift:])
        lo = np.concatenate([lo[:shift], new_lo])
        hi = np.concatenate([hi[:shift], new_hi])
        shift *= 2
    return np.clip(start_m, lo, hi)


def backlash_force(lost_motion_m, stiffness_n_per_m):
    """
    Force lost in a clearance: ``-k * lost_motion``.

    ``lost_motion`` is ``clip(x, -gap, gap)`` for a centred clearance in a restoring spring
    (``hysteretic = 0``: dead zone ``k * (x - clip)`` instead of ``k * x``), or ``x - play(x)``
    for a clearance in front of a non-restoring element (``hysteretic = 1``: lost motion of the
    play operator, the Prandtl elasto-plastic loop).
    """
    return -stiffness_n_per_m * np.asarray(lost_motion_m)


def tire_lift_off_force(force_total_n, threshold_n, gain):
    """Unilateral contact: the load cannot fall below ``threshold``: ``g * max(0, thr - F)``."""
    return gain * np.maximum(threshold_n - np.asarray(force_total_n), 0.0)


def anti_roll_bar_force(disp_m, partner_disp_m, stiffness_n_per_m):
    """Left-right coupling: ``k * (x_this_side - x_other_side)``."""
    return stiffness_n_per_m * (np.asarray(disp_m) - np.asarray(partner_disp_m))


def time_delay_force(force_n, delayed_force_n):
    """Force and acceleration streams offset: ``F(t - d) - F(t)`` (d > 0: force lags)."""
    return np.asarray(delayed_force_n) - np.asarray(force_n)


def clip_indicator(level, limit):
    """``sign(level)`` where the sensor sits at or beyond its range ``limit``, else 0."""
    level = np.asarray(level, dtype=np.float64)
    return np.sign(level) * (np.abs(level) >= limit)


def sensor_saturation_force(clip_feature, force_n):
    """
    Clipped sensor: the lost peaks cost ``force_n`` times the clip indicator.

    ``clip_feature`` is :func:`clip_indicator` passed through the feature filter that is
    ``integration`` (0, 1, 2) orders below the recorded quantity: the missing part of a
    clipped acceleration peak reaches the force directly (0) and through the integrated
    velocity (1) and displacement (2) the linear model builds from it.
    """
    return force_n * np.asarray(clip_feature)


def mass_error_force(accel_mps2, mass_kg):
    """Missing mass ``dm * a``."""
    return mass_kg * np.asarray(accel_mps2)


def stiffness_error_force(disp_m, stiffness_n_per_m):
    """Missing stiffness ``dk * x``."""
    return stiffness_n_per_m * np.asarray(disp_m)


def damping_error_force(vel_mps, damping_n_s_per_m):
    """Missing damping ``dc * v``."""
    return damping_n_s_per_m * np.asarray(vel_mps)


# --- the term description ---------------------------------------------------------------------

def default_source(output_channel: str) -> str:
    """Input channel whose motion drives ``output_channel`` (``lf_fz`` -> ``lf_az``)."""
    corner, sep, axis = output_channel.rpartition('_f')
    if not sep or not corner or len(axis) != 1:
        raise ConfigError(
            f'output channel {output_channel!r}: no default source channel, give sources')
    return f'{corner}_a{axis}'


def _finite(value, name):
    try:
        v = float(value)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'{name} must be a number, got {value!r}') from err
    if not math.isfinite(v):
        raise ConfigError(f'{name} must be finite, got {value!r}')
    return v


@dataclass(frozen=True)
class PhysicsTerm:
    """
    One named effect added to the linear force prediction.

    Attributes
    ----------
    physics : str
        Name from :data:`VOCABULARY`.
    channels : tuple of str
        Output channels the force is added to; the parameters are shared by all of them.
    parameters : mapping str -> float
        Exactly the names :data:`PARAMETERS` lists for ``physics`` (SI units).
    sources : tuple of str
        Input channel whose motion drives each output channel (default ``lf_fz`` -> ``lf_az``).
    partners : tuple of str
        ``anti_roll_bar`` only: the other-side input channel for each output channel.
    input_quantity : str
        What the input channels record: ``'acceleration'`` (spindle IMUs), ``'velocity'`` or
        ``'displacement'``; sets the feature filters.
    highpass_hz : float
        Corner of the integration high-pass (used when integrating; 0 = none needed).
    lowpass_hz : float
        Corner of the differentiation low-pass (used when differentiating; 0 = none needed).
    state : str
        ``'motion'`` (features of the input channel) or ``'load'`` (the channel's linear force
        prediction low-passed at ``state_lowpass_hz``; :data:`LOAD_PARAMETERS` names).
    state_lowpass_hz : float
        First-order low-pass corner of the load state [Hz].

    """

    physics: str
    channels: Tuple[str, ...]
    parameters: Mapping[str, float]
    sources: Tuple[str, ...] = ()
    partners: Tuple[str, ...] = ()
    input_quantity: str = 'acceleration'
    highpass_hz: float = 0.5
    lowpass_hz: float = 0.0
    state: str = 'motion'
    state_lowpass_hz: float = 0.0

    def __post_init__(self):
        if self.state not in STATES:
            raise ConfigError(f'{self.physics}: state must be one of {list(STATES)}, '
                              f'got {self.state!r}')
        if self.state == 'load' and self.physics not in LOAD_PARAMETERS:
            raise ConfigError(f'{self.physics}: no load-driven form (only '
                              f'{list(LOAD_PARAMETERS)})')
        if self.state == 'load' and not _finite(self.state_lowpass_hz, 'state_lowpass_hz') > 0:
            raise ConfigError(f'{self.physics}: state_lowpass_hz must be > 0 for the load state')
        if self.physics not in VOCABULARY:
            raise ConfigError(f'physics {self.physics!r} is not one of {list(VOCABULARY)}')
        channels = tuple(str(c) for c in self.channels)
        if not channels or len(set(channels)) != len(channels):
            raise ConfigError(f'{self.physics}: channels must be unique and non-empty, '
                              f'got {list(channels)}')
        params = dict(self.parameters)
        required = (LOAD_PARAMETERS if self.state == 'load' else PARAMETERS)[self.physics]
        if sorted(params) != sorted(required):
            raise ConfigError(f'{self.physics}: parameters must be {list(required)}, '
                              f'got {sorted(params)}')
        params = {k: _finite(params[k], f'{self.physics}.{k}') for k in required}
        self._check_ranges(params)
        sources = tuple(self.sources) or tuple(default_source(c) for c in channels)
        if len(sources) != len(channels):
            raise ConfigError(f'{self.physics}: {len(sources)} sources for '
                              f'{len(channels)} channels')
        partners = tuple(self.partners)
        if self.physics == 'anti_roll_bar' and len(partners) != len(channels):
            raise ConfigError(f'anti_roll_bar: needs one partner per channel, got '
                              f'{list(partners)} for {list(channels)}')
        if self.input_quantity not in QUANTITIES:
            raise ConfigError(f'input_quantity must be one of {list(QUANTITIES)}, '
                              f'got {self.input_quantity!r}')
        for name in ('highpass_hz', 'lowpass_hz'):
            if _finite(getattr(self, name), name) < 0.0:
                raise ConfigError(f'{self.physics}: {name} must be >= 0')
        object.__setattr__(self, 'channels', channels)
        object.__setattr__(self, 'parameters', types.MappingProxyType(params))
        object.__setattr__(self, 'sources', tuple(str(s) for s in sources))
        object.__setattr__(self, 'partners', tuple(str(s) for s in partners))
        object.__setattr__(self, 'highpass_hz', float(self.highpass_hz))
        object.__setattr__(self, 'lowpass_hz', float(self.lowpass_hz))
        object.__setattr__(self, 'state_lowpass_hz', float(self.state_lowpass_hz))

    def _check_ranges(self, p):
        rules = {'gap_m': (0.0, False), 'exponent': (1.0, False),
                 'velocity_scale_mps': (0.0, True), 'limit': (0.0, True)}
        for key, (low, strict) in rules.items():
            if key in p and (p[key] <= low if strict else p[key] < low):
                raise ConfigError(f'{self.physics}.{key} must be {">" if strict else ">="} '
                                  f'{low}, got {p[key]}')
        if 'integration' in p and p['integration'] not in (0.0, 1.0, 2.0):
            raise ConfigError(f'{self.physics}.integration must be 0, 1 or 2, '
                              f'got {p["integration"]}')
        if 'hysteretic' in p and p['hysteretic'] not in (0.0, 1.0):
            raise ConfigError(f'{self.physics}.hysteretic must be 0 or 1, got {p["hysteretic"]}')

    def to_dict(self) -> Dict:
        """Return a JSON-serialisable description (inverse of :meth:`from_dict`)."""
        out = {'physics': self.physics, 'channels': list(self.channels),
               'parameters': dict(self.parameters), 'sources': list(self.sources),
               'input_quantity': self.input_quantity, 'highpass_hz': self.highpass_hz,
               'lowpass_hz': self.lowpass_hz}
        if self.partners:
            out['partners'] = list(self.partners)
        if self.state != 'motion':
            out['state'] = self.state
            out['state_lowpass_hz'] = self.state_lowpass_hz
        return out

    @classmethod
    def from_dict(cls, data: Mapping) -> 'PhysicsTerm':
        """
        Build a term from :meth:`to_dict` output.

        Raises
        ------
        ConfigError
            Missing or unknown keys, or invalid values.

        """
        if not isinstance(data, Mapping):
            raise ConfigError(f'physics term must be a mapping, got {type(data).__name__}')
        known = {'physics', 'channels', 'parameters', 'sources', 'partners', 'input_quantity',
                 'highpass_hz', 'lowpass_hz', 'state', 'state_lowpass_hz'}
        unknown = sorted(set(data) - known)
        missing = sorted({'physics', 'channels', 'parameters'} - set(data))
        if unknown or missing:
            raise ConfigError(f'physics term: unknown keys {unknown}, missing keys {missing}')
        if not isinstance(data['parameters'], Mapping):
            raise ConfigError('physics term: parameters must be a mapping')
        return cls(physics=str(data['physics']), channels=tuple(data['channels']),
                   parameters=dict(data['parameters']), sources=tuple(data.get('sources', ())),
                   partners=tuple(data.get('partners', ())),
                   input_quantity=str(data.get('input_quantity', 'acceleration')),
                   highpass_hz=data.get('highpass_hz', 0.5),
                   lowpass_hz=data.get('lowpass_hz', 0.0),
                   state=str(data.get('state', 'motion')),
                   state_lowpass_hz=data.get('state_lowpass_hz', 0.0))

    @property
    def filter_key(self) -> Tuple[str, float, float]:
        """Feature filter configuration this term needs."""
        return (self.input_quantity, self.highpass_hz, self.lowpass_hz)


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


# --- the streaming stage ------------------------------------------------------------------------

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

    Raises
    ------
    ConfigError
        A term names a channel that is not there, or needs look-ahead (negative time delay).

    """

    def __init__(self, terms: Sequence[PhysicsTerm], fs_hz: float,
                 input_channels: Sequence[str], output_channels: Sequence[str],
                 rest_inputs=None):
        self.terms = tuple(terms)
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
            for name in term.sources + term.partners:
                if name not in in_idx:
                    raise ConfigError(f'{term.physics}: input channel {name!r} not in '
                                      f'{list(self.input_channels)}')
            if term.physics == 'time_delay':
                delay = term.parameters['delay_s'] * self.fs_hz
                if delay < 0.0:
                    raise ConfigError(
                        f'time_delay of {term.parameters["delay_s"]} s: the force leads the '
                        f'acceleration, which needs look-ahead; shift the force stamps instead')
                self._max_delay = max(self._max_delay, int(math.floor(delay)) + 1)
            if term.physics == 'sensor_saturation':
                order = QUANTITIES.index(term.input_quantity) - int(term.parameters['integration'])
                if order < 0:
                    raise ConfigError(f'sensor_saturation: integration '
                                      f'{term.parameters["integration"]:g} is more than '
                                      f'{term.input_quantity} inputs allow')
            key = term.filter_key
            if key not in banks:
                banks[key] = FeatureBank(self.fs_hz, *key, n_channels=len(self.input_channels))
            self._plan.append((term, banks[key], [out_idx[c] for c in term.channels],
                               [in_idx[c] for c in term.sources],
                               [in_idx[c] for c in term.partners]))
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
        self._clip_banks = {}
        self._load_zi = {}
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
        if not self._plan:
            return f.copy()
        if x.shape[1] == 0:
            return f.copy()
        feats = {key: bank.process(x, self._rest) for key, bank in self._banks.items()}
        delayed = self._delay_line(f)
        out = f.copy()
        for n_term, (term, bank, outs, srcs, partners) in enumerate(self._plan):
            feat = feats[term.filter_key]
            for j, (o, s) in enumerate(zip(outs, srcs)):
                out[o] += self._evaluate(term, feat, s, o, x, f, delayed,
                                         partners[j] if partners else None, (n_term, j))
        return out

    def _delay_line(self, f):
        if not self._max_delay:
            return None
        if self._history is None:
            # Before the first sample the force is held at its first value (batch == stream).
            self._history = np.repeat(f[:, :1], self._max_delay, axis=1)
        ext = np.concatenate([self._history, f], axis=1)
        self._history = ext[:, -self._max_delay:]
        return ext

    def _load_state(self, term, f_o, key):
        """First-order low-pass of the channel's force prediction, state kept per term."""
        b, a = signal.butter(1, term.state_lowpass_hz, fs=self.fs_hz)
        zi = self._load_zi.get(key)
        if zi is None:
            zi = signal.lfilter_zi(b, a) * f_o[0]
        y, self._load_zi[key] = signal.lfilter(b, a, f_o, zi=zi)
        return y

    def _evaluate(self, term, feat, s, o, x, f, delayed, partner, key):
        p = term.parameters
        name = term.physics
        if term.state == 'load':
            load = self._load_state(term, f[o], key)
            if name == 'cubic_stiffness':
                return load_cubic_force(load, p['center_n'], p['gain'])
            if name == 'backlash':
                return load_backlash_force(load, p['center_n'], p['threshold_n'], p['gain'])
            if name in ('mass_error', 'stiffness_error'):
                return load_linear_force(load, p['center_n'], p['gain'])
            return load_stop_force(load, p['threshold_n'], p['gain'], p['exponent'],
                                   1.0 if name == 'bump_stop' else -1.0)
        disp, vel, acc = feat['displacement'][s], feat['velocity'][s], feat['acceleration'][s]
        if name in ('bump_stop', 'rebound_stop'):
            fn = bump_stop_force if name == 'bump_stop' else rebound_stop_force
            return fn(disp, p['gap_m'], p['stiffness_n_per_m'], p['exponent'])
        if name == 'cubic_stiffness':
            return cubic_stiffness_force(disp, p['stiffness_n_per_m3'])
        if name == 'damper_asymmetry':
            return damper_asymmetry_force(vel, p['compression_minus_rebound_n_s_per_m'])
        if name == 'coulomb_friction':
            return coulomb_friction_force(vel, p['friction_n'], p['velocity_scale_mps'])
        if name == 'backlash':
            if p['hysteretic']:
                start = self._play.get(key, disp[0])
                y = play_operator(disp, p['gap_m'], start)
                self._play[key] = y[-1]
                lost = disp - y
            else:
                lost = np.clip(disp, -p['gap_m'], p['gap_m'])
            return backlash_force(lost, p['stiffness_n_per_m'])
        if name == 'tire_lift_off':
            return tire_lift_off_force(f[o], p['threshold_n'], p['gain'])
        if name == 'anti_roll_bar':
            return anti_roll_bar_force(disp, feat['displacement'][partner],
                                       p['stiffness_n_per_m'])
        if name == 'time_delay':
            return time_delay_force(f[o], delayed_signal(delayed[o], p['delay_s'] * self.fs_hz,
                                                         self._max_delay))
        if name == 'sensor_saturation':
            n_term = key[0]
            if n_term not in self._clip_banks:
                self._clip_banks[n_term] = (FeatureBank(self.fs_hz, *term.filter_key,
                                                        n_channels=x.shape[0]), {})
            bank, cache = self._clip_banks[n_term]
            if cache.get('block') is not x:
                feats = bank.process(clip_indicator(x, p['limit']), np.zeros(x.shape[0]))
                cache.update(block=x, feats=feats)
            order = QUANTITIES.index(term.input_quantity) - int(p['integration'])
            return sensor_saturation_force(cache['feats'][QUANTITIES[order]][s], p['force_n'])
        if name == 'mass_error':
            return mass_error_force(acc, p['mass_kg'])
        if name == 'stiffness_error':
            return stiffness_error_force(disp, p['stiffness_n_per_m'])
        return damping_error_force(vel, p['damping_n_s_per_m'])


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
