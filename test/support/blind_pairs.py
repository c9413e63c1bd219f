# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The blind simulator pairs of the diagnosis tests: seeds, effects, records and diagnoses.

Shared by ``test_diagnosis_sim.py`` (the concealed effects named) and
``test_diagnosis_sim_silent.py`` (nothing named where nothing is there or nameable); their
docstrings say what is blind and why.  The two files run on two pytest-xdist workers side by
side; each worker computes the diagnoses its file needs once (``functools.lru_cache``), and
the two files need different ones.
"""
import functools

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import MotionRecording

#: Seeds the concealed sizes, the selection's thresholds and the figures quoted in the
#: diagnosis modules were measured on (holdouts ``seed + 100``, reseeded nulls ``seed + 50``).
CALIBRATION_SEEDS = (0, 1, 2, 4)
#: Seeds the blind tests run: never used to calibrate anything.
SEEDS = (5, 6)
#: Smallest fraction of the (effect, seed) cases of :data:`EFFECTS` whose first finding names
#: the effect on its channels.  The calibration seeds reach 20/24 (0.83: ``mass_error`` missed
#: on 2 of 3, one ``rebound_stop`` and one ``cubic_stiffness`` missed); 3 of 4 is the bar.
MIN_HIT_RATE = 0.75
#: Smallest fraction of the named nonlinear cases whose written model beats the plain fit
#: (issue 14's target; 11/12 on the calibration seeds).
MIN_BETTER_RATE = 0.9
SCALE = 0.2
#: Holdout length (duration scale 0.5 = 5 minutes): before/after are reported on its second
#: half (the gate and the choice of the written model see the first), and a stop engaging on
#: 3 % of the samples needs minutes of unseen road to show whether its model generalises.
HOLDOUT_SCALE = 0.5
SMALL_DRIFT = {'mass_error': {'fraction': 0.01}, 'stiffness_error': {'fraction': 0.02},
               'damping_error': {'fraction': -0.03}}
FZ = tuple(c for c in OUTPUT_CHANNELS if c.endswith('fz'))
#: Effect -> channels the first finding must lie in.
EFFECTS = {
    'rebound_stop': FZ,
    'cubic_stiffness': FZ,
    'damper_asymmetry': FZ,
    'coulomb_friction': FZ,
    'anti_roll_bar': FZ,
    'time_delay': OUTPUT_CHANNELS,
    'sensor_saturation': OUTPUT_CHANNELS,
    'mass_error': OUTPUT_CHANNELS,
}
NONLINEAR = ('rebound_stop', 'cubic_stiffness', 'damper_asymmetry', 'coulomb_friction',
             'sensor_saturation')
#: Concealed but not nameable from these recordings (see ``test_diagnosis_sim_silent.py``).
NOT_NAMEABLE = ('tire_lift_off', 'bump_stop', 'stiffness_error', 'damping_error', 'backlash')
#: At the simulator's resolution rather than concealed (see ``test_diagnosis_sim.py``): the
#: largest ratio to the noise floor allowed for them.
AT_RESOLUTION = {'time_delay': 1.2}


@functools.lru_cache(maxsize=None)
def simulated(effect, seed, scale=SCALE):
    from wheel_force_estimator.sim.api import simulate
    from wheel_force_estimator.sim.concealment import concealed_params
    if effect == 'small_drift':
        return simulate('proving_ground', tuple(SMALL_DRIFT), seed, scale,
                        effect_params=SMALL_DRIFT)
    if effect.startswith('none'):
        return simulate('proving_ground', (), seed, scale)
    return simulate('proving_ground', (effect,), seed, scale,
                    effect_params=concealed_params(effect))


def road_events(result):
    """Road-event starts as the bag reader gives them (seconds on the record's clock)."""
    return tuple(((t - int(result.stamp_ns[0])) * 1e-9, e) for t, e in result.events)


def recording(effect, seed, name, scale=SCALE):
    # With the road events a bag carries: a single holdout bag is halved per event.
    result = simulated(effect, seed, scale)
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS, events=road_events(result))


@functools.lru_cache(maxsize=None)
def diagnosis_of(effect, seed):
    real_seed = seed + 50 if effect == 'none_reseeded' else seed
    sim = [recording('none', seed, 'sim')]
    real = [recording(effect, real_seed, 'real')]
    holdout = [recording(effect, seed + 100, 'holdout', HOLDOUT_SCALE)]
    return diagnose(real, sim, holdout)


def concealment(effect, seed):
    from wheel_force_estimator.sim.concealment import measure_concealment
    from wheel_force_estimator.diagnosis.reference import FrfReference
    model = FrfReference.fit([recording('none', seed, 'sim')], 'sim').model
    return measure_concealment(effect, simulated('none', seed), simulated(effect, seed),
                               model)


def check_concealed(effect, seed):
    hidden = concealment(effect, seed)
    if effect in AT_RESOLUTION:
        assert max(hidden.excess_ratio.values()) < AT_RESOLUTION[effect], hidden.describe()
    else:
        assert hidden.concealed, hidden.describe()


def named_first(effect, seed) -> bool:
    """Return True when the first finding names ``effect`` on channels it acts on."""
    findings = diagnosis_of(effect, seed).findings
    return bool(findings) and findings[0].physics == effect and set(
        findings[0].channels) <= set(EFFECTS[effect])


def mean_over(values, channels):
    return float(np.mean([values[c] for c in channels]))


def travel_recording(effect, seed, name, scale=SCALE):
    # What a DAQ export with string potentiometers gives the generic path: suspension travel
    # (compression from static equilibrium, + jounce) in, vertical wheel forces out.
    result = simulated(effect, seed, scale)
    fz = [OUTPUT_CHANNELS.index(c) for c in FZ]
    travel = tuple(c[:2] + '_travel' for c in FZ)
    return MotionRecording(name, result.fs_hz, result.states['suspension_compression_m'],
                           result.force_n[fz], travel, FZ, input_quantity='displacement')


@functools.lru_cache(maxsize=None)
def travel_diagnosis(effect, seed=SEEDS[0]):
    return diagnose([travel_recording(effect, seed, 'real')],
                    [travel_recording('none', seed, 'sim')],
                    [travel_recording(effect, seed + 100, 'holdout', HOLDOUT_SCALE)])
