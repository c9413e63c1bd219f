# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The candidate designs of ``wheel-force fit`` and their held-out scores (blocked CV).

Candidates (each output row chooses its own: the rows of both estimators are independent
least-squares problems, so a row's choice does not change another row):

- ``h1``: the dual-resolution H1 FRF with Tikhonov regularisation (the paper's method plus
  the low-frequency estimate of :mod:`.pipeline`), over a grid of short segment lengths and
  long-segment regularisations;
- ``ls``: the two-sided least-squares MIMO FIR solved from the Wiener-Hopf normal equations
  (:mod:`.live_estimator`'s multi-rate basis, look-ahead :data:`LS_LOOK_AHEAD_S`), over a
  grid of ridges.  Its factorisation also gives every live estimator (a shorter look-ahead is
  a leading block of the same Cholesky factor), so the live estimator's ridge is chosen on
  the same folds at no extra factorisation;
- ``spliced``: the ``ls`` response below a crossover and the ``h1`` response above it
  (raised cosine from ``c`` to ``1.5 c``).  Measured on held-out simulated cars the LS FIR
  carries the quasi-static band far better than a 16 s Welch segment can (it sees the
  whole-record mean, not a per-window one), the H1 the resonant band above a few Hz.

Scores: :mod:`.crossval` (frequency-domain held-out error of the realised FIR response, both
figures).  The defaults below only bound the search.
"""
import dataclasses
import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.crossval import BlendScorer
from wheel_force_estimator.core.crossval import HeldOutPower
from wheel_force_estimator.core.crossval import hp_power_weight
from wheel_force_estimator.core.crossval import Piece
from wheel_force_estimator.core.crossval import response_on_grid
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.live_estimator import CorrelationAccumulator
from wheel_force_estimator.core.live_estimator import Correlations
from wheel_force_estimator.core.live_estimator import LagOrderedFactor
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.live_estimator import NormalEquations
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import CrossSpectra

#: Short Welch segments tried, as multiples of the configured one.
SEGMENT_FACTORS = (1, 2)
#: Long-segment regularisations tried [-].
LONG_REGULARISATIONS = (1e-2, 5e-2)
#: Ridges of the least-squares FIRs (offline and live) tried [-].
LS_REGULARISATIONS = (1e-4, 1e-3)
#: Crossovers of the spliced candidate [Hz]; 0 = H1 alone, inf = LS alone.
SPLICE_CROSSOVERS_HZ = (0.0, 1.0, 2.0, 4.0, 8.0, math.inf)
#: Key of the scorer's spectra in :func:`block_stats`.
SCORING = 'scoring'
#: Look-ahead of the two-sided least-squares FIR [s] (the longest stored live look-ahead).
LS_LOOK_AHEAD_S = 0.25
#: Live-estimator histories tried, as fractions of the configured one (``LiveDesign``'s
#: ``history_s`` bounds the search; a shorter one reuses its factorisation).
LIVE_HISTORY_FRACTIONS = (0.25, 0.5, 1.0)


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One offline design for a row: an H1 variant, an LS ridge and a splice crossover."""

    segment_length: int
    long_regularisation: float
    ls_regularisation: float
    crossover_hz: float
    ls_look_ahead_s: float = LS_LOOK_AHEAD_S
    ls_history_s: Optional[float] = None

    @property
    def ls_key(self) -> Tuple[float, float, Optional[float]]:
        """Return the key of this candidate's least-squares FIR (ridge, look-ahead, history)."""
        return (self.ls_regularisation, self.ls_look_ahead_s, self.ls_history_s)

    @property
    def family(self) -> str:
        """Return ``'h1'``, ``'ls'`` or ``'spliced'``."""
        if self.crossover_hz <= 0.0:
            return 'h1'
        return 'ls' if math.isinf(self.crossover_hz) else 'spliced'

    def as_dict(self) -> dict:
        """Return the JSON form (only the settings the family uses)."""
        out = {'family': self.family}
        if self.family != 'ls':
            out.update(segment_length=self.segment_length,
                       long_regularisation=self.long_regularisation)
        if self.family != 'h1':
            out.update(ls_regularisation=self.ls_regularisation,
                       ls_look_ahead_s=self.ls_look_ahead_s)
            if self.ls_history_s is not None:
                out.update(ls_history_s=self.ls_history_s)
        if self.family == 'spliced':
            out.update(crossover_hz=self.crossover_hz)
        return out


def candidates(segment_lengths: Sequence[int], long_regs: Sequence[float],
               ls_regs: Sequence[float], crossovers: Sequence[float],
               live_look_ahead_s: Optional[float] = None,
               live_histories_s: Sequence[Optional[float]] = (None,)) -> List[Candidate]:
    """
    Return the distinct candidates of the grids (families ignore settings they lack).

    ``live_look_ahead_s`` adds every live estimator (ridge x history, ``None`` = the full
    history) as an offline candidate (the ``ls`` family at that look-ahead), so the offline
    choice can never score worse than the live estimator on the held-out blocks.
    """
    seen, out = set(), []
    for c in crossovers:
        for seg in segment_lengths:
            for lr in long_regs:
                for r in ls_regs:
                    cand = Candidate(seg, lr, r, c)
                    key = tuple(sorted(cand.as_dict().items()))
                    if key not in seen:
                        seen.add(key)
                        out.append(cand)
    if live_look_ahead_s is not None and math.inf in crossovers:
        out.extend(Candidate(segment_lengths[0], long_regs[0], r, math.inf,
                             float(live_look_ahead_s), h)
                   for h in live_histories_s for r in ls_regs
                   if live_look_ahead_s != LS_LOOK_AHEAD_S or h is not None)
    return out


@dataclasses.dataclass(frozen=True)
class Centred:
    """
    A training segment about its own mean, as every statistic of the search takes it.

    Each chunk of a segment is taken about the *segment's* mean, not its own: the
    differences between the chunks' means are the quasi-static band (braking, cornering,
    load transfer), which the unfiltered RMSE of a whole record counts (measured: half the
    error power of the compact car's Fx below 0.05 Hz) and which a chunk's own mean would
    hide from the least-squares FIRs and from the scorer.
    """

    x: np.ndarray
    y: np.ndarray
    mean_x: np.ndarray
    mean_y: np.ndarray
    source: str

    @classmethod
    def of(cls, seg) -> 'Centred':
        """Return ``seg`` (a validated TrainingSegment) about its own mean."""
        mx = seg.accel_mps2.mean(axis=1)
        my = seg.force_n.mean(axis=1)
        return cls(seg.accel_mps2 - mx[:, None], seg.force_n - my[:, None], mx, my,
                   seg.source)


@dataclasses.dataclass
class BlockStats:
    """What one block contributes: spectra per resolution, correlations and sums."""

    spectra: Dict[int, CrossSpectra]
    corr: Optional[Correlations]
    sum_x: np.ndarray
    sum_y: np.ndarray
    n: int


def block_stats(segments: Sequence[Centred], pieces: Sequence[Piece], welch: Dict[int, object],
                fs_hz: float, max_lag: int) -> BlockStats:
    """
    Accumulate one block's statistics from its pieces (each statistic once per block).

    Parameters
    ----------
    segments : sequence of Centred
        The training segments about their means.
    pieces : sequence of Piece
        The block's pieces.
    welch : dict
        ``{segment_length: WelchConfig}`` of every resolution needed, and the scorer's
        under the key :data:`SCORING` (its windows not detrended, so the quasi-static band
        counts as in the unfiltered RMSE; the H1 resolutions detrend their own windows).
    fs_hz : float
        Sample rate [Hz].
    max_lag : int
        Correlation lags needed [samples] (0 = none).  A piece's correlations are those of
        its fluctuation about its own mean plus its mean's departure from the segment's
        (:meth:`.live_estimator.CorrelationAccumulator.add`).

    """
    first = segments[0]
    n_in, n_out = first.x.shape[0], first.y.shape[0]
    parts: Dict[int, list] = {k: [] for k in welch}
    acc = CorrelationAccumulator(n_in, n_out, max_lag) if max_lag else None
    sum_x, sum_y, n = np.zeros(n_in), np.zeros(n_out), 0
    for p in pieces:
        seg = segments[p.segment]
        x, y = seg.x[:, p.start:p.stop], seg.y[:, p.start:p.stop]
        for key, cfg in welch.items():
            if x.shape[1] >= cfg.segment_length:
                parts[key].append(cross_spectra(x, y, cfg, name=seg.source))
        if acc is not None:
            acc.add(x, y, np.zeros(n_in + n_out))
        sum_x += x.sum(axis=1) + seg.mean_x * x.shape[1]
        sum_y += y.sum(axis=1) + seg.mean_y * y.shape[1]
        n += x.shape[1]
    spectra = {k: combine_spectra(v) for k, v in parts.items() if v}
    return BlockStats(spectra, acc.result(fs_hz) if acc is not None else None, sum_x, sum_y,
                      n)


def combine_correlations(items: Sequence[Correlations]) -> Correlations:
    """Return the sample-weighted average of correlations of disjoint data."""
    total = sum(c.n_samples for c in items)
    rxx = sum(c.rxx * (c.n_samples / total) for c in items)
    rxy = sum(c.rxy * (c.n_samples / total) for c in items)
    return Correlations(rxx, rxy, items[0].fs_hz, int(total))


class LsSolutions:
    """
    The least-squares FIRs of one training set: one factorisation per ridge.

    Each factorisation serves every look-ahead up to :data:`LS_LOOK_AHEAD_S` and every
    history up to ``design.history_s`` (:class:`.live_estimator.LagOrderedFactor`).  Each
    fold needs its own: one normal matrix of all the data with a fold's right-hand side was
    measured 1.5-4x worse on a held-out course (a road course is not stationary: the
    held-out events' inputs would weigh in the matrix without their outputs).
    """

    def __init__(self, corr: Correlations, design: LiveDesign, ridges: Sequence[float]):
        self.fs_hz = corr.fs_hz
        self.d_max = look_ahead_samples(LS_LOOK_AHEAD_S, corr.fs_hz)
        eq = NormalEquations(corr, self.d_max, dataclasses.replace(
            design, look_aheads_s=(LS_LOOK_AHEAD_S,), regularisation=float(ridges[0])))
        self.factors = {r: LagOrderedFactor(eq, r) for r in ridges}
        self._estimators: Dict[Tuple[float, int, Optional[float]], CausalEstimator] = {}

    def estimator(self, ridge: float, look_ahead: int,
                  history_s: Optional[float] = None) -> CausalEstimator:
        """Return the estimator of ``ridge`` at ``look_ahead`` samples (solved once)."""
        key = (ridge, int(look_ahead), history_s)
        if key not in self._estimators:
            factor = self.factors[ridge]
            drop = 0 if history_s is None else factor.history_blocks(history_s)
            self._estimators[key] = factor.estimator(look_ahead, drop)
        return self._estimators[key]

    def response(self, ridge: float, look_ahead: int, n_fft: int,
                 history_s: Optional[float] = None) -> np.ndarray:
        """Return the realised response on the ``n_fft`` grid, shape (nf, n_out, n_in)."""
        fir = self.estimator(ridge, look_ahead, history_s).fir(self.fs_hz)
        return response_on_grid(fir.taps, fir.delay_samples, n_fft)


def score_fold(h1: Dict[Tuple[int, float], np.ndarray],
               ls: Dict[Tuple[float, float, Optional[float]], np.ndarray],
               live: Dict[Tuple[float, Optional[float]], np.ndarray], cands: Sequence[Candidate],
               held_out: CrossSpectra) -> Tuple[List[HeldOutPower], List[HeldOutPower]]:
    """
    Score every candidate (and every live ridge) of one fold on its held-out block.

    Parameters
    ----------
    h1 : dict
        ``{(segment_length, long_regularisation): response}`` on the scoring grid.
    ls : dict
        ``{(ridge, look_ahead_s, history_s): response}`` of the LS FIRs on the scoring grid.
    live : dict
        ``{(ridge, history_s): response}`` of the live LS FIRs on the scoring grid.
    cands : sequence of Candidate
        Offline candidates.
    held_out : CrossSpectra
        Welch spectra of the held-out block (scoring grid).

    Returns
    -------
    (list of HeldOutPower, list of HeldOutPower)
        Per candidate, per live design (in ``live`` order).

    """
    f = held_out.f_hz
    scorer = BlendScorer(held_out, hp_power_weight(f, held_out.config.fs_hz))
    for key, h in h1.items():
        scorer.add(('h1',) + key, h)
    same = {}
    for key, h in ls.items():
        scorer.add(('ls',) + key, h)
        same[id(h)] = ('ls',) + key
    live_keys = []
    for key, h in live.items():
        if id(h) not in same:                 # the live FIR is often an LS candidate too
            same[id(h)] = ('live',) + key
            scorer.add(same[id(h)], h)
        live_keys.append(same[id(h)])
    offline = []
    for c in cands:
        h1_key = ('h1', c.segment_length, c.long_regularisation)
        ls_key = ('ls',) + c.ls_key
        if c.family == 'h1':
            offline.append(scorer.power(h1_key))
        elif c.family == 'ls':
            offline.append(scorer.power(ls_key))
        else:
            offline.append(scorer.power(ls_key, h1_key, blend_weight(f, c.crossover_hz)))
    return offline, [scorer.power(key) for key in live_keys]
