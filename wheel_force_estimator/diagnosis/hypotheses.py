# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Candidate physics: a basis column per shape, a grid of shapes, the term it becomes.

Each hypothesis turns the features of one output channel (:class:`ChannelContext`) into the
force its effect adds with unit strength (the pure functions of :mod:`core.physics` with the
coefficient set to 1).  The diagnosis fits the strength by least squares and picks the shape
(gap, exponent, velocity scale, delay) from a small grid scaled to the training data.
"""
from dataclasses import dataclass
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from scipy import signal

from wheel_force_estimator.core import physics as ph
from wheel_force_estimator.core.filter_design import butter_ba
from wheel_force_estimator.diagnosis.clipping import clip_level
from wheel_force_estimator.diagnosis.features import ChannelContext

Shape = Mapping[str, float]


@dataclass(frozen=True)
class Hypothesis:
    """
    One vocabulary entry as a fittable candidate.

    Attributes
    ----------
    physics : str
        Vocabulary name.
    n_shape : int
        Number of shape parameters searched (0 = linear in its one feature); fewer wins ties.
    fixed_coefficient : bool
        The strength is not fitted (time delay: the delayed prediction replaces the prediction).
    describe : str
        Plain-language description used in the summary.
    regime : str
        Operating regime where the effect shows (for the evidence text).
    priority : bool
        Tried before the ranking when applicable (effects visible in the raw inputs).
    positive : bool
        The fitted strength must be positive to mean this physics (load-driven forms: a stop
        or hardening adds force in the direction of the load excess, a clearance loses it);
        a negative fit is a different effect and explains nothing here.
    lti : bool
        A linear time-invariant map of the recorded motion (a delay, a rate, a left-right
        coupling): inside the span of a MIMO FIR fitted on the same records, so never sought
        against one (the diagnosis without ``--sim``/``--model``), where any gain it shows is
        the FIR's own estimation error.

    """

    physics: str
    n_shape: int
    fixed_coefficient: bool
    describe: str
    regime: str
    _grid: Callable = None
    _basis: Callable = None
    _params: Callable = None
    priority: bool = False
    state: str = 'motion'
    positive: bool = False
    lti: bool = False

    @property
    def key(self) -> str:
        """Return the unique name: the physics, with ``:load`` for the load-driven form."""
        return self.physics if self.state == 'motion' else f'{self.physics}:{self.state}'

    def grid(self, contexts: Sequence[ChannelContext]) -> List[Dict[str, float]]:
        """Shapes to try, scaled to the pooled training features (empty = not applicable)."""
        return self._grid(contexts)

    def basis(self, ctx: ChannelContext, shape: Shape) -> np.ndarray:
        """Force of unit strength for one record [N per unit of the coefficient]."""
        return self._basis(ctx, shape)

    def parameters(self, shape: Shape, coefficient: float) -> Dict[str, float]:
        """Parameters of the :class:`PhysicsTerm` for a fitted shape and strength."""
        return self._params(shape, coefficient)


def _pooled(contexts, attr):
    return np.concatenate([getattr(c, attr) for c in contexts])


def _one(contexts):
    return [{}]


def _stop_grid(sign):
    def grid(contexts):
        d = sign * _pooled(contexts, 'disp')
        gaps = np.quantile(d, [0.6, 0.8, 0.9, 0.95, 0.98, 0.99, 0.995])
        gaps = sorted({float(g) for g in gaps if g >= 0.0})
        return [{'gap_m': g, 'exponent': p} for g in gaps for p in (1.0, 2.0, 3.0)]
    return grid


#: Corners of the load-state low-pass tried [Hz]: high enough to keep stop impacts in phase.
LOAD_LOWPASS_HZ = (2.5, 5.0, 10.0)


def load_state(ctx: ChannelContext, lowpass_hz: float) -> np.ndarray:
    """Predicted load low-passed like :class:`PhysicsStage` does for ``state='load'``."""
    return lowpassed_load(ctx.load, ctx.fs_hz, lowpass_hz)


def lowpassed_load(load_n: np.ndarray, fs_hz: float, lowpass_hz: float) -> np.ndarray:
    """Return ``load_n`` low-passed like the stage's load state (started at its first value)."""
    b, a = butter_ba(1, float(lowpass_hz), 'lowpass', float(fs_hz))
    return signal.lfilter(b, a, load_n, zi=signal.lfilter_zi(b, a) * load_n[0])[0]


def _load_stop_grid(sign):
    def grid(contexts):
        out = []
        for fc in LOAD_LOWPASS_HZ:
            state = np.concatenate([load_state(c, fc) for c in contexts])
            qs = (0.8, 0.9, 0.95, 0.98, 0.99, 0.995)
            for q in qs:
                thr = float(np.quantile(state, q if sign > 0 else 1.0 - q))
                out.extend({'threshold_n': thr, 'exponent': p, 'state_lowpass_hz': fc}
                           for p in (1.0, 2.0))
        return out
    return grid


def _load_cubic_grid(contexts):
    out = []
    for fc in LOAD_LOWPASS_HZ:
        state = np.concatenate([load_state(c, fc) for c in contexts])
        out.append({'center_n': float(np.mean(state)), 'state_lowpass_hz': fc})
    return out


def _load_backlash_grid(contexts):
    out = []
    for fc in LOAD_LOWPASS_HZ:
        state = np.concatenate([load_state(c, fc) for c in contexts])
        sd = float(np.std(state))
        if sd > 0.0:
            out.extend({'center_n': float(np.mean(state)), 'threshold_n': f * sd,
                        'state_lowpass_hz': fc} for f in (0.05, 0.1, 0.2, 0.4))
    return out


def _backlash_grid(contexts):
    sd = float(np.std(_pooled(contexts, 'disp')))
    if sd <= 0.0:
        return []
    return [{'gap_m': f * sd, 'hysteretic': h} for h in (0.0, 1.0)
            for f in (0.05, 0.1, 0.2, 0.4, 0.7)]


def _backlash_basis(ctx, shape):
    if shape['hysteretic']:
        lost = ctx.disp - ph.play_operator(ctx.disp, shape['gap_m'], ctx.disp[0])
    else:
        lost = np.clip(ctx.disp, -shape['gap_m'], shape['gap_m'])
    return ph.backlash_force(lost, 1.0)


def _coulomb_grid(contexts):
    sd = float(np.std(_pooled(contexts, 'vel')))
    return [] if sd <= 0.0 else [{'velocity_scale_mps': f * sd}
                                 for f in (0.003, 0.01, 0.03, 0.1, 0.3)]


def _lift_off_grid(contexts):
    # Only a preloaded contact can lift off: the load must stay well above zero on average
    # (a normal force), not swing around it (a tangential force such as Fx or Fy).
    load = _pooled(contexts, 'load')
    mean = float(np.mean(load))
    if mean <= 2.0 * float(np.std(load)) or float(load.min()) > 0.2 * mean:
        return []
    return [{'threshold_n': f * mean} for f in (0.0, 0.05, 0.15)]


def _arb_grid(contexts):
    return [{}] if all(c.partner_disp is not None for c in contexts) else []


#: Delays tried [samples]: fine near zero (fractional, linear interpolation as in the stage).
DELAYS_SAMPLES = (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0,
                  24.0, 32.0)


def _delay_grid(contexts):
    fs = contexts[0].fs_hz
    steps = [d for d in DELAYS_SAMPLES if d <= 0.1 * fs]
    return [{'delay_samples': s * d} for d in steps for s in (1.0, -1.0)]


def shift_signal(x: np.ndarray, delay_samples: float) -> np.ndarray:
    """
    ``y[n] = x[n - d]`` by linear interpolation, edge values held (d < 0 looks ahead).

    For d >= 0 this is what :class:`PhysicsStage` computes for a time_delay term.
    """
    n = np.arange(x.size, dtype=np.float64)
    return np.interp(n - delay_samples, n, x)


def _saturation_grid(contexts):
    # The clip test of the motion comparison, on the source's whole recorded level (a flat
    # top is judged against the values next to it over all of the record).
    level = clip_level([c.level for c in contexts], contexts[0].n_inputs)
    if level is None:
        return []
    order = ph.QUANTITIES.index(contexts[0].filters[0])
    return [{'limit': level, 'integration': float(k)} for k in range(order + 1)]


def _saturation_basis(ctx, shape):
    quantity, hp, lp = ctx.filters
    bank = ph.FeatureBank(ctx.fs_hz, quantity, hp, lp, 1)
    clip = ph.clip_indicator(ctx.level, shape['limit'])[np.newaxis]
    feats = bank.process(clip, np.zeros(1))
    order = ph.QUANTITIES.index(quantity) - int(shape['integration'])
    return ph.sensor_saturation_force(feats[ph.QUANTITIES[order]][0], 1.0)


HYPOTHESES: Tuple[Hypothesis, ...] = (
    Hypothesis('mass_error', 0, False, 'a mass is missing or wrong (force in phase with '
               'acceleration)', 'high acceleration', _one,
               lambda c, s: ph.mass_error_force(c.acc, 1.0),
               lambda s, k: {'mass_kg': k}, lti=True),
    Hypothesis('stiffness_error', 0, False, 'a stiffness is wrong (force in phase with '
               'displacement)', 'large displacement', _one,
               lambda c, s: ph.stiffness_error_force(c.disp, 1.0),
               lambda s, k: {'stiffness_n_per_m': k}, lti=True),
    Hypothesis('damping_error', 0, False, 'a damping is wrong (force in phase with velocity)',
               'high velocity', _one,
               lambda c, s: ph.damping_error_force(c.vel, 1.0),
               lambda s, k: {'damping_n_s_per_m': k}, lti=True),
    Hypothesis('anti_roll_bar', 0, False, 'left-right coupling is missing (force follows the '
               'left-right displacement difference, like an anti-roll bar)',
               'opposite left-right motion', _arb_grid,
               lambda c, s: ph.anti_roll_bar_force(c.disp, c.partner_disp, 1.0),
               lambda s, k: {'stiffness_n_per_m': k}, lti=True),
    Hypothesis('cubic_stiffness', 0, False, 'symmetric hardening (force grows with the cube '
               'of displacement)', 'large displacement either way', _one,
               lambda c, s: ph.cubic_stiffness_force(c.disp, 1.0),
               lambda s, k: {'stiffness_n_per_m3': k}),
    Hypothesis('damper_asymmetry', 0, False, 'compression and rebound damping differ (force '
               'follows |velocity|)', 'fast compression or rebound', _one,
               lambda c, s: ph.damper_asymmetry_force(c.vel, 1.0),
               lambda s, k: {'compression_minus_rebound_n_s_per_m': k}),
    Hypothesis('sensor_saturation', 0, False, 'the accelerometer clips (flat tops at the '
               'range limit)', 'saturated input', _saturation_grid, _saturation_basis,
               lambda s, k: {'limit': s['limit'], 'force_n': k,
                             'integration': s['integration']}, priority=True),
    Hypothesis('coulomb_friction', 1, False, 'Coulomb friction (a force of constant size '
               'that flips with the direction of motion)', 'velocity reversals', _coulomb_grid,
               lambda c, s: ph.coulomb_friction_force(c.vel, 1.0, s['velocity_scale_mps']),
               lambda s, k: {'friction_n': k, 'velocity_scale_mps': s['velocity_scale_mps']}),
    Hypothesis('tire_lift_off', 1, False, 'the tyre lifts off (the load cannot go below '
               'zero)', 'low load', _lift_off_grid,
               lambda c, s: ph.tire_lift_off_force(c.load, s['threshold_n'], 1.0),
               lambda s, k: {'threshold_n': s['threshold_n'], 'gain': k}),
    Hypothesis('time_delay', 1, True, 'force and acceleration streams are offset in time',
               'fast force changes', _delay_grid,
               lambda c, s: shift_signal(c.load, s['delay_samples']) - c.load,
               None, lti=True),
    Hypothesis('bump_stop', 2, False, 'progressive stiffening in compression, like a jounce '
               'bumper', 'large compression', _stop_grid(1.0),
               lambda c, s: ph.bump_stop_force(c.disp, s['gap_m'], 1.0, s['exponent']),
               lambda s, k: {'gap_m': s['gap_m'], 'stiffness_n_per_m': k,
                             'exponent': s['exponent']}),
    Hypothesis('rebound_stop', 2, False, 'progressive stiffening in extension, like a '
               'rebound stop', 'large extension', _stop_grid(-1.0),
               lambda c, s: ph.rebound_stop_force(c.disp, s['gap_m'], 1.0, s['exponent']),
               lambda s, k: {'gap_m': s['gap_m'], 'stiffness_n_per_m': k,
                             'exponent': s['exponent']}),
    Hypothesis('backlash', 2, False, 'a clearance (dead zone) in the load path',
               'small motion around reversals', _backlash_grid, _backlash_basis,
               lambda s, k: {'gap_m': s['gap_m'], 'stiffness_n_per_m': k,
                             'hysteretic': s['hysteretic']}),
    Hypothesis('bump_stop', 2, False, 'progressive stiffening in compression, like a jounce '
               'bumper (driven by the predicted load, i.e. suspension force)',
               'high load', _load_stop_grid(1.0),
               lambda c, s: ph.load_stop_force(load_state(c, s['state_lowpass_hz']),
                                               s['threshold_n'], 1.0, s['exponent'], 1.0),
               lambda s, k: {'threshold_n': s['threshold_n'], 'gain': k,
                             'exponent': s['exponent']}, state='load', positive=True),
    Hypothesis('rebound_stop', 2, False, 'progressive stiffening in extension, like a '
               'rebound stop (driven by the predicted load)', 'low load',
               _load_stop_grid(-1.0),
               lambda c, s: ph.load_stop_force(load_state(c, s['state_lowpass_hz']),
                                               s['threshold_n'], 1.0, s['exponent'], -1.0),
               lambda s, k: {'threshold_n': s['threshold_n'], 'gain': k,
                             'exponent': s['exponent']}, state='load', positive=True),
    Hypothesis('cubic_stiffness', 1, False, 'symmetric hardening of the suspension (force '
               'grows with the cube of the predicted load change)', 'high load',
               _load_cubic_grid,
               lambda c, s: ph.load_cubic_force(load_state(c, s['state_lowpass_hz']),
                                                s['center_n'], 1.0),
               lambda s, k: {'center_n': s['center_n'], 'gain': k}, state='load', positive=True),
    Hypothesis('backlash', 2, False, 'a clearance (dead zone) in the load path (force lost '
               'while the predicted load crosses its unloaded point, e.g. a bushing)',
               'small load around reversals', _load_backlash_grid,
               lambda c, s: ph.load_backlash_force(load_state(c, s['state_lowpass_hz']),
                                                   s['center_n'], s['threshold_n'], 1.0),
               lambda s, k: {'center_n': s['center_n'], 'threshold_n': s['threshold_n'],
                             'gain': k}, state='load', positive=True),
)


def _load_linear_grid(contexts):
    return [{'center_n': float(np.mean(np.concatenate([load_state(c, fc) for c in contexts]))),
             'state_lowpass_hz': fc} for fc in (1.0, 2.0, 4.0)]


#: Linear omission in the load state: judged against the hardening candidates on pooled
#: vertical channels by :mod:`diagnosis.omissions` (not a per-channel candidate: on a single
#: channel it would also absorb a mass error or an FRF estimation scatter).
LOAD_LINEAR = Hypothesis(
    'stiffness_error', 1, False, 'a spring rate is wrong (force in phase with the spring part '
    'of the predicted suspension force)', 'body motion', _load_linear_grid,
    lambda c, s: ph.load_linear_force(load_state(c, s['state_lowpass_hz']), s['center_n'], 1.0),
    lambda s, k: {'center_n': s['center_n'], 'gain': k}, state='load', lti=True)

#: Linear parameter errors: refitted with every nonlinear term when the reference is a linear
#: law fitted on the real data itself (they stand for what that fit got wrong).
LINEAR_COMPANIONS = ('stiffness_error', 'damping_error', 'mass_error')
#: Feature each linear rate multiplies, with the rate's name and unit (for tolerances).
LINEAR_RATES = {'stiffness_error': ('disp', 'stiffness', 'N/m'),
                'damping_error': ('vel', 'damping', 'N s/m'),
                'mass_error': ('acc', 'mass', 'kg')}
BY_NAME = {h.physics: h for h in HYPOTHESES if h.state == 'motion'}
BY_KEY = {h.key: h for h in HYPOTHESES + (LOAD_LINEAR,)}


def term_parameters(hyp: Hypothesis, shape: Shape, coefficient: float,
                    fs_hz: float) -> Dict[str, float]:
    """Parameters of the PhysicsTerm (time delay converts samples to seconds)."""
    if hyp.physics == 'time_delay':
        return {'delay_s': shape['delay_samples'] / fs_hz}
    return hyp.parameters(shape, coefficient)


def describe_shape(physics: str, params: Mapping[str, float],
                   unit_scale: Optional[float] = None) -> str:
    """Short plain-language detail of the fitted shape (e.g. 'beyond 31 mm compression')."""
    if physics in ('bump_stop', 'rebound_stop') and 'threshold_n' in params:
        side = 'above' if physics == 'bump_stop' else 'below'
        return f'{side} {params["threshold_n"] / 1e3:.2f} kN predicted load'
    if physics == 'cubic_stiffness' and 'center_n' in params:
        return f'around {params["center_n"] / 1e3:.2f} kN predicted load'
    if physics == 'bump_stop':
        return f'beyond {params["gap_m"] * 1e3:.1f} mm compression'
    if physics == 'rebound_stop':
        return f'beyond {params["gap_m"] * 1e3:.1f} mm extension'
    if physics == 'backlash' and 'threshold_n' in params:
        return (f'{params["threshold_n"]:.4g} N of load lost around {params["center_n"]:.4g} N '
                f'predicted load')
    if physics == 'backlash':
        kind = 'hysteretic (lost motion)' if params['hysteretic'] else 'centred dead zone'
        return f'clearance +/-{params["gap_m"] * 1e3:.2f} mm, {kind}'
    if physics == 'coulomb_friction':
        return f'{abs(params["friction_n"]):.4g} N friction level'
    if physics == 'time_delay':
        return f'force lags the motion by {params["delay_s"] * 1e3:.2f} ms'
    if physics == 'tire_lift_off' and 'threshold_n' in params:
        return f'load floor {params["threshold_n"]:.4g} N'
    if physics == 'tire_lift_off' and 'n_flights' in params:
        return (f'{params["n_flights"]:.0f} free flights ({100 * params["flight_fraction"]:.2f} '
                f'% of the samples), outboard mass {params["outboard_mass_kg"]:.1f} kg')
    if physics == 'sensor_saturation':
        return f'input clipped at +/-{params["limit"]:.4g}'
    return ', '.join(f'{k} = {v:.4g}' for k, v in params.items())
