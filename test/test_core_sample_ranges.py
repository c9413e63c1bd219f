# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Sample ranges (``evaluate --samples``, ``fit.report_on``): hand-checked values."""
import numpy as np
import pytest

from wheel_force_estimator.core.sample_ranges import format_ranges
from wheel_force_estimator.core.sample_ranges import parse_ranges
from wheel_force_estimator.core.sample_ranges import per_segment
from wheel_force_estimator.core.sample_ranges import runs


def test_runs_format_and_parse_round_trip():
    mask = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], dtype=bool)
    assert runs(mask).tolist() == [[0, 2], [4, 5], [6, 9]]
    assert runs(np.zeros(4, dtype=bool)).shape == (0, 2)
    assert runs(np.array([0, 1, 1, 0, 0, 1, 0, 1], bool)).tolist() == [[1, 3], [5, 6], [7, 8]]
    text = format_ranges(runs(mask))
    assert text == '0..2,4..5,6..9'
    assert parse_ranges(text) == ((0, 2), (4, 5), (6, 9))
    assert parse_ranges(' 3..7 , 7..8') == ((3, 7), (7, 8))   # touching ranges are fine


@pytest.mark.parametrize('text, needle', [('5..5', "'5..5'"), ('-1..4', "'-1..4'"),
                                          ('1-4', "'1-4'"), ('', "''"),
                                          ('0..10,5..20', 'previous range')])
def test_bad_ranges_are_named(text, needle):
    with pytest.raises(ValueError, match=needle):
        parse_ranges(text)


def test_ranges_over_segments_are_cut_at_the_gaps():
    # segments of 10, 5 and 8 samples: global 0..10 | 10..15 | 15..23
    pieces = per_segment([(8, 17), (20, 23)], [10, 5, 8])
    assert pieces == [(0, 8, 10), (1, 0, 5), (2, 0, 2), (2, 5, 8)]
    assert per_segment([(0, 23)], [10, 5, 8]) == [(0, 0, 10), (1, 0, 5), (2, 0, 8)]
    with pytest.raises(ValueError, match='23 aligned samples'):
        per_segment([(0, 24)], [10, 5, 8])
