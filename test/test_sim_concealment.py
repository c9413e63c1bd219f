# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Concealment of an effect in a nominal / effect pair: hand-checkable parts and invariants."""
import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.sim import simulate
from wheel_force_estimator.sim.concealment import active_fraction
from wheel_force_estimator.sim.concealment import CONCEALED_PARAMS
from wheel_force_estimator.sim.concealment import concealed_params
from wheel_force_estimator.sim.concealment import Concealment
from wheel_force_estimator.sim.concealment import measure_concealment
from wheel_force_estimator.sim.effects import EFFECT_DEFAULTS
from wheel_force_estimator.sim.effects import EFFECT_NAMES

COURSE = [('belgian_block', 20.0), ('pothole', 10.0), ('speed_bump', 10.0)]
SEED = 3


@pytest.fixture(scope='module')
def nominal():
    return simulate(COURSE, seed=SEED)


@pytest.fixture(scope='module')
def model(nominal):
    return fit_model([TrainingSegment(nominal.accel_mps2, nominal.force_n, 'nominal')],
                     nominal.fs_hz, FitConfig(), INPUT_CHANNELS, OUTPUT_CHANNELS)


def test_every_simulated_effect_has_a_concealed_size():
    assert set(CONCEALED_PARAMS) == set(EFFECT_NAMES)


def test_concealed_params_scale_strength_only():
    bump = concealed_params('bump_stop', 0.5)['bump_stop']
    assert bump['gap_m'] == CONCEALED_PARAMS['bump_stop']['gap_m']
    assert bump['stiffness_n_per_m'] == 0.5 * EFFECT_DEFAULTS['bump_stop']['stiffness_n_per_m']
    # The excess over a symmetric damper scales: 1 + 0.5 * (1.145 - 1).
    asym = concealed_params('damper_asymmetry', 0.5)['damper_asymmetry']
    assert asym == {'rebound_to_compression_ratio': pytest.approx(1.0725, abs=1e-12)}
    damping = concealed_params('damping_error', 0.8)['damping_error']
    assert damping == {'fraction': pytest.approx(0.8 * -0.032, abs=1e-12)}
    saturation = concealed_params('sensor_saturation', 0.5)['sensor_saturation']
    assert saturation == dict(EFFECT_DEFAULTS['sensor_saturation'])
    with pytest.raises(ConfigError, match='unknown effect'):
        concealed_params('flux_capacitor')
    with pytest.raises(ConfigError, match='factor must be > 0'):
        concealed_params('backlash', 0.0)


def test_nominal_against_itself_adds_nothing(nominal, model):
    hidden = measure_concealment('cubic_stiffness', nominal, nominal, model)
    assert hidden.active_fraction is None
    assert max(hidden.excess_ratio.values()) == 0.0
    assert max(hidden.excess_ratio_raw.values()) == 0.0
    assert hidden.below_noise and hidden.concealed and not hidden.rare


def test_active_fraction_of_a_bump_stop_is_the_engaged_share(nominal, model):
    real = simulate(COURSE, ('bump_stop',), SEED, effect_params=concealed_params('bump_stop'))
    gap = real.effect_params['bump_stop']['gap_m']
    comp = real.states['suspension_compression_m']
    expected = np.mean(np.any(comp > gap, axis=0))
    assert 0.0 < expected < 1.0
    assert active_fraction('bump_stop', real) == expected
    hidden = measure_concealment('bump_stop', nominal, real, model)
    assert hidden.active_fraction == expected
    # A stop adds vertical force: the largest added error is on an Fz channel.
    assert hidden.worst_channel.endswith('_fz')
    assert hidden.excess_ratio[hidden.worst_channel] > 0.0


def test_a_visible_effect_is_not_concealed(nominal, model):
    # Four samples of WFT delay (the simulator's default is two) leave a large error.
    real = simulate(COURSE, ('time_delay',), SEED,
                    effect_params={'time_delay': {'delay_s': 4 / 512}})
    hidden = measure_concealment('time_delay', nominal, real, model)
    assert hidden.active_fraction is None
    assert not hidden.concealed
    assert 'NOT concealed' in hidden.describe()


def test_rules_of_the_verdict():
    ratios = dict.fromkeys(OUTPUT_CHANNELS, 0.5)
    assert Concealment('x', None, ratios, ratios).concealed
    loud = dict(ratios, lf_fz=3.0)
    assert not Concealment('x', None, loud, loud).concealed
    assert Concealment('x', 0.01, loud, loud).concealed
    assert not Concealment('x', 0.2, loud, loud).concealed
    # An effect that never acts is not "rare": it is absent.
    assert not Concealment('x', 0.0, loud, loud).rare


def test_errors_name_the_fault(nominal, model):
    short = simulate(COURSE[:1], seed=SEED)
    with pytest.raises(ConfigError, match='differ in shape or rate'):
        measure_concealment('backlash', nominal, short, model)
    with pytest.raises(ConfigError, match='not simulated with bump_stop'):
        active_fraction('bump_stop', nominal)
