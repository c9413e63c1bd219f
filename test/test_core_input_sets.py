# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The input set of every output row, chosen by the search's blocked cross-validation."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.spindle import declared_inputs
from wheel_force_estimator.core.spindle import input_sets

FS_HZ = 128.0
INPUTS = INPUT_CHANNELS + RATE_CHANNELS
N_ACC = len(INPUT_CHANNELS)
#: Small live basis (the search's cost, not its rule, depends on it).
CONFIG = FitConfig(segment_length=512, long_segment_length=0,
                   live=LiveDesign(look_aheads_s=(0.05,), history_s=0.25, fine_s=0.03,
                                   blocks_per_octave=4))


def _system(n, seed):
    """
    24 inputs (12 accelerations, 12 rates) -> 2 outputs through known low-pass filters.

    Output 0 depends on accelerations 0 and 1 only; output 1 on acceleration 0 and rates
    0 and 1 (half of its power from the rates).  Output noise 5 % of each output's RMS.
    """
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 30.0, fs=FS_HZ)
    x = signal.lfilter(b, a, rng.normal(size=(len(INPUTS), n)), axis=1)
    b1, a1 = signal.butter(2, 12.0, fs=FS_HZ)
    b2, a2 = signal.cheby1(2, 1.0, 20.0, fs=FS_HZ)
    y0 = signal.lfilter(b1, a1, x[0]) + 0.5 * x[1]
    y1 = (signal.lfilter(b2, a2, x[0]) + signal.lfilter(b1, a1, x[N_ACC])
          - 0.7 * np.roll(x[N_ACC + 1], 3))
    y = np.vstack([y0, y1])
    return x, y + 0.05 * y.std(axis=1, keepdims=True) * rng.normal(size=y.shape)


@pytest.fixture(scope='module')
def fitted():
    # 220 s of training: short against 24 inputs, so 12 irrelevant rates cost row 0 variance
    x, y = _system(28000, 1)
    return fit_design([TrainingSegment(x, y, 'train')], FS_HZ, CONFIG, INPUTS, ('f', 'g'))


def test_input_sets_are_the_nested_groups_the_inputs_carry():
    assert [n for n, _ in input_sets(declared_inputs(True, True))] == [
        'accel', 'accel+rates', 'accel+rates+spin']
    assert input_sets(declared_inputs(False, True)) == (
        ('accel', tuple(range(N_ACC))),
        ('accel+spin', tuple(range(N_ACC + len(SPIN_ACCEL_CHANNELS)))))
    assert input_sets(INPUT_CHANNELS) == (('accel', tuple(range(N_ACC))),)
    # a generic DAQ fit (declared channels, no groups): one set, as before
    assert input_sets(('a', 'b', 'c')) == (('all', (0, 1, 2)),)
    assert input_sets(RATE_CHANNELS + INPUT_CHANNELS) == (('all', tuple(range(24))),)


def test_each_row_chooses_its_inputs_and_excluded_inputs_have_zero_taps(fitted):
    # Bugs caught: a set chosen against its held-out score; one set for all rows; a row on
    # the accelerations whose FIR or live taps still read the rates.
    model, design = fitted.model, fitted.model.fit['design']
    assert [s['name'] for s in design['input_sets']] == ['accel', 'accel+rates']
    assert design['input_sets'][0]['channels'] == list(INPUT_CHANNELS)
    rows = design['rows']
    assert rows['g']['inputs'] == 'accel+rates'       # half of g's power is in the rates
    assert rows['g']['live_inputs'] == 'accel+rates'
    assert rows['f']['inputs'] == 'accel'              # the rates are noise to f
    assert rows['f']['live_inputs'] == 'accel'
    for name, row in rows.items():
        per = row['input_sets']
        assert set(per) == {'accel', 'accel+rates'}
        crit = {k: (v['cv_rmse_pct'] / 100) ** 2 + (v['cv_rmse_hp1_pct'] / 100) ** 2
                for k, v in per.items()}
        # the chosen set is the one whose best candidate scored best held out, for the live
        # estimator too (one set per row, chosen by the offline candidates' folds)
        assert crit[row['inputs']] == pytest.approx(min(crit.values()), rel=1e-6)
        assert crit[row['live_inputs']] == pytest.approx(min(crit.values()), rel=1e-6)
    # g without the rates would be far worse (the known answer: they carry half its power)
    assert rows['g']['input_sets']['accel']['cv_rmse_pct'] > 50.0
    assert rows['g']['input_sets']['accel+rates']['cv_rmse_pct'] < 20.0
    # exactly zero taps for the inputs row f does not use; row g uses them
    assert np.all(model.fir_taps[0, N_ACC:] == 0.0)
    assert np.any(model.fir_taps[0, :N_ACC] != 0.0)
    assert np.any(model.fir_taps[1, N_ACC:] != 0.0)
    assert model.live
    for est in model.live:
        assert est.n_in == len(INPUTS)
        assert np.all(est.fine_taps[0, N_ACC:] == 0.0)
        assert np.all(est.coarse_taps[0, N_ACC:] == 0.0)
        assert np.any(est.fine_taps[1, N_ACC:] != 0.0)
    # every (set, candidate) is recorded
    n_sets = len(design['input_sets'])
    assert len(design['candidates']) % n_sets == 0
    assert {c['inputs'] for c in design['candidates']} == {'accel', 'accel+rates'}


def test_the_live_estimator_takes_its_rows_input_set_from_the_offline_folds():
    # Bug caught (issue 29): each estimator choosing its set on its own folds, so a set the
    # live estimator cannot use within its look-ahead near-ties there and is dropped by
    # noise (measured: the compact car's live y 13.1 % with rf_fy on the accelerations
    # alone, 12.8 % with the set the offline folds chose).  Output h reads a rate 0.2 s
    # ahead: the offline LS FIR (0.25 s look-ahead) needs the rates, the 50 ms live one
    # cannot see them, and the row's set is the offline folds' (every estimator of the row
    # on the same inputs).
    x, y = _system(28000, 4)
    h = signal.lfilter(*signal.butter(2, 12.0, fs=FS_HZ), x[0]) + np.roll(x[N_ACC], -26)
    fitted = fit_design([TrainingSegment(x, np.vstack([y[0], h]), 'train')], FS_HZ, CONFIG,
                        INPUTS, ('f', 'h'))
    rows = fitted.model.fit['design']['rows']
    assert rows['h']['inputs'] == 'accel+rates'
    assert rows['h']['live_inputs'] == 'accel+rates'
    assert rows['f']['live_inputs'] == rows['f']['inputs'] == 'accel'


def test_refit_keeps_each_rows_input_set(fitted):
    # Bug caught: the diagnosis's refit on pieces fitting every row on every input.
    x, y = _system(8192, 2)
    again = fitted.refit([TrainingSegment(x, y, 'other')])
    assert again.fit['design']['rows'] == fitted.model.fit['design']['rows']
    assert np.all(again.fir_taps[0, N_ACC:] == 0.0)
    assert np.any(again.fir_taps[1, N_ACC:] != 0.0)
    assert not np.allclose(again.fir_taps, fitted.model.fir_taps)


def test_imposed_inputs_keep_one_set():
    # Bug caught: `wheel_force_fit.inputs` in the params file searched over anyway.
    x, y = _system(28000, 1)
    design = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, CONFIG, INPUTS, ('f', 'g'),
                        imposed={'inputs'}).model.fit['design']
    assert design['imposed'] == ['inputs']
    assert [s['name'] for s in design['input_sets']] == ['accel+rates']
    assert {r['inputs'] for r in design['rows'].values()} == {'accel+rates'}
    assert {r['live_inputs'] for r in design['rows'].values()} == {'accel+rates'}


def test_fit_prints_and_the_report_shows_each_rows_input_set(fitted, capsys):
    # Bug caught: the choice recorded in the model but shown nowhere (print, report table).
    from wheel_force_estimator.cli.fit import _print_design
    from wheel_force_estimator.report.design_plots import design_tables
    _print_design(fitted.model)
    out = capsys.readouterr().out
    assert 'held-out RMSE % per input set' in out
    assert 'input-set folds' not in out          # 218 s: the scoring folds chose the sets
    line = next(s for s in out.splitlines() if s.strip().startswith('f ') and 'inputs' in s)
    assert 'inputs accel,' in line and 'live_inputs accel' in line
    choice, table = design_tables(fitted.model.fit['design'], ('f', 'g'))
    assert '| live inputs | accel % | accel+rates % |' in choice.splitlines()[0]
    row_f = next(s for s in choice.splitlines() if s.startswith('| f |'))
    assert row_f.startswith('| f | accel ')
    assert '| accel ls ' in table and '| accel+rates ls ' in table


def test_a_subsets_normal_equations_are_a_sub_block_of_the_full_ones():
    # Bug caught: a sub-block taken at the wrong unknowns (the lag-ordered factor's order, or
    # outputs for inputs), which would fit a subset's rows to other inputs' correlations.
    from wheel_force_estimator.core.candidates import subset_correlations
    from wheel_force_estimator.core.correlations import CorrelationAccumulator
    from wheel_force_estimator.core.normal_equations import NormalEquations
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(4, 3000)), rng.normal(size=(2, 3000))
    acc = CorrelationAccumulator(4, 2, 40)
    acc.add(x, y)
    corr = acc.result(FS_HZ)
    design = LiveDesign(look_aheads_s=(0.1,), history_s=0.2, fine_s=0.03, blocks_per_octave=2)
    cols = (0, 2)
    got = NormalEquations(corr, 12, design).subset(cols)
    want = NormalEquations(subset_correlations(corr, cols), 12, design)
    assert got.n_in == 2 and got.a.shape == want.a.shape
    np.testing.assert_array_equal(got.a, want.a)
    np.testing.assert_array_equal(got.rhs, want.rhs)
    np.testing.assert_array_equal(got.ridge_unit, want.ridge_unit)


def test_the_moment_lines_name_each_moments_chosen_set():
    # Bug caught: fit saying every moment was fitted from all the groups offered when its
    # row chose fewer (and the "every moment identifiable" line lost to the new line).
    from types import SimpleNamespace

    from wheel_force_estimator import MOMENT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.report.builders import moment_input_lines
    rows = {m: {'inputs': 'accel' if m.endswith('_mz') else 'accel+rates'}
            for m in MOMENT_CHANNELS}
    model = SimpleNamespace(
        output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS, input_channels=INPUTS,
        fit={'design': {'input_sets': [{'name': 'accel'}, {'name': 'accel+rates'}],
                        'rows': rows}})
    lines = moment_input_lines(model, {'mean_coherence': dict.fromkeys(MOMENT_CHANNELS, 0.9)})
    assert lines[0] == 'moments fitted from: 12 accelerations, 12 angular rates'
    rates = [m for m in MOMENT_CHANNELS if not m.endswith('_mz')]
    accel = [m for m in MOMENT_CHANNELS if m.endswith('_mz')]
    assert lines[1] == ('  input set chosen per moment (held-out blocks): accel+rates: '
                        + ', '.join(rates) + '; accel: ' + ', '.join(accel))
    assert lines[2].startswith('  every moment has a mean multiple coherence')


# --- the traction/braking split (issue 29) ---------------------------------------------------

def test_the_split_is_declared_last_nests_first_and_is_a_spindle_layout():
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.spindle import spindle_layout
    from support.ros_testing import synthetic_model
    assert declared_inputs(False, False, True) == INPUT_CHANNELS + SPLIT_CHANNELS
    assert input_sets(declared_inputs(False, False, True)) == (
        ('accel', tuple(range(N_ACC))), ('accel+split', tuple(range(N_ACC + 2))))
    # the groups nest in declared order, and the derived ones (functions of the
    # accelerations) are offered on the accelerations alone too: a row can take the
    # splits without the 12 rates and the 4 spin accelerations
    from wheel_force_estimator.core.spindle import parents
    assert [n for n, _ in input_sets(declared_inputs(True, True, True))] == [
        'accel', 'accel+split', 'accel+rates', 'accel+rates+spin', 'accel+rates+spin+split']
    six = declared_inputs(True, True, True, True)
    sets = input_sets(six)
    assert [n for n, _ in sets] == [
        'accel', 'accel+split', 'accel+split+cornering', 'accel+rates', 'accel+rates+spin',
        'accel+rates+spin+split', 'accel+rates+spin+split+cornering']
    assert parents(sets) == (None, 0, 1, 0, 3, 4, 5)
    for i, p in enumerate(parents(sets)):
        if p is not None:                       # nested: the parent's columns lead
            inner, (name, outer) = sets[p][1], sets[i]
            assert outer[:len(inner)] == inner and len(outer) > len(inner)
            assert [six[c] for c in outer[len(inner):]] == list(
                {'split': SPLIT_CHANNELS, 'cornering': CORNERING_CHANNELS,
                 'spin': SPIN_ACCEL_CHANNELS, 'rates': RATE_CHANNELS}[name.rpartition('+')[2]])
    assert sets[-1][1] == tuple(range(len(six)))              # the last: every input
    # without a measured group the derived chain is the declared one: no set twice
    assert [n for n, _ in input_sets(declared_inputs(False, False, True, True))] == [
        'accel', 'accel+split', 'accel+split+cornering']
    assert declared_inputs(False, False, True, True)[-4:] == SPLIT_CHANNELS + CORNERING_CHANNELS
    assert [n for n, _ in input_sets(declared_inputs(False, False, False, True))] == [
        'accel', 'accel+cornering']
    # the split anywhere but last is no spindle model (refused, not guessed at)
    assert input_sets(INPUT_CHANNELS + SPLIT_CHANNELS + RATE_CHANNELS)[0][0] == 'all'
    assert input_sets(INPUT_CHANNELS + CORNERING_CHANNELS + SPLIT_CHANNELS)[0][0] == 'all'
    for inputs, derived in ((INPUT_CHANNELS + SPLIT_CHANNELS, SPLIT_CHANNELS),
                            (declared_inputs(False, False, True, True),
                             SPLIT_CHANNELS + CORNERING_CHANNELS)):
        layout = spindle_layout(synthetic_model(n_taps=8, delay_samples=2, seed=1,
                                                input_channels=inputs), 'm.npz')
        assert layout.derived == derived and not layout.rates and not layout.spin
        assert layout.extras == ()


def _kinked_system(n, seed):
    """
    12 accelerations with driver-made braking, traction and turns -> 3 outputs.

    Output 0 is linear in the accelerations; output 1, like a driven wheel's Fx, takes the
    low-passed mean ``ax`` with slope 1 kN per m/s² when positive (traction), 3 kN when
    negative (braking): a kink no linear model holds; output 2 has the same kind of kink in
    the low-passed mean ``ay`` (1 kN left turns, 2.5 kN right turns).  5 % output noise.
    Inputs: the 12 accelerations, then the traction/braking and cornering splits.
    """
    from wheel_force_estimator import CORNERING_CHANNELS
    from wheel_force_estimator import SPLIT_CHANNELS
    from wheel_force_estimator.core.derived import specific_force_parts
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 30.0, fs=FS_HZ)
    x = signal.lfilter(b, a, rng.normal(size=(N_ACC, n)), axis=1)
    bs, as_ = signal.butter(2, 0.2, fs=FS_HZ)
    x[0::3] += 20.0 * signal.lfilter(bs, as_, rng.normal(size=n))[None]
    x[1::3] += 20.0 * signal.lfilter(bs, as_, rng.normal(size=n))[None]
    parts = specific_force_parts(x, FS_HZ, SPLIT_CHANNELS + CORNERING_CHANNELS)
    trac, brake, left, right = parts
    b1, a1 = signal.butter(2, 12.0, fs=FS_HZ)
    y0 = signal.lfilter(b1, a1, x[2]) + 0.5 * x[5]     # az rows: no slow driver content
    y1 = 1000.0 * trac + 3000.0 * brake + 200.0 * signal.lfilter(b1, a1, x[3])
    # like an outer wheel's Fy: a steeper slope in right turns than in left turns
    y2 = 1000.0 * left + 2500.0 * right + 200.0 * signal.lfilter(b1, a1, x[5])
    y = np.vstack([y0, y1, y2])
    y = y + 0.05 * y.std(axis=1, keepdims=True) * rng.normal(size=y.shape)
    return np.concatenate([x, parts]), y


def test_a_kinked_row_chooses_the_split_and_a_linear_row_does_not():
    # Known answer: the split holds row 1's kink exactly and the cornering split row 2's, so
    # the cross-validation must choose them there (and predict the held-out record far better
    # than the accelerations alone); row 0 depends on neither and keeps the accelerations.
    # Bugs caught: a split not offered, offered but never chosen, its columns mixed with
    # others, the cornering parts taken from ax.
    from wheel_force_estimator.core.metrics import rmse_pct
    from wheel_force_estimator.core.predict import predict_forces
    inputs = declared_inputs(False, False, True, True)
    x, y = _kinked_system(28000, 3)
    xv, yv = _kinked_system(14000, 4)
    fitted = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, CONFIG, inputs,
                        ('f', 'g', 'h'))
    rows = fitted.model.fit['design']['rows']
    assert rows['f']['inputs'] == 'accel' and rows['g']['inputs'] == 'accel+split'
    assert rows['h']['inputs'] == 'accel+split+cornering'
    with_split = rmse_pct(yv, predict_forces(fitted.model, xv))
    # the model derives its split itself from the 12 accelerations: the same prediction
    np.testing.assert_allclose(predict_forces(fitted.model, xv[:N_ACC]),
                               predict_forces(fitted.model, xv), rtol=0, atol=1e-6)
    plain = fit_design([TrainingSegment(x[:N_ACC], y, 'train')], FS_HZ, CONFIG,
                       INPUT_CHANNELS, ('f', 'g', 'h'))
    without = rmse_pct(yv, predict_forces(plain.model, xv[:N_ACC]))
    for row in (1, 2):
        assert with_split[row] < 0.5 * without[row], (with_split, without)
        assert with_split[row] < 10.0, with_split


@pytest.mark.parametrize('per_set_basis', [False, True])
def test_the_splits_are_reachable_without_the_rates_and_change_nothing_when_rates_are_idle(
        per_set_basis, monkeypatch):
    # Known answer: the kinked system above with 12 angular rates declared that carry nothing
    # (noise).  The splits are offered on the accelerations alone too, so the cornering row
    # takes accel+split+cornering without the rates (declared before the splits, the rates
    # came first in the only chain until 2026-12-07, and that row had to take all 12 to
    # reach the split).  Every row chosen without the rates must give the model of the same
    # record fitted without them, to round-off (bugs caught: a set's taps put back in the
    # wrong columns, a factor bordered from a set that is not its leading block, the
    # rates' columns not exactly zero).
    # per_set_basis: the live basis left to the default, with a cost bound that gives the
    # 16 inputs without the rates 4 blocks per octave and the 28 with them 2.  Each set
    # takes the basis of its own inputs, so the rows still equal the model without the
    # rates (until 2026-12-07 every set took the 28 inputs' coarser basis).
    from wheel_force_estimator.core import live_estimator
    from wheel_force_estimator.core.predict import predict_forces
    config = CONFIG
    if per_set_basis:
        monkeypatch.setattr(live_estimator, 'BLOCKS_PER_OCTAVE_CHOICES', (4, 2))
        monkeypatch.setattr(live_estimator, 'MAX_PAST_UNKNOWNS', 300)
        config = dataclasses.replace(CONFIG, live=dataclasses.replace(
            CONFIG.live, blocks_per_octave=None))
        assert [config.live.for_inputs(n, FS_HZ).blocks_per_octave for n in (16, 28)] == [4, 2]
    inputs = declared_inputs(True, False, True, True)
    x, y = _kinked_system(28000, 3)
    xv, _ = _kinked_system(14000, 4)
    rng = np.random.default_rng(5)
    rates, rates_v = rng.normal(size=(12, x.shape[1])), rng.normal(size=(12, xv.shape[1]))
    with_rates = np.concatenate([x[:N_ACC], rates, x[N_ACC:]])
    fitted = fit_design([TrainingSegment(with_rates, y, 'train')], FS_HZ, config, inputs,
                        ('f', 'g', 'h'))
    design = fitted.model.fit['design']
    assert [s['name'] for s in design['input_sets']][-1] == 'accel+rates+split+cornering'
    rows = design['rows']
    assert [rows[r]['inputs'] for r in 'fgh'] == ['accel', 'accel+split',
                                                  'accel+split+cornering']
    assert [rows[r]['live_inputs'] for r in 'fgh'] == [rows[r]['inputs'] for r in 'fgh']
    rate_cols = [inputs.index(c) for c in RATE_CHANNELS]
    model = fitted.model
    assert not model.fir_taps[:, rate_cols].any() and not model.h[:, :, rate_cols].any()
    assert not any(e.fine_taps[:, rate_cols].any() or e.coarse_taps[:, rate_cols].any()
                   for e in model.live)
    assert model.fir_taps[2, inputs.index('left_turn_ay')].any()
    if per_set_basis:
        assert {e.info['blocks_per_octave'] for e in model.live} == {4}
    plain = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, config,
                       declared_inputs(False, False, True, True), ('f', 'g', 'h'))
    got = predict_forces(fitted.model, np.concatenate([xv[:N_ACC], rates_v, xv[N_ACC:]]))
    want = predict_forces(plain.model, xv)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())
    for d in [e.look_ahead_samples for e in plain.model.live]:
        got_live = predict_forces(fitted.model, np.concatenate(
            [xv[:N_ACC], rates_v, xv[N_ACC:]]), d)
        want_live = predict_forces(plain.model, xv, d)
        np.testing.assert_allclose(got_live, want_live, rtol=0,
                                   atol=1e-9 * np.abs(want_live).max())


def test_the_long_window_guard_counts_the_smallest_searched_set():
    # The one-resolution fallback guards the set every row can keep (the accelerations);
    # a bigger set fitted from too few windows loses its rows' cross-validation instead.
    # Counted over all inputs, offering the split's two inputs switched every row to one
    # resolution (bench_split.py, 2-minute records).
    from wheel_force_estimator.core.design import _guarded_inputs
    assert _guarded_inputs(declared_inputs(True, True, True), True) == N_ACC
    assert _guarded_inputs(declared_inputs(True, True, True), False) == 30
    assert _guarded_inputs(('a', 'b', 'c'), True) == 3


@pytest.mark.parametrize('inputs, expected', [
    (None, ('traction_ax', 'braking_ax', 'left_turn_ay', 'right_turn_ay')),   # auto
    ('[]', ()), ('["split"]', ('traction_ax', 'braking_ax')),
    ('["cornering", "rates"]', ('left_turn_ay', 'right_turn_ay'))])
def test_the_params_file_chooses_the_derived_inputs(tmp_path, inputs, expected):
    # One rule for `fit` (declared_inputs) and `diagnose` (its real-data fits): the groups
    # `split` and `cornering` of `wheel_force_fit.inputs`, both when it is "auto".
    from wheel_force_estimator.cli.common import fit_channels
    path = tmp_path / 'p.yaml'
    path.write_text('wheel_force_fit:\n  ros__parameters:\n'
                    + (f'    inputs: {inputs}\n' if inputs else '    moments: auto\n'))
    channels = fit_channels(path)
    assert channels.derived == expected
    assert declared_inputs(False, False, channels.split, channels.cornering) == (
        INPUT_CHANNELS + expected)


def test_the_offline_row_stays_in_its_live_estimators_input_set():
    # Bug caught (issue 29): every (set, candidate) pair competing, a pair of a smaller set
    # that the folds score a hair below the live estimator took the row off the set the
    # row's estimators share (the compact car trained on 2 minutes: offline y 16.3 % against
    # live 13.3 % held out; 12.8 % kept in the set).  Known answer from hand-made scores.
    import types
    from wheel_force_estimator.core.candidates import Candidate
    from wheel_force_estimator.core.crossval import HeldOutPower
    from wheel_force_estimator.core.search import _offline_rows
    live_ls = Candidate(512, 1e-2, 1e-3, float('inf'), 0.05)      # the live estimator
    two_sided = Candidate(512, 1e-2, 1e-3, float('inf'))
    h1 = Candidate(512, 1e-2, 1e-3, 0.0)
    sp = types.SimpleNamespace(offline=[live_ls, two_sided, h1])

    def power(unfiltered, high_passed):
        return HeldOutPower(np.array([[unfiltered], [high_passed]]), np.ones((2, 1)))

    scores = [[power(0.30, 0.30), power(0.20, 0.20), power(0.10, 0.10)],   # set 0: accel
              [power(0.25, 0.25), power(0.22, 0.24), power(0.40, 0.40)]]   # set 1: +split
    # set 1's live estimator: set 0's H1 beats it on the folds, set 1's two-sided LS too

    def chosen(live):
        sets, cands = _offline_rows(scores, sp, 0.05, live)
        return int(sets[0]), int(cands[0])
    assert chosen([(1, 1e-3)]) == (1, 1)
    # in set 0 the best candidate wins; without a live estimator every pair competes
    assert chosen([(0, 1e-3)]) == (0, 2)
    assert chosen(None) == (0, 2)
    # never worse than live in either figure: a better sum bought with one figure loses
    scores[1][1] = power(0.26, 0.10)
    assert chosen([(1, 1e-3)]) == (1, 0)


def test_short_records_choose_input_sets_on_blocks_that_sample_the_whole_record():
    # Bug caught (issue 29): on records under ~6.4 min the finest scoring grid left a few
    # long chunks, most blocks one contiguous stretch, so a fold held out a road event its
    # training side never saw; the sets are now chosen on 4 x 4 shorter chunks.
    from wheel_force_estimator.cli.common import load_fit_config
    from wheel_force_estimator.core.search import scoring_blocks
    from wheel_force_estimator.core.search import set_blocks
    config = load_fit_config()                      # the shipped grid: 1024 / 8192 samples
    two_minutes = [120 * 512]
    n_score, blocks = scoring_blocks(two_minutes, config)
    n_set, chunks = set_blocks(two_minutes, config)
    assert (n_score, [len(b) for b in blocks]) == (8192, [2, 1, 1, 1])
    assert (n_set, [len(b) for b in chunks]) == (2048, [4, 4, 4, 4])
    pieces = sorted((p.start, p.stop) for b in chunks for p in b)
    assert pieces[0][0] == 0 and pieces[-1][1] == two_minutes[0]     # nothing dropped
    assert all(a[1] == b[0] for a, b in zip(pieces, pieces[1:]))      # contiguous chunks
    # ten minutes already give 16 chunks at the finest grid: the same folds
    assert set_blocks([600 * 512], config) == scoring_blocks([600 * 512], config)
    # too short for 16 chunks at any grid: the scoring folds
    assert set_blocks([20 * 512], config) == scoring_blocks([20 * 512], config)


def test_the_search_records_the_folds_that_chose_the_input_sets(capsys, tmp_path):
    # 220 s at 128 Hz with a 2048-sample long segment: the scoring grid keeps 9 chunks of
    # 24 s, the input sets are chosen on 16 chunks of ~13.7 s at 1024 samples (one
    # resolution there: the long segment's windows do not fit the chunks).  The known
    # system's sets are still found: f on the accelerations, g with the rates.
    x, y = _system(28000, 1)
    config = FitConfig(segment_length=512, long_segment_length=2048, live=CONFIG.live)
    fitted = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, config, INPUTS, ('f', 'g'))
    design = fitted.model.fit['design']
    assert design['scoring_segment_length'] == 2048
    folds = design['input_set_folds']
    assert folds['n_blocks'] == 4 and folds['scoring_segment_length'] == 1024
    assert sum(folds['blocks_s']) == pytest.approx(28000 / FS_HZ, abs=1.0)
    rows = design['rows']
    assert rows['f']['inputs'] == rows['f']['live_inputs'] == 'accel'
    assert rows['g']['inputs'] == rows['g']['live_inputs'] == 'accel+rates'
    # the per-set figures are the input-set folds' (the evidence for the choice)
    per_set = rows['g']['input_sets']
    assert per_set['accel+rates']['cv_rmse_pct'] < per_set['accel']['cv_rmse_pct']
    # and `fit` says on which folds
    from wheel_force_estimator.cli.fit import _print_design
    _print_design(fitted.model)
    assert 'on the input-set folds: 4 blocks, 1024-sample segments' in capsys.readouterr().out
    # and the fit report
    from wheel_force_estimator.report.builders import _design_section
    from wheel_force_estimator.report.markdown import ReportWriter
    out = ReportWriter(tmp_path)
    _design_section(out, tmp_path, fitted.model)
    text = Path(out.write()).read_text()
    assert 'chosen on folds of shorter chunks' in text and '1024-sample segments' in text


def test_the_four_corners_of_a_component_are_one_group_and_other_outputs_their_own():
    from wheel_force_estimator import MOMENT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    from wheel_force_estimator.core.spindle import component_groups
    assert component_groups(OUTPUT_CHANNELS) == ((0, 3, 6, 9), (1, 4, 7, 10), (2, 5, 8, 11))
    six = component_groups(OUTPUT_CHANNELS + MOMENT_CHANNELS)
    assert len(six) == 6 and all(len(g) == 4 for g in six)
    assert sorted(o for g in six for o in g) == list(range(24))
    assert six[3] == (12, 15, 18, 21)                             # lf_mx rf_mx lr_mx rr_mx
    # a generic recording's channels, and names that only look like a corner's
    assert component_groups(('f', 'g', 'lf', 'xx_fy')) == ((0,), (1,), (2,), (3,))
    assert component_groups(('lf_fy', 'gauge', 'rr_fy')) == ((0, 2), (1,))


def test_a_rows_near_tie_goes_the_way_its_components_four_rows_point():
    # Known answer, the 2-minute SUV's Fy rows on the input-set folds (relative MSEs summed,
    # per set: accelerations, + split, + cornering split): `rf_fy` alone near-ties to the
    # accelerations (0.2951 against 0.2963) and erred 25.7 % on the held-out course where
    # the other Fy rows, with the cornering split, erred 9-10 %.  Summed over the four
    # corners the cornering split wins; a row of its own keeps its own choice.
    from wheel_force_estimator.core.search import _pooled
    fy = np.array([[0.3328, 0.2951, 0.3247, 0.3450],
                   [0.3841, 0.3080, 0.3668, 0.3621],
                   [0.3188, 0.2963, 0.2817, 0.3281]])
    assert list(np.argmin(fy, axis=0)) == [2, 0, 2, 2]
    pooled = _pooled(fy, [(0, 1, 2, 3)])
    assert list(np.argmin(pooled, axis=0)) == [2, 2, 2, 2]
    np.testing.assert_allclose(pooled[:, 0], fy.sum(axis=1))
    np.testing.assert_array_equal(_pooled(fy, [(0,), (1,), (2,), (3,)]), fy)
    # two groups: each takes its own members' sum, not the other's
    two = _pooled(fy, [(0, 1), (2, 3)])
    np.testing.assert_allclose(two[:, 1], fy[:, :2].sum(axis=1))
    np.testing.assert_allclose(two[:, 2], fy[:, 2:].sum(axis=1))
