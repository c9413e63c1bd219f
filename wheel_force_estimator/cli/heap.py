# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Keep freed memory in the process for the one-shot commands (glibc's allocator only).

By default glibc serves every allocation above its mmap threshold (at most 32 MiB) with a
fresh ``mmap`` and unmaps it on ``free``, and it returns the heap's free top to the system
above 128 KiB.  ``fit`` and ``diagnose`` allocate and free arrays of the same few sizes
(spectra, responses on the scoring grid, normal-matrix blocks: 30-300 MB) hundreds of times, so
every one of them faults its pages in again.  Measured on the 20-minute bag of
``bench/bench_cli.py`` (``/usr/bin/time``, two runs each, alternating): 605-621 k minor page
faults and 33-38 s of system time in 87-91 s of wall time by default; 124-129 k faults,
10 s and 59-61 s with mmap off and the trim threshold at its maximum, for 1.5 % more peak RSS
(2.77 -> 2.81 GB).  A freed block is then reused by the next allocation of its size.

Only the batch commands call :func:`keep_freed_memory` (a long-lived node or fleet worker keeps
the default, which gives memory back).  Nothing changes off glibc (no ``mallopt``), and no
number the commands compute depends on it.
"""
import ctypes
import ctypes.util

#: ``mallopt`` parameters (glibc's malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_MAX = -4
#: The largest trim threshold ``mallopt`` takes (an ``int``): free heap above it is returned.
MAX_TRIM_BYTES = 2**31 - 1


def keep_freed_memory() -> bool:
    """
    Serve large blocks from the heap and keep freed ones for reuse; return True if applied.

    False where the C library has no ``mallopt`` (not glibc) or refuses a setting.
    """
    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    # mallopt returns 1 on success, 0 on error
    return bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, MAX_TRIM_BYTES))
