# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Blocked cross-validation: blocks, the held-out scorer, one factorisation, the search."""
import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator.core.candidates import block_stats
from wheel_force_estimator.core.candidates import Candidate
from wheel_force_estimator.core.candidates import candidates
from wheel_force_estimator.core.candidates import combine_correlations
from wheel_force_estimator.core.candidates import LS_LOOK_AHEAD_S
from wheel_force_estimator.core.candidates import LsSolutions
from wheel_force_estimator.core.candidates import SCORING
from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.crossval import BlendScorer
from wheel_force_estimator.core.crossval import block_pieces
from wheel_force_estimator.core.crossval import held_out_power
from wheel_force_estimator.core.crossval import hp_power_weight
from wheel_force_estimator.core.crossval import Piece
from wheel_force_estimator.core.crossval import splice
from wheel_force_estimator.core.design import fit_design
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import response_on_grid
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.live_estimator import look_ahead_samples
from wheel_force_estimator.core.metrics import rmse_hp_pct
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.normal_equations import design_causal
from wheel_force_estimator.core.normal_equations import LagOrderedFactor
from wheel_force_estimator.core.normal_equations import NormalEquations
from wheel_force_estimator.core.overlap_add import apply_fir
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import WelchConfig

FS_HZ = 256.0


def coloured(n_ch, n, seed, cutoff_hz=30.0):
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, cutoff_hz, fs=FS_HZ)
    return signal.lfilter(b, a, rng.normal(size=(n_ch, n)), axis=1)


def test_blocks_deal_contiguous_chunks_in_turn_and_never_straddle_a_gap():
    # two segments of 1000 and 600 samples, 2 blocks, 4 chunks per block -> chunk 200
    blocks = block_pieces([1000, 600], 2, 150)
    flat = [p for b in blocks for p in b]
    assert sorted((p.segment, p.start, p.stop) for p in flat) == (
        [(0, 0, 200), (0, 200, 400), (0, 400, 600), (0, 600, 800), (0, 800, 1000),
         (1, 0, 200), (1, 200, 400), (1, 400, 600)])
    # chunk j goes to block j mod 2: every block samples the whole recording
    assert [(p.segment, p.start) for p in blocks[0]] == [(0, 0), (0, 400), (0, 800), (1, 200)]
    assert [(p.segment, p.start) for p in blocks[1]] == [(0, 200), (0, 600), (1, 0), (1, 400)]


def test_blocks_refuse_data_too_short_for_the_blocks():
    assert block_pieces([500], 4, 150) is None            # 3 chunks of 150 for 4 blocks
    assert block_pieces([100, 100, 100, 100], 4, 150) is None   # no segment holds a chunk
    assert block_pieces([600], 4, 150) is not None


def test_held_out_power_equals_the_time_domain_error_of_the_filter():
    """Frequency-domain score == time-domain MSE of the FIR's prediction (bug: conj/sign)."""
    n = 1 << 16
    x = coloured(2, n, 1)
    rng = np.random.default_rng(2)
    taps = rng.normal(size=(3, 2, 9)) * np.exp(-np.arange(9) / 3.0)
    true = FirFilter(taps, 4, FS_HZ)
    y = apply_fir(true, x) + 0.3 * coloured(3, n, 3, 60.0)
    guess = FirFilter(taps * 0.8 + 0.05, 4, FS_HZ)          # a wrong filter: error to score
    pred = apply_fir(guess, x)
    cut = slice(64, n - 64)                                  # the batch filter's edges
    welch = WelchConfig(fs_hz=FS_HZ, segment_length=1024)
    sp = cross_spectra(x[:, cut], y[:, cut], welch)
    h = response_on_grid(guess.taps, guess.delay_samples, 1024)
    power = held_out_power(h, sp, hp_power_weight(sp.f_hz, FS_HZ))
    np.testing.assert_allclose(power.rmse_pct()[0], rmse_pct(y[:, cut], pred[:, cut]),
                               rtol=0.03)
    np.testing.assert_allclose(power.rmse_pct()[1],
                               rmse_hp_pct(y[:, cut], pred[:, cut], FS_HZ), rtol=0.03)
    # the true filter leaves the noise only: a lower score on every output
    hpw = hp_power_weight(sp.f_hz, FS_HZ)
    exact = held_out_power(response_on_grid(taps, 4, 1024), sp, hpw)
    assert np.all(exact.error < 0.6 * power.error)


def test_response_on_grid_of_an_impulse_at_lag_one_is_a_pure_delay():
    taps = np.zeros((1, 1, 5))
    taps[0, 0, 3] = 1.0                                       # delay 2: lag 1
    h = response_on_grid(taps, 2, 8)[:, 0, 0]
    k = np.arange(5)
    np.testing.assert_allclose(h, np.exp(-2j * np.pi * k / 8), atol=1e-12)


def test_blend_weight_ends():
    f = np.array([0.0, 1.0, 1.25, 1.5, 3.0])
    np.testing.assert_allclose(blend_weight(f, 1.0), [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-12)
    assert np.all(blend_weight(f, 0.0) == 0.0) and np.all(blend_weight(f, math.inf) == 1.0)


def test_one_factorisation_serves_every_look_ahead():
    """Leading blocks of the lag-ordered factor == a design of that look-ahead alone."""
    x = coloured(2, 20000, 4)
    y = np.vstack([np.roll(x[0], -3) + 0.5 * x[1], x[1] - np.roll(x[0], 2)])
    design = LiveDesign(look_aheads_s=(8 / FS_HZ,), history_s=0.25, fine_s=0.05,
                        blocks_per_octave=4, regularisation=1e-3)
    acc = CorrelationAccumulator(2, 2, design.max_lag(FS_HZ))
    acc.add(x, y)
    corr = acc.result(FS_HZ)
    factor = LagOrderedFactor(NormalEquations(corr, 8, design))
    for d in (0, 3, 8):
        alone = design_causal(corr, d, design)
        shared = factor.estimator(d)
        np.testing.assert_allclose(shared.fine_taps, alone.fine_taps, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(shared.coarse_taps, alone.coarse_taps, rtol=1e-7,
                                   atol=1e-9)
    # another ridge from the same equations == the equations built with that ridge
    other = LagOrderedFactor(NormalEquations(corr, 8, design), 1e-1).estimator(3)
    rebuilt = design_causal(corr, 3, dataclasses.replace(design, regularisation=1e-1))
    np.testing.assert_allclose(other.fine_taps, rebuilt.fine_taps, rtol=1e-7, atol=1e-9)


def test_least_squares_solutions_reuse_a_factor_only_for_the_same_inputs():
    """
    Same inputs, other outputs: the stored factor solves the new outputs exactly.

    Bugs caught: a factor served for another training set's inputs (a stale cache), or the
    right-hand side of the first outputs kept.  Known answer: a fresh factorisation.
    """
    x = coloured(2, 20000, 14)
    y1 = np.vstack([np.roll(x[0], -3) + 0.5 * x[1], x[1] - np.roll(x[0], 2)])
    y2 = np.vstack([0.3 * np.roll(x[1], 1), np.roll(x[0], -5)])
    design = LiveDesign(look_aheads_s=(8 / FS_HZ,), history_s=0.25, fine_s=0.05,
                        blocks_per_octave=4, regularisation=1e-3)

    def corr_of(xx, yy):
        acc = CorrelationAccumulator(2, 2, int(round((LS_LOOK_AHEAD_S + 0.25) * FS_HZ)) + 3)
        acc.add(xx, yy)
        return acc.result(FS_HZ)

    def fresh(corr):
        d = look_ahead_samples(LS_LOOK_AHEAD_S, FS_HZ)
        eq = NormalEquations(corr, d, dataclasses.replace(
            design, look_aheads_s=(LS_LOOK_AHEAD_S,)))
        return LagOrderedFactor(eq, 1e-3).estimator(d).fine_taps

    d = look_ahead_samples(LS_LOOK_AHEAD_S, FS_HZ)
    for xx, yy in ((x, y1), (x, y2), (x[:, :15000], y2[:, :15000]), (x, y1)):
        corr = corr_of(xx, yy)
        got = LsSolutions(corr, design, (1e-3,)).estimator(1e-3, d).fine_taps
        np.testing.assert_allclose(got, fresh(corr), rtol=1e-9, atol=1e-12)
    a = LsSolutions(corr_of(x, y1), design, (1e-3,)).estimator(1e-3, d).fine_taps
    b = LsSolutions(corr_of(x, y2), design, (1e-3,)).estimator(1e-3, d).fine_taps
    assert not np.allclose(a, b)


def test_block_sums_equal_the_statistics_of_the_whole():
    """A fold is a sum of blocks: chunked correlations == direct sums over the chunks."""
    x, y = coloured(2, 4000, 5), coloured(1, 4000, 6)
    seg = [TrainingSegment(x, y, 's')]
    pieces = [Piece(0, 0, 1500), Piece(0, 1500, 4000)]
    stats = [block_stats(seg, [p], {}, FS_HZ, 20) for p in pieces]
    both = combine_correlations([s.corr for s in stats])
    acc = CorrelationAccumulator(2, 1, 20)
    mean = np.concatenate([x, y]).mean(axis=1)          # the segment's, not each piece's
    acc.add(x[:, :1500], y[:, :1500], mean)
    acc.add(x[:, 1500:], y[:, 1500:], mean)
    ref = acc.result(FS_HZ)
    np.testing.assert_allclose(both.rxx, ref.rxx, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(both.rxy, ref.rxy, rtol=1e-10, atol=1e-12)
    assert both.n_samples == 4000


def test_a_piece_keeps_its_quasi_static_offset_in_the_held_out_scores():
    """
    Known answer: a piece's statistics have the segment's mean removed, not the piece's.

    The deceleration steps +1 / -1 and the force +c / -c between two halves (a braking event
    and its release): the held-out target power of each half is c² plus the noise, as
    ``evaluate`` (record mean removed) counts it, and the input/force correlation at lag 0 is
    c.  A piece's own mean would have removed the step from both.
    """
    rng = np.random.default_rng(3)
    n, c = 4096, 5.0
    step = np.where(np.arange(n) < n // 2, 1.0, -1.0)
    x = 0.1 * rng.normal(size=(1, n)) + step
    y = 0.1 * rng.normal(size=(1, n)) + c * step
    seg = [TrainingSegment(x, y, 's')]
    welch = {SCORING: WelchConfig(fs_hz=FS_HZ, segment_length=512, detrend='none')}
    for piece in (Piece(0, 0, n // 2), Piece(0, n // 2, n)):
        stats = block_stats(seg, [piece], welch, FS_HZ, 4)
        mean_square = stats.spectra[SCORING].syy[:, 0].sum() * (FS_HZ / 512)   # ∫ Syy df
        assert mean_square == pytest.approx(c ** 2 + 0.01, rel=0.05)
        assert stats.corr.rxy[0, 0, 4] == pytest.approx(c, rel=0.05)      # lag 0
        assert stats.corr.n_samples == n // 2


def _masked_correlation(x, y, chunks, held_out, max_lag):
    """Brute force: the training chunks (the record's mean removed) as one signal, held-out 0."""
    whole = np.concatenate([x, y])
    z = np.zeros((x.shape[0] + y.shape[0], x.shape[1]))
    n = 0
    for b, (a, e) in chunks:
        if b != held_out:
            z[:, a:e] = whole[:, a:e] - whole.mean(axis=1, keepdims=True)
            n += e - a
    ni = x.shape[0]
    full = np.zeros((z.shape[0], z.shape[0], 2 * max_lag + 1))
    for t in range(-max_lag, max_lag + 1):
        lo, hi = max(0, -t), min(z.shape[1], z.shape[1] - t)
        full[:, :, max_lag + t] = z[:, lo:hi] @ z[:, lo + t:hi + t].T
    return full[:ni, :ni] / n, full[:ni, ni:] / n


@pytest.mark.parametrize('lengths', [(300, 250, 400, 350, 320, 380), (30, 25, 40, 35, 32, 38)],
                         ids=['chunks longer than the lags', 'shorter: pairs skip a chunk'])
def test_a_folds_correlations_are_its_chunks_as_one_signal(lengths):
    """Known answer: blocks' sums plus straddling pairs == the masked signal's correlation."""
    from wheel_force_estimator.core.candidates import fold_correlations
    from wheel_force_estimator.core.candidates import straddling_sums
    lag = 60
    n = sum(lengths)
    x, y = coloured(2, n, 7) + 3.0, coloured(1, n, 8) - 1.0     # the record's mean removed
    seg = [TrainingSegment(x, y, 's')]
    edges = np.cumsum((0,) + lengths)
    chunks = [(j % 3, (int(a), int(e))) for j, (a, e) in enumerate(zip(edges[:-1], edges[1:]))]
    blocks = [[Piece(0, a, e) for b, (a, e) in chunks if b == k] for k in range(3)]
    stats = [block_stats(seg, blk, {}, FS_HZ, lag) for blk in blocks]
    straddling = straddling_sums(seg, blocks, lag)
    for k in range(3):
        train = [s.corr for j, s in enumerate(stats) if j != k]
        got = fold_correlations(train, straddling.for_fold(k))
        rxx, rxy = _masked_correlation(x, y, chunks, k, lag)
        np.testing.assert_allclose(got.rxx, rxx, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.rxy, rxy, rtol=1e-9, atol=1e-12)
        # without the straddling pairs the long lags are short of them
        alone = combine_correlations(train)
        assert not np.allclose(alone.rxx[:, :, 0], rxx[:, :, 0], rtol=1e-3)
    # every chunk in training (no block held out): the whole record's correlation
    whole = fold_correlations([s.corr for s in stats], straddling.total)
    rxx, _ = _masked_correlation(x, y, chunks, -1, lag)
    np.testing.assert_allclose(whole.rxx, rxx, rtol=1e-9, atol=1e-12)


def test_candidates_drop_settings_a_family_does_not_use():
    cands = candidates((1024, 2048), (0.01, 0.05), (1e-4, 1e-3), (0.0, 2.0, math.inf), 0.05)
    fams = [c.family for c in cands]
    assert fams.count('h1') == 4 and fams.count('spliced') == 8
    assert fams.count('ls') == 4                    # 2 ridges x (two-sided, live look-ahead)
    assert Candidate(1024, 0.01, 1e-4, 0.0).as_dict() == {
        'family': 'h1', 'segment_length': 1024, 'long_regularisation': 0.01}


def _known_system(n, seed):
    """Two inputs -> two outputs through known 2nd-order filters, plus output noise."""
    x = coloured(2, n, seed)
    b1, a1 = signal.butter(2, 12.0, fs=FS_HZ)
    b2, a2 = signal.cheby1(2, 1.0, 20.0, fs=FS_HZ)
    y = np.vstack([signal.lfilter(b1, a1, x[0]) + 0.5 * x[1],
                   signal.lfilter(b2, a2, x[1]) - 0.3 * np.roll(x[0], 4)])
    rng = np.random.default_rng(seed + 100)
    return x, y + 0.05 * rng.normal(size=y.shape)


def test_the_search_writes_its_choice_and_beats_no_candidate_on_new_data():
    """The chosen rows score within noise of the best candidate, on a fresh record."""
    x, y = _known_system(60000, 7)
    cfg = FitConfig(segment_length=512, long_segment_length=0,
                    live=LiveDesign(look_aheads_s=(0.05,), history_s=0.5))
    fitted = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, cfg, ('a', 'b'), ('f', 'g'))
    design = fitted.model.fit['design']
    assert design['method'] == 'blocked_cross_validation' and design['n_blocks'] == 4
    assert set(design['rows']) == {'f', 'g'}
    for row in design['rows'].values():
        assert row['family'] in {c['family'] for c in design['candidates']}
        # the recorded row score is the lowest criterion among the candidates
        assert row['cv_rmse_pct'] < 100.0
    from wheel_force_estimator.core.predict import predict_forces
    xv, yv = _known_system(30000, 8)
    offline = rmse_pct(yv, predict_forces(fitted.model, xv))
    live = rmse_pct(yv, predict_forces(fitted.model, xv, 13))
    assert np.all(offline < 30.0)                  # noise is ~10 % of the output RMS here
    assert np.all(offline <= live * 1.02)          # offline never worse than live (noise)


def test_the_search_keeps_no_fold_factor_in_the_cache(monkeypatch):
    """
    Only the whole data's factors are kept for later fits on the same inputs.

    A fold's training set is factorised once and never again (each fold has its own
    inputs), so kept it only pushed out reusable factors and held ~220 MB each through the
    final fit of a 20-minute bag.  Bug caught: fold factors stored in the bounded cache.
    """
    from wheel_force_estimator.core import candidates as cand
    fresh = cand._RecentFactors()
    monkeypatch.setattr(cand, '_FACTORS', fresh)
    stored = []
    real = fresh.factor

    def recording(key, eq, ridge, inner=None):
        stored.append(eq.info['n_training_samples'])
        return real(key, eq, ridge, inner)
    monkeypatch.setattr(fresh, 'factor', recording)
    x, y = _known_system(40000, 11)
    cfg = FitConfig(segment_length=512, long_segment_length=0,
                    live=LiveDesign(look_aheads_s=(0.05,), history_s=0.5))
    fitted = fit_design([TrainingSegment(x, y, 'train')], FS_HZ, cfg, ('a', 'b'), ('f', 'g'))
    assert fitted.model.fit['design']['method'] == 'blocked_cross_validation'
    assert fitted.model.live                        # designed, from the whole data
    assert stored and set(stored) == {40000}, stored


def test_too_short_to_cross_validate_falls_back_and_says_why():
    x, y = _known_system(3000, 9)
    fitted = fit_design([TrainingSegment(x, y, 'short.csv')], FS_HZ,
                        FitConfig(segment_length=256), ('a', 'b'), ('f', 'g'))
    assert 'short.csv' in fitted.warning and 'too short to cross-validate' in fitted.warning
    assert fitted.model.fit['design']['method'] == 'defaults'


@pytest.mark.parametrize('explicit', [frozenset({'estimator'})])
def test_an_imposed_estimator_keeps_the_h1_family(explicit):
    x, y = _known_system(60000, 10)
    fitted = fit_design([TrainingSegment(x, y, 'train')], FS_HZ,
                        FitConfig(segment_length=512), ('a', 'b'), ('f', 'g'), imposed=explicit)
    design = fitted.model.fit['design']
    assert design['imposed'] == ['estimator']
    assert {c['family'] for c in design['candidates']} == {'h1'}


def test_refit_with_the_chosen_design_reproduces_the_fit_and_keeps_its_rows():
    # Bugs caught: a refit that searches again or falls back to the default design (the
    # diagnosis's held-out blocks would judge another FIR than the one `fit` writes), or
    # that drops the chosen rows.  Known answer: the same segments give the same model.
    x, y = _known_system(60000, 11)
    cfg = FitConfig(segment_length=512, long_segment_length=0,
                    live=LiveDesign(look_aheads_s=(0.05,), history_s=0.5))
    segments = [TrainingSegment(x, y, 'train')]
    fitted = fit_design(segments, FS_HZ, cfg, ('a', 'b'), ('f', 'g'))
    assert fitted.chosen is not None
    again = fitted.refit(segments)
    np.testing.assert_allclose(again.fir_taps, fitted.model.fir_taps, rtol=0, atol=1e-12)
    assert again.fit['design']['rows'] == fitted.model.fit['design']['rows']
    # on other data it keeps the chosen rows (no new search) and fits that data
    x2, y2 = _known_system(40000, 12)
    other = fitted.refit([TrainingSegment(x2, y2, 'other')])
    assert other.fit['design']['rows'] == fitted.model.fit['design']['rows']
    assert not np.allclose(other.fir_taps, fitted.model.fir_taps)


def test_blend_scorer_equals_the_score_of_the_blended_response(monkeypatch):
    """Expanded blend terms == held_out_power of the spliced FRF (bug: the pair term)."""
    n = 1 << 15
    x = coloured(3, n, 5)
    rng = np.random.default_rng(6)
    taps = rng.normal(size=(2, 3, 7))
    y = apply_fir(FirFilter(taps, 3, FS_HZ), x) + 0.2 * coloured(2, n, 7, 40.0)
    sp = cross_spectra(x, y, WelchConfig(fs_hz=FS_HZ, segment_length=512))
    hpw = hp_power_weight(sp.f_hz, FS_HZ)
    a = response_on_grid(taps * 1.1, 3, 512)
    b = response_on_grid(taps * 0.7 + 0.02, 3, 512)
    scorer = BlendScorer(sp, hpw)
    scorer.add('a', a)
    scorer.add('b', b)
    w = blend_weight(sp.f_hz, 20.0)
    for got, want in ((scorer.power('a'), held_out_power(a, sp, hpw)),
                      (scorer.power('a', 'b', w), held_out_power(splice(a, b, w), sp, hpw))):
        np.testing.assert_allclose(got.error, want.error, rtol=1e-10)
        np.testing.assert_allclose(got.target, want.target, rtol=1e-12)
    assert not np.allclose(scorer.power('a', 'b', w).error, scorer.power('a').error)
    # the pair terms up to the ramp's end only, products in chunks of lines that do not
    # divide the grid: the same figures
    monkeypatch.setattr(BlendScorer, 'CHUNK_LINES', 7)
    banded = BlendScorer(sp, hpw, pair_max_hz=30.0)
    banded.add('a', a)
    banded.add('b', b)
    for key in (('a',), ('a', 'b', w)):
        np.testing.assert_allclose(banded.power(*key).error, scorer.power(*key).error,
                                   rtol=1e-12)
    # a pair band that ends inside the ramp drops a term that counts: the test can fail
    short = BlendScorer(sp, hpw, pair_max_hz=24.0)
    short.add('a', a)
    short.add('b', b)
    assert not np.allclose(short.power('a', 'b', w).error, scorer.power('a', 'b', w).error,
                           rtol=1e-9)


def test_response_on_grid_wraps_taps_longer_than_the_grid():
    """Taps beyond n_fft fold onto the grid (DTFT sampled at k fs / n_fft)."""
    rng = np.random.default_rng(8)
    taps = rng.normal(size=(1, 2, 21))
    delay = 5
    h = response_on_grid(taps, delay, 8)
    k = np.arange(5)[:, None]
    lag = np.arange(21) - delay
    want = (taps[0][None, :, :] * np.exp(-2j * np.pi * k[:, :, None] * lag / 8)).sum(axis=2)
    np.testing.assert_allclose(h[:, 0, :], want, atol=1e-12)


def test_response_on_grid_is_line_major_and_equals_each_pairs_transform():
    """Every line's (n_out, n_in) matrix is one contiguous piece (BlendScorer's products)."""
    rng = np.random.default_rng(9)
    taps = rng.normal(size=(3, 4, 40))
    h = response_on_grid(taps, 6, 32)
    assert h.shape == (17, 3, 4) and h.flags.c_contiguous
    for o in range(3):
        for i in range(4):
            # lag k - 6 at k - 6 modulo 64, then the two periods of 32 folded onto one
            lagged = np.roll(np.pad(taps[o, i], (0, 24)), -6)
            np.testing.assert_allclose(h[:, o, i], np.fft.rfft(lagged[:32] + lagged[32:]),
                                       atol=1e-12)


def test_a_live_look_ahead_beyond_the_least_squares_fir_is_refused_naming_the_range():
    x, y = _known_system(40000, 5)
    cfg = FitConfig(segment_length=512, long_segment_length=0,
                    live=LiveDesign(look_aheads_s=(0.3,), history_s=0.5))
    with pytest.raises(ConfigError, match=r'live_look_ahead_s 0.3 s is outside 0 .. 0.25 s'):
        fit_design([TrainingSegment(x, y, 'train')], FS_HZ, cfg, ('a', 'b'), ('f', 'g'))
