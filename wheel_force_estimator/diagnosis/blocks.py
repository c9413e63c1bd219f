# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Cross-validation over time blocks: the engine every gain of the diagnosis is measured with.

The residual of a channel (real force minus reference prediction) is cut into time blocks;
blocks are dealt to ``n_folds`` folds (the same time block of every channel and recording goes
to the same fold).  Inside each block an offset and a linear trend are projected out of the
residual and of every column, so sensor offsets and slow drifts can never pass as physics
(:class:`CvData`).  Per-block normal equations (:func:`block_stats`) give the held-out sum of
squares of a least-squares fit on the other folds (:func:`cv_sse`).  The shifted-feature null
shifts a candidate's features where they are least like themselves (:func:`null_lags`).
"""
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.diagnosis.features import ChannelContext


@dataclass(frozen=True)
class NullShift:
    """Circular shift [samples] of every piece's features for one null repetition."""

    data: Tuple[int, ...]
    sim: Optional[Tuple[int, ...]] = None


def null_lags(feature: np.ndarray, n_null: int) -> Tuple[int, ...]:
    """
    Return up to ``n_null`` circular shifts [samples] of ``feature`` for the shifted-feature null.

    The null must be a feature *unrelated* to the force.  A shift where the feature is still
    like itself is not: under periodic excitation (a rig's sine test) a shift by a whole
    period reproduces the feature and a half period its negative, and either explains as much
    as the true feature (measured on the friction-damper sine tests: the fixed quarter-record
    shift explained 26 % of the residual, the aligned backlash 46 %).  So the shifts are the
    lags of the middle half of the record where the least of the feature's energy stays in
    phase, frequency by frequency (a per-frequency measure: the harmonics of a periodic
    feature must each be out of phase, not cancel in a sum), at least ``n / (4 n_null)``
    apart, and only lags keeping at most half in phase (what a signal of random phase keeps on
    average; the best lag is always kept), so a short periodic record may give fewer than
    ``n_null``.  Under broadband excitation every lag keeps about half in phase and the
    choice changes nothing but which unrelated lags are used.  A constant feature keeps
    evenly spread lags.
    """
    x = np.asarray(feature, dtype=np.float64)
    n = x.size
    lo, hi = n // 4, max(3 * n // 4, n // 4 + 1)
    x = x - x.mean()
    power = np.abs(np.fft.rfft(x, n)) ** 2
    if not power.sum() > 0.0:
        return tuple(int(round(f * n)) for f in 0.25 + 0.5 * np.arange(n_null)
                     / max(n_null - 1, 1))
    # Per frequency, a shift by ``lag`` keeps cos^2(2 pi f lag) of the feature's energy in
    # phase; weighted by the squared power that is (1 + rho2(2 lag)) / 2, rho2 the
    # normalised autocorrelation of a signal with power spectrum |X|^4.  Summing per
    # frequency (not |rho| of the whole feature, where harmonics can cancel) keeps every
    # harmonic of a periodic feature out of phase as far as one shift can.
    auto2 = np.fft.irfft(power * power, n)
    rho = auto2[(2 * np.arange(lo, hi)) % n] / auto2[0]
    gap = max(1, n // (4 * n_null))
    chosen: List[int] = []
    for lag in (lo + np.argsort(rho, kind='stable')):
        if chosen and rho[lag - lo] > 0.0:
            # More than half the energy in phase: more like the feature than a signal of
            # random phase (which keeps half on average).  A short periodic record has few
            # unrelated shifts; fewer nulls (repeated by the caller) beat related ones.
            break
        if all(abs(int(lag) - c) >= gap for c in chosen):
            chosen.append(int(lag))
            if len(chosen) == n_null:
                break
    return tuple(sorted(chosen))


def block_layout(sizes: Dict[int, int], block_samples: int, n_folds: int,
                 min_block_samples: int) -> Tuple[Optional[int], int]:
    """
    Return ``(block length [samples], number of folds)`` for records of ``sizes`` samples.

    The longest block up to ``block_samples`` that gives every record one block and
    ``n_folds`` blocks in all; records too short for that at ``min_block_samples`` get as
    many folds as they hold blocks of ``min_block_samples`` (leave one block out, at least
    2).  ``(None, 0)`` when not even 2 such blocks fit.
    """
    counts = list(sizes.values())
    shortest = min(counts)
    for length in range(min(block_samples, shortest), min_block_samples - 1, -1):
        if sum(n // length for n in counts) >= n_folds:
            return length, n_folds
    blocks = sum(n // min_block_samples for n in counts)
    if shortest < min_block_samples or blocks < 2:
        return None, 0
    return min_block_samples, min(blocks, n_folds)


@dataclass
class Piece:
    """One output channel of one recording: its features, residual and target force."""

    ctx: ChannelContext
    residual: np.ndarray
    target: np.ndarray
    recording: int
    channel: str
    record_name: str = ''


class CvData:
    """Block and fold structure of a set of pieces, with per-block detrending."""

    def __init__(self, pieces: Sequence[Piece], config):
        self.pieces = list(pieces)
        self.config = config
        fs = self.pieces[0].ctx.fs_hz
        sizes, names = {}, {}
        for p in self.pieces:
            sizes.setdefault(p.recording, p.residual.size)
            names.setdefault(p.recording, p.record_name or f'record {p.recording + 1}')
        # Short records: shorter blocks rather than a refusal.  Blocks shorter than the
        # residual's correlation time make the held-out score optimistic for every candidate
        # alike; the shifted-feature null, scored the same way, keeps the test honest.
        length, self.n_folds = block_layout(sizes, int(round(config.block_s * fs)),
                                            config.n_folds, config.min_block_samples)
        if length is None:
            held = ', '.join(f'{names[r]}: {n} samples ({n / fs:.2f} s)'
                             for r, n in sizes.items())
            raise DiagnosisError(
                f'too little data to cross-validate {self.pieces[0].channel}: after the '
                f"features' settling and the reference's edges the records hold {held}, "
                f'fewer than 2 time blocks of {config.min_block_samples} samples')
        first_block, total = {}, 0
        for rec, n in sizes.items():
            first_block[rec] = total
            total += n // length
        self.starts, folds = [], []
        for p in self.pieces:
            nb = p.residual.size // length
            self.starts.append(np.arange(nb) * length)
            folds.append((first_block[p.recording] + np.arange(nb)) % self.n_folds)
        self.fold = np.concatenate(folds)
        self._design = [self._detrend_design(i) for i in range(len(self.pieces))]
        self.residual = [self.prepare(i, p.residual) for i, p in enumerate(self.pieces)]
        self.target_ss = float(sum(np.sum(self.prepare(i, p.target) ** 2)
                                   for i, p in enumerate(self.pieces)))
        self.n_samples = sum(p.residual.size for p in self.pieces)

    def _detrend_design(self, i):
        n = self.pieces[i].residual.size
        starts = self.starts[i]
        idx = np.arange(n)
        block = np.searchsorted(starts, idx, side='right') - 1
        counts = np.diff(np.append(starts, n))
        tau = idx - (starts[block] + 0.5 * (counts[block] - 1))
        tt = np.add.reduceat(tau * tau, starts)
        return block, counts, tau, np.where(tt > 0.0, tt, 1.0)

    def detrend(self, i: int, x: np.ndarray) -> np.ndarray:
        """Remove an offset and a linear trend inside every block of piece ``i``."""
        block, counts, tau, tt = self._design[i]
        starts = self.starts[i]
        mean = np.add.reduceat(x, starts) / counts
        slope = np.add.reduceat(x * tau, starts) / tt
        return x - mean[block] - slope[block] * tau

    def prepare(self, i: int, x: np.ndarray) -> np.ndarray:
        """High-pass (when configured) and detrend a column of piece ``i``."""
        if self.config.highpass_hz > 0.0 and np.any(x):
            x = highpass(x[np.newaxis], self.pieces[i].ctx.fs_hz, self.config.highpass_hz,
                         'diagnosis column')[0]
        return self.detrend(i, x)

    def block_sums(self, i: int, x: np.ndarray) -> np.ndarray:
        """Sum of ``x`` over every block of piece ``i``."""
        return np.add.reduceat(x, self.starts[i])


@dataclass(frozen=True)
class Stats:
    """Per-block normal equations: ``g[b] = D_b'D_b``, ``h[b] = D_b'r_b``, ``s[b] = r_b'r_b``."""

    g: np.ndarray
    h: np.ndarray
    s: np.ndarray


def block_stats(data: CvData, columns: Sequence[Sequence[np.ndarray]],
                offset: Optional[Sequence[np.ndarray]] = None) -> Stats:
    """Return per-block normal equations of detrended columns and residual minus offset."""
    gs, hs, ss = [], [], []
    for i in range(len(data.pieces)):
        r = data.residual[i] if offset is None else data.residual[i] - offset[i]
        cols = list(columns[i])
        p = len(cols)
        nb = data.starts[i].size
        g = np.zeros((nb, p, p))
        h = np.zeros((nb, p))
        for a in range(p):
            h[:, a] = data.block_sums(i, cols[a] * r)
            for b in range(a, p):
                g[:, a, b] = g[:, b, a] = data.block_sums(i, cols[a] * cols[b])
        gs.append(g)
        hs.append(h)
        ss.append(data.block_sums(i, r * r))
    return Stats(np.concatenate(gs), np.concatenate(hs), np.concatenate(ss))


def solve(g, h):
    """
    Least squares from the normal equations, with a tiny ridge relative to each column.

    Columns are scaled to unit Gram diagonal first: a cubic term of a displacement in metres
    (~1e-6) next to an acceleration companion (~1) would otherwise be ridged away by a ridge
    set from the average diagonal.
    """
    p = h.size
    if p == 0:
        return h
    d = np.sqrt(np.abs(np.diag(g)))
    d = np.where(d > 0.0, d, 1.0)
    gn = g / np.outer(d, d)
    return np.linalg.solve(gn + 1e-10 * np.eye(p), h / d) / d


def cv_sse(stats: Stats, fold: np.ndarray, n_folds: int) -> float:
    """Held-out sum of squared residuals after the fold-wise least-squares fit."""
    if stats.h.shape[1] == 0:
        return float(stats.s.sum())
    total = 0.0
    for k in range(n_folds):
        test = fold == k
        if not test.any():
            continue
        theta = solve(stats.g[~test].sum(0), stats.h[~test].sum(0))
        total += float(stats.s[test].sum() - 2.0 * np.sum(stats.h[test] @ theta)
                       + np.einsum('bij,i,j->', stats.g[test], theta, theta))
    return total


def full_fit(stats: Stats) -> np.ndarray:
    """Least-squares coefficients on all blocks."""
    return solve(stats.g.sum(0), stats.h.sum(0))
