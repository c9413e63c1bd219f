# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Generic recordings (CSV / MAT / NPZ / JSON) and the real friction and MR damper datasets."""
import dataclasses
import json

import numpy as np
import pytest
import scipy.io
import scipy.signal
from support.diagnosis_synthetic import friction_rig
from support.shared_data import dataset
from support.shared_data import SHARED_DATA

from wheel_force_estimator.core.design import product_fit_config
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis.generic import load_generic
from wheel_force_estimator.diagnosis.generic import parse_spec

FRICTION = SHARED_DATA / 'friction_damper'
MR = SHARED_DATA / 'mr_damper'


def test_parse_spec():
    spec = parse_spec('data[1]:displacement:in', 'input')
    assert (spec.key, spec.column, spec.quantity, spec.unit) == ('data', 1, 'displacement', 'in')
    assert spec.scale == pytest.approx(0.0254)
    assert spec.label == 'data[1]'
    assert parse_spec('f:force:kip', 'output').scale == pytest.approx(4448.2216152605)
    assert parse_spec('acc:acceleration:g', 'input').scale == pytest.approx(9.80665)


@pytest.mark.parametrize('text, role, match', [
    ('disp:displacement', 'input', 'NAME:QUANTITY:UNIT'),
    ('disp:force:N', 'input', 'quantity must be one of'),
    ('f:displacement:m', 'output', 'quantity must be one of'),
    ('disp:displacement:furlong', 'input', 'unknown displacement unit'),
])
def test_parse_spec_errors(text, role, match):
    with pytest.raises(DiagnosisError, match=match):
        parse_spec(text, role)


def _signals(n=500):
    t = np.arange(n) / 100.0
    return np.sin(t), 3.0 * np.cos(t)


def test_csv_npz_mat_json_agree(tmp_path):
    x_mm, f_kn = _signals()
    (tmp_path / 'a.csv').write_text('time,x,force\n' + '\n'.join(
        f'{i / 100.0},{float(a)!r},{float(b)!r}' for i, (a, b) in enumerate(zip(x_mm, f_kn)))
        + '\n')
    np.savez(tmp_path / 'a.npz', x=x_mm, force=f_kn)
    scipy.io.savemat(str(tmp_path / 'a.mat'), {'xf': np.stack([x_mm, f_kn], axis=1)})
    (tmp_path / 'a.json').write_text(json.dumps({'data': np.stack([x_mm, f_kn], 1).tolist()}))
    specs = {'a.csv': ('x', 'force'), 'a.npz': ('x', 'force'), 'a.mat': ('xf[0]', 'xf[1]'),
             'a.json': ('data[0]', 'data[1]')}
    for name, (xin, fout) in specs.items():
        rec = load_generic(tmp_path / name, [parse_spec(f'{xin}:displacement:mm', 'input')],
                           [parse_spec(f'{fout}:force:kN', 'output')], 100.0)
        np.testing.assert_allclose(rec.inputs[0], x_mm * 1e-3, rtol=1e-15, err_msg=name)
        np.testing.assert_allclose(rec.outputs[0], f_kn * 1e3, rtol=1e-15, err_msg=name)
        assert rec.input_quantity == 'displacement'
        assert rec.fs_hz == 100.0


def test_csv_without_header_uses_column_numbers(tmp_path):
    (tmp_path / 'b.csv').write_text('1.0,2.0\n3.0,4.0\n')
    rec = load_generic(tmp_path / 'b.csv', [parse_spec('0:velocity:m/s', 'input')],
                       [parse_spec('1:force:N', 'output')], 10.0)
    np.testing.assert_array_equal(rec.outputs[0], [2.0, 4.0])


def test_generic_errors(tmp_path):
    x, f = _signals()
    np.savez(tmp_path / 'c.npz', x=x, force=f[:-1], bad=np.where(x > 0.5, np.nan, x),
             grid=np.zeros((3, 4, 5)))
    inp = [parse_spec('x:displacement:m', 'input')]
    out = [parse_spec('force:force:N', 'output')]
    with pytest.raises(DiagnosisError, match='differ in length'):
        load_generic(tmp_path / 'c.npz', inp, out, 100.0)
    with pytest.raises(DiagnosisError, match="no channel 'y'"):
        load_generic(tmp_path / 'c.npz', [parse_spec('y:displacement:m', 'input')], out, 100.0)
    with pytest.raises(DiagnosisError, match='non-finite value at sample'):
        load_generic(tmp_path / 'c.npz', [parse_spec('bad:displacement:m', 'input')],
                     [parse_spec('x:force:N', 'output')], 100.0)
    with pytest.raises(DiagnosisError, match='pick a column'):
        load_generic(tmp_path / 'c.npz', [parse_spec('grid:displacement:m', 'input')], out,
                     100.0)
    with pytest.raises(DiagnosisError, match='share one quantity'):
        load_generic(tmp_path / 'c.npz', inp + [parse_spec('x:velocity:m/s', 'input')], out,
                     100.0)
    with pytest.raises(DiagnosisError, match='no such file'):
        load_generic(tmp_path / 'missing.csv', inp, out, 100.0)
    (tmp_path / 'd.xlsx').write_text('1,2\n')
    with pytest.raises(DiagnosisError, match='unsupported file type'):
        load_generic(tmp_path / 'd.xlsx', inp, out, 100.0)
    (tmp_path / 'e.csv').write_text('x,force\n1,2\n3\n')
    with pytest.raises(DiagnosisError, match='line 3 has 1 fields'):
        load_generic(tmp_path / 'e.csv', inp, out, 100.0)


def test_generic_synthetic_friction_is_named(tmp_path):
    # Displacement-driven Coulomb friction plus a linear spring and noise, broadband motion:
    # without a simulation the reference is the MIMO FIR `fit` makes on the real data, and
    # only what it cannot represent may be reported.
    rng = np.random.default_rng(4)
    fs = 200.0
    recs = []
    for k in range(4):
        x, force = friction_rig(rng, 60.0, fs)
        np.savez(tmp_path / f'r{k}.npz', x=x, f=force)
        inp = [parse_spec('x:displacement:m', 'input')]
        recs.append(load_generic(tmp_path / f'r{k}.npz', inp,
                                 [parse_spec('f:force:N', 'output')], fs))
    result = diagnose(recs[:2], None, recs[2:])
    assert result.findings[0].physics == 'coulomb_friction'
    # The FIR absorbs part of the friction as equivalent damping; the term carries the rest
    # (measured 143 N of the 300 N): it must be the right sign and order of magnitude.
    assert 50.0 < result.findings[0].parameters['friction_n'] < 400.0
    # The written model (real-data FIR + friction) beats the plain fit on the report file
    # (measured 51.8 % -> 47.6 %).
    assert result.fit.model == 'real_frf+physics'
    assert result.fit.after['f'] < result.fit.real_linear['f'] - 2.0
    assert result.fit.real_linear == result.fit.before


def _friction(name):
    return load_generic(FRICTION / name, [parse_spec('data[1]:displacement:in', 'input')],
                        [parse_spec('data[2]:force:kip', 'output')], 1024.0)


#: Fit settings for the short sine tests of the real dampers: a 256-sample Welch segment (a
#: params file's ``wheel_force_fit: segment_length: 256``); the default 1024 samples are 10 s at
#: the MR damper's 100 Hz, most of its 15 s records.
SHORT = DiagnosisConfig(fit=dataclasses.replace(product_fit_config(), segment_length=256))


def _friction_sets():
    real = [_friction(n) for n in ('1Hz30lbtension0.5amplitude.json',
                                   '1Hz30lbtension1.5amplitude.json',
                                   '2Hz30lbtension0.5amplitude.json')]
    holdout = [_friction('1Hz30lbtension1amplitude.json'),
               _friction('0.5Hz30lbtension1amplitude.json')]
    return real, holdout


def test_friction_damper_against_the_real_data_fir():
    # Coble et al., Dataset-Friction-Damper-with-Backlash (CC BY-SA 4.0), 30 lb band tension.
    # The reference is the FIR `fit` makes on the real sine tests: 62.1 % on the 0.5 Hz
    # holdout file with the default design (71.6 % before `fit` damped the lines the sine
    # tests never excite).  The lost motion explains 49 % of the residual; the null uses only
    # shifts that put the 1 Hz tests out of phase (6 in the middle half of 6 periods: a
    # 7th and 8th would keep 85 % of the feature in phase and explained 27 %), so the
    # dataset's backlash is named with the default design: FIR + backlash 29.8 % against
    # 62.1 % for the plain fit.  With the short segment: 28.7 % against 74.7 %
    # (`evaluate` of each on the 0.5 Hz file).
    dataset(FRICTION.name)  # fails in CI, skips elsewhere, when absent
    real, holdout = _friction_sets()
    for config in (None, SHORT):
        result = diagnose(real, None, holdout, config or DiagnosisConfig())
        assert result.fit.real_linear == result.fit.before
        assert [f.physics for f in result.findings] == ['backlash'], result.summary
        assert result.fit.model == 'real_frf+physics'
        assert result.fit.after['data[2]'] < 0.6 * result.fit.real_linear['data[2]']


def test_mr_damper_short_records_get_a_shorter_segment_and_shorter_blocks():
    # labcontrol-data/mr-damper (MIT): 15 s at 100 Hz per run.  The default 1024-sample
    # segment gives one Welch window (an FRF that fits it exactly, coherence 1 by
    # construction), and its FIR edges leave 7.5 s: 3 blocks of 2 s for 5 folds (refused in
    # earlier versions).  Now the design halves the segment to 512 (4 windows, as `fit` does
    # for such records) and the cross-validation uses shorter blocks.  Measured, good or bad:
    # nothing is named, the plain fit is written, 93.7 % on the report half (162 % before
    # `fit` damped the lines a sine test never excites; 426 % with the 1024-sample FIR).  With
    # the short segment of `SHORT` lost motion, Coulomb friction and a rebound stop are named
    # and the written model reaches 45.7 % against 83.9 % for the plain fit: a sine test does
    # not identify an FIR between its frequencies, and the yield force of an MR damper is
    # friction-like.  As the CLI runs it (segment chosen by cross-validation): the folds
    # cannot fit 512 samples, so the longest length they can, 256, is the default to beat
    # (128 does not beat it fold by fold), and the same findings follow.
    dataset(MR.name)  # fails in CI, skips elsewhere, when absent

    def load(name):
        return load_generic(MR / name, [parse_spec('x_F[0]:displacement:mm', 'input')],
                            [parse_spec('x_F[2]:force:N', 'output')], 100.0)
    real = [load('data_simulation_4.2_MRdamper.mat')]
    hold = [load('data_simulation_4.4_MRdamper.mat')]
    result = diagnose(real, None, hold)
    assert result.baseline.model.fit['segment_length'] == 512
    assert result.fit.real_linear == result.fit.before
    # as measured (the comment above): nothing named, so the plain fit is the written model
    assert result.findings == (), result.summary
    assert result.fit.model == 'real_linear'
    assert result.fit.after == result.fit.real_linear
    for config in (SHORT, DiagnosisConfig(choose_resolution=True)):
        result = diagnose(real, None, hold, config)
        assert result.baseline.model.fit['segment_length'] == 256
        assert result.fit.real_linear == result.fit.before
        assert result.fit.model == 'real_frf+physics'
        assert result.fit.after['x_F[2]'] < 0.8 * result.fit.real_linear['x_F[2]']


def _sine_rig(name, f_hz, amp_m, seconds, seed, backlash=False, fs_hz=1024.0):
    """Return a displacement-driven rig's sine test: F = k x + c v + m a (+ lost motion)."""
    from wheel_force_estimator.core import physics as ph
    from wheel_force_estimator.diagnosis.recording import MotionRecording
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * f_hz
    t = np.arange(int(seconds * fs_hz)) / fs_hz
    x = amp_m * np.sin(w * t)
    force = 2.0e4 * x + 800.0 * amp_m * w * np.cos(w * t) - 5.0 * w * w * x
    if backlash:
        force = force + ph.backlash_force(np.clip(x, -0.002, 0.002), 1.5e4)
    force = force + 0.02 * force.std() * rng.standard_normal(t.size)
    measured = x + 1e-3 * amp_m * rng.standard_normal(t.size)
    return MotionRecording(name, fs_hz, measured[None], force[None], ('x',), ('f',),
                           input_quantity='displacement')


def _sine_tests(seconds, backlash):
    """Return (real, None, holdout) as the friction damper's tests: 1 Hz x2 and 2 Hz; 1, 0.5 Hz."""
    real = [_sine_rig('r1', 1.0, 0.005, seconds, 1, backlash),
            _sine_rig('r2', 1.0, 0.015, seconds, 2, backlash),
            _sine_rig('r3', 2.0, 0.005, seconds / 2, 3, backlash)]
    hold = [_sine_rig('h1', 1.0, 0.01, seconds, 4, backlash),
            _sine_rig('h2', 0.5, 0.01, 2 * seconds, 5, backlash)]
    return real, None, hold


@pytest.mark.parametrize('backlash', [False, True])
def test_sine_tests_of_a_rig_name_lost_motion_only_when_it_is_there(backlash):
    # Sine tests as the friction damper's (1 Hz at two amplitudes and 2 Hz decide nothing;
    # holdout 1 Hz decides, 0.5 Hz reports).  A sine test's features repeat every period, so
    # the shifted-feature null must not shift them by whole periods (where a null explains as
    # much as the aligned feature) nor be so weak that the FIR's linear misfit passes as a
    # time delay (it explains 51 % of the linear rig's residual; the nulls 44-60 %).
    result = diagnose(*_sine_tests(7.0, backlash))
    if not backlash:
        assert not result.findings
        assert result.fit.model == 'real_linear'
        return
    assert [f.physics for f in result.findings] == ['backlash']
    assert result.fit.model == 'real_frf+physics'
    # Measured 11.9 -> 8.8 % on the 0.5 Hz report file.
    assert result.fit.after['f'] < 0.85 * result.fit.real_linear['f']


@pytest.mark.parametrize('backlash', [False, True])
def test_longer_sine_tests_give_the_untested_frequency_a_response(backlash):
    # The same rig and frequencies with 20 s records: long enough for the 8192-sample
    # segment (0.125 Hz lines), so every line but the tested ones is under the water level.
    # Damped to zero there, the plain fit had no response at the 0.5 Hz report file: 94.4 %
    # (linear) / 94.2 % (lost motion), and the written FIR + backlash 105 %.  Bridged from
    # the tested lines (core.frf.bridge_unexcited): measured 5.9 % and 9.2 %, the backlash
    # written at 5.2 %, and still nothing named on the linear rig.
    result = diagnose(*_sine_tests(20.0, backlash))
    assert result.baseline.model.fit['long_segment_length'] == 8192
    assert result.fit.real_linear['f'] < 12.0
    if not backlash:
        assert not result.findings
        assert result.fit.model == 'real_linear'
        return
    assert [f.physics for f in result.findings] == ['backlash']
    assert result.fit.after['f'] < 0.8 * result.fit.real_linear['f']


def _structure(name, seconds, seed, fs_hz=512.0):
    """Base-excited 8 Hz mode, 5 % damping: base acceleration in, base force out (linear)."""
    from wheel_force_estimator.diagnosis.recording import MotionRecording
    rng = np.random.default_rng(seed)
    n = int(seconds * fs_hz)
    b, a = scipy.signal.butter(4, [1.0 / (fs_hz / 2), 40.0 / (fs_hz / 2)], 'bandpass')
    accel = scipy.signal.lfilter(b, a, rng.standard_normal(n))
    wn, zeta, mass_kg = 2 * np.pi * 8.0, 0.05, 100.0
    mode = scipy.signal.lti([mass_kg * 2 * zeta * wn, mass_kg * wn ** 2],
                            [1.0, 2 * zeta * wn, wn ** 2])
    force = scipy.signal.lsim(mode, accel, np.arange(n) / fs_hz)[1]
    force = force + 0.02 * force.std() * rng.standard_normal(n)
    return MotionRecording(name, fs_hz, accel[None], force[None], ('a',), ('f',))


def test_a_lightly_damped_structure_gets_its_resolution_and_no_finding():
    # The resonance (0.8 Hz half-power band) is narrower than the paper's 0.5 Hz grid: the
    # real-data FIR then misses by ~22 % and its residual is all resolution bias, which no
    # physics term may claim.  With the segment chosen by cross-validation (as the CLI does
    # for generic records) the same recordings give the FIR its resolution: measured 22.7 ->
    # 7.8 % on the report half (2.7 % on the whole held-out run; the rest is the FIR's start
    # transient on a 30 s half), and still nothing is named.
    real = [_structure('r1', 60, 1), _structure('r2', 60, 2)]
    hold = [_structure('h', 60, 3)]
    paper = diagnose(real, None, hold)
    chosen = diagnose(real, None, hold, DiagnosisConfig(choose_resolution=True))
    for result in (paper, chosen):
        assert not result.findings
        assert result.fit.model == 'real_linear'
        assert result.fit.after == result.fit.real_linear
    # The real-data linear model is fitted with `fit`'s cross-validated design either way
    # (issue 29), whose least-squares FIR and segment grid resolve the mode: both runs are
    # below half the unresolved paper FIR's 22.7 % (measured before the design search).
    assert chosen.fit.real_linear['f'] < 0.5 * 22.7
    assert paper.fit.real_linear['f'] < 0.5 * 22.7
