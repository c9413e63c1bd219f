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
   every resolution of the grid and the correlations of the least-squares FIRs.
3. **candidates** (:func:`space`): H1 variants x LS ridges x splice crossovers; a setting
   the user imposed keeps its value.
4. **held-out scores**, fold by fold: each candidate is fitted from the sums of the other
   blocks' statistics and scored on the held-out block (:mod:`.crossval`), both figures.
   The live estimator's ridge is scored on the same folds from the same factorisations.
5. **the chosen design**: per output row, the candidate with the lowest held-out error
   (relative MSE, unfiltered plus 1 Hz high-passed) among those no worse than that row's
   live estimator, and per row the live ridge.
6. **the estimate** (:func:`fit_chosen`): the chosen H1 variants and LS factorisations on
   all the data (one factorisation per ridge serves the offline FIR and every live
   look-ahead).
7. **the FIR**: the rows composed into one FRF and realised exactly (:func:`_realised`).
8. **the live estimators**: every stored look-ahead, each row with its chosen ridge; the
   caller builds the model (:func:`.pipeline.build_model`) with ``fit.design``.
"""
import dataclasses
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.candidates import block_stats
from wheel_force_estimator.core.candidates import BlockStats
from wheel_force_estimator.core.candidates import Candidate
from wheel_force_estimator.core.candidates import candidates
from wheel_force_estimator.core.candidates import combine_correlations
from wheel_force_estimator.core.candidates import LONG_REGULARISATIONS
from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
from wheel_force_estimator.core.candidates import LS_REGULARISATIONS
from wheel_force_estimator.core.candidates import LsSolutions
from wheel_force_estimator.core.candidates import score_fold
from wheel_force_estimator.core.candidates import SCORING
from wheel_force_estimator.core.candidates import SEGMENT_FACTORS
from wheel_force_estimator.core.candidates import SPLICE_CROSSOVERS_HZ
from wheel_force_estimator.core.crossval import best_rows
from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.crossval import block_pieces
from wheel_force_estimator.core.crossval import HeldOutPower
from wheel_force_estimator.core.crossval import N_BLOCKS
from wheel_force_estimator.core.crossval import Piece
from wheel_force_estimator.core.crossval import response_on_grid
from wheel_force_estimator.core.crossval import splice
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.pipeline import estimate_h1
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.spectra import combine_spectra

#: Shortest scoring resolution tried [samples]; each block must hold two of its windows.
MIN_SCORING_SEGMENT = 1024
#: Settings that pin the offline estimator to the H1 family when the user sets them.
H1_ONLY_KEYS = frozenset({'estimator'})


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

    """

    h1: Tuple[Tuple[int, float], ...]
    ridges: Tuple[float, ...]
    offline: Tuple[Candidate, ...]
    imposed: Tuple[str, ...]

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
    live_ridges : tuple of float
        Live-estimator ridge per output row.
    scores, live_scores : tuple of HeldOutPower
        Held-out power per offline candidate (``space.offline`` order) and per live ridge.
    space : Space
        What was searched.
    n_score : int
        Scoring resolution [samples].
    blocks_s : tuple of float
        Duration of each block [s].

    """

    rows: Tuple[Candidate, ...]
    live_ridges: Tuple[float, ...]
    scores: Tuple[HeldOutPower, ...]
    live_scores: Tuple[HeldOutPower, ...]
    space: Space
    n_score: int
    blocks_s: Tuple[float, ...]

    def record(self, output_channels: Sequence[str]) -> dict:
        """Return the model's ``fit.design`` entry (JSON)."""
        def figures(score: HeldOutPower) -> dict:
            pct = score.rmse_pct()
            return {'cv_rmse_pct': [round(float(v), 3) for v in pct[0]],
                    'cv_rmse_hp1_pct': [round(float(v), 3) for v in pct[1]]}

        index = {c: k for k, c in enumerate(self.space.offline)}
        rows = {}
        for o, (name, cand) in enumerate(zip(output_channels, self.rows)):
            pct = self.scores[index[cand]].rmse_pct()
            rows[name] = dict(cand.as_dict(), cv_rmse_pct=round(float(pct[0, o]), 3),
                              cv_rmse_hp1_pct=round(float(pct[1, o]), 3),
                              live_regularisation=self.live_ridges[o])
        return {'method': 'blocked_cross_validation', 'n_blocks': len(self.blocks_s),
                'blocks_s': [round(b, 3) for b in self.blocks_s],
                'scoring_segment_length': self.n_score, 'imposed': list(self.space.imposed),
                'rows': rows,
                'candidates': [dict(c.as_dict(), **figures(s))
                               for c, s in zip(self.space.offline, self.scores)],
                'live_candidates': [dict({'regularisation': r}, **figures(s))
                                    for r, s in zip(self.space.ridges, self.live_scores)]}


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


def space(config: FitConfig, imposed: frozenset, n_score: int,
          live_look_ahead_s: Optional[float]) -> Space:
    """Return the candidates: the grids of the defaults, imposed settings kept."""
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
    return Space(tuple((s, lr) for s in segs for lr in lregs), LS_REGULARISATIONS,
                 tuple(candidates(segs, lregs, LS_REGULARISATIONS, crossovers,
                                  live_look_ahead_s)),
                 tuple(sorted(imposed)))


def h1_fits(stats: Sequence[BlockStats], config: FitConfig, variants, fs_hz: float,
            order: int, input_channels) -> Dict[Tuple[int, float], tuple]:
    """Return ``{(segment, long_reg): estimate_h1(...)}`` from the sums of ``stats``."""
    long = config.long_segment_length
    out = {}
    for seg, lreg in variants:
        short = [s.spectra[seg] for s in stats if seg in s.spectra]
        longs = [s.spectra[long] for s in stats if long and long in s.spectra]
        cfg = dataclasses.replace(config, segment_length=seg, long_regularisation=lreg,
                                  long_segment_length=long if longs else 0)
        out[(seg, lreg)] = estimate_h1(combine_spectra(short),
                                       combine_spectra(longs) if longs else None, cfg,
                                       fs_hz, order, input_channels)
    return out


def welch_configs(config: FitConfig, fs_hz: float, sp: Space, n_score: int) -> dict:
    """
    Return ``{segment_length: WelchConfig}`` of every resolution the search needs.

    The scorer's (key :data:`.candidates.SCORING`): ``n_score``-sample windows without
    per-window detrend (each chunk's mean is removed instead), so a window does not hide the
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


def search(used, fs_hz: float, config: FitConfig, input_channels, order: int,
           imposed: frozenset = frozenset(), progress=lambda it, desc: it
           ) -> Optional[Tuple[Choice, dict, int]]:
    """
    Choose each output's design by blocked cross-validation (see the module notes).

    Returns
    -------
    (Choice, dict, int) or None
        The choice, the Welch configurations and correlation lags of the search (for the
        final fit); ``None`` when the data is too short for :data:`.crossval.N_BLOCKS`
        blocks.

    """
    lengths = [s.accel_mps2.shape[1] for s in used]
    n_score, blocks = scoring_blocks(lengths, config)
    if n_score is None:
        return None
    live = config.live or LiveDesign()
    sp = space(config, imposed, n_score, live.look_aheads_s[0])
    # the scorer's window: the longest power of two every chunk holds (the finest grid)
    n_score = 1 << int(np.log2(min(p.stop - p.start for b in blocks for p in b)))
    lags = max_lag(live, fs_hz) if (sp.needs_ls or config.live is not None) else 0
    welch = welch_configs(config, fs_hz, sp, n_score)
    stats = [block_stats(used, b, welch, fs_hz, lags) for b in progress(blocks, 'fit: blocks')]
    d_ls = look_ahead_samples(LS_LOOK_AHEAD_S, fs_hz)
    d_live = look_ahead_samples(live.look_aheads_s[0], fs_hz)
    scores = live_scores = None
    for k in progress(range(len(stats)), 'fit: cross-validation'):
        train = [s for j, s in enumerate(stats) if j != k]
        h1 = {key: response_on_grid(fit[2].taps, fit[2].delay_samples, n_score)
              for key, fit in h1_fits(train, config, sp.h1, fs_hz, order,
                                      input_channels).items()}
        ls_resp, live_resp = {}, {}
        if lags:
            ls = LsSolutions(combine_correlations([s.corr for s in train]), live, sp.ridges)
            live_resp = {r: ls.response(r, d_live, n_score) for r in sp.ridges}
            ls_resp = {(r, LS_LOOK_AHEAD_S): ls.response(r, d_ls, n_score) for r in sp.ridges}
            ls_resp.update({(r, live.look_aheads_s[0]): live_resp[r] for r in sp.ridges})
        off, lv = score_fold(h1, ls_resp, live_resp, sp.offline, stats[k].spectra[SCORING])
        scores = off if scores is None else [a + b for a, b in zip(scores, off)]
        live_scores = lv if live_scores is None else [a + b for a, b in zip(live_scores, lv)]
    n_out = stats[0].sum_y.size
    live_rows = (best_rows(np.stack([s.criterion() for s in live_scores]))[0] if lags
                 else np.zeros(n_out, dtype=int))
    rows = _offline_rows(scores, sp, live.look_aheads_s[0],
                         [sp.ridges[i] for i in live_rows] if lags else None)
    choice = Choice(tuple(sp.offline[i] for i in rows),
                    tuple(float(sp.ridges[i]) for i in live_rows), tuple(scores),
                    tuple(live_scores), sp, n_score, tuple(s.n / fs_hz for s in stats))
    return choice, welch, lags


def _offline_rows(scores: Sequence[HeldOutPower], sp: Space, live_look_ahead_s: float,
                  live_ridges: Optional[Sequence[float]]) -> np.ndarray:
    """
    Return the offline candidate per output, never worse than live on the held-out blocks.

    The lowest criterion among the candidates no worse than that output's live estimator in
    either figure.

    The live estimator is itself a candidate, so the set is never empty: offline can never
    score worse than live, unfiltered or high-passed (a lower sum alone could trade one
    figure for the other: measured on the van, z 11.6 % offline against 10.6 % live
    unfiltered, bought with the high-passed figure).
    """
    rel = np.stack([s.error / np.maximum(s.target, np.finfo(float).tiny) for s in scores])
    criterion = rel.sum(axis=1)                                     # (n_cand, n_out)
    if live_ridges is None:
        return best_rows(criterion)[0]
    rows = best_rows(criterion)[0]
    for o, ridge in enumerate(live_ridges):
        live = [k for k, c in enumerate(sp.offline) if c.family == 'ls'
                and c.ls_regularisation == ridge and c.ls_look_ahead_s == live_look_ahead_s]
        if not live:                      # no LS candidate (an imposed H1 estimator)
            continue
        ok = np.all(rel[:, :, o] <= rel[live[0], :, o] * (1 + 1e-12), axis=1)
        rows[o] = int(np.flatnonzero(ok)[np.argmin(criterion[ok, o])])
    return rows


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
    variants = {(c.segment_length, c.long_regularisation) for c in choice.rows
                if c.family != 'ls'}
    # the indicators (coherence, conditioning) of the least-regularised H1 variant at the
    # configured segment: regularisation biases the multiple coherence low
    default = min((v for v in choice.space.h1 if v[0] == config.segment_length),
                  key=lambda v: v[1], default=choice.space.h1[0])
    fits = h1_fits([whole], config, sorted(variants | {default}), fs_hz, order, input_channels)
    ref_est, _, ref_fir, extra = fits[default]
    live = config.live or LiveDesign()
    ls = None
    n_model = max(ref_fir.n_taps, config.long_segment_length)
    if lags:
        ridges = {c.ls_regularisation for c in choice.rows if c.family != 'h1'}
        if live_estimators:
            ridges |= set(choice.live_ridges)
        ls = LsSolutions(whole.corr, live, sorted(ridges)) if ridges else None
        span = (look_ahead_samples(LS_LOOK_AHEAD_S, fs_hz)
                + int(round(live.history_s * fs_hz)) + 1)
        n_model = max(n_model, 2 * int(2 ** np.ceil(np.log2(span))))
    f_hz = np.fft.rfftfreq(n_model, 1.0 / fs_hz)
    h = _compose(choice.rows, fits, ls, f_hz, n_model)
    fir = _realised(f_hz, h, fs_hz, config.f_max_hz)
    estimators = ()
    if config.live is not None and live_estimators:
        looks = list(dict.fromkeys(look_ahead_samples(v, fs_hz) for v in live.look_aheads_s))
        estimators = tuple(_rows_of([ls.estimator(r, d) for r in choice.live_ridges])
                           for d in looks)
    return (_indicators_on(ref_est, f_hz), h, fir, estimators, extra, whole.sum_x / whole.n,
            whole.sum_y / whole.n)


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


def _compose(rows: Sequence[Candidate], fits, ls, f_hz: np.ndarray, n_model: int):
    """Return the FRF whose row ``o`` is the realised response of ``rows[o]``."""
    responses = {}

    def response(key):
        if key not in responses:
            if key[0] == 'h1':
                fir = fits[key[1:]][2]
                responses[key] = response_on_grid(fir.taps, fir.delay_samples, n_model)
            else:
                d = look_ahead_samples(key[2], ls.fs_hz)
                responses[key] = ls.response(key[1], d, n_model)
        return responses[key]

    h = np.empty((f_hz.size,) + response_shape(fits), dtype=np.complex128)
    for o, c in enumerate(rows):
        h1 = ('h1', c.segment_length, c.long_regularisation)
        if c.family == 'h1':
            h[:, o] = response(h1)[:, o]
        elif c.family == 'ls':
            h[:, o] = response(('ls', c.ls_regularisation, c.ls_look_ahead_s))[:, o]
        else:
            w = blend_weight(f_hz, c.crossover_hz)
            ls_key = ('ls', c.ls_regularisation, c.ls_look_ahead_s)
            h[:, o] = splice(response(ls_key), response(h1), w)[:, o]
    return h


def response_shape(fits) -> Tuple[int, int]:
    """Return (n_out, n_in) of the H1 fits."""
    fir = next(iter(fits.values()))[2]
    return fir.taps.shape[:2]


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
    """Return one estimator whose row ``o`` is row ``o`` of ``estimators[o]`` (one basis)."""
    first = estimators[0]
    rows = np.arange(first.n_out)
    fine = np.stack([e.fine_taps for e in estimators])[rows, rows]
    coarse = np.stack([e.coarse_taps for e in estimators])[rows, rows]
    ridges = [float(e.info['regularisation']) for e in estimators]
    info = dict(first.info, regularisation=ridges[0] if len(set(ridges)) == 1 else ridges)
    return dataclasses.replace(first, fine_taps=fine, coarse_taps=coarse, info=info)
