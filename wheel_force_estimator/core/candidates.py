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
import collections
import dataclasses
import hashlib
import math
import threading
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.correlations import Correlations
from wheel_force_estimator.core.correlations import straddling_products
from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.crossval import BlendScorer
from wheel_force_estimator.core.crossval import HeldOutPower
from wheel_force_estimator.core.crossval import hp_power_weight
from wheel_force_estimator.core.crossval import Piece
from wheel_force_estimator.core.filtering import response_on_grid
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.nested_factor import BorderedFactor
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations
from wheel_force_estimator.core.spectra import CrossSpectra
from wheel_force_estimator.core.spectra import pooled_cross_spectra
from wheel_force_estimator.core.spindle import parents

#: Short Welch segments tried, as multiples of the configured one.
SEGMENT_FACTORS = (1, 2)
#: Long-segment regularisations tried [-].
LONG_REGULARISATIONS = (1e-2, 5e-2)
#: Ridges of the least-squares FIRs (offline and live) tried [-].
LS_REGULARISATIONS = (1e-5, 1e-4, 1e-3)
#: Crossovers of the spliced candidate [Hz]; 0 = H1 alone, inf = LS alone.
SPLICE_CROSSOVERS_HZ = (0.0, 1.0, 2.0, 4.0, 8.0, math.inf)
#: Key of the scorer's spectra in :func:`block_stats`.
SCORING = 'scoring'
#: Look-ahead of the two-sided least-squares FIR [s] (the longest stored live look-ahead).
LS_LOOK_AHEAD_S = 0.25


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One offline design for a row: an H1 variant, an LS ridge and a splice crossover."""

    segment_length: int
    long_regularisation: float
    ls_regularisation: float
    crossover_hz: float
    ls_look_ahead_s: float = LS_LOOK_AHEAD_S

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
        if self.family == 'spliced':
            out.update(crossover_hz=self.crossover_hz)
        return out


def candidates(segment_lengths: Sequence[int], long_regs: Sequence[float],
               ls_regs: Sequence[float], crossovers: Sequence[float],
               live_look_ahead_s: Optional[float] = None) -> List[Candidate]:
    """
    Return the distinct candidates of the grids (families ignore settings they lack).

    ``live_look_ahead_s`` adds the live estimator itself as an offline candidate (the ``ls``
    family at that look-ahead), so the offline choice can never score worse than the live
    estimator on the held-out blocks.
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
                             float(live_look_ahead_s))
                   for r in ls_regs if live_look_ahead_s != LS_LOOK_AHEAD_S)
    return out


@dataclasses.dataclass
class BlockStats:
    """What one block contributes: spectra per resolution, correlations and sums."""

    spectra: Dict[int, CrossSpectra]
    corr: Optional[Correlations]
    sum_x: np.ndarray
    sum_y: np.ndarray
    n: int


def segment_means(segments) -> List[np.ndarray]:
    """Return each segment's mean, inputs then outputs stacked, shape (n_in + n_out,)."""
    return [np.concatenate([s.accel_mps2.mean(axis=1), s.force_n.mean(axis=1)])
            for s in segments]


def block_stats(segments, pieces: Sequence[Piece], welch: Dict[int, object],
                fs_hz: float, max_lag: int,
                means: Optional[Sequence[np.ndarray]] = None) -> BlockStats:
    """
    Accumulate one block's statistics from its pieces (each statistic once per block).

    A piece's correlations and scoring spectra have its *segment's* mean removed
    (:func:`segment_means`), as the final fit on whole segments and ``evaluate`` (the
    record's mean) remove it.  Until 2026-11-28 each piece had its own mean removed: on a
    1-minute record (3.75 s chunks) that took the band below ~0.3 Hz (braking, cornering, the
    static load transfer) out of every fold's fit and every held-out score, so the search
    chose blind to the band that dominates the unfiltered error in x and z.

    Parameters
    ----------
    segments : sequence of TrainingSegment
        Validated segments.
    pieces : sequence of Piece
        The block's pieces.
    welch : dict
        ``{segment_length: WelchConfig}`` of every resolution needed, and the scorer's
        under the key :data:`SCORING`.
    fs_hz : float
        Sample rate [Hz].
    max_lag : int
        Correlation lags needed [samples] (0 = none).
    means : sequence of numpy.ndarray, optional
        :func:`segment_means` of ``segments`` (computed when not given).

    """
    first = segments[0]
    n_in, n_out = first.accel_mps2.shape[0], first.force_n.shape[0]
    means = segment_means(segments) if means is None else means
    parts: Dict[int, list] = {k: [] for k in welch}
    acc = CorrelationAccumulator(n_in, n_out, max_lag) if max_lag else None
    sum_x, sum_y, n = np.zeros(n_in), np.zeros(n_out), 0
    for p in pieces:
        seg = segments[p.segment]
        x = seg.accel_mps2[:, p.start:p.stop]
        y = seg.force_n[:, p.start:p.stop]
        mean_x, mean_y = means[p.segment][:n_in, None], means[p.segment][n_in:, None]
        for key, cfg in welch.items():
            if x.shape[1] < cfg.segment_length:
                continue
            if key == SCORING:
                # the scorer's spectra: the segment's mean removed, windows not detrended,
                # so the quasi-static band counts as in the unfiltered RMSE
                parts[key].append((x - mean_x, y - mean_y))
            else:
                parts[key].append((x, y))
        if acc is not None:
            acc.add(x, y, means[p.segment])
        sum_x += x.sum(axis=1)
        sum_y += y.sum(axis=1)
        n += x.shape[1]
    # one set of spectral matrices per resolution for the whole block
    spectra = {k: pooled_cross_spectra(v, welch[k], name=segments[pieces[0].segment].source)
               for k, v in parts.items() if v}
    return BlockStats(spectra, acc.result(fs_hz) if acc is not None else None, sum_x, sum_y,
                      n)


def subset_spectra(spectra: CrossSpectra, columns: Sequence[int]) -> CrossSpectra:
    """Return ``spectra`` of the inputs ``columns`` only (a sub-block of ``Sxx``, ``Syx``)."""
    if len(columns) == spectra.n_inputs:
        return spectra
    cols = np.asarray(columns)
    return CrossSpectra(spectra.f_hz, spectra.sxx[:, cols[:, None], cols[None, :]],
                        spectra.syx[:, :, cols], spectra.syy, spectra.n_windows,
                        spectra.config)


def subset_correlations(corr: Correlations, columns: Sequence[int]) -> Correlations:
    """Return ``corr`` of the inputs ``columns`` only."""
    if len(columns) == corr.rxx.shape[0]:
        return corr
    cols = np.asarray(columns)
    return Correlations(np.ascontiguousarray(corr.rxx[cols[:, None], cols[None, :]]),
                        np.ascontiguousarray(corr.rxy[cols]), corr.fs_hz, corr.n_samples)


def embedded_response(h: np.ndarray, columns: Sequence[int], n_in: int) -> np.ndarray:
    """Return the response ``h`` (nf, n_out, len(columns)) on all ``n_in`` inputs (0 elsewhere)."""
    if h.shape[2] == n_in:
        return h
    out = np.zeros(h.shape[:2] + (n_in,), dtype=h.dtype)
    out[:, :, np.asarray(columns)] = h
    return out


def embedded_estimator(est: CausalEstimator, columns: Sequence[int],
                       n_in: int) -> CausalEstimator:
    """Return ``est`` on all ``n_in`` inputs: exactly zero taps for the inputs it lacks."""
    if est.n_in == n_in:
        return est
    cols = np.asarray(columns)
    fine = np.zeros((est.n_out, n_in, est.fine_taps.shape[2]))
    coarse = np.zeros((est.n_out, n_in, est.coarse_taps.shape[2]))
    fine[:, cols] = est.fine_taps
    coarse[:, cols] = est.coarse_taps
    return dataclasses.replace(est, fine_taps=fine, coarse_taps=coarse)


@dataclasses.dataclass(frozen=True)
class Straddling:
    """
    The lag products of the sample pairs that straddle two chunks of one segment.

    ``total`` sums every such pair; ``touching[b]`` those with a sample in block ``b``.  A
    fold's training data is every block but one, so its straddling pairs are ``total -
    touching[k]`` (:meth:`for_fold`), formed by sums as the blocks' own correlations are.
    Arrays as :class:`.correlations.Correlations` (``rxx``, ``rxy``), summed, not averaged.
    """

    total: Tuple[np.ndarray, np.ndarray]
    touching: Tuple[Tuple[np.ndarray, np.ndarray], ...]

    def for_fold(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """Return the straddling sums of the pairs outside block ``k`` (its training side)."""
        return (self.total[0] - self.touching[k][0], self.total[1] - self.touching[k][1])


def straddling_sums(segments, blocks: Sequence[Sequence[Piece]], max_lag: int,
                    means: Optional[Sequence[np.ndarray]] = None) -> Straddling:
    """
    Return the straddling pairs' sums of the chunks of ``blocks`` (:class:`Straddling`).

    Every two chunks of one segment less than ``max_lag`` samples apart contribute the pairs
    between the end of the first and the start of the second
    (:func:`.correlations.straddling_products`), with its segment's mean removed as
    :func:`block_stats` removes it (``means``: :func:`segment_means`, computed when not
    given).  With them a fold's training correlations are those of
    its chunks as one piecewise signal: the per-chunk sums alone dropped the pairs across
    chunk edges, a fraction ~τ / chunk at lag τ (47 % at a 4 s lag on 7.5 s chunks), which
    shrank the long lags of every fold's fit and so favoured short filters.
    """
    first = segments[0]
    n_in, n_out = first.accel_mps2.shape[0], first.force_n.shape[0]
    chunks = sorted((p.segment, p.start, p.stop, b) for b, block in enumerate(blocks)
                    for p in block)

    def stacked(s, a, b):
        seg = segments[s]
        return np.concatenate([seg.accel_mps2[:, a:b], seg.force_n[:, a:b]], axis=0)

    means = [m[:, None] for m in (segment_means(segments) if means is None else means)]
    shape = ((n_in, n_in, 2 * max_lag + 1), (n_in, n_out, 2 * max_lag + 1))
    total = [np.zeros(shape[0]), np.zeros(shape[1])]
    touching = [[np.zeros(shape[0]), np.zeros(shape[1])] for _ in blocks]
    for i, (s, a, b, blk) in enumerate(chunks):
        for s2, a2, b2, blk2 in chunks[i + 1:]:
            gap = a2 - b
            if s2 != s or gap >= max_lag:
                break
            if gap < 0:
                raise ValueError(f'straddling pairs: chunks {a}..{b} and {a2}..{b2} of '
                                 f'segment {s} overlap')
            n1 = min(b - a, max_lag)
            n2 = min(b2 - a2, max_lag - gap)
            sums = straddling_products(stacked(s, b - n1, b) - means[s],
                                       stacked(s, a2, a2 + n2) - means[s2], gap,
                                       n_in, max_lag)
            for target in [total, touching[blk]] + ([touching[blk2]] if blk2 != blk else []):
                target[0] += sums[0]
                target[1] += sums[1]
    return Straddling(tuple(total), tuple(tuple(t) for t in touching))


def fold_correlations(train: Sequence[Correlations],
                      straddling: Optional[Tuple[np.ndarray, np.ndarray]]) -> Correlations:
    """
    Return a fold's training correlations: its blocks' combined plus their straddling pairs.

    ``straddling`` is :meth:`Straddling.for_fold` (None: the blocks' own pairs only).
    """
    corr = combine_correlations(train)
    if straddling is None:
        return corr
    n = corr.n_samples
    return Correlations(corr.rxx + straddling[0] / n, corr.rxy + straddling[1] / n,
                        corr.fs_hz, n)


def combine_correlations(items: Sequence[Correlations]) -> Correlations:
    """Return the sample-weighted average of correlations of disjoint data."""
    total = sum(c.n_samples for c in items)
    rxx = sum(c.rxx * (c.n_samples / total) for c in items)
    rxy = sum(c.rxy * (c.n_samples / total) for c in items)
    return Correlations(rxx, rxy, items[0].fs_hz, int(total))


class _RecentFactors:
    """
    The factors of the last few normal matrices, by what determines them, within a budget.

    The normal matrix of the least-squares FIR depends on the inputs' correlations, the
    look-ahead, the basis and the ridge, never on the outputs.  The diagnosis refits one
    design on the same input records with other outputs many times (the backfit's
    alternation, the Frisch-Waugh-Lovell columns, one per term group, the held-out blocks'
    models), and each refit factorised the same matrices again (the largest part of a
    refit).  Keyed on a digest of ``rxx`` and the rest of the matrix's inputs, so another
    training set can never be served a stale factor.  A factor bordered from a smaller
    set's (:class:`.nested_factor.BorderedFactor`) is kept as its parts, under a key that
    also names how it was made (``chain``: the input counts from the factorised set up), so
    a fit gets the same rounding whatever the cache held.

    Bounded by bytes, not entries: a refit whose rows take three input sets at two ridges
    needs five factors, and a bound of four entries evicted each one before its next use
    (one diagnosis of a 2-minute record: 508 s under cProfile, 301 s of them in 226
    factorisations; 2026-12-06).  Two factorised accelerations sets (~220 MB each at the
    defaults) and their bordered parts (~45 MB per added pair of inputs) stay well within
    the budget.
    """

    def __init__(self, max_bytes: int = 1 << 30):
        self._items: 'collections.OrderedDict[tuple, object]' = collections.OrderedDict()
        self._max_bytes = int(max_bytes)
        self._lock = threading.Lock()       # fleet workers may fit in threads

    @staticmethod
    def key(corr: Correlations, d_max: int, design: LiveDesign, ridge: float,
            chain: Tuple[int, ...]) -> tuple:
        digest = hashlib.blake2b(np.ascontiguousarray(corr.rxx).tobytes(),
                                 digest_size=20).hexdigest()
        return (digest, corr.rxx.shape, float(corr.fs_hz), int(d_max), design, float(ridge),
                tuple(chain))

    def factor(self, key: tuple, eq: NormalEquations, ridge: float, inner=None):
        """
        Return ``eq``'s factorisation at ``ridge``, reusing what is stored at ``key``.

        ``inner``: the factor to border from (a :class:`.nested_factor.BorderedFactor`),
        None to factorise (a :class:`.LagOrderedFactor`).
        """
        with self._lock:
            known = self._items.get(key)
            if known is not None:
                self._items.move_to_end(key)
        if inner is None:
            out = LagOrderedFactor(eq, ridge, cholesky=known)
            state = out.cholesky
        else:
            # the parts are formed per look-ahead on first use, into the stored dict
            out = BorderedFactor(inner, eq, ridge, parts=known)
            state = out.parts
        if known is None:
            with self._lock:
                self._items[key] = state
                while len(self._items) > 1 and self.nbytes() > self._max_bytes:
                    self._items.popitem(last=False)
        return out

    def nbytes(self) -> int:
        """Return the bytes of the arrays held (bordered parts as formed so far)."""
        total = 0
        for state in self._items.values():
            if isinstance(state, np.ndarray):
                total += state.nbytes
            else:
                total += sum(a.nbytes for part in list(state.values()) for a in part)
        return total


_FACTORS = _RecentFactors()


class LsSolutions:
    """
    The least-squares FIRs of one training set: one factorisation per ridge.

    ``equations``: the normal equations of ``corr`` already at hand (a subset's, taken from
    the full set's by :meth:`.NormalEquations.subset`), else built here.  ``inner``: the
    solutions of the previous nested input set (its inputs the first of ``corr``'s, and
    ``equations`` given): the factor of each ridge ``inner`` has is bordered from its
    factor (:class:`.nested_factor.BorderedFactor`) instead of factorised from scratch; a
    ridge it does not have is factorised.
    ``cache``: keep the factors in the bounded cache of recent ones (:class:`_RecentFactors`)
    for a later fit on the same inputs; False for a training set fitted once (a fold of the
    search), whose factors would only push out ones that are reused and keep ~220 MB each
    alive (through the final fit of a 20-minute bag).
    """

    def __init__(self, corr: Correlations, design: LiveDesign, ridges: Sequence[float],
                 equations: Optional[NormalEquations] = None,
                 inner: Optional['LsSolutions'] = None, cache: bool = True):
        self.fs_hz = corr.fs_hz
        self.d_max = look_ahead_samples(LS_LOOK_AHEAD_S, corr.fs_hz)
        base = (float(ridges[0]) if equations is None
                else float(equations.info['regularisation']))
        design = dataclasses.replace(design, look_aheads_s=(LS_LOOK_AHEAD_S,),
                                     regularisation=base)
        eq = NormalEquations(corr, self.d_max, design) if equations is None else equations
        inner_factors = inner.factors if inner is not None and equations is not None else {}
        self.factors = {}
        for r in ridges:
            below = inner_factors.get(r)
            if not cache:
                self.factors[r] = (LagOrderedFactor(eq, r) if below is None
                                   else BorderedFactor(below, eq, r))
                continue
            chain = (eq.n_in,) if below is None else below.chain + (eq.n_in,)
            self.factors[r] = _FACTORS.factor(
                _FACTORS.key(corr, self.d_max, design, r, chain), eq, r, below)
        self._estimators: Dict[Tuple[float, int], CausalEstimator] = {}

    def estimator(self, ridge: float, look_ahead: int) -> CausalEstimator:
        """Return the estimator of ``ridge`` at ``look_ahead`` samples (solved once)."""
        key = (ridge, int(look_ahead))
        if key not in self._estimators:
            self._estimators[key] = self.factors[ridge].estimator(look_ahead)
        return self._estimators[key]

    def response(self, ridge: float, look_ahead: int, n_fft: int) -> np.ndarray:
        """Return the realised response on the ``n_fft`` grid, shape (nf, n_out, n_in)."""
        fir = self.estimator(ridge, look_ahead).fir(self.fs_hz)
        return response_on_grid(fir.taps, fir.delay_samples, n_fft)


def set_design(design: LiveDesign, n_in: int, fs_hz: float) -> LiveDesign:
    """
    Return ``design`` with the basis of an input set of ``n_in`` inputs.

    Each set takes the finest basis the cost bound allows for the inputs it holds
    (:meth:`.LiveDesign.for_inputs`), not the model's: a row that uses the 12 accelerations
    keeps their basis when the logger also records the wheel spin.  Measured (2026-12-07,
    ``bench/bench_design.py --cars compact --inputs accel+spin+split+cornering
    --train-scale 0.2``): the model's 20 inputs set 32 blocks per octave for every set, and
    the live ``Fz`` rows, which take the accelerations alone, scored 15.0 % held out against
    9.7 % for the same rows of a model without the spin (48 blocks per octave).
    """
    return design.for_inputs(n_in, fs_hz)


def set_parents(sets, design: LiveDesign, fs_hz: float) -> Tuple[Optional[int], ...]:
    """
    Return :func:`.spindle.parents` of ``sets``, None where a parent's basis differs.

    A factor is bordered from its parent's only on one basis (:mod:`.nested_factor`); a set
    whose basis is coarser than its parent's (:func:`set_design`) is factorised afresh.
    """
    bpo = [set_design(design, len(cols), fs_hz).blocks_per_octave for _, cols in sets]
    return tuple(p if p is not None and bpo[p] == bpo[i] else None
                 for i, p in enumerate(parents(sets)))


def set_equations(corr: Correlations, design: LiveDesign, columns: Sequence[Sequence[int]],
                  base_ridge: float) -> Dict[Tuple[int, ...], Optional[NormalEquations]]:
    """
    Return the LS normal equations of every input set (``columns``) for :class:`LsSolutions`.

    One build per basis (:func:`set_design`) serves every set on it: a subset's matrix is a
    sub-block of the one built on the inputs of all the basis's sets
    (:meth:`.NormalEquations.subset`, its blocks taken from that one); a larger nested set's
    factor is bordered from the smaller set's (``LsSolutions(..., inner=)``).  A set alone on
    its basis: ``None`` (:class:`LsSolutions` builds its own, of that set only).
    """
    fs = corr.fs_hz
    on_basis: Dict[Optional[int], List[Tuple[int, ...]]] = {}
    for c in (tuple(c) for c in columns):
        on_basis.setdefault(set_design(design, len(c), fs).blocks_per_octave, []).append(c)
    out: Dict[Tuple[int, ...], Optional[NormalEquations]] = {}
    for bpo, sets in on_basis.items():
        if len(sets) <= 1:
            out.update(dict.fromkeys(sets))
            continue
        inputs = sorted(set().union(*sets))
        full = NormalEquations(
            corr if len(inputs) == corr.rxx.shape[0] else subset_correlations(corr, inputs),
            look_ahead_samples(LS_LOOK_AHEAD_S, fs),
            dataclasses.replace(design, look_aheads_s=(LS_LOOK_AHEAD_S,), blocks_per_octave=bpo,
                                regularisation=float(base_ridge)))
        at = {j: k for k, j in enumerate(inputs)}
        out.update({c: full if c == tuple(inputs) else full.subset([at[j] for j in c])
                    for c in sets})
    return out


def score_fold(h1: Dict[Tuple[int, float], np.ndarray],
               ls: Dict[Tuple[float, float], np.ndarray],
               live: Dict[float, np.ndarray], cands: Sequence[Candidate],
               held_out: CrossSpectra) -> Tuple[List[HeldOutPower], List[HeldOutPower]]:
    """
    Score every candidate (and every live ridge) of one fold on its held-out block.

    Each distinct response is a base of one :class:`.crossval.BlendScorer`, and a spliced
    candidate is scored from its two bases' terms (no response per candidate).

    Parameters
    ----------
    h1 : dict
        ``{(segment_length, long_regularisation): response}`` on the scoring grid.
    ls : dict
        ``{(ridge, look_ahead_s): response}`` of the LS FIRs on the scoring grid.
    live : dict
        ``{ridge: response}`` of the live LS FIR on the scoring grid.
    cands : sequence of Candidate
        Offline candidates.
    held_out : CrossSpectra
        Welch spectra of the held-out block (scoring grid).

    Returns
    -------
    (list of HeldOutPower, list of HeldOutPower)
        Per candidate, per live ridge (in ``live`` order).

    """
    f = held_out.f_hz
    ramps = [c.crossover_hz for c in cands if c.family == 'spliced']
    # a splice's weights are both non-zero from its crossover to 1.5 times it only
    scorer = BlendScorer(held_out, hp_power_weight(f, held_out.config.fs_hz),
                         pair_max_hz=1.5 * max(ramps, default=0.0))
    for key, h in h1.items():
        scorer.add(('h1',) + key, h)
    same = {}
    for key, h in ls.items():
        scorer.add(('ls',) + key, h)
        same[id(h)] = ('ls',) + key
    live_keys = []
    for key, h in live.items():
        if id(h) not in same:                 # the live FIR is an LS candidate too
            same[id(h)] = ('live', key)
            scorer.add(same[id(h)], h)
        live_keys.append(same[id(h)])
    offline = []
    for c in cands:
        h1_key = ('h1', c.segment_length, c.long_regularisation)
        ls_key = ('ls', c.ls_regularisation, c.ls_look_ahead_s)
        if c.family == 'h1':
            offline.append(scorer.power(h1_key))
        elif c.family == 'ls':
            offline.append(scorer.power(ls_key))
        else:
            offline.append(scorer.power(ls_key, h1_key, blend_weight(f, c.crossover_hz)))
    return offline, [scorer.power(key) for key in live_keys]
