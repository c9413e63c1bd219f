# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``fit`` and ``evaluate`` on generic recordings (CSV, NPZ, MAT) through the real CLI.

Known answer: two displacement inputs drive two forces through short FIR filters, so the FRF
is ``H[o, i](f) = sum_k b[o, i, k] exp(-2j pi f k / fs)`` exactly.  The files hold inches and
kip; the model must hold N/m.
"""
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal
import scipy.io
from support.shared_data import dataset
from support.shared_data import SHARED_DATA

from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.predict import predict_forces

FS_HZ = 256.0
INCH_M = 0.0254
KIP_N = 4448.2216152605
# b[out, in, k] in kip per inch.
TAPS = np.array([[[1.0, 0.6, -0.3, 0.1, 0.05], [0.2, -0.1, 0.05, 0.0, 0.0]],
                 [[-0.15, 0.3, 0.1, 0.0, 0.0], [0.8, -0.5, 0.25, -0.1, 0.0]]])
NOISE = 0.02  # output noise std / output std
ROLES = ['--input', 'x1:displacement:in', '--input', 'x2:displacement:in',
         '--output', 'f1:force:kip', '--output', 'f2:force:kip', '--fs', '256']
FRICTION = SHARED_DATA / 'friction_damper'


def known_system(seconds, seed):
    """Return inputs [in] (low-passed noise), outputs [kip] (FIR + 3 kip + 2 % noise), clean."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS_HZ)
    b, a = signal.butter(4, 80.0 / (FS_HZ / 2))
    x = 0.5 * signal.lfilter(b, a, rng.standard_normal((2, n)), axis=1)
    clean = np.stack([sum(signal.lfilter(TAPS[o, i], [1.0], x[i]) for i in range(2))
                      for o in range(2)])
    y = clean + NOISE * clean.std(axis=1, keepdims=True) * rng.standard_normal((2, n))
    return x, y + 3.0, clean + 3.0


def write(path, x, y):
    """Write channels x1, x2, f1, f2 as CSV (with a time column), NPZ or MAT."""
    if path.suffix == '.csv':
        rows = np.column_stack([np.arange(x.shape[1]) / FS_HZ, x.T, y.T])
        path.write_text('time,x1,x2,f1,f2\n' + '\n'.join(
            ','.join(repr(float(v)) for v in row) for row in rows) + '\n')
    elif path.suffix == '.npz':
        np.savez(path, x1=x[0], x2=x[1], f1=y[0], f2=y[1])
    else:
        scipy.io.savemat(str(path), {'x1': x[0], 'x2': x[1], 'f1': y[0], 'f2': y[1]})
    return path


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp('generic')
    out = {name: write(d / name, *known_system(60.0, seed)[:2])
           for seed, name in enumerate(('train.csv', 'train.npz', 'train.mat'), start=1)}
    x, y, clean = known_system(30.0, 10)
    out['holdout'] = write(d / 'holdout.npz', x, y)
    out['holdout_clean_n'] = clean * KIP_N
    out['holdout_x_m'] = x * INCH_M
    out['short'] = write(d / 'short.csv', *known_system(6.0, 11)[:2])
    out['tiny'] = write(d / 'tiny.npz', *known_system(2.0, 12)[:2])
    return out


@pytest.fixture(scope='module')
def model_path(files):
    path = files['train.csv'].parent / 'model.npz'
    # the shipped defaults: the design is chosen by cross-validation, nothing pinned
    rc = main(['fit', str(files['train.csv']), str(files['train.npz']), str(files['train.mat']),
               '-o', str(path), '--report', str(path.parent / 'fit_report')] + ROLES)
    assert rc == 0
    return path


def analytic_frf_si(f_hz):
    """FRF of the known system in N/m on ``f_hz``, shape (nf, 2, 2)."""
    k = np.arange(TAPS.shape[2])
    phasors = np.exp(-2j * np.pi * np.outer(f_hz, k) / FS_HZ)
    return np.einsum('oik,fk->foi', TAPS, phasors) * (KIP_N / INCH_M)


def test_fitted_frf_matches_the_analytic_one(model_path):
    model = load_model(model_path)
    assert model.input_channels == ('x1', 'x2')
    assert model.output_channels == ('f1', 'f2')
    assert model.units == {'input': 'm', 'output': 'N'}
    assert model.fs_hz == FS_HZ
    assert model.fit['input_quantity'] == 'displacement'
    assert model.fit['long_segment_length'] == 8192      # 60 s records: two resolutions
    h_true = analytic_frf_si(model.f_hz)
    coherence = model.coherence_multiple.min(axis=1)
    scale = np.abs(h_true).max(axis=2, keepdims=True)   # per output row
    err = np.abs(model.h - h_true) / scale
    # Short segments (3-70 Hz, 87 windows): where the multiple coherence is >= 0.99 the
    # normalised random error of H1 is sqrt(1 - g2) / (g sqrt(2 n_d)) <= 0.76 %; leakage of
    # a 5-tap FIR in a 1024-point Hann window and the 1e-4 Tikhonov term are far below that.
    # 3 % is 4 sigma at the worst line.
    band = (model.f_hz >= 3.0) & (model.f_hz <= 70.0) & (coherence >= 0.99)
    assert band.sum() > 1000
    assert err[band].max() < 0.03
    # Long segments (below 2 Hz, only 6 windows): the same random-error formula per line,
    # 4 sigma, plus 2 % for the bias of the 0.01 regularisation of the long estimate.
    low = (model.f_hz >= 0.25) & (model.f_hz < 2.0) & (coherence >= 0.95)
    assert low.sum() > 50
    g2 = coherence[low]
    sigma = np.sqrt((1.0 - g2) / (2 * model.fit['n_windows_long'] * g2))
    assert np.all(err[low] < 4.0 * sigma[:, None, None] + 0.02)


def test_static_force_and_model_file_are_in_si(model_path):
    model = load_model(model_path)
    np.testing.assert_allclose(model.static_force_n, 3.0 * KIP_N, rtol=0.01)
    with np.load(model_path, allow_pickle=False) as npz:
        meta = json.loads(str(npz['meta']))
    assert meta['input_channels'] == ['x1', 'x2']
    assert meta['units'] == {'input': 'm', 'output': 'N'}
    assert meta['fit']['declared_inputs'] == ['x1:displacement:in', 'x2:displacement:in']
    assert len(meta['fit']['recordings']) == 3


def test_fit_report_for_generic_channels(model_path):
    report = model_path.parent / 'fit_report'
    text = (report / 'report.md').read_text()
    for png in ('coherence.png', 'frf.png', 'condition_number.png'):
        assert png in text and (report / png).is_file()


def test_evaluate_holdout_matches_independent_computation(model_path, files, tmp_path):
    out = tmp_path / 'eval.json'
    rc = main(['evaluate', str(model_path), str(files['holdout']), '--json', str(out),
               '--report', str(tmp_path / 'rep')] + ROLES)
    assert rc == 0
    doc = json.loads(out.read_text())
    assert list(doc['channels']) == ['f1', 'f2']
    assert doc['events'] == {}
    assert doc['sample_rate_hz'] == FS_HZ and doc['sn_slope'] == 5.0
    with np.load(files['holdout']) as npz:
        target_n = np.stack([npz['f1'], npz['f2']]) * KIP_N
    pred = predict_forces(load_model(model_path), files['holdout_x_m'])
    t = target_n - target_n.mean(axis=1, keepdims=True)
    p = pred - pred.mean(axis=1, keepdims=True)
    rmse = 100.0 * np.sqrt(((p - t) ** 2).mean(axis=1) / (t ** 2).mean(axis=1))
    got = np.array([doc['channels'][c]['rmse_pct'] for c in ('f1', 'f2')])
    np.testing.assert_allclose(got, rmse, rtol=1e-9)
    # The target carries 2 % noise, which no prediction can follow.
    assert np.all(got < 3.0)
    assert all(doc['channels'][c]['rubric'] == 'perfect' for c in ('f1', 'f2'))
    # Against the noise-free force of the known system the prediction is within 1 %.
    clean = files['holdout_clean_n']
    c = clean - clean.mean(axis=1, keepdims=True)
    assert np.all(np.sqrt(((p - c) ** 2).mean(axis=1) / (c ** 2).mean(axis=1)) < 0.01)
    # Damage is computed in N: the kip -> N conversion is applied to the target.
    np.testing.assert_allclose([doc['channels'][c]['damage_target'] for c in ('f1', 'f2')],
                               pseudo_damage(target_n), rtol=1e-9)
    text = (tmp_path / 'rep' / 'report.md').read_text()
    for png in ('asd.png', 'time_history.png', 'damage_ratio.png',
                'relative_damage_spectrum.png', 'coherence.png'):
        assert png in text and (tmp_path / 'rep' / png).is_file()


@pytest.mark.parametrize('roles', [
    ['--input', 'x1:displacement:in', '--output', 'f1:force:kip', '--output', 'f2:force:kip'],
    ['--input', 'x1:displacement:in', '--input', 'x2:displacement:in', '--output',
     'f2:force:kip'],
    ['--input', 'x2:displacement:in', '--output', 'f2:force:kip'],
], ids=['1x2', '2x1', '1x1'])
def test_any_channel_count_fits_evaluates_and_reports(roles, files, tmp_path):
    model = tmp_path / 'm.npz'
    roles = roles + ['--fs', '256']
    assert main(['fit', str(files['train.npz']), '-o', str(model), '--report',
                 str(tmp_path / 'fit')] + roles) == 0
    assert main(['evaluate', str(model), str(files['holdout']), '--json',
                 str(tmp_path / 'e.json'), '--report', str(tmp_path / 'eval')] + roles) == 0
    doc = json.loads((tmp_path / 'e.json').read_text())
    assert list(doc['channels']) == [r.split(':')[0] for r in roles[1::2]
                                     if r.endswith(':kip')]
    assert (tmp_path / 'fit' / 'frf.png').is_file()
    assert (tmp_path / 'eval' / 'asd.png').is_file()


def test_short_records_fall_back_to_one_resolution_with_a_note(files, tmp_path, capsys):
    model = tmp_path / 'm.npz'
    assert main(['fit', str(files['short']), '-o', str(model)] + ROLES) == 0
    out = capsys.readouterr().out
    assert 'note: no record holds the 8192-sample long segment' in out
    assert 'longest: 1536 samples' in out
    # 1536 samples hold 2 Welch windows of 1024 for 2 inputs: too few (next test), so 512.
    assert 'fitted with segment 512 (5 windows' in out
    # The cross-validation's folds cannot fit 512 either (6 s), so it starts from 256 and
    # takes 128: the 5-tap system needs no finer grid (held-out RMSE of f1 / f2 fitted with
    # 512, 256, 128 samples: 2.49 / 2.58, 2.20 / 2.37, 2.11 / 2.24 %).
    assert 'against 512, which the records cannot cross-validate' in out
    fitted = load_model(model)
    assert 'long_segment_length' not in fitted.fit
    assert fitted.n_taps == 128
    # Asked for explicitly, the long resolution is refused rather than dropped.
    assert main(['fit', str(files['short']), '-o', str(model), '--long-segment-length',
                 '8192'] + ROLES) == 1
    assert 'long_segment_length = 8192' in capsys.readouterr().err
    # Both chosen explicitly: no fallback, no note.
    assert main(['fit', str(files['short']), '-o', str(model), '--long-segment-length',
                 '0', '--segment-length', '1024'] + ROLES) == 0
    assert 'note:' not in capsys.readouterr().out
    assert load_model(model).n_taps == 1024


def test_no_more_windows_than_inputs_gives_a_shorter_segment(files, tmp_path, capsys):
    # Why the few-windows rule exists: with no more Welch windows than inputs, H1 reproduces
    # every window exactly, so the multiple coherence is 1 at every frequency whatever the
    # noise (only the 1e-4 Tikhonov term keeps it below): a check that cannot fail.  Known
    # answer: 2 % output noise leaves 1 - coherence ~ 0.02**2 = 4e-4 in band, shrunk by
    # (n_windows - n_inputs) / n_windows for the estimate (measured 1.1e-4 with 2 windows,
    # 4.2e-4 with the 5 windows of 512 samples; the 23 windows of 128 keep it in the band).
    exact, short = tmp_path / 'exact.npz', tmp_path / 'short.npz'
    assert main(['fit', str(files['short']), '-o', str(exact), '--long-segment-length', '0',
                 '--segment-length', '1024'] + ROLES) == 0
    assert main(['fit', str(files['short']), '-o', str(short), '--long-segment-length', '0']
                + ROLES) == 0
    out = capsys.readouterr().out
    assert 'note: the records hold 2 Welch window(s) of 1024 samples for 2 input(s)' in out
    coh_exact = load_model(exact).coherence_multiple
    coh_short = load_model(short).coherence_multiple
    loss_exact = np.median(1.0 - coh_exact[1:])
    loss_short = np.median(1.0 - coh_short[1:])
    assert NOISE ** 2 / 4 < loss_short < 4 * NOISE ** 2
    assert loss_exact < loss_short / 2
    # 512 from the few-windows rule, then 128 from the cross-validation (previous test)
    assert load_model(short).fit['segment_length'] == 128


@pytest.mark.slow
def test_too_few_long_windows_for_the_inputs_fall_back_to_one_resolution(files, tmp_path,
                                                                         capsys):
    # One 60 s record at 256 Hz holds 2 windows of the 8192-sample long segment for 2 inputs:
    # below the crossover H1 would reproduce them exactly, so the default long segment is
    # dropped with a note (the MR damper's 115 s run beside two 15 s ones held one: the
    # plain fit scored 162 % on a held-out run).  Three such records (6 windows) keep it; a
    # long segment asked for explicitly is kept.
    one, three = tmp_path / 'one.npz', tmp_path / 'three.npz'
    assert main(['fit', str(files['train.csv']), '-o', str(one)] + ROLES) == 0
    out = capsys.readouterr().out
    assert 'the records hold 2 window(s) of the 8192-sample long segment' in out
    assert 'long_segment_length' not in load_model(one).fit
    assert main(['fit', str(files['train.csv']), str(files['train.npz']),
                 str(files['train.mat']), '-o', str(three)] + ROLES) == 0
    assert 'long segment' not in capsys.readouterr().out
    assert load_model(three).fit['long_segment_length'] == 8192
    assert main(['fit', str(files['train.csv']), '-o', str(one), '--long-segment-length',
                 '8192'] + ROLES) == 0
    assert 'long segment' not in capsys.readouterr().out
    assert load_model(one).fit['long_segment_length'] == 8192


def test_a_live_look_ahead_beyond_the_longest_designed_exits_2(files, tmp_path, capsys):
    # Before: a ConfigError from deep in the search, "look-ahead 77 is not within 64 .. 64".
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n    live_look_ahead_s: 0.3\n')
    for extra, where in ((['--live-look-ahead-s', '0.3'], '--live-look-ahead-s = 0.3 s'),
                         (['--config', str(params)], 'p.yaml: live_look_ahead_s = 0.3 s')):
        rc = main(['fit', str(files['train.npz']), '-o', str(tmp_path / 'm.npz')] + extra
                  + ROLES)
        assert rc == 2
        err = capsys.readouterr().err
        assert where in err and 'outside 0 .. 0.25 s' in err, err


def test_fit_refuses_records_shorter_than_one_segment(files, tmp_path, capsys):
    rc = main(['fit', str(files['tiny']), '-o', str(tmp_path / 'm.npz')] + ROLES)
    assert rc == 1
    err = capsys.readouterr().err
    assert 'no recording holds one Welch segment of 1024 samples' in err
    assert 'tiny.npz: 512 samples' in err


@pytest.mark.parametrize('extra, match', [
    ([], 'is a generic recording: declare its channels with --input, --output and --fs'),
    (ROLES[:-2], r'need --input, --output and --fs \(missing: --fs\)'),
    (['--fs', '256'], r'missing: --input, --output'),
    (ROLES[:-1] + ['0'], '--fs must be a finite sample rate > 0 Hz, got 0'),
    (ROLES[:-1] + ['nan'], '--fs must be a finite sample rate'),
])
@pytest.mark.parametrize('command', ['fit', 'evaluate'])
def test_usage_errors_exit_2(command, extra, match, files, model_path, tmp_path, capsys):
    head = (['fit', str(files['train.npz']), '-o', str(tmp_path / 'm.npz')] if command == 'fit'
            else ['evaluate', str(model_path), str(files['train.npz'])])
    assert main(head + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'wheel-force {command}: error: ')
    assert re.search(match, err), err


@pytest.mark.parametrize('command', ['fit', 'evaluate'])
def test_bags_and_generic_files_are_not_mixed(command, files, model_path, tmp_path, capsys):
    bag = tmp_path / 'run1'
    bag.mkdir()
    head = (['fit', '-o', str(tmp_path / 'm.npz')] if command == 'fit'
            else ['evaluate', str(model_path)])
    assert main(head + [str(bag), str(files['train.npz'])] + ROLES) == 2
    assert 'run1 is a bag: bags and generic recordings' in capsys.readouterr().err
    assert main(head + [str(bag), str(files['train.npz'])]) == 2
    assert 'train.npz is a generic recording' in capsys.readouterr().err


@pytest.mark.parametrize('roles, match', [
    (['--input', 'x1:displacement:furlong'] + ROLES[2:], 'unknown displacement unit'),
    (['--input', 'x1:displacement:in'] + ROLES, "input channel 'x1' is declared twice"),
    (['--input', 'x1:velocity:in/s'] + ROLES, 'all inputs must share one quantity'),
    (['--input', 'x3:displacement:in'] + ROLES[2:], r"train.npz: no channel 'x3' \(has: x1"),
])
def test_fit_user_errors_exit_1(roles, match, files, tmp_path, capsys):
    rc = main(['fit', str(files['train.npz']), '-o', str(tmp_path / 'm.npz')] + roles)
    assert rc == 1
    assert re.search(match, capsys.readouterr().err)


@pytest.mark.parametrize('value', ['zero', 'interpolate', 'hold'])
def test_params_file_sets_what_the_fit_does_at_unexcited_lines(value, files, tmp_path, capsys):
    config = tmp_path / 'fit.yaml'
    config.write_text(f'wheel_force_fit:\n  ros__parameters:\n    unexcited: {value}\n')
    out = tmp_path / 'm.npz'
    rc = main(['fit', str(files['train.npz']), '-o', str(out), '--config', str(config)] + ROLES)
    if value == 'hold':
        assert rc == 2                  # a value outside its range is a usage error
        err = capsys.readouterr().err
        assert f'{config}: ' in err and 'unexcited must be one of' in err and 'hold' in err
        return
    assert rc == 0
    assert load_model(out).fit['unexcited'] == value


def test_fit_says_which_lines_it_bridged(tmp_path, capsys):
    # Sine tests at 1 and 2 Hz, 64 s at 256 Hz: the 8192-sample long segment's 0.03 Hz
    # lines between and below them were not excited; `fit` bridges them and says so.
    rng = np.random.default_rng(5)
    paths = []
    for f_hz in (1.0, 2.0):
        t = np.arange(int(64 * FS_HZ)) / FS_HZ
        x = 0.01 * np.sin(2 * np.pi * f_hz * t)
        y = 2e4 * x + 800 * np.gradient(x, t) + 0.01 * 200.0 * rng.standard_normal(t.size)
        paths.append(tmp_path / f'sine_{f_hz:g}.npz')
        np.savez(paths[-1], x=x, f=y)
    rc = main(['fit', *map(str, paths), '-o', str(tmp_path / 'm.npz'), '--input',
               'x:displacement:m', '--output', 'f:force:N', '--fs', '256'])
    assert rc == 0
    out = capsys.readouterr().out
    line = re.search(r'unexcited lines inside the band, bridged from the excited ones '
                     r'\(8192-sample segments; unexcited: interpolate\): x (\d+)', out)
    assert line, out
    assert int(line.group(1)) == load_model(tmp_path / 'm.npz').fit['bridged_lines_long']['x']


def test_missing_file_exit_1(model_path, tmp_path, capsys):
    assert main(['evaluate', str(model_path), str(tmp_path / 'gone.csv')] + ROLES) == 1
    assert 'gone.csv: no such file' in capsys.readouterr().err


@pytest.mark.parametrize('roles, match', [
    (['--input', 'x2:displacement:in', '--input', 'x1:displacement:in'] + ROLES[4:],
     r"model channel 0 is 'x1' but --input declares 'x2'"),
    (ROLES[:4] + ['--output', 'f1:force:kip', '--fs', '256'],
     r"model channel 1 is 'f2' but --output declares nothing"),
    (ROLES[:-1] + ['512'], 'model fitted at 256 Hz but --fs is 512 Hz'),
    (['--input', 'x1:velocity:in/s', '--input', 'x2:velocity:in/s'] + ROLES[4:],
     r'model inputs are displacement \(m\) but --input declares velocity'),
])
def test_evaluate_refuses_a_model_that_does_not_match(roles, match, model_path, files,
                                                      capsys):
    assert main(['evaluate', str(model_path), str(files['holdout'])] + roles) == 1
    err = capsys.readouterr().err
    assert str(model_path) in err
    assert re.search(match, err), err


def test_generic_model_is_refused_for_bags(model_path, tmp_path, capsys):
    assert main(['evaluate', str(model_path), str(tmp_path / 'some_bag')]) == 1
    assert 'are not the spindle accelerations lf_ax ... rr_az' in capsys.readouterr().err


def test_errors_have_no_traceback(model_path, files, tmp_path):
    def run(*args):
        return subprocess.run([sys.executable, '-m', 'wheel_force_estimator', *args],
                              capture_output=True, text=True, timeout=120)
    proc = run('evaluate', str(model_path), str(files['holdout']), *ROLES[:-1], '100')
    assert proc.returncode == 1
    assert 'Traceback' not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    proc = run('fit', str(files['holdout']), '-o', str(tmp_path / 'm.npz'), *ROLES[:-2])
    assert proc.returncode == 2
    assert 'Traceback' not in proc.stderr and 'missing: --fs' in proc.stderr


def test_friction_damper_displacement_to_force(tmp_path, capsys):
    # Coble et al., Dataset-Friction-Damper-with-Backlash (CC BY-SA 4.0), read in place.  A
    # linear FRF cannot represent friction and backlash, so only honest properties are
    # asserted: the model is built from the declared channels and the metrics are finite.
    dataset(FRICTION.name)  # fails in CI, skips elsewhere, when absent
    roles = ['--input', 'data[1]:displacement:in', '--output', 'data[2]:force:kip',
             '--fs', '1024']
    model = tmp_path / 'damper.npz'
    rc = main(['fit', str(FRICTION / '1Hz30lbtension1amplitude.json'), '-o', str(model)]
              + roles)
    assert rc == 0
    assert 'note: no record holds the 8192-sample long segment' in capsys.readouterr().out
    fitted = load_model(model)
    assert fitted.input_channels == ('data[1]',)
    assert fitted.output_channels == ('data[2]',)
    assert fitted.units == {'input': 'm', 'output': 'N'}
    out = tmp_path / 'e.json'
    rc = main(['evaluate', str(model), str(FRICTION / '1Hz30lbtension1.5amplitude.json'),
               '--json', str(out)] + roles)
    assert rc == 0
    figures = json.loads(out.read_text())['channels']['data[2]']
    for key in ('rmse_pct', 'rmse_hp1_pct', 'damage_target', 'damage_prediction'):
        assert np.isfinite(figures[key]) and figures[key] > 0.0, key


def test_fit_chooses_the_resolution_of_a_lightly_damped_mode_unless_told(tmp_path, capsys):
    # An 8 Hz mode with 1 % damping (half-power band 0.16 Hz) against the 0.25 Hz grid of
    # 1024 samples at 256 Hz: cross-validation must pick a longer segment and say so; a
    # segment given on the command line is the user's and stays (bug caught: the choice
    # overriding an explicit setting, or running silently).
    rng = np.random.default_rng(5)
    paths = []
    for k in range(2):
        n = int(240 * FS_HZ)
        b, a = signal.butter(4, [1.0 / (FS_HZ / 2), 40.0 / (FS_HZ / 2)], 'bandpass')
        accel = signal.lfilter(b, a, rng.standard_normal(n))
        wn = 2 * np.pi * 8.0
        mode = signal.lti([100.0 * 0.02 * wn, 100.0 * wn ** 2], [1.0, 0.02 * wn, wn ** 2])
        force = signal.lsim(mode, accel, np.arange(n) / FS_HZ)[1]
        force += 0.02 * force.std() * rng.standard_normal(n)
        paths.append(tmp_path / f'mode{k}.npz')
        np.savez(paths[-1], a=accel, f=force)
    roles = ['--input', 'a:acceleration:m/s^2', '--output', 'f:force:N', '--fs', '256']
    model = tmp_path / 'm.npz'
    assert main(['fit', *map(str, paths), '-o', str(model)] + roles) == 0
    out = capsys.readouterr().out
    assert 'chosen by blocked cross-validation' in out
    assert load_model(model).fit['segment_length'] >= 4096
    assert main(['fit', *map(str, paths), '-o', str(model), '--segment-length', '1024']
                + roles) == 0
    # told: the segment is imposed (kept, said so), the rest of the design still searched
    assert 'imposed settings: segment_length' in capsys.readouterr().out
    assert load_model(model).fit['segment_length'] == 1024
    assert load_model(model).fit['design']['imposed'] == ['segment_length']


def test_quantised_stepped_sines_fit_with_singular_lines_capped(tmp_path, capsys):
    # Three displacement actuators, each record a different combination of 1-3 Hz sines,
    # recorded with an 8-bit ADC: at some lines an input has exactly no power, the CSD
    # matrix has an exactly zero eigenvalue and its condition number is inf.  fit used to
    # die on its own model validation ("cond_sxx contains NaN or infinity"); the model now
    # holds the cap 1/eps there (singular to working precision either way).
    fs = 512.0
    t = np.arange(int(40 * fs)) / fs
    paths = []
    for k, freqs in enumerate(((1.0, 1.5, 2.0), (2.0, 3.0, 1.0), (3.0, 1.0, 1.5))):
        rng = np.random.default_rng(k + 1)
        x = np.stack([0.005 * np.sin(2 * np.pi * f * t + rng.uniform(0, 6)) for f in freqs])
        step = (x.max() - x.min()) / 2 ** 8
        x = np.round(x / step) * step
        y = np.array([2e4, 5e3, 0.0]) @ x + rng.standard_normal(t.size)
        paths.append(tmp_path / f'sine{k}.npz')
        np.savez(paths[-1], a=x[0], b=x[1], c=x[2], f=y)
    roles = ['--input', 'a:displacement:m', '--input', 'b:displacement:m', '--input',
             'c:displacement:m', '--output', 'f:force:N', '--fs', '512']
    model = tmp_path / 'm.npz'
    assert main(['fit', *map(str, paths), '-o', str(model), '--segment-length', '1024']
                + roles) == 0, capsys.readouterr()
    cond = load_model(model).cond_sxx
    assert np.all(np.isfinite(cond))
    assert cond.max() == 1.0 / np.finfo(np.float64).eps


def test_a_european_text_export_fits_like_the_csv(files, tmp_path):
    # The training CSV rewritten as a rig controller exports it: metadata, names, units,
    # ';' separators, decimal commas, a .txt suffix.  The same numbers, the same model.
    lines = files['train.csv'].read_text().splitlines()
    body = [ln.replace(',', ';').replace('.', ',') for ln in lines[1:]]
    txt = tmp_path / 'train.txt'
    txt.write_text('Rig 3 export; 2026-11-26\ntime;x1;x2;f1;f2\ns;in;in;kip;kip\n'
                   + '\n'.join(body) + '\n')
    models = []
    for path in (files['train.csv'], txt):
        models.append(tmp_path / f'{path.suffix[1:]}.npz')
        assert main(['fit', str(path), '-o', str(models[-1]), '--segment-length', '1024']
                    + ROLES) == 0
    csv_model, txt_model = (load_model(m) for m in models)
    np.testing.assert_array_equal(txt_model.h, csv_model.h)
    np.testing.assert_array_equal(txt_model.static_force_n, csv_model.static_force_n)


def test_a_long_regularisation_outside_its_range_exits_2_naming_that_key(
        files, tmp_path, capsys):
    config = tmp_path / 'fit.yaml'
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    long_regularisation: -1\n')
    rc = main(['fit', str(files['train.npz']), '-o', str(tmp_path / 'm.npz'), '--config',
               str(config)] + ROLES)
    err = capsys.readouterr().err
    assert rc == 2
    # the key the user wrote, not the estimator field it feeds ("regularisation")
    assert f'{config}: ' in err and 'long_regularisation must be finite and >= 0' in err, err


def test_spindle_channel_keys_are_validated_and_said_to_be_ignored_for_generic_records(
        files, tmp_path, capsys):
    config = tmp_path / 'fit.yaml'
    head = ['fit', str(files['train.npz']), '-o', str(tmp_path / 'm.npz'), '--config',
            str(config)]
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    inputs: [foo]\n')
    assert main(head + ROLES) == 1
    assert "inputs must be \"auto\" or a list among ['rates', 'spin', 'split', 'cornering']" in (
        capsys.readouterr().err)
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    inputs: [rates]\n')
    assert main(head + ROLES) == 0
    assert 'generic recordings take theirs from --input / --output (ignored here)' in (
        capsys.readouterr().err)
