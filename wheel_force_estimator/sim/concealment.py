# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
How concealed an effect is in a nominal / effect pair: where it acts and what it adds to the error.

A diagnosis is only worth something on effects a durability engineer would *not* see by
looking at the global error.  An effect counts as concealed in a pair of recordings of the
same roads (nominal car = the simulation, car with the effect = "real") when either

- it acts on fewer than :data:`ACTIVE_FRACTION_LIMIT` of the samples (a stop engaging, a
  tyre lifting off, an accelerometer clipping: any corner or channel at that instant), or
- on every force channel, the RMS it adds to the global error of the simulation's FRF is
  below the RMS of the error that FRF already makes on the simulation itself (its noise
  floor: sensor noise plus what a linear FRF cannot represent).  With ``e_sim`` the residual
  of the nominal car and ``e_real`` that of the car with the effect (both predicted by the
  FRF fitted on the nominal car), the added RMS is ``sqrt(max(rms(e_real)^2 - rms(e_sim)^2,
  0))``.  The ratio is measured on the 1 Hz high-passed residual, the metric the diagnosis
  reports, and, for information, unfiltered (where quasi-static load errors dominate).

:data:`CONCEALED_PARAMS` are effect sizes measured to be concealed on the default
proving-ground course (``bench/diagnose_blind.py`` prints the measurement for every case).
"""
from dataclasses import dataclass
from types import MappingProxyType
from typing import Dict, Mapping, Optional

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.sim.api import SimResult

#: Largest fraction of samples an effect may act on and still count as concealed by rarity.
ACTIVE_FRACTION_LIMIT = 0.05
#: Effects whose action is confined to some samples (measured by :func:`active_fraction`).
LOCAL_EFFECTS = ('bump_stop', 'rebound_stop', 'tire_lift_off', 'sensor_saturation')
#: A lifted-off tyre: vertical contact force below this fraction of its static load.
LIFT_OFF_FRACTION = 0.01

#: Effect sizes concealed on the default course and car (defaults: :data:`EFFECT_DEFAULTS`),
#: measured on seeds 0-2 and 4 with 2-minute records (duration scale 0.2) against the FRF
#: the diagnosis fits on the simulation - the design of ``wheel-force fit``
#: (:func:`core.design.product_fit_config`, two resolutions), whose noise floor is about
#: half that of the paper's single-resolution FRF the sizes were first measured with:
#: a bump stop 3 mm further out than the default engages on 3.2-3.4 % of the samples, the
#: other local effects keep their default sizes (0.2-2.1 %); the rest are scaled until the
#: error they add stays below the noise floor on every channel (worst channel 0.78-0.87),
#: except ``time_delay``: one integration step (1/2048 s) is the smallest delay the
#: simulator makes, and it adds 1.01-1.11 x that floor.
CONCEALED_PARAMS = MappingProxyType({
    'bump_stop': MappingProxyType({'gap_m': 0.033}),
    'rebound_stop': MappingProxyType({}),
    'tire_lift_off': MappingProxyType({}),
    'sensor_saturation': MappingProxyType({}),
    'cubic_stiffness': MappingProxyType({'coefficient_n_per_m3': 8.4e5}),
    'damper_asymmetry': MappingProxyType({'rebound_to_compression_ratio': 1.145}),
    'coulomb_friction': MappingProxyType({'force_n': 12.5}),
    'backlash': MappingProxyType({'gap_m': 3.0e-5}),
    'anti_roll_bar': MappingProxyType({'front_n_per_m': 1300.0, 'rear_n_per_m': 650.0}),
    'time_delay': MappingProxyType({'delay_s': 1.0 / 2048.0}),
    'mass_error': MappingProxyType({'fraction': 0.0525}),
    'stiffness_error': MappingProxyType({'fraction': 0.05}),
    'damping_error': MappingProxyType({'fraction': -0.032}),
})
#: Parameters :func:`concealed_params` scales (the strength of an effect; not the gaps and
#: limits that make a local effect rare, nor the delay: the simulator resolves one
#: integration step, the concealed delay).
MAGNITUDES = MappingProxyType({
    'bump_stop': ('stiffness_n_per_m', 'progressive_n_per_m3'),
    'rebound_stop': ('stiffness_n_per_m',),
    'cubic_stiffness': ('coefficient_n_per_m3',),
    'coulomb_friction': ('force_n',),
    'backlash': ('gap_m',),
    'anti_roll_bar': ('front_n_per_m', 'rear_n_per_m'),
    'mass_error': ('fraction',),
    'stiffness_error': ('fraction',),
    'damping_error': ('fraction',),
})


@dataclass(frozen=True)
class Concealment:
    """
    The concealment measurement of one pair.

    Attributes
    ----------
    effect : str
        Vocabulary name of the effect.
    active_fraction : float or None
        Fraction of samples where the effect acts (None: it acts on every sample).
    excess_ratio : Mapping[str, float]
        Per force channel: added error RMS / noise-floor RMS, 1 Hz high-passed.
    excess_ratio_raw : Mapping[str, float]
        The same, unfiltered.

    """

    effect: str
    active_fraction: Optional[float]
    excess_ratio: Mapping[str, float]
    excess_ratio_raw: Mapping[str, float]

    @property
    def worst_channel(self) -> str:
        """Return the channel where the effect shows most (high-passed ratio)."""
        return max(self.excess_ratio, key=self.excess_ratio.get)

    @property
    def rare(self) -> bool:
        """Return True when the effect acts, but on fewer than the limit of the samples."""
        return (self.active_fraction is not None
                and 0.0 < self.active_fraction < ACTIVE_FRACTION_LIMIT)

    @property
    def below_noise(self) -> bool:
        """Return True when the added error is below the floor on every channel."""
        return max(self.excess_ratio.values()) < 1.0

    @property
    def concealed(self) -> bool:
        """Return True when the effect is rare or below the noise floor."""
        return self.rare or self.below_noise

    def describe(self) -> str:
        """One line: the active fraction and the worst-channel ratios."""
        c = self.worst_channel
        active = ('acts always' if self.active_fraction is None
                  else f'acts on {self.active_fraction:.2%} of samples')
        verdict = 'concealed' if self.concealed else 'NOT concealed'
        return (f'{active}; worst channel {c}: adds {self.excess_ratio[c]:.2f} x the noise '
                f'floor RMS (1 Hz high-passed), {self.excess_ratio_raw[c]:.2f} x unfiltered '
                f'-> {verdict}')


def active_fraction(effect: str, real: SimResult) -> Optional[float]:
    """
    Return the fraction of samples where a local effect acts on ``real`` (None otherwise).

    Bump / rebound stop: any suspension compressed / extended beyond the gap; tyre lift-off:
    any tyre's vertical contact force below :data:`LIFT_OFF_FRACTION` of its static load;
    sensor saturation: any accelerometer channel at its range limit.
    """
    if effect not in LOCAL_EFFECTS:
        return None
    params = real.effect_params.get(effect)
    if params is None:
        raise ConfigError(f'the recording was not simulated with {effect}')
    if effect in ('bump_stop', 'rebound_stop'):
        sign = 1.0 if effect == 'bump_stop' else -1.0
        acting = sign * real.states['suspension_compression_m'] > params['gap_m']
    elif effect == 'tire_lift_off':
        static = real.states['static_force_n'][2::3][:, np.newaxis]
        acting = real.states['tyre_force_n'][2::3] < LIFT_OFF_FRACTION * static
    else:
        acting = np.abs(real.accel_mps2) >= params['limit_mps2']
    return float(np.mean(np.any(acting, axis=0)))


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x ** 2, axis=1))


def measure_concealment(effect: str, nominal: SimResult, real: SimResult, model,
                        highpass_hz: float = 1.0) -> Concealment:
    """
    Measure how concealed ``effect`` is in the pair ``nominal`` / ``real``.

    Parameters
    ----------
    effect : str
        The effect ``real`` was simulated with.
    nominal, real : SimResult
        The same roads driven by the nominal car and by the car with the effect.
    model : FrfModel
        The FRF fitted on ``nominal`` (what the diagnosis calls the simulation).
    highpass_hz : float
        Corner of the high-passed ratio [Hz].

    Returns
    -------
    Concealment

    Raises
    ------
    ConfigError
        The recordings differ in length or rate, or ``real`` lacks the effect.

    """
    from wheel_force_estimator.core.predict import predict_forces
    if nominal.force_n.shape != real.force_n.shape or nominal.fs_hz != real.fs_hz:
        raise ConfigError(f'{effect}: nominal and real recordings differ in shape or rate '
                          f'({nominal.force_n.shape} at {nominal.fs_hz:g} Hz vs '
                          f'{real.force_n.shape} at {real.fs_hz:g} Hz)')
    # The FIR's start-up transient is no part of either error.
    skip = min(int(model.n_taps), nominal.force_n.shape[1] // 2)
    residuals = [rec.force_n - predict_forces(model, rec.accel_mps2) for rec in (nominal, real)]
    ratios = []
    for hp in (highpass_hz, 0.0):
        e_sim, e_real = (highpass(e, nominal.fs_hz, hp, 'concealment residual') if hp > 0.0
                         else e for e in residuals)
        floor = _rms(e_sim[:, skip:])
        excess = np.sqrt(np.maximum(_rms(e_real[:, skip:]) ** 2 - floor ** 2, 0.0))
        ratios.append(excess / np.maximum(floor, 1e-300))
    channels = model.output_channels
    by_channel = [MappingProxyType(dict(zip(channels, (float(v) for v in r)))) for r in ratios]
    return Concealment(effect, active_fraction(effect, real), by_channel[0], by_channel[1])


def concealed_params(effect: str, factor: float = 1.0) -> Dict[str, Dict[str, float]]:
    """
    Return ``effect_params`` for a concealed case, its strength scaled by ``factor``.

    The :data:`MAGNITUDES` of the effect are scaled (from the concealed size, or the default
    where :data:`CONCEALED_PARAMS` keeps it); a damper asymmetry scales its excess over a
    symmetric damper (ratio ``1 + factor * 0.3``).  ``factor`` <= 1 keeps a case concealed.

    Raises
    ------
    ConfigError
        Unknown effect or a factor that is not positive.

    """
    from wheel_force_estimator.sim.effects import EFFECT_DEFAULTS
    if effect not in CONCEALED_PARAMS:
        raise ConfigError(f'unknown effect {effect!r} (known: {", ".join(EFFECT_DEFAULTS)})')
    if not factor > 0.0:
        raise ConfigError(f'factor must be > 0, got {factor!r}')
    params = dict(EFFECT_DEFAULTS[effect])
    params.update(CONCEALED_PARAMS[effect])
    if effect == 'damper_asymmetry':
        ratio = params['rebound_to_compression_ratio']
        params['rebound_to_compression_ratio'] = 1.0 + factor * (ratio - 1.0)
    for key in MAGNITUDES.get(effect, ()):
        params[key] *= factor
    return {effect: params}
