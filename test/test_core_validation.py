# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Shared argument checks: reject, never repair."""
from dataclasses import dataclass
from typing import Tuple

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.validation import freeze_paired_record
from wheel_force_estimator.core.validation import paired_signals


class _DomainError(ValueError):
    pass


def test_paired_signals_returns_read_only_copies_of_equal_length():
    x, y = paired_signals(np.ones((2, 5)), [[1.0, 2.0, 3.0, 4.0, 5.0]], ('a', 'b'), ('f',),
                          'run1', _DomainError)
    assert x.shape == (2, 5) and y.shape == (1, 5)
    assert not x.flags.writeable and not y.flags.writeable


@pytest.mark.parametrize('inputs, outputs, min_samples, error, match', [
    (np.ones((1, 5)), np.ones((1, 4)), 1, _DomainError, 'run1: 5 input samples but 4 output'),
    (np.ones((1, 0)), np.ones((1, 0)), 1, _DomainError, 'run1: no samples'),
    (np.ones((1, 3)), np.ones((1, 3)), 4, _DomainError, 'run1: 3 samples, at least 4 required'),
    (np.ones((2, 3)), np.ones((1, 3)), 1, ShapeError, 'inputs of run1: expected 1 channels'),
    (np.ones((1, 3)), [[1.0, np.nan, 2.0]], 1, NonFiniteError, 'outputs of run1.*f at sample 1'),
])
def test_paired_signals_rejects(inputs, outputs, min_samples, error, match):
    with pytest.raises(error, match=match):
        paired_signals(inputs, outputs, ('a',), ('f',), 'run1', _DomainError, min_samples)


@dataclass(frozen=True)
class _Record:
    fs_hz: float
    inputs: object
    outputs: object
    input_channels: Tuple[str, ...]
    output_channels: Tuple[str, ...]
    input_quantity: str = 'acceleration'

    def __post_init__(self):
        freeze_paired_record(self, 'run1', ('displacement', 'acceleration'), _DomainError)


def test_freeze_paired_record_stores_validated_read_only_fields():
    rec = _Record(1024, [[1.0, 2.0, 3.0]], [[4.0, 5.0, 6.0]], ['a'], ['f'])
    assert rec.fs_hz == 1024.0 and isinstance(rec.fs_hz, float)
    assert rec.input_channels == ('a',) and rec.output_channels == ('f',)
    np.testing.assert_array_equal(rec.outputs, [[4.0, 5.0, 6.0]])
    assert not rec.inputs.flags.writeable and not rec.outputs.flags.writeable


def test_freeze_paired_record_raises_the_domain_error_chained():
    with pytest.raises(_DomainError, match='run1: sample rate must be finite') as info:
        _Record(float('nan'), [[1.0]], [[2.0]], ('a',), ('f',))
    assert isinstance(info.value.__cause__, ConfigError)
    with pytest.raises(_DomainError, match="run1: input quantity 'jerk' is not one of"):
        _Record(100.0, [[1.0]], [[2.0]], ('a',), ('f',), 'jerk')
    with pytest.raises(_DomainError, match='run1: 2 input samples but 1 output'):
        _Record(100.0, [[1.0, 2.0]], [[2.0]], ('a',), ('f',))
