# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The chunk CRC equals zlib's for every input form and continuation the bag code uses."""
import zlib

import numpy as np
import pytest

from wheel_force_estimator.bagio.checksum import crc32
from wheel_force_estimator.bagio.checksum import CRC32_LIBRARY


@pytest.mark.parametrize('size', [0, 1, 7, 64, 4097, 1 << 20])
def test_crc32_equals_zlib(size):
    data = np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8)
    assert crc32(data) == zlib.crc32(data.tobytes())
    assert crc32(memoryview(data.tobytes())) == zlib.crc32(data.tobytes())
    half = size // 2
    assert crc32(data[half:], crc32(data[:half])) == zlib.crc32(data.tobytes())
    # a known value: CRC-32 of b'123456789' is 0xCBF43926 (the standard check value)
    assert crc32(b'123456789') == 0xCBF43926


def test_library_reported():
    assert CRC32_LIBRARY in ('isal', 'zlib')
