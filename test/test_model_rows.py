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
from wheel_force_estimator.diagnosis.choice import choice_groups
from wheel_force_estimator.diagnosis.choice import combine
from wheel_force_estimator.diagnosis.choice import linked_channels
from wheel_force_estimator.diagnosis.choice import plain_names
from wheel_force_estimator.diagnosis.choice import touched_channels
from wheel_force_estimator.diagnosis.crossval import FIGURES
from wheel_force_estimator.diagnosis.crossval import pick_rows

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


def test_rows_of_a_model_with_fewer_inputs_take_zero_taps_on_the_others():
    # The diagnosis combines rows of the simulation's FRF (12 accelerations) with rows of the
    # plain fit that also takes the traction/braking split (issue 30).  Bugs caught: the
    # narrower rows refused (the plain fit then written whole), an added input's operating
    # point leaking into the narrower rows' static force, inputs that are not a prefix
    # accepted (a row would read the wrong channel).
    # with per-channel units, as `fit` writes them for spindle channels
    out_units = ['N', 'N', 'N']
    narrow = replace(small_model(n_in=2, n_taps=16, seed=1), physics=(), units={
        'input': 'm/s^2', 'output': 'N', 'input_channels': ['m/s^2'] * 2,
        'output_channels': out_units})
    wide = replace(small_model(n_in=3, n_taps=64, seed=2), physics=(), units={
        'input': 'm/s^2', 'output': 'N', 'input_channels': ['m/s^2'] * 3,
        'output_channels': out_units})
    assert compatible([narrow, wide]) == (True, '')
    assert compatible([wide, narrow]) == (True, '')
    out = compose_rows([narrow, wide], [0, 1, 0], (), {})
    assert out.input_channels == wide.input_channels and out.units == wide.units
    other_units = replace(narrow, units={**narrow.units, 'input_channels': ['m/s', 'm/s^2']})
    assert compatible([other_units, wide]) == (False, 'different units')
    x = np.random.default_rng(4).normal(size=(3, 900)) + 0.7
    y, yn, yw = predict_forces(out, x), predict_forces(narrow, x[:2]), predict_forces(wide, x)
    inner = slice(narrow.fir_taps.shape[2], -narrow.fir_taps.shape[2])
    np.testing.assert_allclose(y[[0, 2], inner], yn[[0, 2], inner], rtol=0, atol=1e-9)
    np.testing.assert_allclose(y[1], yw[1], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(out.fir_taps[[0, 2], 2], 0.0)
    np.testing.assert_array_equal(out.h[:, [0, 2], 2], 0.0)
    # the third input does not move the narrow rows at all
    x2 = x.copy()
    x2[2] += np.random.default_rng(5).normal(size=900)
    np.testing.assert_allclose(predict_forces(out, x2)[[0, 2]], y[[0, 2]], rtol=0, atol=1e-9)
    other = replace(wide, input_channels=('in1', 'in0', 'in2'))
    ok, why = compatible([narrow, other])
    assert not ok and 'are not the first of' in why
    with pytest.raises(ConfigError, match='are not the first of'):
        compose_rows([narrow, other], [0, 1, 0], (), {})


def _term(channels, partners=()):
    term = {'physics': 'coulomb_friction', 'channels': list(channels),
            'sources': ['in0'] * len(channels), 'parameters': {'friction_n': 5.0,
                                                               'velocity_scale_mps': 0.01}}
    if partners:
        term = {'physics': 'anti_roll_bar', 'state': 'load', 'channels': list(channels),
                'partners': list(partners), 'parameters': {'gain': 0.1, 'cutoff_hz': 4.0}}
    return term


def _both(per_channel, hp=None):
    """Scores in both figures (the high-passed one equal to the unfiltered unless given)."""
    return {'rmse_pct': per_channel, 'rmse_hp1_pct': hp or per_channel}


def _pick(candidates, scores, channels, fixed=()):
    return pick_rows(scores, linked_channels(candidates, channels),
                     touched_channels(candidates), 'real_linear', 'rmse_hp1_pct',
                     plain_names(candidates), fixed)


def test_channels_a_term_spans_or_couples_are_chosen_together():
    a, b = _pair()
    with_terms = a.with_physics([_term(['out0', 'out1'])])
    groups = linked_channels({'a': with_terms, 'b': b}, a.output_channels)
    assert sorted(map(sorted, groups)) == [['out0', 'out1'], ['out2']]
    # the group goes to the lower mean score (here b, although out0 alone prefers a)
    plain = a.with_physics([])
    three = {'a': with_terms, 'b': b, 'real_linear': plain}
    scores = {'a': _both({'out0': 10.0, 'out1': 30.0, 'out2': 5.0}),
              'b': _both({'out0': 12.0, 'out1': 20.0, 'out2': 6.0}),
              'real_linear': _both({'out0': 50.0, 'out1': 50.0, 'out2': 4.0})}
    pick = _pick(three, scores, a.output_channels)
    assert pick == {'out0': 'b', 'out1': 'b', 'out2': 'real_linear'}
    model, name, note = combine(three, pick, a.output_channels)
    assert name == 'per_channel' and note == ''
    assert model.physics == ()     # the term's rows went to another model
    assert model.fit['rows_from'] == pick
    # a row no term touches comes from a model without terms, even when one with terms
    # scores lower there; a term's rows bring the term along
    scores['a'] = _both({'out0': 1.0, 'out1': 1.0, 'out2': 1.0})
    pick = _pick(three, scores, a.output_channels)
    assert pick == {'out0': 'a', 'out1': 'a', 'out2': 'real_linear'}
    model, _, _ = combine(three, pick, a.output_channels)
    assert [p['physics'] for p in model.physics] == ['coulomb_friction']
    # unanimous: nothing to combine, that candidate is written whole
    model, name, _ = combine(three, dict.fromkeys(a.output_channels, 'b'), a.output_channels)
    assert model is b and name == 'b'


def test_the_corners_of_a_wheel_force_component_without_a_term_choose_together():
    # Bug caught: one row's blocks of a 1-minute record choosing alone.  Simulator, damper
    # asymmetry, seed 7: every block of lf_fy preferred the simulation's row, which a new
    # recording found 4 points worse; the four fy rows' mean preferred the plain fit's.
    from types import SimpleNamespace

    from wheel_force_estimator import OUTPUT_CHANNELS

    def model(*terms):
        return SimpleNamespace(physics_terms=tuple(
            SimpleNamespace(channels=tuple(t), partners=()) for t in terms))
    candidates = {'sim_frf+physics': model(['rr_fz']), 'sim_frf': model(),
                  'real_linear': model()}
    groups = choice_groups(candidates, OUTPUT_CHANNELS, fixed=['lf_fx'])
    assert sorted(map(sorted, groups)) == [
        ['lf_fx'], ['lf_fy', 'lr_fy', 'rf_fy', 'rr_fy'], ['lf_fz', 'lr_fz', 'rf_fz'],
        ['lr_fx', 'rf_fx', 'rr_fx'], ['rr_fz']]
    # channels that are no spindle corner's component stand alone
    assert sorted(choice_groups({'m': model()}, ('out0', 'out1', 'lf'))) == [
        ['lf'], ['out0'], ['out1']]
    # a term spanning two components' corners keeps its channels together, the rest group
    spanning = {'a': model(['lf_fy', 'lf_fz']), 'b': model()}
    groups = choice_groups(spanning, OUTPUT_CHANNELS)
    assert ['lf_fy', 'lf_fz'] in groups and ['rf_fy', 'lr_fy', 'rr_fy'] in groups
    # the choice: lf_fy alone prefers the simulation's row in every block, the mean of the
    # four does not in the second block, so all four keep the plain fit's rows
    fy = ['lf_fy', 'rf_fy', 'lr_fy', 'rr_fy']

    def both(per_row):
        return {figure: dict(zip(fy, per_row)) for figure in FIGURES}
    blocks = {'sim_frf': [both([50.0, 60.0, 60.0, 60.0]), both([50.0, 90.0, 90.0, 90.0])],
              'real_linear': [both([55.0, 60.0, 60.0, 60.0]),
                              both([55.0, 50.0, 50.0, 50.0])]}
    pooled = {'sim_frf': both([50.0, 75.0, 75.0, 75.0]),
              'real_linear': both([55.0, 55.0, 55.0, 55.0])}
    plain = {'sim_frf': model(), 'real_linear': model()}
    args = (set(), 'real_linear', 'rmse_hp1_pct', ['sim_frf', 'real_linear'])
    assert pick_rows(pooled, [[c] for c in fy], *args, blocks=blocks)['lf_fy'] == 'sim_frf'
    assert pick_rows(pooled, choice_groups(plain, fy), *args,
                     blocks=blocks) == dict.fromkeys(fy, 'real_linear')


def test_a_candidate_worse_than_the_plain_fit_in_either_figure_is_not_written():
    # Bug caught: a model chosen on the high-passed figure alone while its unfiltered error
    # is worse than the plain fit's (an asymmetric damper term spoiling the quasi-static band).
    a, b = _pair()
    with_terms = a.with_physics([_term(['out0'])])
    candidates = {'real_frf+physics': with_terms, 'real_linear': b}
    scores = {'real_frf+physics': _both({'out0': 20.0, 'out1': 9.0, 'out2': 9.0},
                                        {'out0': 5.0, 'out1': 9.0, 'out2': 9.0}),
              'real_linear': _both({'out0': 10.0, 'out1': 9.0, 'out2': 9.0},
                                   {'out0': 8.0, 'out1': 9.0, 'out2': 9.0})}
    assert _pick(candidates, scores, a.output_channels)['out0'] == 'real_linear'
    # better in both: written
    scores['real_frf+physics']['rmse_pct']['out0'] = 9.5
    assert _pick(candidates, scores, a.output_channels)['out0'] == 'real_frf+physics'


def test_motion_channels_no_term_touches_take_the_plain_fit():
    # Bug caught: a tyre-in-the-air channel keeping the simulation's rows because the deciding
    # half preferred them by less than it can resolve (worse on the report half).
    a, b = _pair()
    sim, plain = a.with_physics([]), b
    scores = {'sim_frf': _both({'out0': 5.0, 'out1': 5.0, 'out2': 5.0}),
              'real_linear': _both({'out0': 5.1, 'out1': 5.1, 'out2': 4.0})}
    candidates = {'sim_frf': sim, 'real_linear': plain}
    # out0 is no motion channel, but sim_frf is worse than the plain fit nowhere else there
    scores['sim_frf']['rmse_pct']['out0'] = 5.1
    pick = _pick(candidates, scores, a.output_channels, fixed=['out1'])
    assert pick == {'out0': 'sim_frf', 'out1': 'real_linear', 'out2': 'real_linear'}
    # a motion channel a term touches still chooses on the scores (the clip term's rows)
    with_terms = sim.with_physics([_term(['out1'])])
    scores['sim_frf+physics'] = _both({'out0': 9.0, 'out1': 3.0, 'out2': 9.0})
    pick = _pick({'sim_frf+physics': with_terms, **candidates},
                 {'sim_frf+physics': scores.pop('sim_frf+physics'), **scores},
                 a.output_channels, fixed=['out1'])
    assert pick['out1'] == 'sim_frf+physics'


def test_terms_that_make_their_own_base_worse_are_not_written():
    # Bug caught: the simulation's FRF + terms written because it beats a plain fit that the
    # training blocks fit on less data, while the terms make the simulation's FRF worse.
    a, b = _pair()
    sim = a.with_physics([])
    with_terms = sim.with_physics([_term(['out0'])])
    candidates = {'sim_frf+physics': with_terms, 'sim_frf': sim, 'real_linear': b}
    scores = {'sim_frf+physics': _both({'out0': 9.0, 'out1': 9.0, 'out2': 9.0}),
              'sim_frf': _both({'out0': 8.0, 'out1': 9.0, 'out2': 9.0}),
              'real_linear': _both({'out0': 20.0, 'out1': 20.0, 'out2': 20.0})}
    pick = pick_rows(scores, linked_channels(candidates, a.output_channels),
                     touched_channels(candidates), 'real_linear', 'rmse_hp1_pct',
                     plain_names(candidates), bases={'sim_frf+physics': 'sim_frf'})
    assert pick['out0'] == 'sim_frf'
