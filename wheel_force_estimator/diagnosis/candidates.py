# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The candidate registry: what the diagnosis knows about each kind of physics term, in one table.

Every entry is keyed like :data:`core.physics.TERM_KINDS` (``physics`` or ``physics:load``)
and bound to that kind.  Its fitting basis is the kind's own force law at unit strength
(:meth:`Candidate.basis`: the law the written term computes, read from one record's features
through :class:`ContextView`), so the force the diagnosis fits and the force the model adds
are one function.  The entry carries the rest as attributes: the shape grid
(:mod:`diagnosis.grids`), the plain-language description, the regime where it shows, the
fitted-shape detail of the summary, the state its report plot shows, and the flags the finders
read (tried first, sign-constrained, linear time-invariant, a kind of hardening, searched per
channel).  Every other module looks physics up here: the finders, :mod:`diagnosis.text` and
:mod:`diagnosis.plots`.
"""
from dataclasses import dataclass
import types
from typing import Callable, Dict, Mapping, Optional, Tuple

import numpy as np

from wheel_force_estimator.core import physics as ph
from wheel_force_estimator.core.physics_terms import TERM_KINDS
from wheel_force_estimator.core.physics_terms import TermKind
from wheel_force_estimator.diagnosis import grids
from wheel_force_estimator.diagnosis.features import ChannelContext

Shape = Mapping[str, float]


class ContextView:
    """
    One record's features as a term's force law reads them (:class:`core.physics.TermView`).

    Whole records, so the states start at their first value as the stage starts them; the
    load state's corner comes from the candidate's shape.
    """

    def __init__(self, ctx: ChannelContext, shape: Shape):
        self._ctx, self._shape = ctx, shape
        self.disp, self.vel, self.acc = ctx.disp, ctx.vel, ctx.acc
        self.partner_disp = ctx.partner_disp
        self.force = ctx.load

    def load(self, partner: bool = False) -> np.ndarray:
        """Predicted load low-passed at the shape's ``state_lowpass_hz`` (no partner here)."""
        if partner:
            raise ValueError('a candidate reads no partner load')
        return grids.load_state(self._ctx, self._shape['state_lowpass_hz'])

    def delayed(self, delay_s: float) -> np.ndarray:
        """Return the predicted load ``delay_s`` ago (negative: ahead), edge values held."""
        return grids.shift_signal(self.force, delay_s * self._ctx.fs_hz)

    def play(self, gap_m: float) -> np.ndarray:
        """Play operator of half-width ``gap_m`` on the displacement, from its first value."""
        return ph.play_operator(self.disp, gap_m, self.disp[0])

    def clip_feature(self, limit: float, integration: int) -> np.ndarray:
        """Clip indicator of the recorded level, ``integration`` orders below its quantity."""
        quantity, hp, lp = self._ctx.filters
        bank = ph.FeatureBank(self._ctx.fs_hz, quantity, hp, lp, 1)
        clip = ph.clip_indicator(self._ctx.level, limit)[np.newaxis]
        feats = bank.process(clip, np.zeros(1))
        order = ph.QUANTITIES.index(quantity) - int(integration)
        return feats[ph.QUANTITIES[order]][0]


@dataclass(frozen=True)
class Candidate:
    """
    One registered term kind as a fittable candidate.

    Attributes
    ----------
    key : str
        Its :data:`TERM_KINDS` key.
    n_shape : int
        Number of shape parameters searched (0 = linear in its one feature); fewer wins ties.
    describe : str
        Plain-language description used in the summary and the report.
    regime : str
        Operating regime where the effect shows (for the evidence text).
    grid : callable
        ``grid(contexts) -> list of shapes`` (:mod:`diagnosis.grids`; empty = not applicable).
    params : callable
        ``params(shape, coefficient, fs_hz) -> dict``: the written term's parameters.
    detail : callable
        ``detail(params) -> str or None``: the fitted shape in words (None: list the numbers).
    plot : tuple of str
        State that reveals it in the report: (feature key, axis label).
    fixed_coefficient : bool
        The strength is not fitted (time delay: the delayed prediction replaces the prediction).
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
    hardening : bool
        A kind of stiffening spring law (the kinds compete pooled, :mod:`finders.hardening`).
    per_channel : bool
        Searched channel by channel (False: only pooled, by the structural finder).
    inside : str
        How the kind reads inside a structure (:mod:`finders.structure`), '' if never there.

    """

    key: str
    n_shape: int
    describe: str
    regime: str
    grid: Callable
    params: Callable
    detail: Callable
    plot: Tuple[str, str]
    fixed_coefficient: bool = False
    priority: bool = False
    positive: bool = False
    lti: bool = False
    hardening: bool = False
    per_channel: bool = True
    inside: str = ''

    @property
    def kind(self) -> TermKind:
        """Return the registered term kind."""
        return TERM_KINDS[self.key]

    @property
    def physics(self) -> str:
        """Return the vocabulary name."""
        return self.kind.physics

    @property
    def state(self) -> str:
        """Return ``'motion'`` or ``'load'``."""
        return self.kind.state

    def basis(self, ctx: ChannelContext, shape: Shape) -> np.ndarray:
        """Force of unit strength for one record [N per unit of the coefficient]."""
        # The law reads the grid's shape unvalidated: a grid point may lie outside what a
        # written term allows (a look-ahead delay, tried to name a stamp offset).
        params = types.SimpleNamespace(**self.params(shape, 1.0, ctx.fs_hz))
        return self.kind.force(params, ContextView(ctx, shape))

    def parameters(self, shape: Shape, coefficient: float) -> Dict[str, float]:
        """Parameters of the :class:`PhysicsTerm` for a fitted shape and strength."""
        return self.params(shape, coefficient, None)


def _gap_detail(side):
    def detail(p):
        if 'threshold_n' in p:
            return (f'{"above" if side == "compression" else "below"} '
                    f'{p["threshold_n"] / 1e3:.2f} kN predicted load')
        return f'beyond {p["gap_m"] * 1e3:.1f} mm {side}'
    return detail


def _cubic_detail(p):
    return f'around {p["center_n"] / 1e3:.2f} kN predicted load' if 'center_n' in p else None


def _backlash_detail(p):
    if 'threshold_n' in p:
        return (f'{p["threshold_n"]:.4g} N of load lost around {p["center_n"]:.4g} N '
                f'predicted load')
    kind = 'hysteretic (lost motion)' if p['hysteretic'] else 'centred dead zone'
    return f'clearance +/-{p["gap_m"] * 1e3:.2f} mm, {kind}'


def _lift_off_detail(p):
    if 'threshold_n' in p:
        return f'load floor {p["threshold_n"]:.4g} N'
    if 'n_flights' in p:
        return (f'{p["n_flights"]:.0f} free flights ({100 * p["flight_fraction"]:.2f} '
                f'% of the samples), outboard mass {p["outboard_mass_kg"]:.1f} kg')
    return None


def _none(p):
    return None


def _strength(name):
    return lambda s, k, fs: {name: k}


def _stop(s, k, fs):
    return {'gap_m': s['gap_m'], 'stiffness_n_per_m': k, 'exponent': s['exponent']}


def _load_stop(s, k, fs):
    return {'threshold_n': s['threshold_n'], 'gain': k, 'exponent': s['exponent']}


_DISP = ('displacement', 'displacement [m]')
_VEL = ('velocity', 'velocity [m/s]')
_LOAD = ('load', 'predicted force [N]')

_ENTRIES: Tuple[Candidate, ...] = (
    Candidate('mass_error', 0, 'a mass is missing or wrong (force in phase with acceleration)',
              'high acceleration', grids.one, _strength('mass_kg'), _none,
              ('acceleration', 'acceleration [m/s^2]'), lti=True),
    Candidate('stiffness_error', 0, 'a stiffness is wrong (force in phase with displacement)',
              'large displacement', grids.one, _strength('stiffness_n_per_m'), _none, _DISP,
              lti=True),
    Candidate('damping_error', 0, 'a damping is wrong (force in phase with velocity)',
              'high velocity', grids.one, _strength('damping_n_s_per_m'), _none, _VEL,
              lti=True),
    Candidate('anti_roll_bar', 0, 'left-right coupling is missing (force follows the '
              'left-right displacement difference, like an anti-roll bar)',
              'opposite left-right motion', grids.arb_grid, _strength('stiffness_n_per_m'),
              _none, _DISP, lti=True),
    Candidate('cubic_stiffness', 0, 'symmetric hardening (force grows with the cube of '
              'displacement)', 'large displacement either way', grids.one,
              _strength('stiffness_n_per_m3'), _cubic_detail, _DISP, hardening=True),
    Candidate('damper_asymmetry', 0, 'compression and rebound damping differ (force follows '
              '|velocity|)', 'fast compression or rebound', grids.one,
              _strength('compression_minus_rebound_n_s_per_m'), _none, _VEL),
    Candidate('sensor_saturation', 0, 'the accelerometer clips (flat tops at the range limit)',
              'saturated input', grids.saturation_grid,
              lambda s, k, fs: {'limit': s['limit'], 'force_n': k,
                                'integration': s['integration']},
              lambda p: f'input clipped at +/-{p["limit"]:.4g}', ('level', 'recorded input'),
              priority=True),
    Candidate('coulomb_friction', 1, 'Coulomb friction (a force of constant size that flips '
              'with the direction of motion)', 'velocity reversals', grids.coulomb_grid,
              lambda s, k, fs: {'friction_n': k, 'velocity_scale_mps': s['velocity_scale_mps']},
              lambda p: f'{abs(p["friction_n"]):.4g} N friction level', _VEL),
    Candidate('tire_lift_off', 1, 'the tyre lifts off (the load cannot go below zero)',
              'low load', grids.lift_off_grid,
              lambda s, k, fs: {'threshold_n': s['threshold_n'], 'gain': k},
              _lift_off_detail, _LOAD),
    Candidate('time_delay', 1, 'force and acceleration streams are offset in time',
              'fast force changes', grids.delay_grid,
              lambda s, k, fs: {'delay_s': s['delay_samples'] / fs},
              lambda p: f'force lags the motion by {p["delay_s"] * 1e3:.2f} ms', _LOAD,
              fixed_coefficient=True, lti=True),
    Candidate('bump_stop', 2, 'progressive stiffening in compression, like a jounce bumper',
              'large compression', grids.stop_grid(1.0), _stop, _gap_detail('compression'),
              _DISP, hardening=True),
    Candidate('rebound_stop', 2, 'progressive stiffening in extension, like a rebound stop',
              'large extension', grids.stop_grid(-1.0), _stop, _gap_detail('extension'),
              _DISP, hardening=True),
    Candidate('backlash', 2, 'a clearance (dead zone) in the load path',
              'small motion around reversals', grids.backlash_grid,
              lambda s, k, fs: {'gap_m': s['gap_m'], 'stiffness_n_per_m': k,
                                'hysteretic': s['hysteretic']}, _backlash_detail, _DISP),
    Candidate('bump_stop:load', 2, 'progressive stiffening in compression, like a jounce '
              'bumper (driven by the predicted load, i.e. suspension force)', 'high load',
              grids.load_stop_grid(1.0), _load_stop, _gap_detail('compression'), _DISP,
              positive=True, hardening=True),
    Candidate('rebound_stop:load', 2, 'progressive stiffening in extension, like a rebound '
              'stop (driven by the predicted load)', 'low load', grids.load_stop_grid(-1.0),
              _load_stop, _gap_detail('extension'), _DISP, positive=True, hardening=True),
    Candidate('cubic_stiffness:load', 1, 'symmetric hardening of the suspension (force grows '
              'with the cube of the predicted load change)', 'high load',
              grids.load_cubic_grid, lambda s, k, fs: {'center_n': s['center_n'], 'gain': k},
              _cubic_detail, _DISP, positive=True, hardening=True,
              inside='hardening in the load path (the cube of the predicted load change)'),
    Candidate('backlash:load', 2, 'a clearance (dead zone) in the load path (force lost '
              'while the predicted load crosses its unloaded point, e.g. a bushing)',
              'small load around reversals', grids.load_backlash_grid,
              lambda s, k, fs: {'center_n': s['center_n'], 'threshold_n': s['threshold_n'],
                                'gain': k}, _backlash_detail, _DISP, positive=True),
    # Linear omission in the load state: judged against the hardening candidates on pooled
    # vertical channels by :mod:`diagnosis.omissions` (not a per-channel candidate: on a
    # single channel it would also absorb a mass error or an FRF estimation scatter).
    Candidate('stiffness_error:load', 1, 'a spring rate is wrong (force in phase with the '
              'spring part of the predicted suspension force)', 'body motion',
              grids.load_linear_grid, lambda s, k, fs: {'center_n': s['center_n'], 'gain': k},
              _none, _DISP, lti=True, per_channel=False),
    # Searched only inside a structure (:mod:`finders.structure`), with its own grid.
    Candidate('coulomb_friction:load', 1, 'Coulomb friction in the load path',
              'load reversals', lambda contexts: [],
              lambda s, k, fs: {'friction_n': k, 'rate_scale_n_per_s': s['rate_scale_n_per_s']},
              lambda p: f'{abs(p["friction_n"]):.4g} N friction level', _VEL,
              per_channel=False, inside='friction in the load path (the rate of the predicted '
              'load, i.e. of the deflection)'),
)

#: The registry, in the order the selection tries the candidates (its ties follow it).
CANDIDATES: Mapping[str, Candidate] = types.MappingProxyType({c.key: c for c in _ENTRIES})
#: Candidates by key (alias of :data:`CANDIDATES`).
BY_KEY = CANDIDATES
#: The per-channel candidates, in the selection's order.
HYPOTHESES: Tuple[Candidate, ...] = tuple(c for c in _ENTRIES if c.per_channel)
#: The pooled-only linear omission in the load state.
LOAD_LINEAR = CANDIDATES['stiffness_error:load']
#: Motion-state candidates by physics: the physics' description, detail and plot.
BY_NAME = types.MappingProxyType({c.physics: c for c in HYPOTHESES if c.state == 'motion'})
#: The kinds of hardening of the vocabulary, in registry order.
HARDENINGS = tuple(dict.fromkeys(c.physics for c in _ENTRIES if c.hardening))
#: Hardening candidates a wrong spring rate can pass for (compared on pooled Fz channels).
STIFFENING = tuple(c.key for c in HYPOTHESES if c.hardening)
#: Linear parameter errors: refitted with every nonlinear term when the reference is a linear
#: law fitted on the real data itself (they stand for what that fit got wrong).
LINEAR_COMPANIONS = ('stiffness_error', 'damping_error', 'mass_error')
#: Feature each linear rate multiplies, with the rate's name and unit (for tolerances).
LINEAR_RATES = {'stiffness_error': ('disp', 'stiffness', 'N/m'),
                'damping_error': ('vel', 'damping', 'N s/m'),
                'mass_error': ('acc', 'mass', 'kg')}


def term_parameters(candidate: Candidate, shape: Shape, coefficient: float,
                    fs_hz: float) -> Dict[str, float]:
    """Parameters of the PhysicsTerm (time delay converts samples to seconds)."""
    return candidate.params(shape, coefficient, fs_hz)


def describe_shape(physics: str, params: Mapping[str, float]) -> str:
    """Short plain-language detail of the fitted shape (e.g. 'beyond 31 mm compression')."""
    candidate: Optional[Candidate] = BY_NAME.get(physics)
    text = None if candidate is None else candidate.detail(params)
    return text or ', '.join(f'{k} = {v:.4g}' for k, v in params.items())
