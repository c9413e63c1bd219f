# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Blocked cross-validation of the written model on the training recordings (no holdout)."""
from dataclasses import replace

import numpy as np
import pytest

from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.resolution import fold_bounds
from wheel_force_estimator.diagnosis.crossval import cut
from wheel_force_estimator.diagnosis.crossval import FIGURES
from wheel_force_estimator.diagnosis.crossval import held_out_figures
from wheel_force_estimator.diagnosis.crossval import training_folds
from wheel_force_estimator.diagnosis.recording import MotionRecording

from test_core_model import small_model  # noqa: I100  (the tests' own helper)


def _records(model, lengths, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for k, n in enumerate(lengths):
        x = rng.normal(size=(len(model.input_channels), n))
        out.append(MotionRecording(f'r{k}', model.fs_hz, x, predict_forces(model, x),
                                   model.input_channels, model.output_channels))
    return out


def test_folds_hold_out_fit_s_contiguous_blocks_once_each():
    # Bugs caught: interleaved samples held out (a FIR would see each one's neighbours), a
    # sample held out twice or never, train and held-out masks overlapping, blocks that are
    # not the ones `fit`'s resolution cross-validation uses.
    model = replace(small_model(), physics=())
    records = _records(model, (103, 40))
    folds = training_folds(records)
    assert len(folds) == 4
    held_count = [np.zeros(r.n_samples, int) for r in records]
    for k, (train, held) in enumerate(folds):
        for rec, t, h, count in zip(records, train, held, held_count):
            assert not np.any(t & h) and np.all(t | h)
            a, b = fold_bounds(rec.n_samples, 4, k)
            assert np.array_equal(np.flatnonzero(h), np.arange(a, b))
            count += h
    assert all(np.all(c == 1) for c in held_count)
    # the training pieces are the runs before and after the block, each a record of its own
    pieces = cut(records, folds[1][0])
    a, b = fold_bounds(103, 4, 1)
    assert [p.n_samples for p in pieces] == [a, 103 - b, 10, 20]
    assert np.array_equal(pieces[1].inputs, records[0].inputs[:, b:])
    assert pieces[1].start_s == pytest.approx(b / model.fs_hz)


def test_held_out_figures_score_each_fold_s_own_model_on_its_block():
    # Known answer: the forces are the model's prediction, so the model itself scores 0 % on
    # every held-out block in both figures, and a model fitted on the wrong fold does not.
    # Bug caught: a fold's block scored with another fold's model, or all samples scored.
    model = replace(small_model(), physics=())
    other = replace(small_model(seed=5), physics=())
    records = _records(model, (4000, 3000))
    folds = training_folds(records)
    calls = []

    def build(train, fold):
        calls.append((fold, sum(r.n_samples for r in train)))
        return {'true': model, 'wrong': other if fold == 2 else model}
    scores = held_out_figures(build, records, folds)
    assert [c[0] for c in calls] == [0, 1, 2, 3]
    assert all(n == 7000 - sum(np.sum(h) for h in folds[k][1]) for k, n in calls)
    for fig in FIGURES:
        assert max(scores['true'][fig].values()) < 1e-9
        assert min(scores['wrong'][fig].values()) > 1.0


def test_the_holdout_gate_strips_harmful_terms_and_keeps_the_names():
    # Bug caught: the holdout dropping a finding from the names (the anti-roll bar case was
    # named bump_stop with --holdout), so what is named depended on whether one was given.
    from types import SimpleNamespace

    from wheel_force_estimator.core.physics import PhysicsTerm
    from wheel_force_estimator.diagnosis.holdout import holdout_gate
    from wheel_force_estimator.diagnosis.result import Finding
    fs, n = 256.0, 4096
    rng = np.random.default_rng(1)
    accel = np.cumsum(rng.normal(size=(1, n)), axis=1)
    accel -= accel.mean()
    force = 100.0 * accel + rng.normal(size=(1, n))
    rec = MotionRecording('hold', fs, accel, force, ('x',), ('f',))
    hold = SimpleNamespace(recordings=[rec], targets=[force], full_predictions=[force.copy()],
                           spans=[(0, n)])

    def finding(physics, force_n):
        term = PhysicsTerm('coulomb_friction', ('f',), {'friction_n': force_n,
                                                        'velocity_scale_mps': 0.01},
                           sources=('x',))
        return Finding(physics, ('f',), {}, 0.5, 'test', (term,))
    harmful, harmless = finding('coulomb_friction', 500.0), finding('coulomb_friction', 0.0)
    kept, gated = holdout_gate([harmful, harmless], hold, ('f',), 0.0, None)
    assert [f.physics for f in kept] == ['coulomb_friction', 'coulomb_friction']
    assert kept[0].terms == () and kept[1].terms == harmless.terms
    assert len(gated) == 1 and 'named, its term not written' in gated[0]


def test_a_candidate_worse_than_the_plain_fit_in_one_block_keeps_the_plain_fit():
    # Bug caught: pooled squares alone let the one block of an unseen road event decide (the
    # plain fit extrapolating badly there) and wrote rows that lose on every other block.
    from wheel_force_estimator.diagnosis.crossval import pick_rows

    def both(value):
        return {figure: {'out0': value} for figure in FIGURES}
    pooled = {'sim_frf': both(60.0), 'real_linear': both(130.0)}
    blocks = {'sim_frf': [both(20.0), both(20.0), both(21.0), both(100.0)],
              'real_linear': [both(12.0), both(11.0), both(15.0), both(250.0)]}
    args = (pooled, [['out0']], set(), 'real_linear', 'rmse_hp1_pct',
            ['sim_frf', 'real_linear'])
    assert pick_rows(*args) == {'out0': 'sim_frf'}
    assert pick_rows(*args, blocks=blocks) == {'out0': 'real_linear'}
    # better in every block as well: the candidate is written
    better = {'sim_frf': [both(10.0)] * 4, 'real_linear': blocks['real_linear']}
    assert pick_rows(*args, blocks=better) == {'out0': 'sim_frf'}


def test_the_joint_strengths_are_a_candidate_written_under_the_public_name():
    # The joint least-squares strengths compete as a candidate of their own (before: a
    # post-gate swap with its own margin, on the gate half only and never without a
    # holdout).  They must be no worse than the alternation's strengths in either figure,
    # and are reported as `real_frf+physics` with a note.
    from wheel_force_estimator.diagnosis.choice import _bases
    from wheel_force_estimator.diagnosis.choice import JOINT
    from wheel_force_estimator.diagnosis.choice import written_rows
    from wheel_force_estimator.diagnosis.crossval import pick_rows

    def figs(unfiltered, hp):
        return {'rmse_pct': {'a': unfiltered, 'b': 20.0},
                'rmse_hp1_pct': {'a': hp, 'b': 20.0}}
    names = ['real_frf+physics', JOINT, 'real_linear']
    bases = _bases(dict.fromkeys(names))
    assert bases == {'real_frf+physics': 'real_linear', JOINT: 'real_frf+physics'}
    args = ([['a'], ['b']], {'a'}, 'real_linear', 'rmse_hp1_pct', ['real_linear'])
    scores = {'real_frf+physics': figs(10.0, 8.0), JOINT: figs(9.5, 7.0),
              'real_linear': figs(12.0, 10.0)}
    pick = pick_rows(scores, *args, bases=bases)
    assert pick == {'a': JOINT, 'b': 'real_linear'}
    notes = []
    rows = written_rows(pick, 'per_channel', notes)
    assert rows == {'a': 'real_frf+physics', 'b': 'real_linear'}
    assert len(notes) == 1 and 'joint least-squares step' in notes[0] and 'for a.' in notes[0]
    # better high-passed but worse unfiltered than the alternation: not eligible
    scores[JOINT] = figs(10.5, 6.0)
    assert pick_rows(scores, *args, bases=bases)['a'] == 'real_frf+physics'
    notes = []
    assert written_rows({'a': 'real_frf+physics'}, 'real_frf+physics', notes) == {}
    assert notes == []
