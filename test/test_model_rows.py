# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Rows of several models combined: each output predicted exactly as by its own model."""
from dataclasses import replace

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.model_rows import compatible
from wheel_force_estimator.core.model_rows import compose_rows
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.diagnosis.written import compose
from wheel_force_estimator.diagnosis.written import linked_channels

from test_core_model import small_model  # noqa: I100  (the tests' own helper)


def _pair():
    # different tap counts, lag zeros, frequency lines and operating points
    a = replace(small_model(n_taps=16, seed=1), physics=())
    b = replace(small_model(n_taps=64, seed=2), physics=())
    return a, b


def test_each_row_predicts_as_the_model_it_came_from():
    # Bugs caught: a shorter FIR embedded off its lag zero, the static force of a row not
    # corrected for the other model's operating point, rows swapped.
    a, b = _pair()
    x = np.random.default_rng(3).normal(size=(2, 900)) + 0.7
    out = compose_rows([a, b], [0, 1, 0], (), {})
    y, ya, yb = (predict_forces(m, x) for m in (out, a, b))
    # Exact away from the record's ends: there each model pads the record with its own
    # operating point (its mean input), for as long as its lag zero / tail reach.
    inner = slice(a.fir_taps.shape[2], -a.fir_taps.shape[2])
    np.testing.assert_allclose(y[[0, 2], inner], ya[[0, 2], inner], rtol=0, atol=1e-9)
    np.testing.assert_allclose(y[1], yb[1], rtol=0, atol=1e-9)
    assert np.abs(y[0] - ya[0]).max() > 1e-3  # the ends do differ (the test sees the rows)
    assert out.fir_taps.shape == b.fir_taps.shape and out.live == ()
    # the frequency description of a shorter row is its own, on the longer grid
    np.testing.assert_allclose(out.h[:, 0], np.array([np.interp(b.f_hz, a.f_hz, a.h[:, 0, i].real)
                                                      for i in range(2)]).T
                               + 1j * np.array([np.interp(b.f_hz, a.f_hz, a.h[:, 0, i].imag)
                                                for i in range(2)]).T)
    np.testing.assert_array_equal(out.h[:, 1], b.h[:, 1])


def test_identity_composition_is_the_model():
    a, _ = _pair()
    out = compose_rows([a], [0, 0, 0], (), {'k': 1})
    for name in ('h', 'fir_taps', 'static_force_n', 'static_accel_mps2'):
        np.testing.assert_array_equal(getattr(out, name), getattr(a, name))
    assert out.fit == {'k': 1}


def test_incompatible_models_and_bad_sources_are_refused():
    a, b = _pair()
    other = small_model(n_taps=64, fs_hz=128.0, seed=2)
    assert not compatible([a, other])[0]
    with pytest.raises(ConfigError, match='sample rates'):
        compose_rows([a, other], [0, 1, 0], (), {})
    with pytest.raises(ConfigError, match='row sources'):
        compose_rows([a, b], [0, 2, 0], (), {})


def _term(channels, partners=()):
    term = {'physics': 'coulomb_friction', 'channels': list(channels),
            'sources': ['in0'] * len(channels), 'parameters': {'friction_n': 5.0,
                                                               'velocity_scale_mps': 0.01}}
    if partners:
        term = {'physics': 'anti_roll_bar', 'state': 'load', 'channels': list(channels),
                'partners': list(partners), 'parameters': {'gain': 0.1, 'cutoff_hz': 4.0}}
    return term


def test_channels_a_term_spans_or_couples_are_chosen_together():
    a, b = _pair()
    with_terms = a.with_physics([_term(['out0', 'out1'])])
    groups = linked_channels({'a': with_terms, 'b': b}, a.output_channels)
    assert sorted(map(sorted, groups)) == [['out0', 'out1'], ['out2']]
    # the group goes to the lower mean gate score (here b, although out0 alone prefers a)
    gate = {'a': {'out0': 10.0, 'out1': 30.0, 'out2': 5.0},
            'b': {'out0': 12.0, 'out1': 20.0, 'out2': 6.0}}
    plain = a.with_physics([])
    three = {'a': with_terms, 'b': b, 'c': plain}
    gate['c'] = {'out0': 50.0, 'out1': 50.0, 'out2': 4.0}
    model, pick, note = compose(three, gate, a.output_channels)
    assert pick == {'out0': 'b', 'out1': 'b', 'out2': 'c'} and note == ''
    assert model.physics == ()     # the term's rows went to another model
    assert model.fit['rows_from'] == pick
    # a row no term touches comes from a model without terms, even when one with terms
    # scores lower there; a term's rows bring the term along
    gate['a'] = {'out0': 1.0, 'out1': 1.0, 'out2': 1.0}
    model, pick, _ = compose(three, gate, a.output_channels)
    assert pick == {'out0': 'a', 'out1': 'a', 'out2': 'c'}
    assert [p['physics'] for p in model.physics] == ['coulomb_friction']
    # unanimous: nothing to combine, the caller writes that candidate whole
    gate['a'] = {'out0': 90.0, 'out1': 90.0, 'out2': 1.0}
    model, pick, _ = compose({'a': with_terms, 'b': b}, gate, a.output_channels)
    assert model is None and set(pick.values()) == {'b'}


def test_motion_channels_no_term_touches_take_the_plain_fit():
    # Bug caught: a tyre-in-the-air channel keeping the simulation's rows because the deciding
    # half preferred them by less than it can resolve (worse on the report half).
    a, b = _pair()
    sim, plain = a.with_physics([]), b
    gate = {'sim_frf': {'out0': 5.0, 'out1': 5.0, 'out2': 5.0},
            'real_linear': {'out0': 5.1, 'out1': 5.1, 'out2': 4.0}}
    candidates = {'sim_frf': sim, 'real_linear': plain}
    _, pick, _ = compose(candidates, gate, a.output_channels, motion_channels=['out1'])
    assert pick == {'out0': 'sim_frf', 'out1': 'real_linear', 'out2': 'real_linear'}
    # a motion channel a term touches still chooses on the gate half (the clip term's rows)
    with_terms = sim.with_physics([_term(['out1'])])
    gate['sim_frf+physics'] = {'out0': 9.0, 'out1': 3.0, 'out2': 9.0}
    _, pick, _ = compose({'sim_frf+physics': with_terms, **candidates}, gate,
                         a.output_channels, motion_channels=['out1'])
    assert pick['out1'] == 'sim_frf+physics'
