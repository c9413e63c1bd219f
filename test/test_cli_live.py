# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""fit / predict --causal / evaluate --causal through the real CLI on real rosbag2 files."""
import json

from known_system import known_system
import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces

FS_HZ = 512.0
PERIOD_NS = 1_953_125
T0_NS = 1_750_000_000 * 10**9


def write_bag(path, seconds, seed):
    """Write a bag of a known 12x12 system (coloured inputs through 2nd-order filters)."""
    n = int(seconds * FS_HZ)
    x, y = known_system(n, seed)
    stamps = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    write_recording(path, stamps, x, y)


@pytest.fixture(scope='module')
def setup(tmp_path_factory):
    # The model is fitted by the library with a short live history and a 3-point sweep: the
    # CLI's full design (12 x ~250 unknowns, 6 look-aheads) costs a minute on a loaded
    # machine; its look-ahead handling is tested on a 1-channel recording below.
    d = tmp_path_factory.mktemp('live')
    write_bag(d / 'train', 60, 1)
    write_bag(d / 'val', 10, 2)
    rec = read_recording(d / 'train', TopicConfig(), require_wft=True)
    cfg = FitConfig(live=LiveDesign(look_aheads_s=(0.04, 0.0, 0.025), history_s=0.3,
                                    fine_s=0.03, blocks_per_octave=4))
    model = fit_model([TrainingSegment(s.accel_mps2, s.force_n, 'train') for s in rec.segments],
                      FS_HZ, cfg, INPUT_CHANNELS, OUTPUT_CHANNELS)
    return d, save_model(model, d / 'model.npz')


def test_fit_stores_the_configured_look_ahead_first_and_the_sweep(tmp_path, capsys):
    rng = np.random.default_rng(5)
    x = signal.lfilter(*signal.butter(2, 0.3), rng.normal(size=30 * 256))
    y = signal.lfilter([0.5, 1.0, -0.4], [1.0], x)
    np.savez(tmp_path / 'rec.npz', x=x, f=y)
    model = tmp_path / 'm.npz'
    assert main(['fit', str(tmp_path / 'rec.npz'), '-o', str(model), '--input',
                 'x:acceleration:m/s^2', '--output', 'f:force:N', '--fs', '256',
                 '--live-look-ahead-s', '0.04']) == 0
    assert 'live estimator: look-ahead 10 samples (39.1 ms)' in capsys.readouterr().out
    # 0.04 s -> 10 samples (configured, first), then 0, 25, 50, 100, 250 ms at 256 Hz.
    live = load_model(model).live
    assert [e.look_ahead_samples for e in live] == [10, 0, 6, 13, 26, 64]
    assert live[0].info['method'] == 'multirate_ls_fir'


def test_predict_causal_writes_what_the_predictor_computes(setup, capsys):
    d, path = setup
    out = d / 'pred'
    assert main(['predict', str(path), str(d / 'val'), '-o', str(out), '--causal',
                 '--live-look-ahead-s', '0.04']) == 0
    assert 'live estimator: look-ahead 20 samples (39.1 ms)' in capsys.readouterr().out
    _, written = read_wrench_topics(out, TopicConfig().output_topics)
    val = read_recording(d / 'val', TopicConfig(), require_wft=True)
    want = predict_forces(load_model(path), val.segments[0].accel_mps2, 20)
    np.testing.assert_allclose(written, want, rtol=0,
                               atol=1e-9 * np.abs(want).max())
    # Bug caught: --causal silently running the two-sided filter.
    assert np.abs(want - predict_forces(load_model(path), val.segments[0].accel_mps2)).max() \
        > 1e-3 * np.abs(want).max()


def test_evaluate_causal_puts_offline_and_live_side_by_side(setup, capsys):
    d, path = setup
    js, rep = d / 'ev.json', d / 'rep'
    assert main(['evaluate', str(path), str(d / 'val'), '--causal', '--live-look-ahead-s',
                 '0.04', '--json', str(js), '--report', str(rep)]) == 0
    text = capsys.readouterr().out
    assert 'offline (two-sided) vs live (live estimator, look-ahead 39.1 ms)' in text
    doc = json.loads(js.read_text())
    assert doc['live']['look_ahead_samples'] == 20
    assert [round(s['look_ahead_s'] * FS_HZ) for s in doc['look_ahead_sweep']] == [0, 13, 20]
    # The live figures are what `evaluate --causal-delay-samples 20` reports, the offline
    # ones what plain `evaluate` reports: one scoring path.
    js2, js3 = d / 'ev2.json', d / 'ev3.json'
    assert main(['evaluate', str(path), str(d / 'val'), '--causal-delay-samples', '20',
                 '--json', str(js2)]) == 0
    assert main(['evaluate', str(path), str(d / 'val'), '--json', str(js3)]) == 0
    assert doc['live']['channels'] == json.loads(js2.read_text())['channels']
    assert doc['offline']['channels'] == json.loads(js3.read_text())['channels']
    report = (rep / 'report.md').read_text()
    assert 'Offline vs live' in report and 'accuracy_vs_look_ahead.png' in report
    assert (rep / 'accuracy_vs_look_ahead.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_unfitted_look_ahead_exits_1_naming_the_ones_the_model_has(setup, capsys):
    d, path = setup
    rc = main(['predict', str(path), str(d / 'val'), '-o', str(d / 'x'),
               '--live-look-ahead-s', '0.2'])
    err = capsys.readouterr().err
    assert rc == 1
    assert '20 (39.1 ms), 0 (0.0 ms), 13 (25.4 ms)' in err and 'refit' in err
    assert not (d / 'x').exists()


def test_old_model_predicts_causal_with_a_warning(setup, capsys, tmp_path):
    d, path = setup
    with np.load(path, allow_pickle=False) as npz:
        contents = {k: npz[k] for k in npz.files if not k.startswith('live')}
    meta = json.loads(str(contents['meta']))
    meta['schema_version'] = 1
    del meta['live_estimators']
    contents['meta'] = np.array(json.dumps(meta))
    old = tmp_path / 'old.npz'
    np.savez(old, **contents)
    assert main(['predict', str(old), str(d / 'val'), '-o', str(tmp_path / 'p'),
                 '--causal']) == 0
    err = capsys.readouterr().err
    assert f'warning: {old}: the model has no live (causal) estimator' in err
    assert 'cut to 26 samples' in err


def test_both_look_ahead_options_are_a_usage_error(setup, capsys):
    d, path = setup
    rc = main(['predict', str(path), str(d / 'val'), '-o', str(d / 'y'),
               '--causal-delay-samples', '20', '--live-look-ahead-s', '0.04'])
    assert rc == 2
    assert 'not both' in capsys.readouterr().err


def test_look_ahead_from_the_params_file_follows_the_node_section_precedence(tmp_path):
    from wheel_force_estimator.cli.common import configured_look_ahead_s
    from wheel_force_estimator.core.errors import ConfigError
    from wheel_force_estimator.core.live_estimator import DEFAULT_LIVE_LOOK_AHEAD_S
    both = tmp_path / 'both.yaml'
    both.write_text('/**:\n  ros__parameters:\n    live_look_ahead_s: 0.1\n'
                    'wheel_force_node:\n  ros__parameters:\n    live_look_ahead_s: 0.2\n')
    # The node-specific section overrides the wildcard, as for the topics (bagio.topics).
    assert configured_look_ahead_s(both) == 0.2
    assert configured_look_ahead_s(both, 0.03) == 0.03
    fit_only = tmp_path / 'fit.yaml'
    fit_only.write_text('wheel_force_fit:\n  segment_length: 512\n')
    assert configured_look_ahead_s(fit_only) == DEFAULT_LIVE_LOOK_AHEAD_S
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    live_look_ahead_s: -1\n')
    with pytest.raises(ConfigError, match=r'bad.yaml: /\*\*.ros__parameters.live_look_ahead_s'):
        configured_look_ahead_s(bad)
