# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The compressions rosbag2 and MCAP use (chunks, messages, storage files): name -> function.

zstd goes through the ``zstandard`` package when it is installed (the ``fast`` extra; the
``mcap`` package brings it too), with one reusable decompression context per thread: the
standard-library-style ``backports.zstd`` builds a new context for every call (~40 us), which
is more than decompressing a 4 KiB chunk costs.  Anything ``zstandard`` does not decode in one
step (several frames, no content size) goes to ``backports.zstd``; both give the same bytes.
"""
import sys
import threading

from lz4.frame import decompress as _lz4_frame_decompress

try:  # optional accelerator
    import zstandard as _zstandard
except ImportError:  # pragma: no cover - depends on the installation
    _zstandard = None

_LOCAL = threading.local()


def _zstd_general(data: bytes) -> bytes:
    if sys.version_info >= (3, 14):
        from compression import zstd
        return zstd.decompress(data)
    from backports import zstd  # a rosbags dependency
    return zstd.decompress(data)


def _zstd_decompress(data: bytes) -> bytes:
    if _zstandard is not None:
        context = getattr(_LOCAL, 'zstd', None)
        if context is None:
            context = _LOCAL.zstd = _zstandard.ZstdDecompressor()
        try:
            return context.decompress(data, allow_extra_data=False)
        except _zstandard.ZstdError:
            pass  # several frames, no content size, or damage: the general decoder decides
    return _zstd_general(data)


def chunk_decompressor(name: str):
    """
    Return the fastest ``decompress(bytes) -> bytes`` for many small inputs of ``name``.

    For zstd with ``zstandard`` installed: this thread's context, bound once (the general
    decoder still takes what it does not decode in one step).
    """
    if name != 'zstd' or _zstandard is None:
        return DECOMPRESS[name]
    context = getattr(_LOCAL, 'zstd', None)
    if context is None:
        context = _LOCAL.zstd = _zstandard.ZstdDecompressor()
    one_step, error = context.decompress, _zstandard.ZstdError

    def decompress(data):
        try:
            return one_step(data, allow_extra_data=False)
        except error:
            return _zstd_general(data)
    return decompress


def _lz4_decompress(data: bytes) -> bytes:
    return _lz4_frame_decompress(data)


#: Compression name (as mcap chunks and rosbag2 metadata.yaml spell it) -> decompress(bytes).
DECOMPRESS = {'zstd': _zstd_decompress, 'lz4': _lz4_decompress}
