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
import functools
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
    else:
        from backports import zstd  # a rosbags dependency
    try:
        return zstd.decompress(data)
    except zstd.ZstdError as err:  # an Exception only: callers take damage as ValueError
        raise ValueError(str(err)) from err


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
    Return ``(decompress, refused)``: the fastest decoder of many small inputs of ``name``.

    ``decompress(bytes) -> bytes`` may raise ``refused`` (a tuple of exception types) for an
    input it does not decode in one step: ``DECOMPRESS[name]`` decides about that one.  For
    zstd with ``zstandard`` installed it is this thread's context, bound once, refusing
    several frames or a missing content size; otherwise ``DECOMPRESS[name]``, refusing nothing.
    """
    if name == 'lz4':
        return _lz4_frame_decompress, ()
    if name != 'zstd' or _zstandard is None:
        return DECOMPRESS[name], ()
    context = getattr(_LOCAL, 'zstd', None)
    if context is None:
        context = _LOCAL.zstd = _zstandard.ZstdDecompressor()
    return functools.partial(context.decompress, allow_extra_data=False), (
        _zstandard.ZstdError,)


def decompress_joined(name: str, data, out) -> bool:
    """
    Decompress the concatenated frames ``data`` of ``name`` straight into ``out``, if possible.

    One call for many small frames (zstd through ``zstandard``'s stream reader, which reads
    across frames into the caller's buffer): no bytes object and no copy per frame.

    Returns
    -------
    bool
        True if the frames filled ``out`` exactly.  False if this is not available for
        ``name``, or the frames do not decode to exactly ``len(out)`` bytes (damage: the caller
        decodes them one by one, which names the fault).

    """
    if name != 'zstd' or _zstandard is None:
        return False
    context = getattr(_LOCAL, 'zstd', None)
    if context is None:
        context = _LOCAL.zstd = _zstandard.ZstdDecompressor()
    target = memoryview(out).cast('B')
    got = 0
    try:
        with context.stream_reader(data, read_across_frames=True) as reader:
            while got < len(target):
                n = reader.readinto(target[got:])
                if not n:
                    return False
                got += n
            return not reader.read(1)
    except _zstandard.ZstdError:
        return False


def _lz4_decompress(data: bytes) -> bytes:
    return _lz4_frame_decompress(data)


#: Compression name (as mcap chunks and rosbag2 metadata.yaml spell it) -> decompress(bytes).
DECOMPRESS = {'zstd': _zstd_decompress, 'lz4': _lz4_decompress}
