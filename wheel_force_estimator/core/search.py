# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The fit of ``wheel-force fit``, read top to bottom: scores, design, estimate, FIR, live.

:func:`search` then :func:`fit_chosen` are the whole sequence (the bag path and the
generic-recording path both reach them through :func:`.design.fit_design`, which adds the
fallbacks for records too short to search and builds the model):

1. **blocks** (:func:`scoring_blocks`): the longest scoring resolution (long Welch segment
   first) whose windows every block holds twice; the data cut into chunks dealt to
   :data:`.crossval.N_BLOCKS` blocks.  Too short: ``None`` (the caller fits the defaults and
   says so).
2. **statistics per block, once** (:func:`.candidates.block_stats`): Welch cross-spectra at
   every resolution of the grid and the correlations of the least-squares FIRs, plus the
   pairs that straddle two chunks (:func:`.candidates.straddling_sums`), so a fold's
   training correlations are those of its chunks as one signal.
3. **candidates** (:func:`space`): input sets x H1 variants x LS ridges x splice
   crossovers; a setting the user imposed keeps its value.  The input sets are nested by
   group (:func:`.spindle.input_sets`: accelerations; + angular rates; + spin; + the
   splits, those the model has, and the splits on the accelerations alone; one set of
   every input for a generic recording or when the user imposed ``inputs``).
4. **held-out scores**, fold by fold and input set by input set: each candidate is fitted
   from the sums of the other blocks' statistics (the set's columns of them) and scored on
   the held-out block (:mod:`.crossval`), both figures.  The live estimator's ridge is
   scored on the same folds from the same factorisations (one per set and ridge: the
   lag-ordered factor interleaves the inputs, so a subset needs its own; its normal matrix
   is a sub-block of the full set's, built once per fold).
5. **the chosen design**: per output row, the input set whose best offline candidate has
   the lowest held-out error (relative MSE, unfiltered plus 1 Hz high-passed) on folds
   whose every block samples the whole record (:func:`set_blocks`: on records under ~6.4
   min a second cross-validation on shorter chunks and a coarser grid), summed over the
   four corners' rows of the row's component (:func:`.spindle.component_groups`), and in that set
   the live estimator's ridge with the lowest held-out error of the live estimator; then
   the set's candidate with the lowest held-out error among those no worse than that live
   estimator in either figure.
6. **the estimate** (:func:`fit_chosen`): the chosen H1 variants and LS factorisations on
   all the data, per input set (one factorisation per set and ridge serves the offline FIR
   and every live look-ahead).
7. **the FIR**: the rows composed into one FRF over every input (exactly zero for the
   inputs outside a row's set) and realised exactly (:func:`_realised`).
8. **the live estimators**: every stored look-ahead, each row with its chosen set and ridge
   (zero taps outside the set); the caller builds the model
   (:func:`.pipeline.build_model`) with ``fit.design``.
"""
import dataclasses
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.candidates import block_stats
from wheel_force_estimator.core.candidates import BlockStats
from wheel_force_estimator.core.candidates import Candidate
from wheel_force_estimator.core.candidates import candidates
from wheel_force_estimator.core.candidates import embedded_estimator
from wheel_force_estimator.core.candidates import embedded_response
from wheel_force_estimator.core.candidates import fold_correlations
from wheel_force_estimator.core.candidates import LONG_REGULARISATIONS
from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
from wheel_force_estimator.core.candidates import LS_REGULARISATIONS
from wheel_force_estimator.core.candidates import LsSolutions
from wheel_force_estimator.core.candidates import score_fold
from wheel_force_estimator.core.candidates import SCORING
from wheel_force_estimator.core.candidates import SEGMENT_FACTORS
from wheel_force_estimator.core.candidates import segment_means
from wheel_force_estimator.core.candidates import set_equations
from wheel_force_estimator.core.candidates import set_parents
from wheel_force_estimator.core.candidates import SPLICE_CROSSOVERS_HZ
from wheel_force_estimator.core.candidates import straddling_sums
from wheel_force_estimator.core.candidates import subset_correlations
from wheel_force_estimator.core.candidates import subset_spectra
from wheel_force_estimator.core.crossval import best_rows
from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.crossval import block_pieces
from wheel_force_estimator.core.crossval import CHUNKS_PER_BLOCK
from wheel_force_estimator.core.crossval import HeldOutPower
from wheel_force_estimator.core.crossval import N_BLOCKS
from wheel_force_estimator.core.crossval import Piece
from wheel_force_estimator.core.crossval import splice
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import response_on_grid
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.live_estimator import on_common_edges
from wheel_force_estimator.core.pipeline import estimate_h1
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spindle import component_groups
from wheel_force_estimator.core.spindle import input_sets

#: Shortest scoring resolution tried [samples]; each block must hold two of its windows.
MIN_SCORING_SEGMENT = 1024
#: Settings that pin the offline estimator to the H1 family when the user sets them.
H1_ONLY_KEYS = frozenset({'estimator'})
#: The setting that pins the input set (``wheel_force_fit.inputs``): all inputs, not searched.
INPUTS_KEY = 'inputs'


@dataclasses.dataclass(frozen=True)
class Space:
    """
    What the search covers.

    Attributes
    ----------
    h1 : tuple of (int, float)
        H1 variants: (short segment length, long-segment regularisation).
    ridges : tuple of float
        LS ridges (offline and live).
    offline : tuple of Candidate
        Offline candidates.
    imposed : tuple of str
        Settings the user imposed (kept, not searched).
    input_sets : tuple of (str, tuple of int)
        The nested input sets tried (:func:`.spindle.input_sets`): name and the columns of
        the inputs; the last one is every input.

    """

    h1: Tuple[Tuple[int, float], ...]
    ridges: Tuple[float, ...]
    offline: Tuple[Candidate, ...]
    imposed: Tuple[str, ...]
    input_sets: Tuple[Tuple[str, Tuple[int, ...]], ...] = ()

    @property
    def needs_ls(self) -> bool:
        """Return whether any candidate uses the least-squares FIR."""
        return any(c.family != 'h1' for c in self.offline)


@dataclasses.dataclass(frozen=True)
class Choice:
    """
    The chosen design and every candidate's held-out score.

    Attributes
    ----------
    rows : tuple of Candidate
        Offline design per output row.
    row_sets : tuple of int
        Input set per output row of the offline design (index into ``space.input_sets``).
    live_ridges : tuple of float
        Live-estimator ridge per output row.
    live_sets : tuple of int
        Input set per output row of the live estimator.
    scores, live_scores : tuple of tuple of HeldOutPower
        Per input set, the held-out power per offline candidate (``space.offline`` order)
        and per live ridge (``space.ridges`` order).
    space : Space
        What was searched.
    n_score : int
        Scoring resolution [samples].
    blocks_s : tuple of float
        Duration of each block [s].
    set_scores : tuple of tuple of HeldOutPower
        Per input set, the held-out power per offline candidate of the folds that chose
        the input sets (:func:`set_blocks`; ``scores`` when they are the same folds).
    set_n_score : int
        Their scoring resolution [samples].
    set_blocks_s : tuple of float
        Duration of each of their blocks [s].

    """

    rows: Tuple[Candidate, ...]
    row_sets: Tuple[int, ...]
    live_ridges: Tuple[float, ...]
    live_sets: Tuple[int, ...]
    scores: Tuple[Tuple[HeldOutPower, ...], ...]
    live_scores: Tuple[Tuple[HeldOutPower, ...], ...]
    space: Space
    n_score: int
    blocks_s: Tuple[float, ...]
    set_scores: Tuple[Tuple[HeldOutPower, ...], ...]
    set_n_score: int
    set_blocks_s: Tuple[float, ...]

    def record(self, output_channels: Sequence[str], input_channels: Sequence[str]) -> dict:
        """
        Return the model's ``fit.design`` entry (JSON).

        Per row: the chosen candidate and input set (``inputs``) with its held-out RMSE, the
        live ridge and input set, and under ``input_sets`` the held-out RMSE of the best
        candidate (lowest criterion) of every input set tried, on the folds that chose the
        input sets (``input_set_folds``); ``input_set_groups``: the rows that chose their
        input set together (:func:`.spindle.component_groups`, groups of two or more).
        """
        def figures(score: HeldOutPower) -> dict:
            pct = score.rmse_pct()
            return {'cv_rmse_pct': [round(float(v), 3) for v in pct[0]],
                    'cv_rmse_hp1_pct': [round(float(v), 3) for v in pct[1]]}

        sets = self.space.input_sets
        index = {c: k for k, c in enumerate(self.space.offline)}
        best = np.argmin(_criteria(self.set_scores), axis=1)                    # (set, o)
        rows = {}
        for o, (name, cand) in enumerate(zip(output_channels, self.rows)):
            pct = self.scores[self.row_sets[o]][index[cand]].rmse_pct()
            per_set = {}
            for s, (set_name, _) in enumerate(sets):
                p = self.set_scores[s][best[s, o]].rmse_pct()
                per_set[set_name] = {'cv_rmse_pct': round(float(p[0, o]), 3),
                                     'cv_rmse_hp1_pct': round(float(p[1, o]), 3)}
            rows[name] = dict(cand.as_dict(), inputs=sets[self.row_sets[o]][0],
                              cv_rmse_pct=round(float(pct[0, o]), 3),
                              cv_rmse_hp1_pct=round(float(pct[1, o]), 3),
                              live_regularisation=self.live_ridges[o],
                              live_inputs=sets[self.live_sets[o]][0], input_sets=per_set)
        return {'method': 'blocked_cross_validation', 'n_blocks': len(self.blocks_s),
                'blocks_s': [round(b, 3) for b in self.blocks_s],
                'scoring_segment_length': self.n_score, 'imposed': list(self.space.imposed),
                'input_set_folds': {'n_blocks': len(self.set_blocks_s),
                                    'blocks_s': [round(b, 3) for b in self.set_blocks_s],
                                    'scoring_segment_length': self.set_n_score},
                'input_sets': [{'name': n, 'channels': [input_channels[i] for i in cols]}
                               for n, cols in sets],
                'input_set_groups': [[output_channels[o] for o in g]
                                     for g in component_groups(output_channels) if len(g) > 1],
                'rows': rows,
                'candidates': [dict(c.as_dict(), inputs=n, **figures(sc))
                               for (n, _), per in zip(sets, self.scores)
                               for c, sc in zip(self.space.offline, per)],
                'live_candidates': [dict({'regularisation': r, 'inputs': n}, **figures(sc))
                                    for (n, _), per in zip(sets, self.live_scores)
                                    for r, sc in zip(self.space.ridges, per)]}


def other_set_folds(design: dict) -> dict:
    """
    Return ``design['input_set_folds']`` when they are not the scoring folds, else ``{}``.

    ``design``: a model's ``meta.fit.design`` (:meth:`Choice.record`); a model written
    before the input-set folds has none.
    """
    folds = design.get('input_set_folds') or {}
    same = (folds.get('blocks_s') == design.get('blocks_s')
            and folds.get('scoring_segment_length') == design.get('scoring_segment_length'))
    return {} if not folds or same else folds


def scoring_blocks(lengths: Sequence[int], config: FitConfig
                   ) -> Tuple[Optional[int], Optional[List[List[Piece]]]]:
    """Return the scoring segment (longest that every block holds twice) and the blocks."""
    length = max(config.long_segment_length, 2 * config.segment_length)
    while length >= max(MIN_SCORING_SEGMENT, config.segment_length):
        # two 50 %-overlapping windows need 1.5 segments
        blocks = block_pieces(lengths, N_BLOCKS, (3 * length) // 2)
        if blocks is not None:
            return length, blocks
        length //= 2
    return None, None


def set_blocks(lengths: Sequence[int], config: FitConfig
               ) -> Tuple[Optional[int], Optional[List[List[Piece]]]]:
    """
    Return the scoring segment and blocks of the input-set choice: every block's chunks.

    The longest scoring segment whose chunks still number
    ``N_BLOCKS * CHUNKS_PER_BLOCK`` (each block samples the whole recording, as
    :func:`.crossval.block_pieces` promises); on a record too short for that at the
    shortest segment, :func:`scoring_blocks`'s.  :func:`scoring_blocks` prefers the finer
    grid, so on short records (under ~6.4 min at 512 Hz) it deals a few long chunks, most
    blocks one contiguous stretch: a fold then holds out a road event its training side
    never saw, and a slope per turn side (the cornering split) learnt without it scores
    worse than the accelerations' one slope although the whole record carries both turns
    (docs/fit_design.md, "Input sets").
    """
    length = max(config.long_segment_length, 2 * config.segment_length)
    while length >= max(MIN_SCORING_SEGMENT, config.segment_length):
        blocks = block_pieces(lengths, N_BLOCKS, (3 * length) // 2)
        if blocks is not None and sum(map(len, blocks)) >= N_BLOCKS * CHUNKS_PER_BLOCK:
            return length, blocks
        length //= 2
    return scoring_blocks(lengths, config)


def space(config: FitConfig, imposed: frozenset, n_score: int,
          live_look_ahead_s: Optional[float], input_channels: Sequence[str]) -> Space:
    """
    Return the candidates: the grids of the defaults, imposed settings kept.

    The input sets: the nested groups of :func:`.spindle.input_sets`, or every input alone
    when the user imposed them (:data:`INPUTS_KEY`).
    """
    long = config.long_segment_length
    if 'segment_length' in imposed:
        segs = (config.segment_length,)
    else:
        segs = tuple(config.segment_length * k for k in SEGMENT_FACTORS
                     if config.segment_length * k <= n_score
                     and (not long or config.segment_length * k < long))
    lregs = ((config.long_regularisation,) if 'long_regularisation' in imposed or not long
             else LONG_REGULARISATIONS)
    crossovers = (0.0,) if imposed & H1_ONLY_KEYS else SPLICE_CROSSOVERS_HZ
    sets = input_sets(input_channels)
    if INPUTS_KEY in imposed:
        sets = sets[-1:]
    return Space(tuple((s, lr) for s in segs for lr in lregs), LS_REGULARISATIONS,
                 tuple(candidates(segs, lregs, LS_REGULARISATIONS, crossovers,
                                  live_look_ahead_s)),
                 tuple(sorted(imposed)), sets)


def h1_fits(stats: Sequence[BlockStats], config: FitConfig, variants, fs_hz: float,
            order: int, input_channels, columns: Optional[Sequence[int]] = None
            ) -> Dict[Tuple[int, float], tuple]:
    """
    Return ``{(segment, long_reg): estimate_h1(...)}`` from the sums of ``stats``.

    ``columns``: fit on those inputs only (``input_channels`` are all the inputs); None: all.
    """
    long = config.long_segment_length
    cols = tuple(range(len(input_channels))) if columns is None else tuple(columns)
    names = [input_channels[i] for i in cols]
    out = {}
    for seg, lreg in variants:
        short = [s.spectra[seg] for s in stats if seg in s.spectra]
        longs = [s.spectra[long] for s in stats if long and long in s.spectra]
        cfg = dataclasses.replace(config, segment_length=seg, long_regularisation=lreg,
                                  long_segment_length=long if longs else 0)
        out[(seg, lreg)] = estimate_h1(
            subset_spectra(combine_spectra(short), cols),
            subset_spectra(combine_spectra(longs), cols) if longs else None, cfg, fs_hz,
            order, names)
    return out


def welch_configs(config: FitConfig, fs_hz: float, sp: Space, n_score: int) -> dict:
    """
    Return ``{segment_length: WelchConfig}`` of every resolution the search needs.

    The scorer's (key :data:`.candidates.SCORING`): ``n_score``-sample windows without
    per-window detrend (the segment's mean is removed instead), so a window does not hide the
    quasi-static error below its own resolution from the unfiltered figure; measured, per-window
    detrend made the H1 rows of the van's Fz look 30 % better than the live estimator where
    a held-out course found them 7 % worse.
    """
    lengths = {s for s, _ in sp.h1} | {config.long_segment_length}
    out = {n: dataclasses.replace(config.welch(fs_hz), segment_length=n) for n in lengths if n}
    out[SCORING] = dataclasses.replace(config.welch(fs_hz), segment_length=n_score,
                                       detrend='none')
    return out


def max_lag(live: LiveDesign, fs_hz: float) -> int:
    """Return the correlation lags the LS FIRs need (the offline look-ahead included)."""
    return dataclasses.replace(live, look_aheads_s=live.look_aheads_s + (
        LS_LOOK_AHEAD_S,)).max_lag(fs_hz)


def live_design(config: FitConfig) -> LiveDesign:
    """
    Return the live design of ``config`` (default if unset).

    A basis left to the default is resolved per input set, for the inputs the set holds
    (:func:`.candidates.set_design`).
    """
    return config.live or LiveDesign()


def search(used, fs_hz: float, config: FitConfig, input_channels, order: int,
           imposed: frozenset = frozenset(), progress=lambda it, desc: it,
           output_channels: Sequence[str] = ()) -> Optional[Tuple[Choice, dict, int]]:
    """
    Choose each output's design by blocked cross-validation (see the module notes).

    ``output_channels`` name the rows (:func:`.spindle.component_groups`: the four corners'
    rows of one component choose their input set together); none: each row alone.

    Returns
    -------
    (Choice, dict, int) or None
        The choice, the Welch configurations and correlation lags of the search (for the
        final fit); ``None`` when the data is too short for :data:`.crossval.N_BLOCKS`
        blocks.

    """
    live = live_design(config)
    too_long = [v for v in live.look_aheads_s if v > LS_LOOK_AHEAD_S]
    if too_long:
        raise ConfigError(f'live_look_ahead_s {too_long[0]:g} s is outside 0 .. '
                          f'{LS_LOOK_AHEAD_S:g} s: the live estimators are solved from the '
                          f'factorisation of the {LS_LOOK_AHEAD_S:g} s least-squares FIR')
    lengths = [s.accel_mps2.shape[1] for s in used]
    n_score, blocks = scoring_blocks(lengths, config)
    if n_score is None:
        return None
    sp = space(config, imposed, n_score, live.look_aheads_s[0], input_channels)
    lags = max_lag(live, fs_hz) if (sp.needs_ls or config.live is not None) else 0
    means = segment_means(used)         # removed from every piece, as the final fit does
    folds = _Folds(used, fs_hz, config, order, input_channels, live, lags, means, progress)
    # the scorer's window: the longest power of two every chunk holds (the finest grid)
    n_score = _grid(blocks)
    welch = welch_configs(config, fs_hz, sp, n_score)
    scores, live_scores, blocks_s = folds.scores(blocks, sp, welch, n_score, 'fit')
    n_out = scores[0][0].error.shape[-1]
    set_scores, set_grid, set_blocks_s = scores, n_score, blocks_s
    if lags:
        # the input set per row: the offline candidates' best (which inputs carry a row's
        # force is one question; the offline candidates' scores separate the sets where
        # the live ones near-tie: docs/fit_design.md §5), on folds whose every block
        # samples the whole record (:func:`set_blocks`); the live ridge within it
        n_set, s_blocks = set_blocks(lengths, config)
        if len(sp.input_sets) > 1 and s_blocks != blocks:
            set_grid = _grid(s_blocks)
            # the long segment only where the set's chunks hold its windows
            cfg = (config if n_set >= config.long_segment_length
                   else dataclasses.replace(config, long_segment_length=0))
            s_sp = space(cfg, imposed, n_set, live.look_aheads_s[0], input_channels)
            set_scores, _, set_blocks_s = folds.scores(
                s_blocks, s_sp, welch_configs(cfg, fs_hz, s_sp, set_grid), set_grid,
                'fit: input sets')
        live_sets = np.argmin(_pooled(_criteria(set_scores).min(axis=1),
                                      component_groups(output_channels)), axis=0)
        live_rows = np.argmin(_criteria(live_scores)[live_sets, :, np.arange(n_out)], axis=1)
    else:
        live_sets = live_rows = np.zeros(n_out, dtype=int)
    row_sets, rows = _offline_rows(scores, sp, live.look_aheads_s[0],
                                   [(int(i), sp.ridges[r]) for i, r in zip(live_sets, live_rows)]
                                   if lags else None)
    choice = Choice(tuple(sp.offline[i] for i in rows), tuple(int(i) for i in row_sets),
                    tuple(float(sp.ridges[i]) for i in live_rows),
                    tuple(int(i) for i in live_sets),
                    tuple(tuple(per) for per in scores), tuple(tuple(per) for per in live_scores),
                    sp, n_score, blocks_s, tuple(tuple(per) for per in set_scores), set_grid,
                    set_blocks_s)
    return choice, welch, lags


def _grid(blocks: Sequence[Sequence[Piece]]) -> int:
    """Return the scorer's window [samples]: the longest power of two every chunk holds."""
    return 1 << int(np.log2(min(p.stop - p.start for b in blocks for p in b)))


@dataclasses.dataclass(frozen=True)
class _Folds:
    """What every cross-validation of one search shares: the data and the live design."""

    used: Sequence
    fs_hz: float
    config: FitConfig
    order: int
    input_channels: Sequence[str]
    live: LiveDesign
    lags: int
    means: Sequence
    progress: object

    def scores(self, blocks, sp: Space, welch: dict, n_score: int, desc: str):
        """
        Return the held-out powers of ``blocks``' folds, per input set.

        Returns
        -------
        (list, list, tuple)
            Per input set, the pooled held-out power per offline candidate (``sp.offline``
            order) and per live ridge (``sp.ridges`` order); each block's duration [s].

        """
        used, fs_hz, lags, live = self.used, self.fs_hz, self.lags, self.live
        stats = [block_stats(used, b, welch, fs_hz, lags, self.means)
                 for b in self.progress(blocks, f'{desc}: blocks')]
        # the pairs across chunk edges, so each fold's correlations are its chunks' as one
        # signal
        straddling = straddling_sums(used, blocks, lags, self.means) if lags else None
        d_ls = look_ahead_samples(LS_LOOK_AHEAD_S, fs_hz)
        d_live = look_ahead_samples(live.look_aheads_s[0], fs_hz)
        scores = [None] * len(sp.input_sets)
        live_scores = [None] * len(sp.input_sets)
        parent = set_parents(sp.input_sets, live, fs_hz)
        for k in self.progress(range(len(stats)), f'{desc}: cross-validation'):
            train = [s for j, s in enumerate(stats) if j != k]
            corr = (fold_correlations([s.corr for s in train], straddling.for_fold(k))
                    if lags else None)
            # every input set from the same block statistics: its columns of the spectra and
            # correlations; a set's LS factors bordered from its parent's (the earlier set
            # its columns begin with), kept until no later set borders from them
            eqs = (set_equations(corr, live, [c for _, c in sp.input_sets], min(sp.ridges))
                   if lags else {})
            solved: Dict[int, LsSolutions] = {}
            ls = None
            for i, (_, cols) in enumerate(sp.input_sets):
                h1 = {key: response_on_grid(fit[2].taps, fit[2].delay_samples, n_score)
                      for key, fit in h1_fits(train, self.config, sp.h1, fs_hz, self.order,
                                              self.input_channels, cols).items()}
                ls_resp, live_resp = {}, {}
                if lags:
                    ls = LsSolutions(subset_correlations(corr, cols), live, sp.ridges,
                                     eqs.pop(cols), inner=solved.get(parent[i]), cache=False)
                    solved = {j: v for j, v in solved.items() if j in parent[i + 1:]}
                    if i in parent[i + 1:]:
                        solved[i] = ls
                    live_resp = {r: ls.response(r, d_live, n_score) for r in sp.ridges}
                    ls_resp = {(r, LS_LOOK_AHEAD_S): ls.response(r, d_ls, n_score)
                               for r in sp.ridges}
                    ls_resp.update({(r, live.look_aheads_s[0]): live_resp[r]
                                    for r in sp.ridges})
                off, lv = score_fold(h1, ls_resp, live_resp, sp.offline,
                                     subset_spectra(stats[k].spectra[SCORING], cols))
                scores[i] = off if scores[i] is None else [a + b for a, b in zip(scores[i], off)]
                live_scores[i] = (lv if live_scores[i] is None
                                  else [a + b for a, b in zip(live_scores[i], lv)])
            del ls, solved
        return scores, live_scores, tuple(s.n / fs_hz for s in stats)


def _pooled(criteria: np.ndarray, groups: Sequence[Sequence[int]]) -> np.ndarray:
    """Return ``criteria`` (set, o) with every row of a group given the group's sum."""
    out = criteria.copy()
    for members in groups:
        out[:, list(members)] = criteria[:, list(members)].sum(axis=1, keepdims=True)
    return out


def _criteria(per_set: Sequence[Sequence[HeldOutPower]]) -> np.ndarray:
    """Return the held-out criterion per input set, candidate and output, (set, cand, o)."""
    return np.stack([[p.criterion() for p in per] for per in per_set])


def _offline_rows(scores: Sequence[Sequence[HeldOutPower]], sp: Space,
                  live_look_ahead_s: float,
                  live: Optional[Sequence[Tuple[int, float]]]) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the input set and offline candidate per output, never worse than live held out.

    With a live estimator (``live``: its input set and ridge per output), the row keeps its
    input set, and the lowest criterion among that set's candidates no worse than the live
    estimator in either figure wins.  Which inputs carry a row's force is one question for
    all its estimators (docs/fit_design.md, §5): a pair from another set that beats the
    live estimator on the folds by a hair is not evidence that the row needs other inputs.
    Measured (2026-12-06, ``bench/bench_design.py --cars compact --train-scale 0.2``): with
    every pair competing, two Fy rows took a pair of ``accel`` or ``accel+split`` that the
    folds scored below the live estimator of ``accel+split+cornering``, and on the held-out
    course offline y was 16.3 % against live 13.3 %; kept in the live set, 12.8 %.

    The live estimator is itself a candidate in its input set, so the candidates kept are
    never empty: offline can never score worse than live, unfiltered or high-passed (a lower
    sum alone could trade one figure for the other: measured on the van, z 11.6 % offline
    against 10.6 % live unfiltered, bought with the high-passed figure).  Without a live
    estimator every (input set, candidate) pair competes.
    """
    n_cand = len(sp.offline)
    flat = [p for per in scores for p in per]                       # set-major
    rel = np.stack([s.error / np.maximum(s.target, np.finfo(float).tiny) for s in flat])
    criterion = rel.sum(axis=1)                                     # (n_set n_cand, n_out)
    best = best_rows(criterion)[0]
    if live is not None:
        for o, (i_set, ridge) in enumerate(live):
            same = [k for k, c in enumerate(sp.offline) if c.family == 'ls'
                    and c.ls_regularisation == ridge and c.ls_look_ahead_s == live_look_ahead_s]
            if not same:                  # no LS candidate (an imposed H1 estimator)
                continue
            ref = i_set * n_cand + same[0]
            ok = np.all(rel[:, :, o] <= rel[ref, :, o] * (1 + 1e-12), axis=1)
            ok &= np.arange(ok.size) // n_cand == i_set
            best[o] = int(np.flatnonzero(ok)[np.argmin(criterion[ok, o])])
    return best // n_cand, best % n_cand


def fit_chosen(used, choice: Choice, welch: dict, lags: int, fs_hz: float,
               config: FitConfig, order: int, input_channels, live_estimators: bool = True):
    """
    Fit the chosen design of every row on all the data and compose the rows.

    ``live_estimators`` False: the offline rows alone (no live estimator, no factorisation
    of a ridge only they use), for a caller that refits the design on pieces to score them
    offline (the diagnosis's held-out blocks: one refit cost ~2 x with them).

    Returns
    -------
    (FrfEstimate, numpy.ndarray, FirFilter, tuple of CausalEstimator, dict, ndarray, ndarray)
        Indicators (of the configured H1 variant, on the model grid), the composed FRF, its
        FIR, the live estimators (``config.live``'s look-aheads, configured one first; none
        when ``config.live`` is None), the ``fit`` metadata of the H1 estimate, the static
        inputs and outputs.

    """
    # from the whole segments: no window or pair lost at a chunk edge
    whole = block_stats(used, [Piece(i, 0, s.accel_mps2.shape[1]) for i, s in enumerate(used)],
                        welch, fs_hz, lags)
    sets = choice.space.input_sets
    n_in = len(input_channels)
    # the indicators (coherence, conditioning) of the least-regularised H1 variant at the
    # configured segment, on every input: regularisation biases the multiple coherence low
    default = min((v for v in choice.space.h1 if v[0] == config.segment_length),
                  key=lambda v: v[1], default=choice.space.h1[0])
    variants = {i: set() for i in range(len(sets))}
    ridges = {i: set() for i in range(len(sets))}
    for c, i in zip(choice.rows, choice.row_sets):
        if c.family != 'ls':
            variants[i].add((c.segment_length, c.long_regularisation))
        if c.family != 'h1':
            ridges[i].add(c.ls_regularisation)
    if live_estimators and lags:
        for r, i in zip(choice.live_ridges, choice.live_sets):
            ridges[i].add(r)
    variants[len(sets) - 1].add(default)                     # the last set: every input
    fits = {i: h1_fits([whole], config, sorted(v), fs_hz, order, input_channels, sets[i][1])
            for i, v in variants.items() if v}
    ref_est, _, ref_fir, extra = fits[len(sets) - 1][default]
    live = live_design(config)
    ls = {}
    n_model = max(ref_fir.n_taps, config.long_segment_length)
    if lags:
        ls = _ls_solutions(whole.corr, sets, ridges, live,
                           bordered=not (live_estimators and config.live is not None))
        span = (look_ahead_samples(LS_LOOK_AHEAD_S, fs_hz)
                + int(round(live.history_s * fs_hz)) + 1)
        n_model = max(n_model, 2 * int(2 ** np.ceil(np.log2(span))))
    f_hz = np.fft.rfftfreq(n_model, 1.0 / fs_hz)
    h = _compose(choice, fits, ls, f_hz, n_model, n_in)
    fir = _realised(f_hz, h, fs_hz, config.f_max_hz)
    estimators = ()
    if config.live is not None and live_estimators:
        estimators = _live_rows(ls, choice, live, fs_hz, n_in)
    return (_indicators_on(ref_est, f_hz), h, fir, estimators, extra, whole.sum_x / whole.n,
            whole.sum_y / whole.n)


def chosen_live(corr, choice: Choice, live: LiveDesign, n_in: int) -> tuple:
    """
    Return the live estimators of ``choice`` designed from ``corr``, as :func:`fit_chosen` does.

    Every stored look-ahead of ``live`` (configured one first), each output row with the input
    set and ridge the cross-validation chose for its live estimator (zero taps outside the
    set).  For a caller whose targets differ from the search's but whose design should not (the
    diagnosis: the real forces minus the written physics terms' force).

    Parameters
    ----------
    corr : Correlations
        Input and target correlations to :func:`max_lag` lags at least.
    choice : Choice
        The search's choice (its ``live_ridges`` and ``live_sets``).
    live : LiveDesign
        Look-aheads and filter design (the search's).
    n_in : int
        Inputs of the model (the search's ``input_channels``).

    Raises
    ------
    ConfigError
        ``corr`` has too few lags or the wrong number of inputs for the design.

    """
    sets = choice.space.input_sets
    if corr.rxx.shape[0] != n_in or corr.max_lag < max_lag(live, corr.fs_hz):
        raise ConfigError(f'correlations of {corr.rxx.shape[0]} inputs to lag '
                          f'{corr.max_lag} cannot design live estimators of {n_in} inputs '
                          f'needing lag {max_lag(live, corr.fs_hz)}')
    ridges: Dict[int, set] = {}
    for r, i in zip(choice.live_ridges, choice.live_sets):
        ridges.setdefault(i, set()).add(r)
    return _live_rows(_ls_solutions(corr, sets, ridges, live), choice, live, corr.fs_hz, n_in)


def _ls_solutions(corr, sets, ridges: Dict[int, set], live: LiveDesign,
                  bordered: bool = False) -> Dict[int, LsSolutions]:
    """
    Return the LS factorisations of each input set (index into ``sets``) at its ridges.

    ``bordered``: a ridge's factor of a set is bordered from its parent's (the earlier set its
    columns begin with, on the same basis: :func:`.candidates.set_parents`;
    :class:`.nested_factor.BorderedFactor`), as the search's folds do, and the sets between two
    on one branch that use a ridge carry it too (bordered), to pass it on.  A refit's rows take
    up to three sets at two ridges (the diagnosis's held-out refits of a 2-minute record:
    accelerations at 1e-3 and 1e-4, the split at both, the cornering split at 1e-4), so five
    factorisations from scratch become two and three borderings, about half the arithmetic
    (each bordering's triangular solve with the added inputs' columns costs ~0.3-0.4 of a
    factorisation; ``bench/bench_nested_factor.py``).  For offline rows only: a bordered factor
    forms its added part per look-ahead, and a chain of two borderings solves with the inner
    factor per look-ahead too, so the live estimators' five look-aheads would cost more than
    the factorisations saved.
    """
    used = {i: set(r) for i, r in ridges.items() if r}
    parent = set_parents(sets, live, corr.fs_hz)
    if bordered:
        # a ridge used by a set and by one of its ancestors is carried by every set between
        for i in sorted(used, reverse=True):
            for r in sorted(used[i]):
                between, a = [], parent[i]
                while a is not None and r not in used.get(a, ()):
                    between.append(a)
                    a = parent[a]
                for b in between if a is not None else ():
                    used.setdefault(b, set()).add(r)
    used = {i: sorted(used[i]) for i in sorted(used)}
    eqs = set_equations(corr, live, [sets[i][1] for i in used],
                        min((r for rs in used.values() for r in rs), default=0.0))
    out: Dict[int, LsSolutions] = {}
    for i, r in used.items():          # a parent comes before its children (lower index)
        inner = out.get(parent[i]) if bordered else None
        out[i] = LsSolutions(subset_correlations(corr, sets[i][1]), live, r, eqs[sets[i][1]],
                             inner=inner)
    return out


def _live_rows(ls, choice: Choice, live: LiveDesign, fs_hz: float, n_in: int) -> tuple:
    """Return one estimator per stored look-ahead, each row from its chosen set and ridge."""
    sets = choice.space.input_sets
    looks = list(dict.fromkeys(look_ahead_samples(v, fs_hz) for v in live.look_aheads_s))
    return tuple(_rows_of([embedded_estimator(ls[i].estimator(r, d), sets[i][1], n_in)
                           for r, i in zip(choice.live_ridges, choice.live_sets)])
                 for d in looks)


def _realised(f_hz: np.ndarray, h: np.ndarray, fs_hz: float, f_max_hz) -> FirFilter:
    """
    Return the FIR whose response on the grid is exactly ``h`` (lag 0 at the centre).

    Every row is a blend of FIRs that fit the grid (the H1 FIR, the LS FIR), so the inverse
    FFT is their exact blend: no taper and no DC substitution (``fir_from_frf``'s), which
    would change the response the cross-validation scored (the quasi-static gain of an LS
    row included).
    """
    if f_max_hz is not None:
        h = np.where((f_hz <= f_max_hz)[:, None, None], h, 0.0)
    n_fft = 2 * (f_hz.size - 1)
    lag_major = np.fft.irfft(h, n=n_fft, axis=0)                   # lag 0 at index 0
    delay = n_fft // 2
    taps = np.roll(lag_major, delay, axis=0)                       # tap k is lag k - delay
    return FirFilter(np.ascontiguousarray(taps.transpose(1, 2, 0)), delay, fs_hz)


def _compose(choice: Choice, fits, ls, f_hz: np.ndarray, n_model: int, n_in: int):
    """
    Return the FRF whose row ``o`` is the realised response of ``choice.rows[o]``.

    A row fitted on an input set has exactly zero response to the inputs outside it.
    """
    responses = {}
    sets = choice.space.input_sets

    def response(i, key):
        if (i, key) not in responses:
            if key[0] == 'h1':
                fir = fits[i][key[1:]][2]
                h = response_on_grid(fir.taps, fir.delay_samples, n_model)
            else:
                h = ls[i].response(key[1], look_ahead_samples(key[2], ls[i].fs_hz), n_model)
            responses[(i, key)] = embedded_response(h, sets[i][1], n_in)
        return responses[(i, key)]

    n_out = len(choice.rows)
    h = np.empty((f_hz.size, n_out, n_in), dtype=np.complex128)
    for o, (c, i) in enumerate(zip(choice.rows, choice.row_sets)):
        h1 = ('h1', c.segment_length, c.long_regularisation)
        ls_key = ('ls', c.ls_regularisation, c.ls_look_ahead_s)
        if c.family == 'h1':
            h[:, o] = response(i, h1)[:, o]
        elif c.family == 'ls':
            h[:, o] = response(i, ls_key)[:, o]
        else:
            w = blend_weight(f_hz, c.crossover_hz)
            h[:, o] = splice(response(i, ls_key), response(i, h1), w)[:, o]
    return h


def _indicators_on(est, f_hz: np.ndarray):
    """Return ``est``'s coherences and condition numbers on the grid ``f_hz`` (nearest line)."""
    if est.f_hz.size == f_hz.size:
        return est
    nearest = np.clip(np.rint(f_hz / est.f_hz[1]).astype(int), 0, est.f_hz.size - 1)
    return dataclasses.replace(
        est, f_hz=f_hz, h=est.h[nearest],
        coherence_ordinary=est.coherence_ordinary[nearest],
        coherence_multiple=est.coherence_multiple[nearest], cond_sxx=est.cond_sxx[nearest])


def _rows_of(estimators):
    """
    Return one estimator whose row ``o`` is row ``o`` of ``estimators[o]``.

    Rows of sets on different bases (:func:`.candidates.set_design`) are put on the union
    of their coarse edges first (:func:`.live_estimator.on_common_edges`: the same taps).
    """
    estimators = on_common_edges(estimators)
    first = estimators[0]
    rows = np.arange(first.n_out)
    fine = np.stack([e.fine_taps for e in estimators])[rows, rows]
    coarse = np.stack([e.coarse_taps for e in estimators])[rows, rows]
    info = dict(first.info)
    for key in ('regularisation', 'blocks_per_octave'):
        values = [e.info[key] for e in estimators]
        info[key] = values[0] if len(set(values)) == 1 else values
    return dataclasses.replace(first, fine_taps=fine, coarse_taps=coarse, info=info)
