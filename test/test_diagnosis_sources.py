# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Several inputs: the physics may hang on an input other than the linearly dominant one."""
import numpy as np
import pytest
from support import diagnosis_synthetic as sy

from wheel_force_estimator.core import physics_laws as law
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis.features import paired_by_coherence
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.recording import MotionRecording


FS_HZ = 256.0


def _two_actuators(effect, seed):
    # Two independent displacement actuators; reaction force f0 dominated by x0 (30 kN/m
    # against 8 kN/m), f1 by x1.  The effect acts on x1's stroke and shows in f0 only.
    rng = np.random.default_rng(seed)
    m = sy.random_motion(rng, int(60 * FS_HZ), FS_HZ)
    x, v = m.x, m.v
    f = np.stack([3e4 * x[0] + 1500 * v[0] + 8e3 * x[1] + 400 * v[1] + 20 * m.a[0],
                  1e4 * x[0] + 2e4 * x[1] + 800 * v[1]])
    if effect == 'bump_stop':
        f[0] += law.bump_stop_force(x[1], float(np.quantile(x[1], 0.97)), 3e5, 2.0)
    elif effect == 'coulomb_friction':
        f[0] += law.coulomb_friction_force(v[1], 60.0, 0.01)
    f += 0.05 * f.std(axis=1, keepdims=True) * rng.standard_normal(f.shape)
    return MotionRecording(f'{effect}{seed}', FS_HZ, x, f, ('x0', 'x1'), ('f0', 'f1'),
                           input_quantity='displacement')


def test_pairing_by_coherence_is_recognised():
    assert paired_by_coherence(('f0', 'f1'), ('x0', 'x1'))
    assert not paired_by_coherence(('f0',), ('x0',))
    assert not paired_by_coherence(('lf_fz', 'rf_fz'), ('lf_az', 'rf_az'))
    recs = [_two_actuators('none', 1)]
    assert pairing(('f0', 'f1'), ('x0', 'x1'), recs)[0] == ('x0', 'x1')


@pytest.mark.slow
@pytest.mark.parametrize('effect', ['bump_stop', 'coulomb_friction'])
def test_physics_on_the_weaker_input_is_named_with_that_input(effect):
    real = [_two_actuators(effect, 1), _two_actuators(effect, 2)]
    holdout = [_two_actuators(effect, 3), _two_actuators(effect, 4)]
    result = diagnose(real, None, holdout, DiagnosisConfig(choose_resolution=True))
    finding = result.findings[0]
    assert (finding.physics, finding.channels) == (effect, ('f0',))
    # The coherence pairing says x0 drives f0; the selection found the term on x1.
    assert {t.sources for t in result.terms} == {('x1',)}
    # Measured: bump stop 38.1 -> 9.8 %, friction 7.4 -> 6.9 % (f0, report half); before the
    # other inputs were tried nothing was named (bump stop: the x0-driven stand-in failed the
    # gate) and the plain fit was written.
    margin = 20.0 if effect == 'bump_stop' else 0.3
    assert result.fit.after['f0'] < result.fit.real_linear['f0'] - margin
    assert result.fit.after['f1'] == result.fit.real_linear['f1']


def test_a_linear_two_actuator_rig_names_nothing():
    real = [_two_actuators('none', 1), _two_actuators('none', 2)]
    holdout = [_two_actuators('none', 3), _two_actuators('none', 4)]
    result = diagnose(real, None, holdout, DiagnosisConfig(choose_resolution=True))
    assert result.findings == ()
    assert result.fit.model == 'real_linear'


@pytest.mark.slow
def test_the_input_search_shows_progress_on_a_terminal(monkeypatch):
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    real = [_two_actuators('none', 1), _two_actuators('none', 2)]
    holdout = [_two_actuators('none', 3), _two_actuators('none', 4)]
    quiet = Terminal()
    monkeypatch.setattr(sys, 'stderr', quiet)
    diagnose(real, None, holdout)
    assert quiet.getvalue() == ''  # the library default prints nothing
    shown = Terminal()
    monkeypatch.setattr(sys, 'stderr', shown)
    diagnose(real, None, holdout, DiagnosisConfig(progress=True))
    assert 'physics on each input' in shown.getvalue()
