# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The compressions rosbag2 and MCAP use (chunks, messages, storage files): name -> function."""
import sys


def _zstd_decompress(data: bytes) -> bytes:
    if sys.version_info >= (3, 14):
        from compression import zstd
        return zstd.decompress(data)
    try:
        from backports import zstd
        return zstd.decompress(data)
    except ImportError:
        import zstandard  # older rosbags releases depend on this one
        return zstandard.ZstdDecompressor().decompress(data)


def _lz4_decompress(data: bytes) -> bytes:
    from lz4.frame import decompress
    return decompress(data)


#: Compression name (as mcap chunks and rosbag2 metadata.yaml spell it) -> decompress(bytes).
DECOMPRESS = {'zstd': _zstd_decompress, 'lz4': _lz4_decompress}
