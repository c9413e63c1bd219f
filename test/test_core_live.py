# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Live (causal) estimator: design from spectra, stream filter, model file, Predictor rule."""
import dataclasses
import json

import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator.core.causal_filter import CausalFilter
from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.live_estimator import CausalEstimator
from wheel_force_estimator.core.live_estimator import lag_edges
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.normal_equations import design_causal
from wheel_force_estimator.core.normal_equations import design_live
from wheel_force_estimator.core.normal_equations import gather
from wheel_force_estimator.core.normal_equations import solve_leading
from wheel_force_estimator.core.overlap_add import OverlapAddFilter
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.core.predict import Predictor

FS_HZ = 128.0
INS = ('a', 'b', 'c')
OUTS = ('f', 'g')


def coloured_inputs(n, seed):
    """Three correlated, low-passed inputs (a realistic, non-white input spectrum)."""
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 0.5)
    w = signal.lfilter(b, a, rng.normal(size=(3, n)), axis=1)
    return np.array([w[0], w[1] + 0.5 * w[0], w[2] - 0.3 * w[1]])


def apply_lags(x, taps_by_lag):
    """``y_o(n) = sum_{i,l} g[o, i, l] x_i(n - l)`` for a dict lag -> (o, i) matrix."""
    y = np.zeros((len(OUTS), x.shape[1]))
    for lag, g in taps_by_lag.items():
        shifted = np.roll(x, lag, axis=1)
        y += g @ shifted
    return y


def correlate(x, y, max_lag):
    """Accumulate the correlations of one or more (x, y) segments."""
    acc = CorrelationAccumulator(x[0].shape[0], y[0].shape[0], max_lag)
    for a, b in zip(x, y):
        acc.add(a, b)
    return acc.result(FS_HZ)


def test_correlations_equal_the_direct_sums_over_segments():
    # Hand-checkable: sum over each segment of x_i(n) y_o(n + τ) after removing its mean,
    # divided by all samples; a pair never straddles two segments.  Segments longer than one
    # accumulator block (4096 + T) check the block joins too.
    rng = np.random.default_rng(3)
    xs = [rng.normal(size=(2, 9000)) + 5.0, rng.normal(size=(2, 300))]
    ys = [rng.normal(size=(1, 9000)), rng.normal(size=(1, 300)) - 2.0]
    corr = correlate(xs, ys, 7)
    assert corr.max_lag == 7 and corr.n_samples == 9300
    for tau in range(-7, 8):
        want_xx = np.zeros((2, 2))
        want_xy = np.zeros((2, 1))
        for x, y in zip(xs, ys):
            x, y = x - x.mean(axis=1, keepdims=True), y - y.mean(axis=1, keepdims=True)
            n = x.shape[1]
            lo, hi = max(0, -tau), min(n, n - tau)
            want_xx += x[:, lo:hi] @ x[:, lo + tau:hi + tau].T
            want_xy += x[:, lo:hi] @ y[:, lo + tau:hi + tau].T
        np.testing.assert_allclose(corr.rxx[:, :, 7 + tau], want_xx / 9300, atol=1e-12)
        np.testing.assert_allclose(corr.rxy[:, :, 7 + tau], want_xy / 9300, atol=1e-12)


def test_design_recovers_a_known_causal_system_with_look_ahead():
    # Known answer: a system with a 2-sample lead and 6 lags of history is inside the fine
    # basis, so least squares finds its taps (noise-free data: only spectral estimation error).
    rng = np.random.default_rng(0)
    truth = {lag: rng.normal(size=(2, 3)) for lag in range(-2, 7)}
    x = coloured_inputs(400_000, 1)
    y = apply_lags(x, truth)
    design = LiveDesign(look_aheads_s=(2 / FS_HZ,), history_s=0.5, fine_s=0.1,
                        regularisation=1e-9)
    est = design_causal(correlate([x], [y], design.max_lag(FS_HZ)), 2, design)
    fir = est.fir(FS_HZ)
    for lag, g in truth.items():
        np.testing.assert_allclose(fir.taps[:, :, lag + 2], g, atol=0.03)
    assert np.max(np.abs(fir.taps[:, :, 2 + 7:])) < 0.03


def test_design_recovers_piecewise_constant_history():
    # The coarse blocks: a long, slowly varying history constant over each coarse block.
    design = LiveDesign(history_s=63 / FS_HZ, fine_s=0.0, blocks_per_octave=2,
                        regularisation=1e-9)
    edges = lag_edges(0, 1, 63, 2)
    rng = np.random.default_rng(4)
    theta = rng.normal(size=(2, 3, edges.size - 1)) / np.diff(edges)
    truth = {}
    for p in range(edges.size - 1):
        for lag in range(edges[p], edges[p + 1]):
            truth[int(lag)] = theta[:, :, p]
    x = coloured_inputs(400_000, 2)
    corr = correlate([x], [apply_lags(x, truth)], design.max_lag(FS_HZ))
    est = design_causal(corr, 0, design)
    n_fine = est.fine_taps.shape[2]
    np.testing.assert_array_equal(np.concatenate([np.arange(n_fine), est.coarse_edges]), edges)
    np.testing.assert_allclose(np.concatenate([est.fine_taps, est.coarse_taps], axis=2),
                               theta, atol=0.02 * np.abs(theta).max())


def test_design_needs_correlations_to_its_longest_lag():
    x = coloured_inputs(20_000, 5)
    design = LiveDesign(look_aheads_s=(3 / FS_HZ,), history_s=0.5)
    corr = correlate([x], [x[:2]], design.max_lag(FS_HZ))
    est = design_causal(corr, 3, design)
    assert est.history_samples == 64 and est.info['history_s'] == 0.5
    with pytest.raises(ConfigError, match='need correlations to lag 70, have 69'):
        design_causal(corr, 4, design)


def test_design_live_submatrices_equal_separate_designs():
    # Bug caught: a wrong principal submatrix (lags of another input kept) for the shorter
    # look-aheads that design_live derives from the longest one's equations.
    x = coloured_inputs(30_000, 9)
    design = LiveDesign(look_aheads_s=(2 / FS_HZ, 6 / FS_HZ, 0.0), history_s=0.5,
                        blocks_per_octave=4)
    corr = correlate([x], [x[:2] * 2.0 + np.roll(x[1:], 3, axis=1)], design.max_lag(FS_HZ))
    for est in design_live(corr, design):
        alone = design_causal(corr, est.look_ahead_samples, design)
        np.testing.assert_allclose(est.fir(FS_HZ).taps, alone.fir(FS_HZ).taps, rtol=0,
                                   atol=1e-9 * np.abs(alone.fine_taps).max())
        assert est.info == alone.info


def random_estimator(look_ahead=3, seed=0):
    rng = np.random.default_rng(seed)
    edges = lag_edges(look_ahead, 8, 300, 4)
    n_fine = 8 + look_ahead
    return CausalEstimator(look_ahead, rng.normal(size=(2, 3, n_fine)), edges[n_fine:],
                           rng.normal(size=(2, 3, edges.size - 1 - n_fine)) * 0.01, {})


@pytest.mark.parametrize('n_rows, n_cols', [(150, 120), (150, 30), (7, 200), (0, 120)])
def test_gather_equals_the_fancy_index_for_wide_and_narrow_blocks(n_rows, n_cols):
    # 120 / 200 of 200 columns: rows copied 64 at a time; 30: the fancy index; 0 rows: empty
    rng = np.random.default_rng(n_rows + n_cols)
    a = rng.normal(size=(200, 200))
    rows = rng.permutation(200)[:n_rows]
    cols = rng.permutation(200)[:n_cols]
    got = gather(a, rows, cols)
    assert got.flags.c_contiguous
    np.testing.assert_array_equal(got, a[np.ix_(rows, cols)])


@pytest.mark.parametrize('m, k', [(60, 1), (60, 3), (20, 50), (80, 3)])
def test_solve_leading_equals_the_solve_with_the_leading_block(m, k):
    # (60, 3): the zero-padded solve with the whole factor; (20, 50): many right-hand sides
    # and a small block, the copied block; (80, 3): the whole factor
    rng = np.random.default_rng(m + k)
    g = rng.normal(size=(80, 80))
    lower = np.linalg.cholesky(g @ g.T + 80 * np.eye(80))
    b = rng.normal(size=(m, k)) if k > 1 else rng.normal(size=m)
    block = lower[:m, :m]
    np.testing.assert_allclose(solve_leading(lower, m, b, transposed=False),
                               np.linalg.solve(block, b), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(solve_leading(lower, m, b, transposed=True),
                               np.linalg.solve(block.T, b), rtol=1e-12, atol=1e-14)


def test_stream_filter_equals_the_full_rate_fir_for_any_chunking():
    # Bug caught: running-sum carry or history lost between calls, or an edge off by one.
    est = random_estimator()
    x = coloured_inputs(5000, 6) + 3.0     # an offset: S grows, its differences must not
    ref = OverlapAddFilter(est.fir(FS_HZ)).process(x)
    flt = CausalFilter(est, FS_HZ)
    batch = flt.process(x)
    np.testing.assert_allclose(batch, ref, atol=1e-10 * np.abs(ref).max())
    flt.reset()
    rng = np.random.default_rng(1)
    parts, i = [], 0
    while i < x.shape[1]:
        m = int(rng.integers(0, 40))
        parts.append(flt.process(x[:, i:i + m]))
        i += m
    np.testing.assert_allclose(np.concatenate(parts, axis=1), batch,
                               atol=1e-11 * np.abs(batch).max())
    assert flt.delay_samples == 3


@pytest.fixture(scope='module')
def fitted():
    x = coloured_inputs(int(FS_HZ * 200), 7) + np.array([[0.0], [0.0], [9.81]])
    rng = np.random.default_rng(8)
    y = apply_lags(x, {lag: rng.normal(size=(2, 3)) for lag in range(-3, 40, 3)}) + 100.0
    cfg = FitConfig(segment_length=256, long_segment_length=1024,
                    live=LiveDesign(look_aheads_s=(4 / FS_HZ, 0.0), history_s=1.0,
                                    blocks_per_octave=32))      # coarse blocks to check
    model = fit_model([TrainingSegment(x, y, 'train')], FS_HZ, cfg, INS, OUTS)
    return model, x, y


def test_fit_stores_one_estimator_per_look_ahead_and_it_beats_the_cut_fir(fitted):
    model, x, y = fitted
    assert [e.look_ahead_samples for e in model.live] == [4, 0]
    live = predict_forces(model, x, causal_delay_samples=4)
    cut = Predictor(dataclasses.replace(model, live=()), 4)
    assert cut.fallback is not None and 'cut' in cut.fallback
    cut_y = predict_forces(dataclasses.replace(model, live=()), x, causal_delay_samples=4)
    err_live = np.sqrt(np.mean((live - y) ** 2))
    err_cut = np.sqrt(np.mean((cut_y - y) ** 2))
    assert err_live < 0.5 * err_cut


def test_predictor_streams_the_live_estimator_like_the_batch(fitted):
    model, x, _ = fitted
    predictor = Predictor(model, 4)
    assert predictor.fallback is None and predictor.delay_samples == 4
    batch = predict_forces(model, x, causal_delay_samples=4)
    rng = np.random.default_rng(2)
    parts, i = [], 0
    while i < x.shape[1]:
        m = int(rng.integers(1, 33))
        parts.append(predictor.process(x[:, i:i + m]))
        i += m
    parts.append(predictor.flush())
    stream = np.concatenate(parts, axis=1)[:, 4:]
    np.testing.assert_allclose(stream, batch, atol=1e-9 * np.abs(batch).max())


def test_unfitted_look_ahead_names_the_available_ones(fitted):
    model, _, _ = fitted
    with pytest.raises(ConfigError, match=r'look-aheads of 4 \(31.2 ms\), 0 \(0.0 ms\).*refit'):
        Predictor(model, 5)
    assert Predictor(model, None).fallback is None        # the two-sided path is unchanged


def test_model_round_trip_keeps_the_live_estimators(fitted, tmp_path):
    model, x, _ = fitted
    loaded = load_model(save_model(model, tmp_path / 'm.npz'))
    # schema 2 brought the live estimators; 3 (issue 33) adds per-channel units
    assert json.loads(str(np.load(tmp_path / 'm.npz')['meta']))['schema_version'] == 3
    for a, b in zip(model.live, loaded.live):
        np.testing.assert_array_equal(a.fir(FS_HZ).taps, b.fir(FS_HZ).taps)
        assert a.info == b.info
    np.testing.assert_array_equal(predict_forces(loaded, x[:, :3000], 0),
                                  predict_forces(model, x[:, :3000], 0))


def _contents(path):
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def test_schema_1_file_loads_and_falls_back_to_the_cut_fir(fitted, tmp_path):
    model, x, _ = fitted
    contents = _contents(save_model(model, tmp_path / 'm.npz'))
    meta = json.loads(str(contents['meta']))
    meta['schema_version'] = 1
    del meta['live_estimators']
    contents = {k: v for k, v in contents.items() if not k.startswith('live')}
    contents['meta'] = np.array(json.dumps(meta))
    np.savez(tmp_path / 'v1.npz', **contents)
    old = load_model(tmp_path / 'v1.npz')
    assert old.live == ()
    predictor = Predictor(old, 4)
    assert 'no live (causal) estimator' in predictor.fallback
    assert 'wheel-force fit' in predictor.fallback


def test_malformed_live_section_is_refused_naming_the_field(fitted, tmp_path):
    model, _, _ = fitted
    contents = _contents(save_model(model, tmp_path / 'm.npz'))
    bad = dict(contents)
    del bad['live4_coarse_taps']
    np.savez(tmp_path / 'missing.npz', **bad)
    with pytest.raises(ModelFileError, match='live4_coarse_taps'):
        load_model(tmp_path / 'missing.npz')
    bad = dict(contents, live0_fine_taps=contents['live0_fine_taps'][:, :, :0])
    np.savez(tmp_path / 'short.npz', **bad)
    with pytest.raises(ModelFileError, match='fine_taps'):
        load_model(tmp_path / 'short.npz')
    assert contents['live0_coarse_edges'].size > 2        # reversed, they are not increasing
    bad = dict(contents, live0_coarse_edges=contents['live0_coarse_edges'][::-1].copy())
    np.savez(tmp_path / 'edges.npz', **bad)
    with pytest.raises(ModelFileError, match='coarse_edges'):
        load_model(tmp_path / 'edges.npz')


@pytest.mark.parametrize('kwargs, match', [
    ({'look_aheads_s': ()}, 'look-aheads'), ({'look_aheads_s': (-0.1,)}, 'look-aheads'),
    ({'history_s': 0.0}, 'history_s'), ({'blocks_per_octave': 0}, 'blocks_per_octave'),
    ({'regularisation': float('nan')}, 'regularisation')])
def test_live_design_rejects_bad_values(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        LiveDesign(**kwargs)


def test_full_look_ahead_of_a_model_is_the_offline_filter(fitted):
    model, x, _ = fitted
    full = Predictor(model, model.fir_delay_samples)
    assert full.fallback is None and full.delay_samples == model.fir_delay_samples
    np.testing.assert_array_equal(predict_forces(model, x, model.fir_delay_samples),
                                  predict_forces(model, x))


def test_the_default_basis_is_the_finest_the_cost_bound_allows_for_the_inputs():
    from wheel_force_estimator.core.live_estimator import BLOCKS_PER_OCTAVE_CHOICES
    from wheel_force_estimator.core.live_estimator import MAX_PAST_UNKNOWNS
    fs = 512.0
    design = LiveDesign()
    assert design.blocks_per_octave is None
    fine, history = int(round(design.fine_s * fs)), int(round(design.history_s * fs))
    seen = set()
    for n_in in (1, 12, 14, 16, 24, 30):
        got = design.for_inputs(n_in, fs).blocks_per_octave
        # past lags of every input, counted from the basis itself
        fits = [b for b in BLOCKS_PER_OCTAVE_CHOICES
                if n_in * (lag_edges(0, fine, history, b).size - 1) <= MAX_PAST_UNKNOWNS]
        assert got == (fits[0] if fits else BLOCKS_PER_OCTAVE_CHOICES[-1]), n_in
        seen.add(got)
    assert len(seen) > 1                  # a car's inputs and six components' differ
    # a resolution set by the caller is kept, whatever the inputs
    assert LiveDesign(blocks_per_octave=8).for_inputs(30, fs).blocks_per_octave == 8
    with pytest.raises(ConfigError, match='blocks_per_octave'):
        LiveDesign(blocks_per_octave=0)


def _estimator_on(blocks_per_octave, rng, d=3, fine=64, history=2048, n_out=2, n_in=3):
    """Return a random estimator on the multi-rate basis of ``blocks_per_octave``."""
    from wheel_force_estimator.core.normal_equations import _fine_count
    edges = lag_edges(d, fine, history, blocks_per_octave)
    n_fine = _fine_count(edges)           # the one-sample blocks are full-rate taps
    return CausalEstimator(d, rng.normal(size=(n_out, n_in, n_fine)), edges[n_fine:],
                           rng.normal(size=(n_out, n_in, edges.size - 1 - n_fine)),
                           {'regularisation': 1e-4, 'blocks_per_octave': blocks_per_octave})


def test_estimators_on_common_edges_are_the_same_filters():
    # Rows of input sets on different bases (48 and 32 blocks per octave) are composed into
    # one model estimator on the union of their edges: each must stay the same filter, exactly.
    from wheel_force_estimator.core.live_estimator import on_common_edges
    from wheel_force_estimator.core.search import _rows_of
    rng = np.random.default_rng(0)
    fine48, fine32 = _estimator_on(48, rng), _estimator_on(32, rng)
    # the finer basis begins its coarse part with more one-sample blocks: a longer fine part
    assert fine48.fine_taps.shape[2] > fine32.fine_taps.shape[2]
    assert not np.array_equal(fine48.coarse_edges, fine32.coarse_edges)
    union = np.union1d(fine48.coarse_edges, fine32.coarse_edges)
    for before, after in zip((fine48, fine32), on_common_edges([fine48, fine32])):
        np.testing.assert_array_equal(after.coarse_edges, fine48.coarse_edges[:1].tolist()
                                      + union[union > fine48.coarse_edges[0]].tolist())
        assert after.fine_taps.shape == fine48.fine_taps.shape
        np.testing.assert_array_equal(after.fir(FS_HZ).taps, before.fir(FS_HZ).taps)
    composed = _rows_of([fine48, fine32])
    for o, est in enumerate((fine48, fine32)):
        np.testing.assert_array_equal(composed.fir(FS_HZ).taps[o], est.fir(FS_HZ).taps[o])
    assert composed.info['blocks_per_octave'] == [48, 32]
    # on one basis nothing changes
    assert on_common_edges([fine48, fine48])[1] is fine48
    with pytest.raises(ValueError, match='no common basis'):
        on_common_edges([fine48, _estimator_on(32, rng, history=1000)])
