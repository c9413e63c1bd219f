# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Shared argument checks: reject, never repair."""
import numpy as np
import pytest

from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
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
