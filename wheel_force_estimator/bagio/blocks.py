# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Signals handed to the bag writer block by block instead of as one array.

``wheel-force predict`` computes an hour of forces (12 x 1.8 M samples, 177 MB) while the bag
is being written: the storage writers ask for the payload fields of consecutive sample ranges
(a chunk / batch at a time, every dense topic the same range), so a window over the stream of
force blocks is all they need.  Memory stays at a block or two however long the recording.
"""
from collections import deque
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.validation import as_signals


@dataclass(frozen=True, eq=False)  # holds an iterator: identity, not value
class SignalBlocks:
    """
    ``n_samples`` samples of ``len(channels)`` signals, delivered as consecutive blocks.

    Attributes
    ----------
    channels : tuple of str
        Channel names, row order of every block.
    n_samples : int
        Total samples over all blocks (must equal the stamps written with them).
    blocks : iterable of numpy.ndarray, each (len(channels), m)
        Consumed once, in order, while the bag is written; every block is checked for shape
        and non-finite values when it arrives.

    """

    channels: Sequence[str]
    n_samples: int
    blocks: Iterable[np.ndarray]


class BlockWindow:
    """
    Sample ranges ``[first, stop)`` of a :class:`SignalBlocks` stream, never going back.

    Blocks are pulled as a request needs them and dropped once a request starts after them.
    """

    def __init__(self, source: SignalBlocks, name: str):
        self.n = int(source.n_samples)
        self.channels = tuple(source.channels)
        self._name = name
        self._iter = iter(source.blocks)
        self._blocks: deque = deque()  # (first sample, block)
        self._start = 0  # first sample still held
        self._end = 0  # one past the last sample pulled

    def rows(self, first: int, stop: int) -> np.ndarray:
        """Return samples ``first..stop-1`` as a (channels, stop - first) array."""
        if first < self._start or stop > self.n or stop < first:
            raise BagError(f'{self._name}: samples {first}..{stop} requested out of order '
                           f'(held from {self._start}, {self.n} in total)')
        while self._end < stop:
            self._pull()
        while self._blocks and self._blocks[0][0] + self._blocks[0][1].shape[1] <= first:
            self._blocks.popleft()
        self._start = first
        pieces = []
        for at, block in self._blocks:
            lo, hi = max(first - at, 0), min(stop - at, block.shape[1])
            if lo < hi:
                pieces.append(block[:, lo:hi])
            if at + block.shape[1] >= stop:
                break
        if stop == self.n:
            self._check_exhausted()
        if len(pieces) == 1:
            return pieces[0]
        if not pieces:
            return np.empty((len(self.channels), 0))
        return np.concatenate(pieces, axis=1)

    def _pull(self):
        try:
            block = next(self._iter)
        except StopIteration:
            raise BagError(f'{self._name}: the stream ended after {self._end} of {self.n} '
                           'samples') from None
        block = as_signals(block, f'{self._name} block at sample {self._end}', self.channels,
                           min_samples=0)
        if self._end + block.shape[1] > self.n:
            raise BagError(f'{self._name}: the stream holds more than {self.n} samples')
        self._blocks.append((self._end, block))
        self._end += block.shape[1]

    def _check_exhausted(self):
        for block in self._iter:
            if np.asarray(block).size:
                raise BagError(f'{self._name}: the stream holds more than {self.n} samples')


class RowSource:
    """
    Rows ``row..row+2`` of a :class:`BlockWindow` seen as an (n, 3) array, for slicing only.

    What a dense topic's value field needs (:class:`.plan.DenseTopic` slices
    ``source[first:stop]`` in increasing order).
    """

    ndim = 2

    def __init__(self, window: BlockWindow, row: int):
        self.window = window
        self.row = row

    def __len__(self) -> int:
        """Return the number of samples."""
        return self.window.n

    def __getitem__(self, key) -> np.ndarray:
        """Return ``(stop - start, 3)`` values of the sample slice ``key``."""
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError('a streamed signal can only be read by contiguous sample slices')
        first, stop, _ = key.indices(self.window.n)
        return self.window.rows(first, stop)[self.row:self.row + 3].T
