# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force fleet`` on a real Dask LocalCluster of 2 worker processes, on real rosbag2 files.

One cluster is shared by the module (started once: a loaded 2-core machine needs seconds per
start); the CLI joins it with ``--scheduler``.  One test starts its own cluster through
``--workers 2``.  Bags are 20 s of a known 12x12 system at 512 Hz (fast to write and fit).
"""
import json
import os
from pathlib import Path
import shutil
import time

from known_system import known_system
import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import read_wrench_topics
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.fleet import run_fleet
from wheel_force_estimator.fleet.task import process_bag

distributed = pytest.importorskip('distributed')

FS_HZ = 512.0
T0_NS = 1_750_000_000 * 10**9
CHANNELS = ('lf_fx', 'lf_fy', 'lf_fz', 'rf_fx', 'rf_fy', 'rf_fz',
            'lr_fx', 'lr_fy', 'lr_fz', 'rr_fx', 'rr_fy', 'rr_fz')
pytestmark = pytest.mark.timeout(600)


def write_bag(path, seconds, seed, storage='mcap', wft=True, road_gain=1.0, fs_hz=FS_HZ,
              events=()):
    n = int(seconds * fs_hz)
    x, y = known_system(n, seed, road_gain)
    stamps = T0_NS + np.round(np.arange(n) * 1e9 / fs_hz).astype(np.int64)
    write_recording(path, stamps, x, y if wft else None, storage=storage, events=events)
    return path


class _Cluster:
    def __init__(self, client):
        self.scheduler_address = client.scheduler.address


@pytest.fixture(scope='module')
def cluster():
    # the LocalCluster `fleet --workers 2` starts (allowed failures, one bag per worker, ...)
    from wheel_force_estimator.fleet.engine import dask_client
    with dask_client(None, 2) as client:
        yield _Cluster(client)


@pytest.fixture(scope='module')
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp('fleet')
    # The paper's plain H1 model, written by save_model: the fleet is judged against
    # `predict` / `evaluate` of the same model file, whatever its design (a `fit` of the bag
    # with its design search cost the fast tier ~50 s here; `fit`'s models are predicted by
    # the same code path in test_cli_offline).
    x, y = known_system(int(60 * FS_HZ), 1)
    save_model(fit_model([TrainingSegment(x, y, 'train')], FS_HZ, FitConfig(),
                         INPUT_CHANNELS, OUTPUT_CHANNELS), d / 'model.npz')
    fleet = d / 'fleet'
    half = T0_NS + int(10 * 1e9)
    write_bag(fleet / 'car_01' / 'run_1', 20, 11, 'mcap',
              events=[(T0_NS, 'cobblestone'), (half, 'braking')])
    write_bag(fleet / 'car_01' / 'run_2', 20, 12, 'sqlite3')
    write_bag(fleet / 'car_02' / 'run_1', 20, 13, 'mcap', road_gain=1.5)
    write_bag(fleet / 'car_03' / 'no_wft', 20, 14, 'mcap', wft=False, road_gain=0.7)
    write_bag(fleet / 'car_04' / 'sqlite_no_wft', 20, 15, 'sqlite3', wft=False)
    return d


def _fleet_json(out):
    return json.loads((Path(out) / 'fleet.json').read_text())


def test_fleet_equals_serial_evaluate_and_predict(cluster, data, tmp_path, capsys):
    """Bug caught: fleet damage / RMSE / forces drifting from what evaluate and predict give."""
    out = tmp_path / 'out'
    rc = main(['fleet', str(data / 'model.npz'), str(data / 'fleet'), '--out', str(out),
               '--scheduler', cluster.scheduler_address, '--write-forces'])
    assert rc == 0, capsys.readouterr().err
    doc = _fleet_json(out)
    rows = {Path(r['path']).relative_to(data / 'fleet').as_posix(): r for r in doc['bags']}
    assert sorted(rows) == ['car_01/run_1', 'car_01/run_2', 'car_02/run_1', 'car_03/no_wft',
                            'car_04/sqlite_no_wft']
    assert all(r['status'] == 'ok' and r['error'] is None for r in rows.values())
    assert rows['car_01/run_1']['events'] == ['cobblestone', 'braking']
    for bag_id, row in rows.items():
        bag = data / 'fleet' / bag_id
        assert row['bag_id'] == bag_id
        assert row['duration_s'] == pytest.approx(20.0)
        if 'no_wft' in bag_id:
            # serial predict, then the damage of the force bag it wrote
            pred = tmp_path / f'pred_{bag_id.replace("/", "_")}'
            assert main(['predict', str(data / 'model.npz'), str(bag), '-o', str(pred)]) == 0
            ref = _forces(pred)
            expected = dict(zip(CHANNELS, pseudo_damage(ref, 5.0)))
            assert row['rmse_pct'] is None
        else:
            js = tmp_path / f'eval_{bag_id.replace("/", "_")}.json'
            assert main(['evaluate', str(data / 'model.npz'), str(bag), '--json',
                         str(js)]) == 0
            ev = json.loads(js.read_text())
            expected = {c: ev['channels'][c]['damage_prediction'] for c in CHANNELS}
            assert row['rmse_pct'] == {c: ev['channels'][c]['rmse_pct'] for c in CHANNELS}
            assert row['relative_damage_spectrum'] == ev['relative_damage_spectrum'][
                'prediction']
            pred = tmp_path / f'pred_{bag_id.replace("/", "_")}'
            assert main(['predict', str(data / 'model.npz'), str(bag), '-o', str(pred)]) == 0
            ref = _forces(pred)
        if 'no_wft' in bag_id:
            np.testing.assert_allclose([row['damage'][c] for c in CHANNELS],
                                       [expected[c] for c in CHANNELS], rtol=1e-12)
        else:
            assert row['damage'] == expected  # the very numbers evaluate prints
        for c in CHANNELS:
            assert row['damage_per_hour'][c] == pytest.approx(row['damage'][c] * 180.0,
                                                              rel=1e-12)
        # --write-forces wrote what predict writes
        np.testing.assert_array_equal(_forces(out / 'forces' / bag_id), ref)
    # a rougher road does more damage per hour on every channel
    for c in CHANNELS:
        assert (rows['car_02/run_1']['damage_per_hour'][c]
                > rows['car_03/no_wft']['damage_per_hour'][c])
    rates = np.array([[r['damage_per_hour'][c] for c in CHANNELS] for r in rows.values()])
    for p in ('50', '90', '95', '99'):
        np.testing.assert_allclose([doc['percentiles'][p][c] for c in CHANNELS],
                                   np.percentile(rates, float(p), axis=0), rtol=1e-12)
    csv_lines = (out / 'fleet.csv').read_text().splitlines()
    assert len(csv_lines) == 1 + 5 and csv_lines[0].startswith('path,bag_id,duration_s,status')
    # a forces bag deleted since is written again; the other bags come from --out
    shutil.rmtree(out / 'forces' / 'car_02' / 'run_1')
    again = run_fleet(data / 'model.npz', [data / 'fleet'], out, write_forces=True,
                      scheduler=cluster.scheduler_address)
    assert (again.n_cached, again.n_computed) == (4, 1)
    assert (out / 'forces' / 'car_02' / 'run_1' / 'metadata.yaml').is_file()
    assert (out / 'fleet.csv').read_text().splitlines() == csv_lines


def _forces(bag):
    _, force_n = read_wrench_topics(bag, TopicConfig().output_topics)
    return force_n


@pytest.mark.slow
def test_corrupt_bags_and_wrong_rate_fail_alone_on_a_local_cluster(data, tmp_path, capsys):
    """Bug caught: one bad bag aborting the run, or a failure without a reason or exit 1."""
    bad = tmp_path / 'fleet'
    write_bag(bad / 'good_a', 20, 21)
    write_bag(bad / 'good_b', 20, 22, wft=False)
    truncated = write_bag(bad / 'truncated', 20, 23)
    mcap = next(truncated.glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:mcap.stat().st_size // 2])
    (bad / 'garbage.bag').write_bytes(b'this is not a ROS 1 bag')
    write_bag(bad / 'slow_rate', 20, 24, fs_hz=256.0)
    out = tmp_path / 'out'
    rc = main(['fleet', str(data / 'model.npz'), str(bad), '--out', str(out), '--workers',
               '2', '--reference', str(data / 'fleet' / 'car_01' / 'run_1'), '--report',
               str(tmp_path / 'report')])
    err = capsys.readouterr().err
    assert rc == 1
    assert '3 of 6 bag(s) failed' in err
    rows = {r['bag_id']: r for r in _fleet_json(out)['bags']}
    assert {k: r['status'] for k, r in rows.items()} == {
        'garbage.bag': 'failed', 'good_a': 'ok', 'good_b': 'ok', 'slow_rate': 'failed',
        'truncated': 'failed'}
    assert 'garbage.bag' in rows['garbage.bag']['error']
    assert 'truncated' in rows['truncated']['error']
    assert '256' in rows['slow_rate']['error'] and '512' in rows['slow_rate']['error']
    csv_text = (out / 'fleet.csv').read_text()
    assert csv_text.count(',failed,') == 3 and csv_text.count(',ok,') == 2
    doc = _fleet_json(out)
    assert doc['n_ok'] == 2 and doc['n_failed'] == 3
    # the reference finished: repeats = P-th percentile rate x target hours / one pass
    ref = doc['reference']
    for c in CHANNELS:
        assert ref['repeats_for_target']['95'][c] == pytest.approx(
            doc['percentiles']['95'][c] * 6000.0 / ref['damage'][c], rel=1e-12)
    for png in ('damage_rate_distribution.png', 'relative_damage_spectrum_fleet.png'):
        assert (tmp_path / 'report' / png).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'failed' in (tmp_path / 'report' / 'report.md').read_text()


@pytest.mark.slow
def test_interrupted_run_resumes_to_the_uninterrupted_table(cluster, data, tmp_path):
    """Bug caught: a resumed run recomputing finished bags or ending with another table."""
    model = data / 'model.npz'
    paths = [data / 'fleet']
    full = run_fleet(model, paths, tmp_path / 'full', scheduler=cluster.scheduler_address)
    assert full.n_computed == 5 and not full.failed

    seen = []

    def interrupt(result, n_done, n_total):
        seen.append(result.bag_id)
        if len(seen) == 2:
            raise KeyboardInterrupt
    out = tmp_path / 'resumed'
    with pytest.raises(KeyboardInterrupt):
        run_fleet(model, paths, out, scheduler=cluster.scheduler_address,
                  on_result=interrupt)
    assert not (out / 'fleet.csv').exists() and not (out / 'fleet.json').exists()
    assert len(list((out / 'results').glob('*.json'))) == 2
    # the cancelled tasks are gone from the cluster
    client = distributed.Client(cluster.scheduler_address)
    try:
        deadline = time.monotonic() + 60
        while any(k.startswith('fleet-') for k in client.who_has()) and \
                time.monotonic() < deadline:
            time.sleep(0.2)
    finally:
        client.close()
    resumed = run_fleet(model, paths, out, scheduler=cluster.scheduler_address)
    assert (resumed.n_cached, resumed.n_computed) == (2, 3)
    assert (out / 'fleet.csv').read_text() == (tmp_path / 'full' / 'fleet.csv').read_text()
    assert _fleet_json(out)['bags'] == _fleet_json(tmp_path / 'full')['bags']
    # a changed bag (new mtime) is processed again, the others are taken from --out
    bag = data / 'fleet' / 'car_02' / 'run_1' / 'metadata.yaml'
    os.utime(bag, ns=(bag.stat().st_atime_ns, bag.stat().st_mtime_ns + 10**9))
    again = run_fleet(model, paths, out, scheduler=cluster.scheduler_address)
    assert (again.n_cached, again.n_computed) == (4, 1)
    # another S-N slope is another result
    other = run_fleet(model, paths, out, scheduler=cluster.scheduler_address, sn_slope=3.0)
    assert (other.n_cached, other.n_computed) == (0, 5)


@pytest.mark.slow
def test_a_bag_that_kills_two_workers_is_failed_and_the_rest_finish(
        cluster, data, tmp_path):
    """Bug caught: a crashing bag retried forever, aborting the run, or taking others down."""
    def crash_on_run_2(ref, settings):
        if ref.bag_id == 'car_01/run_2':
            os._exit(3)  # like a segfault or the OOM killer: the worker process is gone
        return process_bag(ref, settings)

    outcome = run_fleet(data / 'model.npz', [data / 'fleet'], tmp_path / 'out',
                        scheduler=cluster.scheduler_address, task=crash_on_run_2)
    status = {r.bag_id: r.status for r in outcome.results}
    assert status.pop('car_01/run_2') == 'failed'
    assert set(status.values()) == {'ok'} and len(status) == 4
    (row,) = outcome.failed
    assert 'killed 2 worker processes' in row.error


def test_unreachable_scheduler_exits_1_quickly_naming_it(data, tmp_path, capsys):
    """Bug caught: hanging on a wrong address, or a traceback instead of a message."""
    t0 = time.monotonic()
    rc = main(['fleet', str(data / 'model.npz'), str(data / 'fleet'), '--out',
               str(tmp_path / 'out'), '--scheduler', 'tcp://127.0.0.1:9'])
    elapsed = time.monotonic() - t0
    err = capsys.readouterr().err
    assert rc == 1 and elapsed < 10.0
    assert 'tcp://127.0.0.1:9' in err and 'Traceback' not in err
    assert not (tmp_path / 'out' / 'fleet.csv').exists()


def test_path_without_bags_exits_1_naming_it(data, tmp_path, capsys):
    """Bug caught: an empty or mistyped PATH silently giving an empty table."""
    empty = tmp_path / 'empty'
    (empty / 'sub').mkdir(parents=True)
    rc = main(['fleet', str(data / 'model.npz'), str(data / 'fleet'), str(empty), '--out',
               str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert rc == 1 and f'{empty}: no bags found' in err
    assert not (tmp_path / 'out' / 'fleet.csv').exists()
