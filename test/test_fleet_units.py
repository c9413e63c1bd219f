# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Fleet pieces without a cluster: bag discovery, result store, statistics, tables, report."""
import json
import os

import numpy as np
import pytest

from wheel_force_estimator.core.evaluation import damage_figures
from wheel_force_estimator.core.fatigue import damage_bands_hz
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.fatigue import relative_damage_spectrum
from wheel_force_estimator.fleet.discover import bag_signature
from wheel_force_estimator.fleet.discover import BagRef
from wheel_force_estimator.fleet.discover import find_bags
from wheel_force_estimator.fleet.errors import FleetError
from wheel_force_estimator.fleet.result import BagResult
from wheel_force_estimator.fleet.result import failed
from wheel_force_estimator.fleet.store import atomic_write_text
from wheel_force_estimator.fleet.store import ResultStore
from wheel_force_estimator.fleet.summary import fleet_csv
from wheel_force_estimator.fleet.summary import fleet_document
from wheel_force_estimator.fleet.summary import percentiles
from wheel_force_estimator.fleet.summary import Reference
from wheel_force_estimator.fleet.summary import repeats_for_target
from wheel_force_estimator.fleet.task import FleetSettings

BANDS = ((0.0, 2.2), (1.8, 4.4))


def _rosbag2(path):
    path.mkdir(parents=True)
    (path / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    (path / f'{path.name}_0.mcap').write_bytes(b'x' * 10)
    return path


def _ok(bag_id, rates, duration_s=1800.0, rds=None):
    damage = {c: r * duration_s / 3600.0 for c, r in rates.items()}
    return BagResult(path=f'/fleet/{bag_id}', bag_id=bag_id, status='ok',
                     duration_s=duration_s, damage=damage, damage_per_hour=dict(rates),
                     rds=rds or {c: (1.0, 3.0) for c in rates}, bands_hz=BANDS)


def test_find_bags_walks_directories_but_not_into_bags_nor_the_output(tmp_path):
    """Bug caught: an .mcap inside a rosbag2 directory or a predicted bag taken as a car."""
    root = tmp_path / 'fleet'
    _rosbag2(root / 'car_1' / 'run_1')
    _rosbag2(root / 'car_1' / 'run_1' / 'nested')  # inside a bag: part of it, not a bag
    _rosbag2(root / 'car_2' / 'run_1')
    (root / 'car_3').mkdir()
    (root / 'car_3' / 'old.bag').write_bytes(b'')
    (root / 'car_3' / 'notes.txt').write_text('')
    _rosbag2(root / 'out' / 'forces' / 'car_1' / 'run_1')
    refs = find_bags([root], exclude=[root / 'out'])
    assert [r.bag_id for r in refs] == ['car_1/run_1', 'car_2/run_1', 'car_3/old.bag']
    # a PATH that is a bag is listed under its own name; a bag reached twice is listed once
    refs = find_bags([root / 'car_2' / 'run_1', root / 'car_2'])
    assert [(r.bag_id, r.path) for r in refs] == [('run_1', str(root / 'car_2' / 'run_1'))]


def test_find_bags_names_a_path_without_bags(tmp_path):
    """Bug caught: an empty directory or a typo giving an empty fleet instead of an error."""
    (tmp_path / 'empty' / 'sub').mkdir(parents=True)
    with pytest.raises(FleetError, match=r'empty: no bags found'):
        find_bags([tmp_path / 'empty'])
    with pytest.raises(FleetError, match=r'missing: no such file or directory'):
        find_bags([tmp_path / 'missing'])


def test_same_relative_name_under_two_paths_gets_the_full_path_as_id(tmp_path):
    """Bug caught: two cars' run_1 sharing one id (and one forces/ output)."""
    a = _rosbag2(tmp_path / 'a' / 'run_1')
    b = _rosbag2(tmp_path / 'b' / 'run_1')
    refs = find_bags([tmp_path / 'a', tmp_path / 'b'])
    assert sorted(r.bag_id for r in refs) == sorted([str(a), str(b)])


def test_bag_signature_follows_every_file_of_a_rosbag2_directory(tmp_path):
    """Bug caught: a bag re-recorded in place (same dir mtime) keeping its old result."""
    bag = _rosbag2(tmp_path / 'run')
    size, mtime = bag_signature(bag)
    assert size == len('rosbag2_bagfile_information: {}\n') + 10
    data = bag / 'run_0.mcap'
    os.utime(data, ns=(mtime + 5 * 10**9, mtime + 5 * 10**9))
    assert bag_signature(bag) == (size, mtime + 5 * 10**9)


def test_store_keys_results_by_bag_and_settings(tmp_path):
    """Bug caught: a result reused after the model, the S-N slope or the bag changed."""
    bag = _rosbag2(tmp_path / 'run')
    ref = BagRef(str(bag), 'run')
    settings = FleetSettings('/m.npz', 'aa', 5.0)
    store = ResultStore(tmp_path / 'out', settings.key())
    key = store.key(ref)
    assert store.get(key) is None
    result = _ok('run', {'lf_fz': 2.0})
    store.put(key, result)
    assert store.get(key) == result
    for other in (FleetSettings('/m.npz', 'bb', 5.0), FleetSettings('/m.npz', 'aa', 3.0),
                  FleetSettings('/m.npz', 'aa', 5.0, forces_dir='/out/forces')):
        assert ResultStore(tmp_path / 'out', other.key()).key(ref) != key
    (bag / 'run_0.mcap').write_bytes(b'y' * 11)
    assert store.key(ref) != key
    # failed results are not kept (a rerun retries them); a damaged entry is not trusted
    store.put('k2', failed('/x', 'x', 'boom'))
    assert store.get('k2') is None
    (tmp_path / 'out' / 'results' / 'k3.json').write_text('{"path": ')
    assert store.get('k3') is None


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    """Bug caught: a crash while writing leaving a truncated fleet.csv or a temp file."""
    target = atomic_write_text(tmp_path / 'fleet.csv', 'old\n')
    with pytest.raises(TypeError):
        atomic_write_text(target, None)
    assert target.read_text() == 'old\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['fleet.csv']


def test_result_round_trip_and_validation():
    """Bug caught: a stored result read back differently (the resume would change the table)."""
    r = _ok('car/run', {'lf_fx': 1.5, 'lf_fy': 2.5})
    r = BagResult(**{**r.__dict__, 'events': ('cobblestone',), 'rmse_pct': {'lf_fx': 12.0},
                     'rmse_hp1_pct': {'lf_fx': 10.0}})
    assert BagResult.from_dict(json.loads(json.dumps(r.to_dict()))) == r
    with pytest.raises(ValueError, match='needs an error'):
        BagResult(path='p', bag_id='p', status='failed')
    with pytest.raises(ValueError, match='status'):
        BagResult(path='p', bag_id='p', status='done')


def test_percentiles_and_repeats_by_hand():
    """Bug caught: percentiles over damage instead of damage per hour; a wrong repeat formula."""
    results = [_ok(f'b{i}', {'lf_fz': rate}, duration_s=600.0 * i)
               for i, rate in enumerate([1.0, 2.0, 3.0, 4.0], start=1)]
    results.append(failed('/bad', 'bad', 'corrupt'))
    pct = percentiles(results)
    assert pct['50']['lf_fz'] == pytest.approx(2.5)   # (2 + 3) / 2
    assert pct['90']['lf_fz'] == pytest.approx(3.7)   # 3 + 0.7 (4 - 3)
    assert pct['99']['lf_fz'] == pytest.approx(3.97)
    # reference: one pass does damage 0.5 (two bags 0.2 + 0.3); target 100 h
    ref = Reference((_ok('pg1', {'lf_fz': 0.4}), _ok('pg2', {'lf_fz': 0.6})), 100.0)
    assert ref.damage == {'lf_fz': pytest.approx(0.5)}
    reps = repeats_for_target(pct, ref)
    assert reps['50']['lf_fz'] == pytest.approx(2.5 * 100.0 / 0.5)
    zero = Reference((_ok('pg', {'lf_fz': 0.0}),), 100.0)
    assert repeats_for_target(pct, zero)['95']['lf_fz'] is None
    assert percentiles([failed('/bad', 'bad', 'corrupt')]) is None
    with pytest.raises(ValueError, match='every bag ok'):
        Reference((failed('/bad', 'bad', 'x'),), 100.0)


def test_document_pools_relative_damage_spectra_and_csv_leaves_failed_rows_empty():
    """Bug caught: failed bags counted in the fleet spectrum, or figures in a failed row."""
    results = [_ok('a', {'lf_fz': 1.0}, rds={'lf_fz': (1.0, 3.0)}),
               _ok('b', {'lf_fz': 2.0}, rds={'lf_fz': (3.0, 1.0)}),
               failed('/c', 'c', 'bad, "quoted" reason')]
    doc = fleet_document(results, None, 5.0, 'car.npz')
    assert doc['relative_damage_spectrum']['damage']['lf_fz'] == [4.0, 4.0]
    assert doc['relative_damage_spectrum']['fraction']['lf_fz'] == [0.5, 0.5]
    assert (doc['n_ok'], doc['n_failed'], doc['reference']) == (2, 1, None)
    assert [b['status'] for b in doc['bags']] == ['ok', 'ok', 'failed']
    lines = fleet_csv(results, ['lf_fz']).splitlines()
    assert lines[0] == 'path,bag_id,duration_s,status,error,damage_lf_fz,damage_per_hour_lf_fz'
    assert lines[1] == '/fleet/a,a,1800.0,ok,,0.5,1.0'
    assert lines[3] == '/c,c,,failed,"bad, ""quoted"" reason",,'


def test_damage_figures_is_evaluates_rule_per_segment():
    """Bug caught: segments joined before rainflow counting (a join is not a reversal)."""
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 3000)), rng.normal(size=(2, 2000)) + 5.0
    bands = damage_bands_hz(512.0)
    damage, rds = damage_figures([a, b], 512.0, 5.0, bands)
    np.testing.assert_allclose(damage, pseudo_damage(a) + pseudo_damage(b), rtol=1e-14)
    assert not np.allclose(damage, pseudo_damage(np.concatenate([a, b], axis=1)))
    np.testing.assert_allclose(rds, relative_damage_spectrum(a, 512.0, bands_hz=bands)
                               + relative_damage_spectrum(b, 512.0, bands_hz=bands),
                               rtol=1e-14)


def test_report_writes_plots_and_a_readable_table(tmp_path):
    """Bug caught: the report failing on a fleet with a failed bag or a reference."""
    from wheel_force_estimator.fleet.run import FleetOutcome
    from wheel_force_estimator.report.fleet import fleet_text
    from wheel_force_estimator.report.fleet import write_fleet_report
    channels = ('lf_fx', 'lf_fz')
    results = tuple(_ok(f'car_{i}', {c: float(i + j) for j, c in enumerate(channels)})
                    for i in range(1, 6)) + (failed('/x', 'car_9', 'corrupt bag'),)
    ref = Reference((_ok('pg', dict.fromkeys(channels, 2.0)),), 10.0)
    doc = fleet_document(results, ref, 5.0, 'car.npz')
    outcome = FleetOutcome(results, ref.results, ref, doc, 0, 7, tmp_path / 'a.csv',
                           tmp_path / 'a.json')
    text = fleet_text(outcome)
    # car_5 has the highest rates on both channels: ranked first
    ranked = [line.split()[1] for line in text.splitlines() if line.strip()[:1].isdigit()]
    assert ranked[:5] == ['car_5', 'car_4', 'car_3', 'car_2', 'car_1']
    assert 'failed: corrupt bag' in text
    report = write_fleet_report(tmp_path / 'rep', outcome)
    md = report.read_text()
    assert 'damage_rate_distribution.png' in md and 'P95 repeats' in md
    for png in ('damage_rate_distribution.png', 'relative_damage_spectrum_fleet.png'):
        assert (tmp_path / 'rep' / png).read_bytes()[:4] == b'\x89PNG'


def test_cli_usage_errors_exit_2(tmp_path, capsys):
    """Bug caught: options that do not fit together silently ignored."""
    from wheel_force_estimator.cli.main import main
    bag = _rosbag2(tmp_path / 'run')
    base = ['fleet', str(tmp_path / 'm.npz'), str(bag), '--out', str(tmp_path / 'out')]
    for extra, message in ((['--target-hours', '10'], '--target-hours needs --reference'),
                           (['--workers', '2', '--scheduler', 'tcp://h:1'], 'own workers'),
                           (['--workers', '0'], '--workers must be >= 1'),
                           (['--sn-slope', '-1'], '--sn-slope must be')):
        assert main(base + extra) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


def test_cli_module_imports_dask_lazily():
    """Bug caught: `wheel-force --help` paying for (or failing on) the Dask import."""
    import subprocess
    import sys
    code = ('import sys, wheel_force_estimator.cli.main as m; m.build_parser(); '
            'print("distributed" in sys.modules, "dask" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout
    assert out.split() == ['False', 'False']
