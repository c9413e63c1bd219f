# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Data a diagnosis must refuse, with the reason named."""
from dataclasses import replace
import re

import numpy as np
import pytest
from support.diagnosis_synthetic import make_recording
from support.diagnosis_synthetic import synthetic_pair

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.blocks import block_layout
from wheel_force_estimator.diagnosis.features import FeatureConfig

CONFIG = DiagnosisConfig(linear='regression')


def _relabel(rec, **changes):
    fields = {'name': rec.name, 'fs_hz': rec.fs_hz, 'inputs': rec.inputs,
              'outputs': rec.outputs, 'input_channels': rec.input_channels,
              'output_channels': rec.output_channels}
    fields.update(changes)
    return MotionRecording(**fields)


@pytest.fixture(scope='module')
def pair():
    sim, real, holdout, _ = synthetic_pair('bump_stop', seed=11, duration_s=40.0)
    return sim, real, holdout


def test_different_rates_are_refused(pair):
    sim, real, _ = pair
    slow = [_relabel(r, fs_hz=200.0) for r in sim]
    with pytest.raises(DiagnosisError, match='200 Hz.*256 Hz|256 Hz.*200 Hz'):
        diagnose(real, slow, (), CONFIG)


def test_different_channels_are_refused(pair):
    sim, real, holdout = pair
    other = [_relabel(r, output_channels=('lr_fz', 'rr_fz')) for r in sim]
    with pytest.raises(DiagnosisError, match='output_channels'):
        diagnose(real, other, (), CONFIG)
    with pytest.raises(DiagnosisError, match='holdout'):
        diagnose(real, sim, [_relabel(holdout[0], fs_hz=512.0)], CONFIG)


def test_short_records_are_diagnosed_with_shorter_blocks(pair):
    sim, _, _ = pair
    # 16 s: the 15 s settle of the 0.2 Hz integrators leaves 1 s, less than 5 blocks of 2 s.
    # The blocks shrink until 5 fit (0.2 s) instead of refusing (before: "too little data to
    # cross-validate"); the concealed bump stop is still named where it is.
    short, _ = make_recording('bump_stop', 5, duration_s=16.0)
    result = diagnose([short], sim, (), CONFIG)
    assert [(f.physics, f.channels) for f in result.findings] == [('bump_stop', ('lf_fz',))]


def test_a_record_within_its_settling_time_is_refused_naming_the_corner(pair):
    sim, _, _ = pair
    tiny, _ = make_recording('bump_stop', 5, duration_s=10.0)
    with pytest.raises(DiagnosisError, match='settle') as refused:
        diagnose([tiny], sim, (), CONFIG)
    # The error names the integrator corner that would fit; at that corner the record gets
    # past the settle check, and what is left cannot hold 2 blocks, which is said, naming
    # the channel and the record.
    corner = re.search(r'--highpass-hz ([0-9.e+-]+) or above', str(refused.value))
    assert corner, str(refused.value)
    higher = replace(CONFIG, features=FeatureConfig(float(corner.group(1))))
    with pytest.raises(DiagnosisError, match=rf'cross-validate lf_fz: .*{tiny.name}: \d+ '
                       r'samples \(0\.\d+ s\), fewer than 2 time blocks'):
        diagnose([tiny], sim, (), higher)


@pytest.mark.parametrize('sizes, expected', [
    ({0: 5000}, (1000, 5)),          # 5 blocks of 1000 rather than 4 of 1024
    ({0: 800, 1: 800}, (266, 5)),    # 3 + 3: 320 (the old rule) gave 2 + 2
    ({0: 3000, 1: 300}, (300, 5)),   # every record holds a block: none longer than 300
    ({0: 200}, (64, 3)),             # 3 blocks of the shortest length: 3 folds
    ({0: 100}, (None, 0)),           # 1 block: nothing to hold out
])
def test_block_layout(sizes, expected):
    assert block_layout(sizes, 1024, 5, 64) == expected


def test_no_overlap_in_operating_range(pair):
    sim, real, _ = pair
    # The simulation driven 50x more gently than the real system.
    gentle = [_relabel(r, inputs=9.81 + (r.inputs - 9.81) / 50.0) for r in sim]
    with pytest.raises(DiagnosisError, match='operating ranges do not overlap on lf_az'):
        diagnose(real, gentle, (), CONFIG)


def test_recording_with_unequal_lengths_is_refused():
    with pytest.raises(DiagnosisError, match='100 input samples but 99 output samples'):
        MotionRecording('bad', 100.0, np.zeros((1, 100)), np.zeros((1, 99)), ('a',), ('f',))


def test_recording_with_nan_names_the_channel():
    y = np.zeros((1, 50))
    y[0, 17] = np.nan
    with pytest.raises(ValueError, match='f at sample 17'):
        MotionRecording('bad', 100.0, np.zeros((1, 50)), y, ('a',), ('f',))


def test_no_real_recordings():
    with pytest.raises(DiagnosisError, match='no real recordings'):
        diagnose([], None)


def test_unpairable_channels_are_refused():
    rng = np.random.default_rng(0)
    rec = MotionRecording('r', 100.0, rng.standard_normal((2, 4000)),
                          rng.standard_normal((3, 4000)), ('a', 'b'), ('f', 'g', 'h'),
                          input_quantity='displacement')
    # Names and counts do not pair: the pairing needs recordings to measure coherence on
    # (diagnose passes them; a caller without data is refused).
    from wheel_force_estimator.diagnosis.features import pairing
    with pytest.raises(DiagnosisError, match='which input drives which output'):
        pairing(rec.output_channels, rec.input_channels)
    sources, _ = pairing(rec.output_channels, rec.input_channels, [rec])
    assert set(sources) <= {'a', 'b'}
