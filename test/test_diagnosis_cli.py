# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""``wheel-force diagnose`` end to end: generic files and simulated bags."""
import json

import numpy as np
import pytest
from support.diagnosis_synthetic import friction_rig
from support.diagnosis_synthetic import make_recording

from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.predict import select_filter


def _write_npz(path, rec):
    np.savez(path, a=rec.inputs[0], b=rec.inputs[1], fa=rec.outputs[0], fb=rec.outputs[1])


@pytest.fixture(scope='module')
def generic_files(tmp_path_factory):
    d = tmp_path_factory.mktemp('generic')
    files = {}
    for name, effect, seed, noise in (('sim1', 'none', 1, 0.0), ('sim2', 'none', 2, 0.0),
                                      ('real1', 'damper_asymmetry', 3, 0.05),
                                      ('real2', 'damper_asymmetry', 4, 0.05),
                                      ('hold', 'damper_asymmetry', 5, 0.05)):
        rec, _ = make_recording(effect, seed, duration_s=40.0, noise=noise)
        files[name] = d / f'{name}.npz'
        _write_npz(files[name], rec)
    return files


ROLES = ['--input', 'a:acceleration:m/s^2', '--input', 'b:acceleration:m/s^2',
         '--output', 'fa:force:N', '--output', 'fb:force:N', '--fs', '256',
         '--linear', 'regression']


def test_generic_sim_diagnosis_writes_json_and_report(generic_files, tmp_path, capsys):
    f = generic_files
    out = tmp_path / 'd.json'
    rc = main(['diagnose', '--real', str(f['real1']), str(f['real2']), '--sim', str(f['sim1']),
               str(f['sim2']), '--holdout', str(f['hold']), '--json', str(out),
               '--report', str(tmp_path / 'rep')] + ROLES)
    assert rc == 0
    doc = json.loads(out.read_text())
    assert doc['findings'][0]['physics'] == 'damper_asymmetry'
    assert doc['findings'][0]['channels'] == ['fa']
    assert doc['fit']['data'] == 'holdout'
    # The static-law reference (--linear regression) is not an FRF and cannot be written:
    # the written model and `after` are built on the FIR fitted on the real data (whole, or
    # per channel).  Bug caught: a candidate built on a reference that has no FRF.
    sources = set(doc['fit'].get('rows_from', {}).values()) or {doc['fit']['model']}
    assert sources and not any(s.startswith('sim_frf') for s in sources), sources
    assert (tmp_path / 'rep' / 'report.md').is_file()
    assert list((tmp_path / 'rep').glob('regime_*.png'))
    assert 'rebound damping differ' in capsys.readouterr().out


def test_generic_without_sim_fits_linear_on_real(generic_files, tmp_path):
    f = generic_files
    out = tmp_path / 'd.json'
    rc = main(['diagnose', '--real', str(f['real1']), str(f['real2']), '--holdout',
               str(f['hold']), '--json', str(out)] + ROLES)
    assert rc == 0
    doc = json.loads(out.read_text())
    # Without --sim/--model the reference is the MIMO FIR `fit` makes on the real data (never
    # a static law), so `before` is `real_linear`.  These files hold a displacement law seen
    # through accelerations excited at 0.5-25 Hz only; since `fit` damps the unexcited lines
    # (water level) the FIR identifies it (8.0 % on fa; it was 200-6000 %, the unexcited
    # lines' gain ringing from the record's ends), and the damper asymmetry of fa is named
    # on that reference.  Whether its term is written is the held-out data's call: with the
    # live basis at 32 blocks per octave the FIR scored 8.0 % on fa and FIR + term 7.2 %;
    # at 48 blocks per octave and ridge 1e-5 (2026-11-29) the FIR alone scores 7.1 % and the
    # term no longer pays in both figures on the gate half, so the FIR is written.
    assert doc['reference'] == 'real (linear fit) (frf)'
    assert doc['fit']['real_linear'] == doc['fit']['before']
    assert doc['findings'][0]['physics'] == 'damper_asymmetry'
    assert doc['findings'][0]['channels'] == ['fa']
    for figure in ('unfiltered', 'hp1'):
        after, linear = doc['fit'][f'after_{figure}'], doc['fit'][f'real_linear_{figure}']
        assert all(after[c] <= linear[c] for c in linear), (figure, after, linear)
    assert doc['fit']['real_linear']['fa'] < 20.0


def test_records_too_short_to_hold_out_blocks_write_the_plain_fit_and_say_why(tmp_path,
                                                                              capsys):
    # Two 5 s rig records (displacement in, force out) with Coulomb friction, and a 512-sample
    # segment imposed in the params file: the finders' blocks shrink to fit, the friction is
    # named, but a quarter held out leaves no training piece one segment long.  The plain fit
    # is written, and the JSON (fit.data) and stderr say why, naming the recordings and their
    # lengths (before: "too little data to cross-validate", exit 1).
    rng = np.random.default_rng(4)
    paths = []
    for k in range(2):
        x, force = friction_rig(rng, 5.0)
        paths.append(tmp_path / f'r{k}.npz')
        np.savez(paths[-1], x=x, f=force)
    params = tmp_path / 'p.yaml'
    params.write_text('wheel_force_fit:\n  ros__parameters:\n    segment_length: 512\n')
    out = tmp_path / 'd.json'
    rc = main(['diagnose', '--real', *map(str, paths), '--json', str(out), '--out-model',
               str(tmp_path / 'm.npz'), '--config', str(params), '--input',
               'x:displacement:m', '--output', 'f:force:N', '--fs', '200'])
    assert rc == 0
    doc = json.loads(out.read_text())
    assert [f['physics'] for f in doc['findings']] == ['coulomb_friction']
    assert doc['fit']['data'] == 'too_short'
    assert doc['fit']['model'] == 'real_linear'
    err = capsys.readouterr().err
    assert 'too short to hold out blocks' in err, err
    assert 'r0.npz (5.0 s)' in err and 'r1.npz (5.0 s)' in err, err
    assert not load_model(tmp_path / 'm.npz').physics


def test_usage_errors_exit_2(generic_files, tmp_path, capsys):
    f = generic_files
    base = ['diagnose', '--real', str(f['real1']), '--json', str(tmp_path / 'x.json')]
    assert main(base + ['--input', 'a:acceleration:m/s^2']) == 2
    assert 'need --input, --output and --fs' in capsys.readouterr().err
    assert main(base) == 2
    assert '--input' in capsys.readouterr().err
    with pytest.raises(SystemExit) as err:
        main(['diagnose', '--json', 'x.json'])
    assert err.value.code == 2


def test_user_errors_exit_1(generic_files, tmp_path, capsys):
    rc = main(['diagnose', '--real', str(tmp_path / 'missing.npz'), '--json',
               str(tmp_path / 'x.json')] + ROLES)
    assert rc == 1
    assert 'missing.npz: no such file' in capsys.readouterr().err
    rc = main(['diagnose', '--real', str(generic_files['real1']), '--json',
               str(tmp_path / 'x.json'), '--input', 'a:acceleration:furlong', '--output',
               'fa:force:N', '--fs', '256'])
    assert rc == 1
    assert 'unknown acceleration unit' in capsys.readouterr().err


@pytest.mark.slow
def test_bags_from_the_simulator_and_augmented_model(tmp_path):
    from wheel_force_estimator.sim.api import simulate_pair
    paths = simulate_pair(tmp_path / 'pair', ('damper_asymmetry',), seed=3,
                          duration_scale=0.1)
    out = tmp_path / 'd.json'
    model = tmp_path / 'aug.npz'
    rc = main(['diagnose', '--real', str(paths['real']), '--sim', str(paths['sim']),
               '--holdout', str(paths['holdout']), '--json', str(out), '--out-model',
               str(model)])
    assert rc == 0
    doc = json.loads(out.read_text())
    assert doc['fit']['metric'] == 'rmse_hp1_pct'
    # The effect is named (on Fz).  Its first place is not asserted: this 1-minute pair also
    # names a left-right coupling (anti_roll_bar) that ranks first as a whole-vehicle
    # finding; the gate half of the holdout finds its term harmful, which used to drop the
    # name with --holdout only (the holdout judges models, not names: a false finding of the
    # coupling stage, now named on both paths - see issue 30's notes).
    named = {f['physics']: f['channels'] for f in doc['findings']}
    assert set(named.get('damper_asymmetry', ['none'])) <= {'lf_fz', 'rf_fz', 'lr_fz', 'rr_fz'}
    physics = load_model(model).physics
    # The written model is the one the gate half preferred; JSON and file agree on it.
    # (or rows of several, each named in rows_from, with the terms of the rows it took)
    sources = set(doc['fit'].get('rows_from', {}).values()) or {doc['fit']['model']}
    if not physics:
        assert not any(s.endswith('+physics') for s in sources)
    # a term the gate rejected is not in the written model
    rejected = {p for p in named if any(f'{p} fitted the real data but its term' in r
                                        for r in doc['rejected'])}
    assert not rejected & {p['physics'] for p in physics}, (rejected, physics)
    # Like `fit`, the written model carries live estimators (configured 50 ms first), so the
    # node runs it without cutting the offline FIR.
    written = load_model(model)
    looks = [e.look_ahead_samples for e in written.live]
    assert looks[0] == round(0.05 * written.fs_hz) and len(looks) == 5
    _, fallback = select_filter(written, looks[0])
    assert fallback is None


def _evaluated(model, bag, path):
    """Mean over all channels of ``evaluate --json``: (unfiltered, 1 Hz high-passed) RMSE %."""
    assert main(['evaluate', str(model), str(bag), '--json', str(path)]) == 0
    channels = json.loads(path.read_text())['channels'].values()
    return tuple(float(np.mean([c[k] for c in channels])) for k in ('rmse_pct', 'rmse_hp1_pct'))


@pytest.mark.slow
def test_without_holdout_the_written_model_is_no_worse_than_a_plain_fit(tmp_path, capsys):
    # Bug caught: without --holdout the simulation's FRF + terms written unconditionally,
    # worse than a plain `fit` on the real bags on every lateral channel (issue 30).  Judged
    # where the user would judge it: `evaluate` of both models on a bag neither saw, both
    # figures, mean over the 12 channels; 0.5 % is the bar for "no worse".
    from wheel_force_estimator.sim.api import simulate_pair
    paths = simulate_pair(tmp_path / 'pair', ('damper_asymmetry',), seed=7,
                          duration_scale=0.1)
    out, written, plain = tmp_path / 'd.json', tmp_path / 'w.npz', tmp_path / 'p.npz'
    assert main(['diagnose', '--real', str(paths['real']), '--sim', str(paths['sim']),
                 '--json', str(out), '--out-model', str(written)]) == 0
    assert main(['fit', str(paths['real']), '-o', str(plain)]) == 0
    capsys.readouterr()
    fit = json.loads(out.read_text())['fit']
    assert fit['data'] == 'cross_validation'
    # both figures of all three models, per channel, on the held-out blocks
    for key in ('before', 'real_linear', 'after'):
        for figure in ('unfiltered', 'hp1'):
            assert len(fit[f'{key}_{figure}']) == 12, key
    assert fit['after'] == fit['after_hp1']
    for c in fit['after']:
        assert fit['after_hp1'][c] <= fit['real_linear_hp1'][c] + 1e-9, c
        assert fit['after_unfiltered'][c] <= fit['real_linear_unfiltered'][c] + 1e-9, c
    w = _evaluated(written, paths['holdout'], tmp_path / 'w.json')
    p = _evaluated(plain, paths['holdout'], tmp_path / 'p.json')
    assert w[0] <= 1.005 * p[0] and w[1] <= 1.005 * p[1], (w, p)
