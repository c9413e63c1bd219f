# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The finders' shared rules: the candidate registry, the acceptance rule, the combining rule."""
import numpy as np
import pytest

from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.core.physics_terms import TERM_KINDS
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.candidates import term_parameters
from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.finders.acceptance import rejection
from wheel_force_estimator.diagnosis.finders.reconcile import reconcile
from wheel_force_estimator.diagnosis.finders.reconcile import supersedes
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.diagnosis.selection import SelectionConfig

FS_HZ = 256.0
FZ = ('lf_fz', 'rf_fz', 'lr_fz', 'rr_fz')


def _finding(physics, *channels):
    return Finding(physics, channels, {}, 0.1, f'{physics} on {channels}')


def test_every_candidate_is_bound_to_its_term_kind():
    # Bug caught: an entry whose key names no kind, or a kind bound to another physics.
    for key, cand in BY_KEY.items():
        assert TERM_KINDS[key] is cand.kind
        assert key == (cand.physics if cand.state == 'motion' else f'{cand.physics}:load')
    # The report plots a state for every physics the per-channel selection can name.
    assert {k for k, _ in (c.plot for c in BY_NAME.values())} <= {
        'displacement', 'velocity', 'acceleration', 'level', 'load'}


@pytest.mark.parametrize('key, shape', [
    ('bump_stop:load', {'threshold_n': 3.4e3, 'exponent': 2.0, 'state_lowpass_hz': 5.0}),
    ('cubic_stiffness:load', {'center_n': 3e3, 'state_lowpass_hz': 2.5}),
    ('backlash:load', {'center_n': 3e3, 'threshold_n': 150.0, 'state_lowpass_hz': 10.0}),
    ('stiffness_error:load', {'center_n': 3e3, 'state_lowpass_hz': 1.0}),
    ('tire_lift_off', {'threshold_n': 3.0e3}),
    ('time_delay', {'delay_samples': 3.0}),
])
def test_candidate_basis_is_the_written_terms_force_at_unit_strength(key, shape):
    # Bug caught: the force the diagnosis fits differs from the force the written term adds
    # (the registry derives the basis from the kind's own law; the stage is the product).
    rng = np.random.default_rng(3)
    n = 2048
    load = 3e3 + np.cumsum(rng.normal(0.0, 40.0, n))
    zeros = np.zeros(n)
    ctx = ChannelContext(zeros, zeros, zeros, zeros, load, None, FS_HZ)
    cand = BY_KEY[key]
    params = term_parameters(cand, shape, 1.0, FS_HZ)
    term = PhysicsTerm(cand.physics, ('lf_fz',), params, sources=('lf_az',),
                       state=cand.state, state_lowpass_hz=shape.get('state_lowpass_hz', 0.0))
    added = apply_physics([term], FS_HZ, ('lf_az',), ('lf_fz',), zeros[np.newaxis],
                          load[np.newaxis])[0] - load
    basis = cand.basis(ctx, shape)
    assert np.any(basis)
    np.testing.assert_allclose(basis, added, rtol=0.0, atol=1e-9 * np.max(np.abs(added)))


def test_acceptance_rule_judges_the_figures_it_is_given():
    rules = SelectionConfig()                       # min_gain 5 %, null x2, 0.2 points
    assert 'explains 4.0% < 5%' in rejection(rules, 0.04)
    assert rejection(rules, 0.3) is None            # the null is not known yet: not judged
    assert 'time-shifted' in rejection(rules, 0.3, null=0.15)
    assert rejection(rules, 0.3, null=0.149) is None
    assert 'only 0.10 points' in rejection(rules, 0.3, 0.1, drop_pct=0.1)
    # A pooled fit against a rival: the rival's gain times a factor is the floor.
    assert rejection(rules, 0.04, min_gain=0.03) is None
    assert rejection(rules, 0.3, min_gain=0.39) is not None


def test_a_later_finding_supersedes_the_same_physics_on_a_shared_channel_only():
    per_corner = _finding('anti_roll_bar', 'lf_fz')
    rear = _finding('anti_roll_bar', 'lr_fz')
    axle = _finding('anti_roll_bar', 'lf_fz', 'rf_fz')
    assert supersedes(axle, per_corner) and not supersedes(axle, rear)
    assert not supersedes(_finding('damping_error', 'lf_fz'), per_corner)


def test_a_spring_rate_supersedes_the_hardenings_within_its_channels():
    # Bug caught: a hardening named on one corner survives next to the spring-rate error that
    # it linearised, and the model carries both.
    inside = _finding('rebound_stop', 'lf_fz')
    across = _finding('cubic_stiffness', 'lf_fz', 'lf_fy')
    spring = _finding('stiffness_error', *FZ)
    friction = _finding('coulomb_friction', 'lf_fz')
    assert supersedes(spring, inside)
    assert not supersedes(spring, across)           # reaches beyond the vertical channels
    assert not supersedes(spring, friction)
    # A kind of hardening pooled over the axis supersedes the per-corner kinds, not the
    # spring-rate error.
    pooled = _finding('bump_stop', *FZ)
    assert supersedes(pooled, inside) and not supersedes(pooled, spring)


def test_reconcile_keeps_the_earlier_findings_in_order_then_the_new_ones():
    a, b, c = (_finding('damper_asymmetry', 'lf_fz'), _finding('rebound_stop', 'rf_fz'),
               _finding('time_delay', 'lr_fz'))
    spring = _finding('stiffness_error', *FZ)
    mass = _finding('mass_error', *FZ)
    assert reconcile([a, b, c], [spring, mass]) == [a, c, spring, mass]
    assert reconcile([], [a]) == [a]
    assert reconcile([a, b], []) == [a, b]
