# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The differentiator low-pass of displacement / velocity rigs: two corners, the gate chooses."""
import numpy as np
import pytest
from support import diagnosis_synthetic as sy

from wheel_force_estimator.core import physics_laws as law
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis.corner import sharper_lowpass_hz
from wheel_force_estimator.diagnosis.features import FeatureConfig
from wheel_force_estimator.diagnosis.recording import MotionRecording


FS_HZ = 256.0


def _rig(effect, seed, quantity='displacement', seconds=60.0):
    # One displacement-driven corner of the synthetic law (spring, damper, mass, 1-25 Hz
    # motion) plus a force that flips with the velocity, 5 % force noise.
    rng = np.random.default_rng(seed)
    m = sy.random_motion(rng, int(seconds * FS_HZ), FS_HZ)
    force = sy.linear_force(m)[:1]
    v = m.v[:1]
    if effect == 'coulomb_friction':
        force = force + law.coulomb_friction_force(v, 60.0, 0.01)
    elif effect == 'damper_asymmetry':
        force = force + law.damper_asymmetry_force(v, 500.0)
    force = force + 0.05 * np.std(force) * rng.standard_normal(force.shape)
    motion = {'displacement': m.x, 'velocity': m.v}[quantity][:1]
    return MotionRecording(f'rig{seed}', FS_HZ, motion, force, ('x',), ('f',),
                           input_quantity=quantity)


def _sine_pair(f_hz, fs_hz=256.0, seconds=60.0, noise=0.0, quantity='displacement'):
    rng = np.random.default_rng(0)
    t = np.arange(int(seconds * fs_hz)) / fs_hz
    x = 0.01 * np.sin(2 * np.pi * f_hz * t)
    force = 2e4 * x + 1.0 * rng.standard_normal(t.size)
    x = x + noise * rng.standard_normal(t.size)
    return [MotionRecording('sine', fs_hz, x[None], force[None], ('x',), ('f',),
                            input_quantity=quantity)]


def test_sharper_corner_leaves_five_degrees_at_the_top_of_the_coherent_band():
    # A 4 Hz displacement sine: the Hann-windowed Welch estimate (1024 samples, 0.25 Hz
    # lines) puts 1/6 of its power on each neighbour line, so 99 % of the velocity power lies
    # below 4.25 Hz, and a 2nd-order Butterworth lags 5 deg at f / fc = 0.0616 -> 69.0 Hz
    # (above fs/8 = 32 Hz).
    corner = sharper_lowpass_hz(_sine_pair(4.0), FeatureConfig())
    assert corner == pytest.approx(4.25 / 0.061629, rel=1e-3)
    # Input noise that no output follows does not push the corner up (coherence weighting):
    # white noise at 1 % of the sine's RMS carries ~100x the sine's velocity power above 10 Hz.
    noisy = sharper_lowpass_hz(_sine_pair(4.0, noise=0.01 * 0.01 / np.sqrt(2)),
                               FeatureConfig())
    assert noisy == pytest.approx(corner, rel=0.05)
    # Clamped at 0.4 fs; None when not above fs / 8, for acceleration inputs (nothing is
    # differentiated) and when the corner was set explicitly.
    assert sharper_lowpass_hz(_sine_pair(10.0), FeatureConfig()) == pytest.approx(0.4 * 256)
    assert sharper_lowpass_hz(_sine_pair(1.0), FeatureConfig()) is None
    assert sharper_lowpass_hz(_sine_pair(4.0, quantity='acceleration'), FeatureConfig()) is None
    assert sharper_lowpass_hz(_sine_pair(4.0), FeatureConfig(lowpass_hz=50.0)) is None


@pytest.mark.parametrize('effect', ['coulomb_friction', 'damper_asymmetry'])
def test_velocity_forces_of_a_displacement_rig_are_named_with_the_sharper_corner(effect):
    real = [_rig(effect, 1), _rig(effect, 2)]
    holdout = [_rig(effect, 3), _rig(effect, 4)]
    result = diagnose(real, None, holdout)
    assert result.findings[0].physics == effect
    note, = [n for n in result.fit.notes if n.startswith('Differentiator low-pass')]
    assert note.startswith('Differentiator low-pass: 102 Hz kept over 32 Hz')
    assert note in result.summary
    assert all(t.lowpass_hz == pytest.approx(0.4 * FS_HZ) for t in result.findings[0].terms)
    assert [t['lowpass_hz'] for t in result.model.physics] == pytest.approx(
        [0.4 * FS_HZ] * len(result.model.physics))
    # Measured: coulomb 6.35 -> 6.02 %, damper asymmetry 7.67 -> 6.18 % (report half).
    assert result.fit.after['f'] < result.fit.real_linear['f'] - 0.2
    # With fs / 8 alone (explicit corner: one run) the velocity lags 30 deg at 25 Hz and the
    # effect is missed (friction) or called a bump stop (asymmetry): why both corners run.
    alone = diagnose(real, None, holdout, DiagnosisConfig(features=FeatureConfig(
        lowpass_hz=FS_HZ / 8)))
    assert effect not in [f.physics for f in alone.findings]
    assert not [n for n in alone.fit.notes if n.startswith('Differentiator')]
    assert alone.fit.after['f'] > result.fit.after['f']


@pytest.mark.parametrize('quantity', ['displacement', 'velocity'])
def test_a_linear_rig_names_nothing_with_either_corner(quantity):
    real = [_rig('none', 1, quantity), _rig('none', 2, quantity)]
    holdout = [_rig('none', 3, quantity), _rig('none', 4, quantity)]
    result = diagnose(real, None, holdout)
    assert result.findings == ()
    assert result.fit.model == 'real_linear'
    assert result.fit.after == result.fit.real_linear
    note, = [n for n in result.fit.notes if n.startswith('Differentiator low-pass')]
    assert note.startswith('Differentiator low-pass: 32 Hz kept over 102 Hz')


def test_a_model_reference_gets_both_corners_a_simulation_one():
    from wheel_force_estimator.diagnosis.run import real_linear_fit
    real = [_rig('coulomb_friction', 1), _rig('coulomb_friction', 2)]
    holdout = [_rig('coulomb_friction', 3), _rig('coulomb_friction', 4)]
    model = real_linear_fit(real, DiagnosisConfig()).model
    with_model = diagnose(real, model, holdout)
    note, = [n for n in with_model.fit.notes if n.startswith('Differentiator low-pass')]
    assert '102 Hz' in note and '32 Hz' in note
    # A simulation's linear law reads the features: one corner, fs / 8.
    sim = [_rig('none', 5), _rig('none', 6)]
    with_sim = diagnose(real, sim, holdout)
    assert not [n for n in with_sim.fit.notes if n.startswith('Differentiator')]
    assert all(t.lowpass_hz == FS_HZ / 8 for t in with_sim.terms)


def test_a_second_corner_that_cannot_run_leaves_the_first_with_a_note(monkeypatch):
    from wheel_force_estimator.core.errors import DiagnosisError
    from wheel_force_estimator.diagnosis import pipeline
    once = pipeline.diagnose_once
    corners = []

    def refuse_sharp(real, sim, holdout, config):
        corners.append(config.features.lowpass_hz)
        if config.features.lowpass_hz > 0.0:
            raise DiagnosisError('rig3: too short (test)')
        return once(real, sim, holdout, config)

    monkeypatch.setattr(pipeline, 'diagnose_once', refuse_sharp)
    real = [_rig('none', 1), _rig('none', 2)]
    holdout = [_rig('none', 3), _rig('none', 4)]
    result = diagnose(real, None, holdout)
    assert corners == [0.0, pytest.approx(0.4 * FS_HZ)]
    assert result.fit.model == 'real_linear'
    assert result.fit.notes[-1] == ('Differentiator low-pass 102 Hz not tried: rig3: too short '
                                    '(test)')
    assert result.summary[-1] == result.fit.notes[-1]


def test_without_a_holdout_the_cross_validation_blocks_choose_the_corner():
    real = [_rig('coulomb_friction', 1), _rig('coulomb_friction', 2),
            _rig('coulomb_friction', 3)]
    result = diagnose(real, None, (), DiagnosisConfig(choose_resolution=True))
    assert result.findings[0].physics == 'coulomb_friction'
    note, = [n for n in result.fit.notes if n.startswith('Differentiator low-pass')]
    assert note.startswith('Differentiator low-pass: 102 Hz kept over 32 Hz')
    assert 'chosen on the cross-validation blocks (no holdout)' in note
    assert result.fit.data == 'cross_validation'
    # Nothing to choose without terms: the default corner stays.
    linear = diagnose([_rig('none', 1), _rig('none', 2), _rig('none', 3)], None, (),
                      DiagnosisConfig(choose_resolution=True))
    note, = [n for n in linear.fit.notes if n.startswith('Differentiator low-pass')]
    assert note.startswith('Differentiator low-pass: 32 Hz kept over 102 Hz')
