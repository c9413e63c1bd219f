# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Motion findings: clipped sensors and tyres in the air, from the recordings themselves."""
import json

import numpy as np
import pytest
from scipy import stats

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis.clipping import clip_test
from wheel_force_estimator.diagnosis.features import pairing
from wheel_force_estimator.diagnosis.finders.motion import motion_findings
from wheel_force_estimator.diagnosis.finders.motion import supporting_mass
from wheel_force_estimator.diagnosis.finders.reconcile import merge_motion
from wheel_force_estimator.diagnosis.recording import MotionRecording
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.sim.api import simulate

SOURCES, _ = pairing(OUTPUT_CHANNELS, INPUT_CHANNELS)
#: Rough course where the rear wheels leave the ground (0.1-0.2 % of the samples).
ROUGH = [('pothole', 20.0), ('speed_bump', 10.0)]


def _rec(result, name):
    return MotionRecording(name, result.fs_hz, result.accel_mps2, result.force_n,
                           INPUT_CHANNELS, OUTPUT_CHANNELS)


@pytest.fixture(scope='module')
def rough():
    nominal = simulate(ROUGH, seed=0)
    return {'sim': nominal,
            'lift': simulate(ROUGH, ('tire_lift_off',), seed=0),
            'lift_reseeded': simulate(ROUGH, ('tire_lift_off',), seed=7),
            'reseeded': simulate(ROUGH, (), seed=7)}


def test_clip_found_below_a_tenth_of_a_percent_and_not_on_clean_or_quantised_data():
    rng = np.random.default_rng(3)
    x = rng.standard_normal(50_000)
    level = float(np.quantile(x, 1 - 8e-4))
    clipped = np.minimum(x, level)
    assert np.mean(clipped == level) < 1e-3
    clip = clip_test(clipped, 'a')
    # Bug caught: the level taken from a quantile or a threshold instead of the data.
    assert clip is not None and clip.level == level and clip.count == np.sum(x >= level)
    assert clip.p_value < 1e-20
    # A clean record and a coarsely quantised one (values repeat, but less at the extreme).
    for clean in (x, np.round(x * 20) / 20):
        clip = clip_test(clean, 'a')
        assert clip is None or clip.p_value > 1e-3


def test_a_quantised_turning_point_is_not_a_clip():
    # A displacement-controlled rig reversing: a slow sine, quantised, dwells longest at its
    # extreme value (like a clip) but creeps into it instead of being cut while moving.
    t = np.arange(20_000) / 100.0
    x = np.round(20.0 * np.sin(2 * np.pi * 0.1 * t) / 0.01) * 0.01
    _, counts = np.unique(x, return_counts=True)
    # The repeat count alone would call it a clip (140 samples vs 46 for the neighbours).
    assert stats.poisson.sf(counts[-1] - 1, counts[-21:-1].mean()) < 1e-20
    # Bug caught: the entry-speed rule lost (the MR-damper rig's reversals became clips).
    assert clip_test(x, 'x') is None
    # The same sine clipped at 90 % of its amplitude is a clip (entered at speed).
    clip = clip_test(np.minimum(x, 18.0), 'x')
    assert clip is not None and clip.level == 18.0 and clip.p_value < 1e-10


def test_a_rest_at_the_start_of_a_record_is_not_a_clip_nor_is_the_join_of_records():
    # A rig at rest at its extreme position before the test (the MR damper's runs 4.2 and
    # 4.3 rest 1.45 and 5.8 s at their lowest displacement), then moving: the rest shows no
    # entry into the level, so nothing tells it from a rest.  Joined after another record
    # the record's first sample would look like an entry at speed (the bug: the MR damper's
    # three runs named `sensor_saturation` at the start position of one of them).
    rng = np.random.default_rng(4)
    t = np.arange(3000) / 100.0
    moving = np.round(0.01 * np.sin(2 * np.pi * 0.7 * t + 0.3) + 1e-4 * rng.standard_normal(
        t.size), 5)
    low = float(moving.min()) - 0.005
    rest = np.concatenate([np.full(300, low), low + np.cumsum(np.full(50, 1e-4)), moving])
    other = np.round(0.004 * np.sin(2 * np.pi * 0.9 * t), 5)    # inside the rest's level
    assert clip_test(rest, 'x') is None
    assert clip_test([other, rest], 'x') is None
    joined = clip_test(np.concatenate([other, rest]), 'x')
    assert joined is not None and joined.level == low   # what the list form avoids
    # a real clip (the top quarter of the motion, entered at speed) in the second record is
    # still found, counted on its own samples
    top = float(np.quantile(moving, 0.75))
    clip = clip_test([other, np.concatenate([rest[:350], np.minimum(moving, top)])], 'x')
    assert clip is not None and clip.level == top
    assert clip.count == np.sum(moving >= top)


def test_supporting_mass_is_the_outboard_mass_of_a_flying_wheel():
    rng = np.random.default_rng(0)
    az = rng.uniform(-40.0, 30.0, 5000)
    tyre = np.maximum(3000.0 + 80.0 * az + rng.normal(0, 300, 5000), 0.0)
    fz = tyre - 20.0 * az                       # WFT: tyre force minus outboard inertia
    assert tyre.min() == 0.0
    # Flying samples sit exactly on Fz = -20 kg * az, all others above it.
    assert supporting_mass(fz, az) == pytest.approx(20.0, rel=1e-12)
    assert supporting_mass(fz[az > 0], az[az > 0]) is None


def test_tire_lift_off_named_with_corner_and_time(rough):
    found = motion_findings([_rec(rough['lift'], 'real')], [_rec(rough['sim'], 'sim')], SOURCES)
    assert [f.physics for f in found] == ['tire_lift_off']
    f = found[0]
    tyre = rough['lift'].states['tyre_force_n'][2::3]
    static = rough['lift'].states['static_force_n'][2::3]
    lifted = {c for c, row in zip(('lf', 'rf', 'lr', 'rr'), tyre) if np.any(row <= 0.0)}
    # Bug caught: corners named that never left the ground, or one that did missed.
    assert {c[:2] for c in f.channels} <= lifted and {'lr', 'rr'} <= {c[:2] for c in f.channels}
    # The outboard mass (20-21 kg simulated) is read from the free flight.
    assert 19.0 < f.parameters['outboard_mass_kg'] < 21.5
    # Every reported window holds a low-load instant (tyre force below 10 % of static).
    t_s = np.arange(tyre.shape[1]) / rough['lift'].fs_hz
    low = np.any(tyre < 0.1 * static[:, np.newaxis], axis=0)
    assert f.time_windows_s
    for a, b in f.time_windows_s:
        assert np.any(low[(t_s >= a - 0.01) & (t_s <= b + 0.01)]), (a, b)
    assert f.terms == ()
    assert json.loads(json.dumps(f.to_dict()))['time_windows_s'][0] == list(f.time_windows_s[0])


def test_tire_lift_off_named_on_other_roads_of_the_same_course(rough):
    found = motion_findings([_rec(rough['lift_reseeded'], 'real')],
                            [_rec(rough['sim'], 'sim')], SOURCES)
    assert [f.physics for f in found] == ['tire_lift_off']


@pytest.mark.parametrize('real', ['sim', 'reseeded'])
def test_null_cases_name_nothing(rough, real):
    # Matched pair, and the nominal car on other roads of the same course (its tyres pull
    # the road as often as the simulation's do).
    assert motion_findings([_rec(rough[real], 'real')], [_rec(rough['sim'], 'sim')],
                           SOURCES) == []


def test_sensor_saturation_named_with_a_tenth_of_a_percent_clipped(rough):
    sim = rough['sim']
    # A range that 0.08 % of the simulated samples exceed on some channel.
    limit = float(np.quantile(np.max(np.abs(sim.accel_mps2), axis=0), 1 - 8e-4))
    real = simulate(ROUGH, ('sensor_saturation',), seed=0,
                    effect_params={'sensor_saturation': {'limit_mps2': limit}})
    at_limit = np.abs(real.accel_mps2) >= limit
    fraction = float(np.mean(np.any(at_limit, axis=0)))
    assert 0.0 < fraction <= 1e-3
    found = motion_findings([_rec(real, 'real')], [_rec(sim, 'sim')], SOURCES)
    assert [f.physics for f in found] == ['sensor_saturation']
    f = found[0]
    # The clip level is the sensor range, read back from the data (sensor noise is added
    # before the ADC clip, so the flat top is the range itself).
    assert f.parameters['limit'] == pytest.approx(limit, rel=1e-9)
    # Counted on the channels it names (the sources of its output channels); channels that
    # touch the range only a few times are not significant alone.
    named = [INPUT_CHANNELS.index(SOURCES[OUTPUT_CHANNELS.index(c)]) for c in f.channels]
    assert f.parameters['clipped_fraction'] == np.mean(np.any(at_limit[named], axis=0))
    assert f.parameters['clipped_fraction'] > 0.5 * fraction
    t_s = np.arange(real.stamp_ns.size) / real.fs_hz
    first = t_s[np.any(at_limit[named], axis=0)][0]
    assert f.time_windows_s[0][0] == pytest.approx(first, abs=1e-3)
    # The simulation modelling the same range is no mismatch.
    assert motion_findings([_rec(real, 'real')], [_rec(real, 'sim')], SOURCES) == []


def test_merge_keeps_the_ranked_term_and_adds_the_windows():
    motion = Finding('sensor_saturation', ('lf_fz',), {'limit': 50.0}, 0.0, 'flat tops',
                     time_windows_s=((1.0, 1.5),))
    other = Finding('time_delay', ('lf_fz',), {'delay_s': 0.001}, 0.1, 'late')
    assert merge_motion([other], [motion]) == [motion, other]
    ranked = Finding('sensor_saturation', ('lf_fz',), {'limit': 50.0}, 0.2, 'residual')
    merged = merge_motion([ranked], [motion])
    assert len(merged) == 1 and merged[0].time_windows_s == ((1.0, 1.5),)
    assert merged[0].explained_fraction == 0.2 and 'flat tops' in merged[0].evidence
