# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""fit -> predict -> evaluate through the real CLI on real rosbag2 files (mcap and sqlite3)."""
import json
from pathlib import Path
import subprocess
import sys

from known_system import known_system
import numpy as np
import pytest

from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.predict import predict_forces

FS_HZ = 512.0
PERIOD_NS = 1_953_125
T0_NS = 1_750_000_000 * 10**9


def write_bag(path, seconds, seed, storage='mcap', events=()):
    n = int(seconds * FS_HZ)
    x, y = known_system(n, seed)
    stamps = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    write_recording(path, stamps, x, y, events=events, storage=storage)
    return stamps, x, y


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    d = tmp_path_factory.mktemp('bags')
    write_bag(d / 'train_a', 60, 1, 'mcap')
    write_bag(d / 'train_b', 60, 2, 'sqlite3')
    half = T0_NS + PERIOD_NS * int(30 * FS_HZ)
    write_bag(d / 'val', 60, 3, 'sqlite3', events=[(T0_NS, 'cobblestone'), (half, 'braking')])
    return d


@pytest.fixture(scope='module')
def model_path(bags):
    out = bags / 'model.npz'
    # the shipped defaults: the design is chosen by cross-validation, nothing pinned
    assert main(['fit', str(bags / 'train_a'), str(bags / 'train_b'), '-o', str(out),
                 '--report', str(bags / 'fit_report')]) == 0
    return out


def test_fit_report_and_summary(model_path, bags, capsys):
    model = load_model(model_path)
    assert model.fit['total_duration_s'] == pytest.approx(120.0)
    assert len(model.fit['segments']) == 2
    report = (bags / 'fit_report' / 'report.md').read_text()
    # the design was chosen by cross-validation and the report shows every candidate
    design = model.fit['design']
    assert design['method'] == 'blocked_cross_validation' and design['imposed'] == []
    assert set(design['rows']) == set(model.output_channels)
    assert 'Chosen per output by blocked cross-validation' in report
    for name, row in design['rows'].items():
        assert f'| {name} |' in report
        # the four corners of a component choose their input set together
        assert row['inputs'] == design['rows'][f'lf_{name[3:]}']['inputs'], name
        # the chosen candidate has the lowest held-out criterion of its input set's
        o = model.output_channels.index(name)
        crit = [(c['cv_rmse_pct'][o] / 100) ** 2 + (c['cv_rmse_hp1_pct'][o] / 100) ** 2
                for c in design['candidates'] if c['inputs'] == row['inputs']]
        chosen = (row['cv_rmse_pct'] / 100) ** 2 + (row['cv_rmse_hp1_pct'] / 100) ** 2
        assert chosen == pytest.approx(min(crit), rel=1e-3)
    assert design['input_set_groups'] == [[f'{c}_{k}' for c in ('lf', 'rf', 'lr', 'rr')]
                                          for k in ('fx', 'fy', 'fz')]
    assert 'The four corners of a component chose their input set together' in report
    # 2 x 60 s fall back to one resolution (12 long windows for 12 inputs): the 2048-sample
    # scoring grid already deals 16 chunks, so the same folds chose the input sets, and the
    # report has no paragraph about other folds
    assert design['scoring_segment_length'] == 2048
    assert design['input_set_folds'] == {'n_blocks': 4, 'blocks_s': design['blocks_s'],
                                         'scoring_segment_length': 2048}
    assert 'chosen on folds of shorter chunks' not in report
    for png in ('coherence.png', 'frf_diagonal.png', 'condition_number.png',
                'design_scores.png'):
        assert png in report
        assert (bags / 'fit_report' / png).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.slow
def test_a_bag_with_too_few_long_windows_for_12_inputs_is_fitted_with_one_resolution(
        bags, tmp_path, capsys):
    # 60 s at 512 Hz hold 6 windows of the 8192-sample long segment for 12 inputs: below the
    # crossover H1 would be an exact fit of them (a 1-minute simulated car: held-out 32.9 %
    # with it, 29.4 % without), so the default long segment is dropped with a note; asked
    # for explicitly it is kept.
    out = tmp_path / 'm.npz'
    assert main(['fit', str(bags / 'val'), '-o', str(out)]) == 0
    assert 'the records hold 6 window(s) of the 8192-sample long segment' in (
        capsys.readouterr().out)
    assert 'long_segment_length' not in load_model(out).fit
    assert main(['fit', str(bags / 'val'), '-o', str(out), '--long-segment-length',
                 '8192']) == 0
    assert 'long segment' not in capsys.readouterr().out
    assert load_model(out).fit['n_windows_long'] == 6


def test_predict_writes_virtual_wft_with_input_stamps(model_path, bags):
    out = bags / 'pred'
    assert main(['predict', str(model_path), str(bags / 'val'), '-o', str(out)]) == 0
    meta = (out / 'metadata.yaml').read_text()
    assert 'sqlite3' in meta  # same storage as the input
    stamps, force = read_wrench_topics(out, TopicConfig().output_topics)
    rec = read_recording(bags / 'val')
    seg, = rec.segments
    np.testing.assert_array_equal(stamps, seg.stamp_ns)
    expected = predict_forces(load_model(model_path), seg.accel_mps2)
    np.testing.assert_array_equal(force, expected)
    # a known linear system: held-out RMSE below 2 % (edges included: the predictor holds
    # the first/last sample instead of stepping from zero)
    err = force - seg.force_n
    rmse = 100 * err.std(axis=1) / seg.force_n.std(axis=1)
    assert np.all(rmse < 2.0), rmse


@pytest.mark.parametrize('compression', ['zstd', 'none'])
def test_predict_mcap_output_compression_read_by_rosbags(model_path, bags, compression):
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    out = bags / f'pred_{compression}'
    assert main(['predict', str(model_path), str(bags / 'train_a'), '-o', str(out),
                 '--compression', compression]) == 0
    with (out / f'{out.name}.mcap').open('rb') as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    stored = '' if compression == 'none' else 'zstd'
    assert chunks and {c.compression for c in chunks} == {stored}
    seg, = read_recording(bags / 'train_a').segments
    expected = predict_forces(load_model(model_path), seg.accel_mps2)
    # rosbags (an independent reader) decodes every message to the same bits
    topics = TopicConfig().output_topics
    got = {t: [] for t in topics}
    with AnyReader([out]) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            got[conn.topic].append((msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z))
    for k, topic in enumerate(topics):
        np.testing.assert_array_equal(np.array(got[topic]).T, expected[3 * k:3 * k + 3])


def test_evaluate_json_matches_independent_computation(model_path, bags):
    out = bags / 'eval.json'
    assert main(['evaluate', str(model_path), str(bags / 'val'), '--json', str(out),
                 '--report', str(bags / 'eval_report')]) == 0
    doc = json.loads(out.read_text())
    seg, = read_recording(bags / 'val').segments
    pred = predict_forces(load_model(model_path), seg.accel_mps2)
    t = seg.force_n - seg.force_n.mean(1, keepdims=True)
    p = pred - pred.mean(1, keepdims=True)
    rmse = 100 * np.sqrt(((p - t) ** 2).mean(1) / (t ** 2).mean(1))
    names = list(doc['channels'])
    assert names[:3] == ['lf_fx', 'lf_fy', 'lf_fz']
    got = np.array([doc['channels'][c]['rmse_pct'] for c in names])
    np.testing.assert_allclose(got, rmse, rtol=1e-9)
    assert np.all(got < 2.0)
    assert all(doc['channels'][c]['rubric'] == 'perfect' for c in names)
    ratio = pseudo_damage(pred) / pseudo_damage(seg.force_n)
    np.testing.assert_allclose([doc['channels'][c]['damage_ratio'] for c in names], ratio,
                               rtol=1e-9)
    assert set(doc['events']) == {'cobblestone', 'braking'}
    assert doc['sample_rate_hz'] == FS_HZ and doc['sn_slope'] == 5.0
    report = (bags / 'eval_report' / 'report.md').read_text()
    for png in ('rmse_events.png', 'damage_ratio.png', 'relative_damage_spectrum.png',
                'asd.png', 'time_history.png'):
        assert png in report and (bags / 'eval_report' / png).is_file()


def test_evaluate_samples_judges_pieces_of_the_whole_prediction(model_path, bags, tmp_path,
                                                                capsys):
    # Bugs caught: --samples counted per segment instead of over the recording (a range
    # across the gap), pieces predicted on their own (FIR edges at every cut), or a range
    # past the end silently shortened.
    n = int(20 * FS_HZ)
    x, y = known_system(2 * n, 7)
    stamps = T0_NS + PERIOD_NS * np.arange(2 * n, dtype=np.int64)
    stamps[n:] += 10**9                                    # a 1 s gap: two segments
    write_recording(tmp_path / 'gapped', stamps, x, y)
    segments = read_recording(tmp_path / 'gapped').segments
    assert [s.force_n.shape[1] for s in segments] == [n, n]
    out = tmp_path / 'e.json'
    spec = f'100..3000,{n - 2000}..{n + 4000}'          # the second range spans the gap
    assert main(['evaluate', str(model_path), str(tmp_path / 'gapped'), '--samples', spec,
                 '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    model = load_model(model_path)
    preds = [predict_forces(model, s.accel_mps2) for s in segments]
    pieces = [(0, 100, 3000), (0, n - 2000, n), (1, 0, 4000)]
    t = np.hstack([segments[i].force_n[:, a:b] for i, a, b in pieces])
    p = np.hstack([preds[i][:, a:b] for i, a, b in pieces])
    t, p = t - t.mean(1, keepdims=True), p - p.mean(1, keepdims=True)
    rmse = 100 * np.sqrt(((p - t) ** 2).mean(1) / (t ** 2).mean(1))
    np.testing.assert_allclose([doc['channels'][c]['rmse_pct'] for c in doc['channels']],
                               rmse, rtol=1e-9)
    damage = sum(pseudo_damage(segments[i].force_n[:, a:b]) for i, a, b in pieces)
    np.testing.assert_allclose([doc['channels'][c]['damage_target'] for c in doc['channels']],
                               damage, rtol=1e-9)
    # every sample selected == no selection
    assert main(['evaluate', str(model_path), str(tmp_path / 'gapped'), '--samples',
                 f'0..{2 * n}', '--json', str(tmp_path / 'all.json')]) == 0
    assert main(['evaluate', str(model_path), str(tmp_path / 'gapped'), '--json',
                 str(tmp_path / 'none.json')]) == 0
    assert (json.loads((tmp_path / 'all.json').read_text())['channels']
            == json.loads((tmp_path / 'none.json').read_text())['channels'])
    # a range past the end: a user error naming the file and the length; nothing shortened
    # (in-process: an exception instead of the error would fail here as a traceback would)
    capsys.readouterr()
    code, err = _in_process('evaluate', str(model_path), str(tmp_path / 'gapped'), '--samples',
                            f'0..{2 * n + 1}', capsys=capsys)
    assert code == 1 and 'gapped' in err and str(2 * n) in err
    # malformed, overlapping, or more than one recording: bad arguments
    for bad in (['--samples', '5..5'], ['--samples', '0..10,5..20'], ['--samples', 'a..b']):
        assert _in_process('evaluate', str(model_path), str(tmp_path / 'gapped'), *bad,
                           capsys=capsys)[0] == 2
    code, err = _in_process('evaluate', str(model_path), str(tmp_path / 'gapped'),
                            str(bags / 'val'), '--samples', '0..10', capsys=capsys)
    assert code == 2 and 'one recording' in err


def test_two_bags_fit_equals_per_segment_average(model_path, bags):
    """The fit of two bags averages their Welch windows; it never joins them."""
    from wheel_force_estimator.cli.common import load_fit_config
    from wheel_force_estimator.core.pipeline import fit_model
    from wheel_force_estimator.core.pipeline import TrainingSegment
    from wheel_force_estimator import INPUT_CHANNELS
    from wheel_force_estimator import OUTPUT_CHANNELS
    cfg = load_fit_config()   # the settings model_path was fitted with
    segs = [read_recording(bags / b).segments[0] for b in ('train_a', 'train_b')]
    per_segment = fit_model([TrainingSegment(s.accel_mps2, s.force_n, 'x') for s in segs],
                            FS_HZ, cfg, INPUT_CHANNELS, OUTPUT_CHANNELS)
    joined = fit_model([TrainingSegment(np.hstack([s.accel_mps2 for s in segs]),
                                        np.hstack([s.force_n for s in segs]), 'joined')],
                       FS_HZ, cfg, INPUT_CHANNELS, OUTPUT_CHANNELS)
    assert per_segment.fit['n_windows'] == joined.fit['n_windows'] - 1  # the straddling window
    assert not np.allclose(per_segment.h, joined.h, rtol=1e-6)
    # the CLI's cross-validated fit keeps the two bags apart too (bug: bags concatenated)
    model = load_model(model_path)
    assert len(model.fit['segments']) == 2
    assert model.fit['n_windows'] == per_segment.fit['n_windows']


def _in_process(*args, capsys):
    """Return ``(exit code, stderr)`` of ``wheel-force args`` run by :func:`main` here."""
    try:
        code = main(list(args))
    except SystemExit as stop:     # argparse's own usage errors
        code = stop.code
    return code, capsys.readouterr().err


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, '-m', 'wheel_force_estimator', *args],
                          capture_output=True, text=True, cwd=cwd, timeout=120)


@pytest.mark.parametrize('case', ['missing_bag', 'garbage_model', 'missing_topic'])
def test_user_errors_exit_1_without_traceback(case, model_path, bags, tmp_path):
    if case == 'missing_bag':
        proc = _cli('evaluate', str(model_path), str(tmp_path / 'nope'))
        needle = 'nope'
    elif case == 'garbage_model':
        bad = tmp_path / 'bad.npz'
        bad.write_bytes(b'not a zip')
        proc = _cli('predict', str(bad), str(bags / 'val'), '-o', str(tmp_path / 'o'))
        needle = 'bad.npz'
    else:
        n = 2000
        stamps = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
        write_recording(tmp_path / 'imu_only', stamps, np.zeros((12, n)))
        proc = _cli('fit', str(tmp_path / 'imu_only'), '-o', str(tmp_path / 'm.npz'))
        needle = '/wft/lf/wrench'
    assert proc.returncode == 1, proc.stderr
    assert 'Traceback' not in proc.stderr
    assert needle in proc.stderr


def test_bad_arguments_exit_2():
    proc = _cli('fit')
    assert proc.returncode == 2
    assert 'usage' in proc.stderr


@pytest.mark.slow
def test_closed_stdout_exits_quietly(tmp_path):
    # The reader is gone before the command prints its summary (``wheel-force fit ... | head
    # -0``): no traceback, the exit code a SIGPIPE death would give (141).
    rng = np.random.default_rng(0)
    x = rng.normal(size=4096)
    data = np.column_stack([x, 3.0 * x + 0.1 * rng.normal(size=x.size)])
    np.savetxt(tmp_path / 'rig.csv', data, delimiter=',', header='disp,force', comments='')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'wheel_force_estimator', 'fit', str(tmp_path / 'rig.csv'),
         '-o', str(tmp_path / 'm.npz'), '--input', 'disp:displacement:m',
         '--output', 'force:force:N', '--fs', '512'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, stderr
    assert 'Traceback' not in stderr and 'BrokenPipe' not in stderr
    assert (tmp_path / 'm.npz').is_file()  # the work was done; only the summary was lost


def test_help_lists_every_subcommand():
    proc = _cli('--help')
    assert proc.returncode == 0
    for name in ('simulate', 'fit', 'predict', 'evaluate', 'diagnose', 'node', 'replay'):
        assert name in proc.stdout


def test_package_root():
    assert (Path(__file__).resolve().parents[1] / 'README.md').is_file()


def test_a_fit_setting_outside_its_range_exits_2_naming_the_key_and_range(bags, tmp_path,
                                                                          capsys):
    config = tmp_path / 'bad.yaml'
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    regularisation: -1.0\n')
    assert main(['fit', str(bags / 'val'), '-o', str(tmp_path / 'm.npz'), '--config',
                 str(config)]) == 2
    err = capsys.readouterr().err
    assert 'bad.yaml' in err and 'regularisation' in err and '>= 0' in err
    assert not (tmp_path / 'm.npz').exists()
