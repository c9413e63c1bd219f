# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Typed physics terms: one frozen parameter class per physics family, one registry.

A :class:`PhysicsTerm` names one effect of the DESIGN.md vocabulary, the output channels it
adds force to and its parameters.  The parameters are parsed into the frozen dataclass of the
term's kind (:data:`TERM_KINDS`, keyed ``physics`` or ``physics:load``) when the term is built,
so a bad model file fails when it is loaded, with the term and the field named, never later
in a hot loop.  The registry is the one place that binds a kind to its parameters and its
force law (:mod:`core.physics_laws`); :class:`core.physics.PhysicsStage` and the diagnosis
iterate it instead of dispatching on names.

The force law of a kind reads what it needs from a *view* of one output channel of one block
(:class:`core.physics.TermView`): ``disp``/``vel``/``acc``/``partner_disp`` (features of the
source and partner input channels), ``force`` (the linear prediction, static force
included), and the stateful helpers ``load(lowpass_hz)``, ``delayed(delay_s)``,
``load_rate()``, ``play(gap_m)`` and ``clip_feature(limit, integration)`` that keep their
state in the stage.

A term may carry a causal *response* (``response_taps``): its force then passes through that
FIR before it is added.  A nonlinear element inside a structure (a friction joint between a
measured base and an unmeasured mass) does not add its force to the measured one: the force
reaches the sensor through the structure's dynamics (:mod:`diagnosis.finders.structure`).
"""
import dataclasses
from dataclasses import dataclass
import math
import types
from typing import Callable, Dict, Mapping, Optional, Tuple

import numpy as np

from wheel_force_estimator.core import physics_laws as law
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.physics_params import AntiRollBarParams
from wheel_force_estimator.core.physics_params import BacklashParams
from wheel_force_estimator.core.physics_params import CoulombFrictionParams
from wheel_force_estimator.core.physics_params import CubicStiffnessParams
from wheel_force_estimator.core.physics_params import DamperAsymmetryParams
from wheel_force_estimator.core.physics_params import DampingErrorParams
from wheel_force_estimator.core.physics_params import finite_number
from wheel_force_estimator.core.physics_params import LiftOffParams
from wheel_force_estimator.core.physics_params import LoadBacklashParams
from wheel_force_estimator.core.physics_params import LoadFrictionParams
from wheel_force_estimator.core.physics_params import LoadLinearParams
from wheel_force_estimator.core.physics_params import LoadRollParams
from wheel_force_estimator.core.physics_params import LoadStopParams
from wheel_force_estimator.core.physics_params import MassErrorParams
from wheel_force_estimator.core.physics_params import SaturationParams
from wheel_force_estimator.core.physics_params import StiffnessErrorParams
from wheel_force_estimator.core.physics_params import StopParams
from wheel_force_estimator.core.physics_params import TermParams
from wheel_force_estimator.core.physics_params import TimeDelayParams

QUANTITIES = law.QUANTITIES
STATES = law.STATES
VOCABULARY = law.VOCABULARY


@dataclass(frozen=True)
class TermKind:
    """
    One registered kind of term: its physics, state, parameter class and force law.

    Attributes
    ----------
    physics : str
        Vocabulary name.
    state : str
        ``'motion'`` or ``'load'``.
    params : type
        The :class:`TermParams` subclass.
    force : callable
        ``force(params, view) -> ndarray (n,)`` [N] added to the output channel.
    needs_partner : bool
        The term needs one partner channel per output channel: an input channel for the
        motion state, the other side's output channel for the load state.
    strength : str or None
        The parameter the force is proportional to (a strength factor found later, e.g. by
        the diagnosis's joint fit, scales it and nothing else); None when the force is not
        proportional to any one parameter (``time_delay``).
    history_samples : callable, optional
        ``(params, fs_hz) -> int``: past force samples the law needs (delay line).
    reads_features : bool
        A motion-state law that reads the filtered motion features (displacement, velocity,
        acceleration or the clip feature), whose integrators need time to settle after a
        (re)start; False for ``time_delay`` and ``tire_lift_off``, which read only the force
        prediction (as every load-state law does, whatever this flag says).

    """

    physics: str
    state: str
    params: type
    force: Callable
    strength: Optional[str] = None
    needs_partner: bool = False
    history_samples: Optional[Callable] = None
    reads_features: bool = True

    def __post_init__(self):
        if self.strength is not None and self.strength not in self.params.names():
            raise ConfigError(f'{self.physics} ({self.state}): strength parameter '
                              f'{self.strength!r} is not one of {list(self.params.names())}')

    @property
    def key(self) -> str:
        """Return ``physics`` or ``physics:state`` (the registry key)."""
        return self.physics if self.state == 'motion' else f'{self.physics}:{self.state}'


def _stop_motion(sign):
    fn = law.bump_stop_force if sign > 0 else law.rebound_stop_force
    return lambda p, v: fn(v.disp, p.gap_m, p.stiffness_n_per_m, p.exponent)


def _stop_load(sign):
    return lambda p, v: law.load_stop_force(v.load(), p.threshold_n, p.gain, p.exponent, sign)


def _backlash(p, v):
    lost = v.disp - v.play(p.gap_m) if p.hysteretic else np.clip(v.disp, -p.gap_m, p.gap_m)
    return law.backlash_force(lost, p.stiffness_n_per_m)


_KINDS = (
    TermKind('bump_stop', 'motion', StopParams, _stop_motion(1.0), 'stiffness_n_per_m'),
    TermKind('rebound_stop', 'motion', StopParams, _stop_motion(-1.0), 'stiffness_n_per_m'),
    TermKind('cubic_stiffness', 'motion', CubicStiffnessParams,
             lambda p, v: law.cubic_stiffness_force(v.disp, p.stiffness_n_per_m3),
             'stiffness_n_per_m3'),
    TermKind('damper_asymmetry', 'motion', DamperAsymmetryParams,
             lambda p, v: law.damper_asymmetry_force(
                 v.vel, p.compression_minus_rebound_n_s_per_m),
             'compression_minus_rebound_n_s_per_m'),
    TermKind('coulomb_friction', 'motion', CoulombFrictionParams,
             lambda p, v: law.coulomb_friction_force(v.vel, p.friction_n, p.velocity_scale_mps),
             'friction_n'),
    TermKind('backlash', 'motion', BacklashParams, _backlash, 'stiffness_n_per_m'),
    TermKind('tire_lift_off', 'motion', LiftOffParams,
             lambda p, v: law.tire_lift_off_force(v.force, p.threshold_n, p.gain), 'gain',
             reads_features=False),
    TermKind('anti_roll_bar', 'motion', AntiRollBarParams,
             lambda p, v: law.anti_roll_bar_force(v.disp, v.partner_disp, p.stiffness_n_per_m),
             'stiffness_n_per_m', needs_partner=True),
    TermKind('time_delay', 'motion', TimeDelayParams,
             lambda p, v: law.time_delay_force(v.force, v.delayed(p.delay_s)),
             history_samples=lambda p, fs: int(math.floor(p.delay_s * fs)) + 1,
             reads_features=False),
    TermKind('sensor_saturation', 'motion', SaturationParams,
             lambda p, v: law.sensor_saturation_force(v.clip_feature(p.limit, p.integration),
                                                      p.force_n), 'force_n'),
    TermKind('mass_error', 'motion', MassErrorParams,
             lambda p, v: law.mass_error_force(v.acc, p.mass_kg), 'mass_kg'),
    TermKind('stiffness_error', 'motion', StiffnessErrorParams,
             lambda p, v: law.stiffness_error_force(v.disp, p.stiffness_n_per_m),
             'stiffness_n_per_m'),
    TermKind('damping_error', 'motion', DampingErrorParams,
             lambda p, v: law.damping_error_force(v.vel, p.damping_n_s_per_m),
             'damping_n_s_per_m'),
    TermKind('bump_stop', 'load', LoadStopParams, _stop_load(1.0), 'gain'),
    TermKind('rebound_stop', 'load', LoadStopParams, _stop_load(-1.0), 'gain'),
    TermKind('cubic_stiffness', 'load', LoadLinearParams,
             lambda p, v: law.load_cubic_force(v.load(), p.center_n, p.gain), 'gain'),
    TermKind('coulomb_friction', 'load', LoadFrictionParams,
             lambda p, v: law.coulomb_friction_force(v.load_rate(), p.friction_n,
                                                     p.rate_scale_n_per_s), 'friction_n'),
    TermKind('backlash', 'load', LoadBacklashParams,
             lambda p, v: law.load_backlash_force(v.load(), p.center_n, p.threshold_n, p.gain),
             'gain'),
    TermKind('anti_roll_bar', 'load', LoadRollParams,
             lambda p, v: law.load_roll_force(v.load(), v.load(partner=True), p.gain), 'gain',
             needs_partner=True),
    TermKind('mass_error', 'load', LoadLinearParams,
             lambda p, v: law.load_linear_force(v.load(), p.center_n, p.gain), 'gain'),
    TermKind('stiffness_error', 'load', LoadLinearParams,
             lambda p, v: law.load_linear_force(v.load(), p.center_n, p.gain), 'gain'),
)

#: The registry: every kind of term, keyed ``physics`` (motion state) or ``physics:load``.
TERM_KINDS: Mapping[str, TermKind] = types.MappingProxyType({k.key: k for k in _KINDS})
#: Parameter names each physics requires (SI units in the names), from the registry.
PARAMETERS = types.MappingProxyType(
    {k.physics: k.params.names() for k in _KINDS if k.state == 'motion'})
#: Parameter names of the effects that can also be driven by the predicted-load state: the
#: linear force prediction of the channel, low-passed at ``state_lowpass_hz`` (suspension
#: force through ``k / (k + c s)`` tracks the compression that the spindle IMU cannot see).
LOAD_PARAMETERS = types.MappingProxyType(
    {k.physics: k.params.names() for k in _KINDS if k.state == 'load'})


def term_kind(physics: str, state: str = 'motion') -> TermKind:
    """
    Return the registered kind of ``physics`` in ``state``.

    Raises
    ------
    ConfigError
        Unknown physics or state, or no such form of the physics.

    """
    if physics not in VOCABULARY:
        raise ConfigError(f'physics {physics!r} is not one of {list(VOCABULARY)}')
    if state not in STATES:
        raise ConfigError(f'{physics}: state must be one of {list(STATES)}, got {state!r}')
    kind = TERM_KINDS.get(physics if state == 'motion' else f'{physics}:{state}')
    if kind is None:
        raise ConfigError(f'{physics}: no {state}-driven form (only '
                          f'{sorted(k.physics for k in _KINDS if k.state == state)})')
    return kind


def default_source(output_channel: str) -> str:
    """Input channel whose motion drives ``output_channel`` (``lf_fz`` -> ``lf_az``)."""
    corner, sep, axis = output_channel.rpartition('_f')
    if not sep or not corner or len(axis) != 1:
        raise ConfigError(
            f'output channel {output_channel!r}: no default source channel, give sources')
    return f'{corner}_a{axis}'


#: Keys of :meth:`PhysicsTerm.to_dict`; the first three are required.
_KEYS = ('physics', 'channels', 'parameters', 'sources', 'partners', 'input_quantity',
         'highpass_hz', 'lowpass_hz', 'state', 'state_lowpass_hz', 'response_taps',
         'force_range_n')
#: Longest response FIR a term may carry [taps] (a model file from a stranger is bounded).
MAX_RESPONSE_TAPS = 65536


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
    parameters : mapping str -> float, or TermParams
        Exactly the names of the kind's parameter class (SI units); read back as a read-only
        ``{name: float}`` mapping.  :attr:`params` holds the typed object.
    sources : tuple of str
        Input channel whose motion drives each output channel (default ``lf_fz`` -> ``lf_az``).
    partners : tuple of str
        ``anti_roll_bar`` only: the other-side input channel for each output channel.  One
        term on ``(lf_fz, rf_fz)`` with sources ``(lf_az, rf_az)`` and partners
        ``(rf_az, lf_az)`` applies ``+k (x_l - x_r)`` left and ``-k (x_l - x_r)`` right.  In
        the load state the partners are the other side's OUTPUT channels (``(rf_fz, lf_fz)``):
        ``+g/2 (F_l - F_r)`` left, ``-g/2 (F_l - F_r)`` right, loads low-passed.
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
    response_taps : tuple of float
        Causal FIR [-] (lag 0 first) the term's force passes through before it is added to
        the channel; empty (default) = added as it is.  Through it a term inside a structure
        reaches the sensor through the structure's dynamics.  At most
        :data:`MAX_RESPONSE_TAPS` finite taps.
    force_range_n : tuple of (float, float)
        Per output channel, the least and the greatest force [N] the term may add: the
        range it added on the recordings its strength was fitted on (see
        ``diagnosis.written.bounded_terms``).  Beyond it the term holds the edge value
        instead of extrapolating its force law (a progressive stop fed a load the fit never
        saw).  Empty (default): unbounded.

    Raises
    ------
    ConfigError
        Any invalid field; the message names the physics and the field.

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
    response_taps: Tuple[float, ...] = ()
    force_range_n: Tuple[Tuple[float, float], ...] = ()
    params: TermParams = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self):
        kind = term_kind(self.physics, self.state)
        name = self.physics
        corner = finite_number(self.state_lowpass_hz, 'state_lowpass_hz')
        if self.state == 'load' and not corner > 0:
            raise ConfigError(f'{name}: state_lowpass_hz must be > 0 for the load state')
        channels = tuple(str(c) for c in self.channels)
        if not channels or len(set(channels)) != len(channels):
            raise ConfigError(f'{name}: channels must be unique and non-empty, '
                              f'got {list(channels)}')
        params = self.parameters
        if not isinstance(params, TermParams):
            if not isinstance(params, Mapping):
                raise ConfigError(f'{name}: parameters must be a mapping, got '
                                  f'{type(params).__name__}')
            try:
                params = kind.params.from_mapping(params)
            except ConfigError as err:
                raise ConfigError(f'{name}.{err}' if not str(err).startswith('parameters')
                                  else f'{name}: {err}') from err
        elif not isinstance(params, kind.params):
            raise ConfigError(f'{name}: parameters must be {kind.params.__name__}, '
                              f'got {type(params).__name__}')
        sources = tuple(self.sources) or tuple(default_source(c) for c in channels)
        if len(sources) != len(channels):
            raise ConfigError(f'{name}: {len(sources)} sources for {len(channels)} channels')
        partners = tuple(self.partners)
        if kind.needs_partner and len(partners) != len(channels):
            raise ConfigError(f'{name}: needs one partner per channel, got '
                              f'{list(partners)} for {list(channels)}')
        if self.input_quantity not in QUANTITIES:
            raise ConfigError(f'input_quantity must be one of {list(QUANTITIES)}, '
                              f'got {self.input_quantity!r}')
        if name == 'sensor_saturation' and \
                params.integration > QUANTITIES.index(self.input_quantity):
            raise ConfigError(f'{name}.integration {params.integration} is more than '
                              f'{self.input_quantity} inputs allow')
        for field_name in ('highpass_hz', 'lowpass_hz'):
            if finite_number(getattr(self, field_name), field_name) < 0.0:
                raise ConfigError(f'{name}: {field_name} must be >= 0')
        object.__setattr__(self, 'response_taps', _response_taps(self.response_taps, name))
        object.__setattr__(self, 'force_range_n',
                           _force_range(self.force_range_n, len(channels), name))
        object.__setattr__(self, 'channels', channels)
        object.__setattr__(self, 'params', params)
        object.__setattr__(self, 'parameters', types.MappingProxyType(params.as_dict()))
        object.__setattr__(self, 'sources', tuple(str(s) for s in sources))
        object.__setattr__(self, 'partners', tuple(str(s) for s in partners))
        for field_name in ('highpass_hz', 'lowpass_hz', 'state_lowpass_hz'):
            object.__setattr__(self, field_name, float(getattr(self, field_name)))

    @property
    def kind(self) -> TermKind:
        """Return the registry entry of this term."""
        return term_kind(self.physics, self.state)

    @property
    def key(self) -> str:
        """Return the registry key: ``physics`` or ``physics:load``."""
        return self.kind.key

    @property
    def partners_are_outputs(self) -> bool:
        """Return True when :attr:`partners` name output channels (load-state coupling)."""
        return self.state == 'load' and bool(self.partners)

    @property
    def filter_key(self) -> Tuple[str, float, float]:
        """Feature filter configuration this term needs."""
        return (self.input_quantity, self.highpass_hz, self.lowpass_hz)

    def scaled(self, factor: float) -> 'PhysicsTerm':
        """
        Return this term with its force multiplied by ``factor`` (its strength parameter).

        Raises
        ------
        ConfigError
            When the kind has no strength parameter (:attr:`TermKind.strength`).

        """
        name = self.kind.strength
        if name is None:
            raise ConfigError(f'{self.physics}: no strength parameter to scale')
        params = dict(self.parameters)
        params[name] = params[name] * float(factor)
        # the bounds were what the term added at its old strength: scaled with it
        bounds = tuple(sorted((lo * float(factor), hi * float(factor)))
                       for lo, hi in self.force_range_n)
        return dataclasses.replace(self, parameters=params, force_range_n=bounds)

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
        if self.response_taps:
            out['response_taps'] = list(self.response_taps)
        if self.force_range_n:
            out['force_range_n'] = [list(r) for r in self.force_range_n]
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
        unknown = sorted(set(data) - set(_KEYS))
        missing = sorted(set(_KEYS[:3]) - set(data))
        if unknown or missing:
            raise ConfigError(f'physics term: unknown keys {unknown}, missing keys {missing}')
        for key in ('channels', 'sources', 'partners', 'response_taps'):
            if isinstance(data.get(key, ()), (str, bytes)):
                raise ConfigError(f'{data["physics"]}: {key} must be a list of channel names, '
                                  f'got {data[key]!r}')
        return cls(physics=str(data['physics']), channels=tuple(data['channels']),
                   parameters=data['parameters'], sources=tuple(data.get('sources', ())),
                   partners=tuple(data.get('partners', ())),
                   input_quantity=str(data.get('input_quantity', 'acceleration')),
                   highpass_hz=data.get('highpass_hz', 0.5),
                   lowpass_hz=data.get('lowpass_hz', 0.0),
                   state=str(data.get('state', 'motion')),
                   state_lowpass_hz=data.get('state_lowpass_hz', 0.0),
                   response_taps=tuple(data.get('response_taps', ())),
                   force_range_n=data.get('force_range_n', ()))


def _force_range(ranges, n_channels: int, name: str) -> Tuple[Tuple[float, float], ...]:
    """Validate per-channel force bounds: empty, or ``n_channels`` finite pairs ``lo <= hi``."""
    if isinstance(ranges, (str, bytes)) or not hasattr(ranges, '__len__'):
        raise ConfigError(f'{name}: force_range_n must be a list of [least, greatest] pairs, '
                          f'got {ranges!r}')
    if len(ranges) and len(ranges) != n_channels:
        raise ConfigError(f'{name}: force_range_n has {len(ranges)} pairs for {n_channels} '
                          f'channels')
    out = []
    for i, pair in enumerate(ranges):
        if isinstance(pair, (str, bytes)) or not hasattr(pair, '__len__') or len(pair) != 2:
            raise ConfigError(f'{name}: force_range_n[{i}] must be [least, greatest] [N], '
                              f'got {pair!r}')
        try:
            lo, hi = (finite_number(v, f'force_range_n[{i}]') for v in pair)
        except ConfigError as err:
            raise ConfigError(f'{name}.{err}') from err
        if lo > hi:
            raise ConfigError(f'{name}: force_range_n[{i}] least {lo:g} N is above its '
                              f'greatest {hi:g} N')
        out.append((lo, hi))
    return tuple(out)


def _response_taps(taps, name: str) -> Tuple[float, ...]:
    """Validate a response FIR: a sequence of at most MAX_RESPONSE_TAPS finite numbers."""
    if isinstance(taps, (str, bytes)) or not hasattr(taps, '__len__'):
        raise ConfigError(f'{name}: response_taps must be a list of numbers, got {taps!r}')
    if len(taps) > MAX_RESPONSE_TAPS:
        raise ConfigError(f'{name}: response_taps has {len(taps)} taps, at most '
                          f'{MAX_RESPONSE_TAPS} allowed')
    out = []
    for i, t in enumerate(taps):
        try:
            out.append(finite_number(t, f'response_taps[{i}]'))
        except ConfigError as err:
            raise ConfigError(f'{name}.{err}') from err
    return tuple(out)
