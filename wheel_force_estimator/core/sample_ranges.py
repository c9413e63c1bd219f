# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Sample ranges of a recording: ``A..B,C..D`` (half-open, 0-based sample indices).

Also the one home of :func:`runs` (the True runs of a sample mask), which the motion
findings use to locate clipped or airborne stretches.

The one text form of the samples ``wheel-force evaluate --samples`` scores and
``diagnose`` prints in ``fit.report_on`` for a single holdout file.  Indices count the aligned
samples of one recording over its gap-free segments in order (segment 0's samples, then
segment 1's, ...), so a range may span a gap; it is cut there.
"""
from typing import List, Sequence, Tuple

import numpy as np

Range = Tuple[int, int]


def runs(mask: np.ndarray) -> np.ndarray:
    """Return ``(k, 2)`` start / stop (exclusive) indices of the True runs of ``mask``."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, dtype=np.int8), [0]]))
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1)], axis=1)


def format_ranges(ranges: Sequence[Range]) -> str:
    """Return ``'A..B,C..D'`` (what :func:`parse_ranges` reads)."""
    return ','.join(f'{a}..{b}' for a, b in ranges)


def parse_ranges(text: str) -> Tuple[Range, ...]:
    """
    Read ``'A..B[,C..D...]'``: ascending, non-overlapping, non-empty half-open ranges.

    Raises
    ------
    ValueError
        Naming the item that is not ``A..B`` with integers ``0 <= A < B``, or the ranges out
        of order.

    """
    out: List[Range] = []
    for item in (s.strip() for s in str(text).split(',')):
        lo, sep, hi = item.partition('..')
        try:
            a, b = int(lo), int(hi)
        except ValueError:
            a = b = -1
        if not sep or a < 0 or b <= a:
            raise ValueError(f'{item!r} is not A..B with sample indices 0 <= A < B')
        if out and a < out[-1][1]:
            raise ValueError(f'{item!r} starts before the previous range ends '
                             f'({out[-1][0]}..{out[-1][1]}): give ascending ranges that do '
                             f'not overlap')
        out.append((a, b))
    return tuple(out)


def per_segment(ranges: Sequence[Range], lengths: Sequence[int]) -> List[Tuple[int, int, int]]:
    """
    Cut ranges over concatenated segments into ``(segment, start, stop)`` local pieces.

    Raises
    ------
    ValueError
        A range ends after the last sample (``sum(lengths)``).

    """
    total = int(sum(lengths))
    if len(ranges) and ranges[-1][1] > total:
        a, b = ranges[-1]
        raise ValueError(f'range {a}..{b} ends after the recording has ended ({total} aligned '
                         'samples)')
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(int)
    pieces = []
    for a, b in ranges:
        for i, (o, n) in enumerate(zip(offsets[:-1], lengths)):
            lo, hi = max(a, o), min(b, o + n)
            if hi > lo:
                pieces.append((i, int(lo - o), int(hi - o)))
    return pieces
