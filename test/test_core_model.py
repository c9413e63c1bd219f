# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Model file: round trip, safe loading, schema and shape validation."""
import json
import pickle

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.model import save_model


def small_model(n_in=2, n_out=3, n_taps=16, fs_hz=64.0, seed=0):
    """Return a valid random model (shapes only matter here)."""
    rng = np.random.default_rng(seed)
    nf = n_taps // 2 + 1
    return FrfModel(
        fs_hz=fs_hz, input_channels=tuple(f'in{i}' for i in range(n_in)),
        output_channels=tuple(f'out{o}' for o in range(n_out)),
        f_hz=np.linspace(0, fs_hz / 2, nf),
        h=rng.normal(size=(nf, n_out, n_in)) + 1j * rng.normal(size=(nf, n_out, n_in)),
        coherence_ordinary=rng.uniform(size=(nf, n_out, n_in)),
        coherence_multiple=rng.uniform(size=(nf, n_out)), cond_sxx=rng.uniform(1, 9, nf),
        fir_taps=rng.normal(size=(n_out, n_in, n_taps)), fir_delay_samples=n_taps // 2,
        static_force_n=rng.normal(size=n_out), static_accel_mps2=rng.normal(size=n_in),
        estimator='h1', fit={'segment_length': n_taps}, created='2026-11-22T00:00:00+00:00',
        physics=({'physics': 'bump_stop', 'channels': ['out0'], 'sources': ['in0'],
                  'parameters': {'gap_m': 0.03, 'stiffness_n_per_m': 1e5, 'exponent': 2.0}},))


def _rewrite(src, dst, **changes):
    with np.load(src, allow_pickle=False) as npz:
        contents = {k: npz[k] for k in npz.files}
    for key, value in changes.items():
        if value is None:
            contents.pop(key)
        else:
            contents[key] = value
    np.savez(dst, **contents)
    return dst


def test_round_trip_is_exact(tmp_path):
    model = small_model()
    path = save_model(model, tmp_path / 'm.npz')
    back = load_model(path)
    for name in ('f_hz', 'h', 'coherence_ordinary', 'coherence_multiple', 'cond_sxx',
                 'fir_taps', 'static_force_n', 'static_accel_mps2'):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert back.input_channels == model.input_channels
    assert back.output_channels == model.output_channels
    assert back.fir_delay_samples == model.fir_delay_samples
    assert back.physics == model.physics and back.fit == model.fit
    assert back.fs_hz == model.fs_hz and back.created == model.created


def test_file_is_plain_npz_with_json_meta(tmp_path):
    path = save_model(small_model(), tmp_path / 'm')
    assert path.suffix == '.npz'
    with np.load(path, allow_pickle=False) as npz:
        meta = json.loads(str(npz['meta']))
    for key in ('schema_version', 'sample_rate_hz', 'input_channels', 'output_channels',
                'units', 'estimator', 'fit', 'created'):
        assert key in meta


def test_arrays_are_read_only():
    model = small_model()
    with pytest.raises(ValueError):
        model.h[0, 0, 0] = 1.0


def test_pickled_content_is_refused(tmp_path):
    path = save_model(small_model(), tmp_path / 'm.npz')
    evil = _rewrite(path, tmp_path / 'evil.npz',
                    fit_extra=np.array([{'a': 1}], dtype=object))
    with pytest.raises(ModelFileError, match='not a safe model file'):
        load_model(evil)


def test_plain_pickle_file_is_refused(tmp_path):
    path = tmp_path / 'pickle.npz'
    path.write_bytes(pickle.dumps({'h': 1}))
    with pytest.raises(ModelFileError, match='pickle.npz'):
        load_model(path)


def test_missing_file_and_garbage(tmp_path):
    with pytest.raises(ModelFileError, match='not found'):
        load_model(tmp_path / 'nope.npz')
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(b'PK\x03\x04 truncated')
    with pytest.raises(ModelFileError, match='bad.npz'):
        load_model(bad)


@pytest.mark.parametrize('field', ['h', 'fir_taps', 'static_force_n', 'meta'])
def test_missing_field_is_named(tmp_path, field):
    path = save_model(small_model(), tmp_path / 'm.npz')
    broken = _rewrite(path, tmp_path / 'b.npz', **{field: None})
    with pytest.raises(ModelFileError, match=f"'{field}' is missing"):
        load_model(broken)


def test_wrong_shape_is_named(tmp_path):
    path = save_model(small_model(), tmp_path / 'm.npz')
    broken = _rewrite(path, tmp_path / 'b.npz', static_force_n=np.zeros(7))
    with pytest.raises(ModelFileError, match=r"'static_force_n'.*shape \(3,\)"):
        load_model(broken)


def test_wrong_dtype_is_named(tmp_path):
    path = save_model(small_model(), tmp_path / 'm.npz')
    broken = _rewrite(path, tmp_path / 'b.npz', h=np.zeros((9, 3, 2)))
    with pytest.raises(ModelFileError, match="'h' has dtype float64"):
        load_model(broken)


def test_bad_meta(tmp_path):
    path = save_model(small_model(), tmp_path / 'm.npz')
    with np.load(path, allow_pickle=False) as npz:
        meta = json.loads(str(npz['meta']))
    broken = _rewrite(path, tmp_path / 'b1.npz', meta=np.array('{not json'))
    with pytest.raises(ModelFileError, match='not valid JSON'):
        load_model(broken)
    meta_v = dict(meta, schema_version=99)
    broken = _rewrite(path, tmp_path / 'b2.npz', meta=np.array(json.dumps(meta_v)))
    with pytest.raises(ModelFileError, match='schema_version'):
        load_model(broken)
    meta_c = dict(meta, input_channels=['a'])
    broken = _rewrite(path, tmp_path / 'b3.npz', meta=np.array(json.dumps(meta_c)))
    with pytest.raises(ModelFileError, match="'h'.*shape"):
        load_model(broken)
    meta_m = dict(meta)
    meta_m.pop('sample_rate_hz')
    broken = _rewrite(path, tmp_path / 'b4.npz', meta=np.array(json.dumps(meta_m)))
    with pytest.raises(ModelFileError, match='meta.sample_rate_hz'):
        load_model(broken)


def _term(physics='bump_stop', **changes):
    term = {'physics': physics, 'channels': ['out0'], 'sources': ['in0'],
            'parameters': {'gap_m': 0.03, 'stiffness_n_per_m': 1e5, 'exponent': 2.0}}
    term.update(changes)
    return term


@pytest.mark.parametrize('term, match', [
    # Bug caught: a range check lost in the typed parameters (negative gap loads silently).
    (_term(parameters={'gap_m': -0.03, 'stiffness_n_per_m': 1e5, 'exponent': 2.0}),
     r'term 1 \(bump_stop\): bump_stop\.gap_m must be >= 0'),
    (_term(parameters={'gap_m': 0.03, 'stiffness_n_per_m': 'stiff', 'exponent': 2.0}),
     r'term 1 \(bump_stop\): bump_stop\.stiffness_n_per_m must be a number'),
    (_term(parameters={'gap_m': 0.03}), r'term 1 \(bump_stop\).*parameters must be'),
    (_term('time_delay', parameters={'delay_s': -0.001}),
     r'term 1 \(time_delay\): time_delay\.delay_s must be >= 0'),
    (_term(channels=['out7']), r"term 1 \(bump_stop\): output channel 'out7'"),
    (_term(sources=['in9']), r"term 1 \(bump_stop\): input channel 'in9'"),
    (_term('warp_drive'), r'term 1 \(warp_drive\).*not one of'),
    (_term(force_range_n=[[5.0, -5.0]]),
     r'term 1 \(bump_stop\): bump_stop: force_range_n\[0\] least 5 N is above'),
    (_term(force_range_n=[[0.0, None]]),
     r'term 1 \(bump_stop\): bump_stop\.force_range_n\[0\]'),
])
def test_bad_physics_section_names_the_term_and_field(tmp_path, term, match):
    path = save_model(small_model(), tmp_path / 'm.npz')
    with np.load(path, allow_pickle=False) as npz:
        meta = json.loads(str(npz['meta']))
    meta['physics'] = [meta['physics'][0], term]
    broken = _rewrite(path, tmp_path / 'bad.npz', meta=np.array(json.dumps(meta)))
    with pytest.raises(ModelFileError, match=match):
        load_model(broken)


def test_old_physics_section_loads_as_typed_terms(tmp_path):
    # A section as written before the typed terms (flags as floats, no optional keys).
    old = [{'physics': 'backlash', 'channels': ['out1'], 'sources': ['in1'],
            'parameters': {'gap_m': 5e-4, 'stiffness_n_per_m': 1e4, 'hysteretic': 1.0},
            'input_quantity': 'acceleration', 'highpass_hz': 0.5, 'lowpass_hz': 0.0},
           {'physics': 'mass_error', 'channels': ['out2'], 'sources': ['in0'],
            'parameters': {'center_n': 100.0, 'gain': 0.05}, 'state': 'load',
            'state_lowpass_hz': 1.0}]
    path = save_model(small_model(), tmp_path / 'm.npz')
    with np.load(path, allow_pickle=False) as npz:
        meta = json.loads(str(npz['meta']))
    meta['physics'] = old
    model = load_model(_rewrite(path, tmp_path / 'old.npz', meta=np.array(json.dumps(meta))))
    backlash, mass = model.physics_terms
    assert backlash.params.hysteretic is True and backlash.params.gap_m == 5e-4
    assert mass.key == 'mass_error:load' and mass.params.gain == 0.05
    # Written back unchanged: the JSON format did not move.
    assert backlash.to_dict() == old[0]
    assert [t.to_dict() for t in model.physics_terms] == list(model.with_physics(
        model.physics_terms).physics)


def test_non_finite_and_bad_values_rejected():
    model = small_model()
    with pytest.raises(ModelFileError, match="'h'.*NaN"):
        FrfModel(**{**model.__dict__, 'h': np.full_like(model.h, np.nan)})
    with pytest.raises(ModelFileError, match='fir_delay_samples'):
        FrfModel(**{**model.__dict__, 'fir_delay_samples': 99})
    with pytest.raises(ModelFileError, match='sample_rate_hz'):
        FrfModel(**{**model.__dict__, 'fs_hz': -1.0})
    with pytest.raises(ModelFileError, match='Nyquist'):
        FrfModel(**{**model.__dict__, 'fs_hz': 100.0})
    with pytest.raises(ModelFileError, match='unique channel names'):
        FrfModel(**{**model.__dict__, 'input_channels': ('a', 'a')})
