# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
CRC-32 (the zlib / MCAP polynomial) of bag chunks, from the fastest library installed.

MCAP chunks carry a CRC-32 of their records; both rosbags and this package verify it on read
and write it on write.  ISA-L (``isal``, a pip package) computes it with carry-less multiply
instructions at ~30 GB/s on the benchmark machine, stdlib zlib at ~6 GB/s: for a 1 h bag
(3.6 GB) that is 0.1 s instead of 0.6 s.  ``isal`` is optional (``pip install isal``, installed
by ``make venv``); the result is bit-identical either way.
"""
try:
    from isal.isal_zlib import crc32 as _crc32
    CRC32_LIBRARY = 'isal'
except ImportError:  # optional speed-up: stdlib zlib gives the same value
    from zlib import crc32 as _crc32
    CRC32_LIBRARY = 'zlib'


def crc32(data, value: int = 0) -> int:
    """
    Return the CRC-32 of ``data`` continued from ``value``, as ``zlib.crc32`` does.

    Parameters
    ----------
    data : bytes-like
        Any contiguous buffer (bytes, memoryview, numpy array).
    value : int
        CRC of the data before (0 to start).

    Returns
    -------
    int
        Unsigned 32-bit CRC.

    """
    return _crc32(data, value)
