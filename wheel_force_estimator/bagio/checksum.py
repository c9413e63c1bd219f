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


#: ``crc32(data, value=0) -> int``: the CRC-32 of a contiguous buffer (bytes, memoryview, numpy
#: array) continued from ``value`` (0 to start), as ``zlib.crc32`` computes it.  The library
#: function itself, not a wrapper: the reader calls it once per chunk, ~10 000 times for a
#: recording in 4 KiB chunks.
crc32 = _crc32
