# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Six components (issue 33): old model files, moments / rates / spin in bags, their errors.

The schema-2 model in ``test/data`` was written by the code before issue 33 together with
its predictions on fixed accelerations; it must still load, pass the spindle rule and predict
exactly that.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from wheel_force_estimator import CORNERING_CHANNELS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator import SPIN_CHANNELS
from wheel_force_estimator import SPLIT_CHANNELS
from wheel_force_estimator.bagio import available_extras
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.spindle import channel_units
from wheel_force_estimator.core.spindle import spindle_layout

DATA = Path(__file__).resolve().parent / 'data'
FS_HZ = 512.0
T0_NS = 1_760_000_000 * 10**9
PERIOD_NS = 1_953_125


def test_schema2_model_still_loads_and_predicts_the_same():
    # bug caught: a schema bump that refuses old files, or changes what they predict
    model = load_model(DATA / 'model_schema2.npz')
    assert json.loads(str(np.load(DATA / 'model_schema2.npz')['meta']))['schema_version'] == 2
    layout = spindle_layout(model, 'old')
    assert layout.torque_rows is None and layout.extras == ()
    assert channel_units(model) == (('m/s^2',) * 12, ('N',) * 12)
    expected = np.load(DATA / 'model_schema2_expected.npz')
    np.testing.assert_array_equal(predict_forces(model, expected['accel_mps2']),
                                  expected['force_n'])


def test_per_channel_units_round_trip_and_unit_mismatch_refused(tmp_path):
    old = load_model(DATA / 'model_schema2.npz')
    import dataclasses
    units = {'input': 'm/s^2', 'output': 'N', 'input_channels': ['m/s^2'] * 12,
             'output_channels': ['N'] * 12}
    path = save_model(dataclasses.replace(old, units=units), tmp_path / 'm3.npz')
    again = load_model(path)
    assert json.loads(str(np.load(path)['meta']))['schema_version'] == 3
    assert again.units == units
    bad = dict(units, output_channels=['N'] * 11 + ['kN'])
    save_model(dataclasses.replace(old, units=bad), tmp_path / 'bad.npz')
    # bug caught: a model in kN applied to a bag in N without a word (both units named)
    with pytest.raises(ModelFileError, match=r"rr_fz is 'kN' but the bag's WrenchStamped "
                                             r"force is in 'N'"):
        spindle_layout(load_model(tmp_path / 'bad.npz'), 'bad')
    with pytest.raises(ModelFileError, match=r'units.output_channels'):
        dataclasses.replace(old, units=dict(units, output_channels=['N'] * 3))


def _signals(n, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(12, n)), rng.normal(size=(12, n)) * 100,
            rng.normal(size=(12, n)) * 10, rng.normal(size=(12, n)) * 0.1,
            20 + rng.normal(size=(4, n)), rng.normal(size=(4, n)) * 0.01)


@pytest.mark.parametrize('travel', [False, True])
def test_moments_rates_spin_round_trip_exactly(tmp_path, travel):
    n = 300
    accel, force, torque, rate, spin, comp = _signals(n)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    path = write_recording(tmp_path / 'b', stamp, accel, force, torque_nm=torque,
                           rate_radps=rate, rate_variance=4e-6, spin_radps=spin,
                           travel_m=comp if travel else None)
    assert available_extras(path) == ('moments', 'rates', 'spin')
    for bulk in (True, False):  # the bulk decoder and rosbags' deserialiser agree bit for bit
        rec = read_recording(path, bulk=bulk, travel=travel,
                             extras=('moments', 'rates', 'spin'))
        (seg,) = rec.segments
        assert np.array_equal(seg.moment_nm, torque) and np.array_equal(seg.force_n, force)
        assert np.array_equal(seg.rate_radps, rate) and np.array_equal(seg.spin_radps, spin)
        if travel:
            assert np.array_equal(seg.travel_m, comp)
        inputs = INPUT_CHANNELS + RATE_CHANNELS + SPIN_CHANNELS
        assert np.array_equal(seg.signals(inputs), np.concatenate([accel, rate, spin]))
        # the model input is the spin acceleration, derived on the segment's stamps
        derived = seg.signals(SPIN_ACCEL_CHANNELS)
        inner = (spin[:, 2:] - spin[:, :-2]) / (2 * PERIOD_NS * 1e-9)
        np.testing.assert_allclose(derived[:, 1:-1], inner, rtol=1e-9)
        np.testing.assert_allclose(derived[:, 0], (spin[:, 1] - spin[:, 0]) / (PERIOD_NS * 1e-9),
                                   rtol=1e-9)
        assert np.array_equal(seg.signals(OUTPUT_CHANNELS + MOMENT_CHANNELS),
                              np.concatenate([force, torque]))


def test_recording_without_rates_names_every_topic(tmp_path, capsys):
    n = 300
    accel, force, torque, *_ = _signals(n)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    path = write_recording(tmp_path / 'b', stamp, accel, force, torque_nm=torque)
    assert available_extras(path) == ('moments',)       # fit only what is there
    # covariance[0] = -1 (REP-145 "not provided"): an error, never zeros
    with pytest.raises(BagError, match=r'angular velocity not provided .*/spindle/lf/imu '
                                       r'\(300 of 300 messages\).*/spindle/rr/imu'):
        read_recording(path, extras=('rates',))
    with pytest.raises(BagError, match=r'topic /suspension/joint_states .* not found'):
        read_recording(path, extras=('spin',))
    # a --config declaring angular-rate inputs the bag lacks: exit 1 naming the topics
    config = tmp_path / 'fit.yaml'
    config.write_text('wheel_force_fit:\n  ros__parameters:\n    inputs: ["rates"]\n')
    rc = main(['fit', str(path), '-o', str(tmp_path / 'm.npz'), '--config', str(config)])
    err = capsys.readouterr().err
    assert rc == 1 and '/spindle/lf/imu' in err and 'covariance[0] = -1' in err
    assert 'Traceback' not in err


def test_moments_evaluated_with_their_own_sn_slope():
    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments
    from wheel_force_estimator.core.fatigue import pseudo_damage
    rng = np.random.default_rng(3)
    target = rng.normal(size=(24, 2000)) * 50
    seg = EvalSegment(target, 2.0 * target, np.arange(2000, dtype=np.int64) * PERIOD_NS, 's')
    ev = evaluate_segments([seg], FS_HZ, OUTPUT_CHANNELS + MOMENT_CHANNELS, 5.0,
                           sn_slope_moment=8.0)
    # damage of a doubled load is 2**k: k = 5 for forces, 8 for moments
    np.testing.assert_allclose(ev.damage_ratio[:12], 2.0 ** 5, rtol=1e-12)
    np.testing.assert_allclose(ev.damage_ratio[12:], 2.0 ** 8, rtol=1e-12)
    np.testing.assert_allclose(ev.damage_target[12:], pseudo_damage(target[12:], 8.0),
                               rtol=1e-12)
    assert ev.to_json()['sn_slope_moment'] == 8.0


def test_force_rows_of_a_six_component_model_predict_as_in_the_whole_model():
    # what the diagnosis gets of a 24-output model: its forces, exactly (bug caught: rows of
    # the FRF, FIR, static force or live estimators taken from another output)
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from support.ros_testing import synthetic_accel
    from support.ros_testing import synthetic_model
    from wheel_force_estimator.core.model import select_outputs
    full = synthetic_model(output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS, seed=5)
    forces = select_outputs(full, OUTPUT_CHANNELS)
    x = synthetic_accel(700, seed=2)
    np.testing.assert_array_equal(predict_forces(forces, x), predict_forces(full, x)[:12])
    moments = select_outputs(full, MOMENT_CHANNELS[::-1])
    np.testing.assert_array_equal(predict_forces(moments, x), predict_forces(full, x)[:11:-1])
    with pytest.raises(ModelFileError, match='lf_fq'):
        select_outputs(full, ('lf_fq',))


def test_fit_report_names_moments_the_inputs_cannot_explain():
    # the coherence decides (bug caught: a moment without support reported as fitted)
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from support.ros_testing import synthetic_model
    from wheel_force_estimator.report.builders import moment_input_lines
    model = synthetic_model(output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS)
    coherence = dict.fromkeys(model.output_channels, 0.9)
    coherence['rf_my'] = 0.3
    lines = moment_input_lines(model, {'mean_coherence': coherence})
    assert lines[0] == 'moments fitted from: 12 accelerations'
    assert len(lines) == 2 and 'rf_my: NOT identifiable' in lines[1] and 'spin' in lines[1]
    coherence['rf_my'] = 0.9
    assert 'every moment' in moment_input_lines(model, {'mean_coherence': coherence})[1]
    assert moment_input_lines(synthetic_model(), {'mean_coherence': {}}) == []


@pytest.mark.slow
def test_cli_fit_and_evaluate_a_24_output_model(tmp_path):
    # `wheel-force fit` (shipped defaults, design search per output row) on a bag whose WFT
    # carries moments: 24 outputs found by itself, and `evaluate` scores all of them
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from known_system import known_system

    def write(path, seconds, seed):
        n = int(seconds * FS_HZ)
        x, y = known_system(n, seed)
        moment = np.zeros((12, n))       # a known linear map: other rows, 0.3 m, one sample
        moment[:, 1:] = 0.3 * (y[::-1, :-1] - 3000.0)
        write_recording(path, T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64), x, y,
                        torque_nm=moment)
    write(tmp_path / 'train', 60, 1)
    write(tmp_path / 'val', 10, 2)
    assert main(['fit', str(tmp_path / 'train'), '-o', str(tmp_path / 'm.npz')]) == 0
    model = load_model(tmp_path / 'm.npz')
    assert model.output_channels == OUTPUT_CHANNELS + MOMENT_CHANNELS
    # no rates, no spin in this bag; the splits are derived from the accelerations (auto)
    assert model.input_channels == INPUT_CHANNELS + SPLIT_CHANNELS + CORNERING_CHANNELS
    assert channel_units(model)[1] == ('N',) * 12 + ('N*m',) * 12
    assert main(['evaluate', str(tmp_path / 'm.npz'), str(tmp_path / 'val'), '--json',
                 str(tmp_path / 'e.json'), '--sn-slope-moment', '7']) == 0
    doc = json.loads((tmp_path / 'e.json').read_text())
    assert list(doc['channels']) == list(OUTPUT_CHANNELS + MOMENT_CHANNELS)
    assert doc['sn_slope_moment'] == 7.0
    # noise-free linear system: moments as good as the forces they follow (a wrong row ~100 %)
    worst = max(doc['channels'][c]['rmse_pct'] for c in MOMENT_CHANNELS)
    assert worst < 5.0, worst


def test_default_constructed_rates_are_not_inputs(tmp_path):
    """Rates all zero with a zero covariance (a tool that fills only the acceleration)."""
    n = 300
    accel, force, _, rate, *_ = _signals(n)
    stamp = T0_NS + PERIOD_NS * np.arange(n, dtype=np.int64)
    path = write_recording(tmp_path / 'zero', stamp, accel, force,
                           rate_radps=np.zeros_like(rate), rate_variance=0.0)
    # bug caught: every bag from such a tool gained 12 zero-power inputs by default
    assert available_extras(path) == ()
    live = write_recording(tmp_path / 'live', stamp, accel, force, rate_radps=rate,
                           rate_variance=0.0)
    assert available_extras(live) == ('rates',)
