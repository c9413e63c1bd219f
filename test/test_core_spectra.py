# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of core.spectra: scipy agreement, hand-computable densities, combining, errors."""
import dataclasses
import tracemalloc

import numpy as np
import pytest
import scipy.signal

from wheel_force_estimator.core import spectra as spectra_mod
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.spectra import auto_spectral_density
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import CrossSpectra
from wheel_force_estimator.core.spectra import pooled_cross_spectra
from wheel_force_estimator.core.spectra import WelchConfig

FS_HZ = 200.0
# Our engine and scipy do the same arithmetic in a different order (batched FFT and matmul vs
# per-pair), so they agree to a few ulps of the largest value: 1e-12 relative leaves margin.
RTOL_SCIPY = 1e-12

CONFIGS = [
    WelchConfig(FS_HZ, 256, 0.5, 'hann', 'constant'),
    WelchConfig(FS_HZ, 255, 0.3, ('tukey', 0.3), 'linear'),
    WelchConfig(FS_HZ, 64, 0.0, 'boxcar', 'none'),
    WelchConfig(FS_HZ, 100, 0.75, 'hamming', 'linear'),
]


def _scipy_detrend(config):
    return False if config.detrend == 'none' else config.detrend


def _signals(seed, n_in=3, n_out=2, n=5000):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n_in, n)) + 0.3
    y = rng.standard_normal((n_out, n)) + x[:n_out] - 2.0 * x[-1]
    return x, y


def _close(a, b):
    """Max deviation relative to the largest magnitude (densities span decades)."""
    return np.max(np.abs(a - b)) <= RTOL_SCIPY * np.max(np.abs(b))


@pytest.mark.parametrize('config', CONFIGS, ids=lambda c: f'{c.segment_length}-{c.detrend}')
def test_every_pair_equals_scipy_csd(config):
    x, y = _signals(0)
    s = cross_spectra(x, y, config)
    kw = {'fs': FS_HZ, 'window': config.window, 'nperseg': config.segment_length,
          'noverlap': config.overlap_samples, 'detrend': _scipy_detrend(config)}
    for i in range(x.shape[0]):
        for j in range(x.shape[0]):
            f_hz, pxx = scipy.signal.csd(x[i], x[j], **kw)
            assert _close(s.sxx[:, i, j], pxx)
        for o in range(y.shape[0]):
            _, pxy = scipy.signal.csd(x[i], y[o], **kw)
            assert _close(s.syx[:, o, i], pxy)
    _, pyy = scipy.signal.welch(y, **kw)
    assert _close(s.syy, pyy.T)
    np.testing.assert_array_equal(s.f_hz, f_hz)
    assert s.n_windows == (x.shape[1] - config.overlap_samples) // config.step_samples


@pytest.mark.parametrize('config', CONFIGS, ids=lambda c: f'{c.segment_length}-{c.detrend}')
def test_auto_spectral_density_equals_scipy_welch(config):
    x, _ = _signals(1, n_in=4)
    f_hz, psd = auto_spectral_density(x, config)
    f_ref, psd_ref = scipy.signal.welch(
        x, fs=FS_HZ, window=config.window, nperseg=config.segment_length,
        noverlap=config.overlap_samples, detrend=_scipy_detrend(config))
    np.testing.assert_array_equal(f_hz, f_ref)
    assert psd.shape == (4, config.segment_length // 2 + 1)
    assert _close(psd, psd_ref)
    # A 1-D signal is one channel.
    _, psd1 = auto_spectral_density(x[2], config)
    np.testing.assert_allclose(psd1[0], psd[2], rtol=1e-12)


def test_cosine_on_a_bin_has_hand_computed_density():
    # Boxcar, no overlap, cosine of amplitude A exactly on bin k: |X_k| = A L / 2, scale
    # 1 / (fs L), one-sided x2  ->  P_k = A² L / (2 fs), i.e. P_k * df = A² / 2 (its power).
    length, k, amp = 64, 5, 3.0
    config = WelchConfig(FS_HZ, length, 0.0, 'boxcar', 'none')
    t = np.arange(length * 10)
    x = amp * np.cos(2 * np.pi * k * t / length)
    f_hz, psd = auto_spectral_density(x, config)
    df = FS_HZ / length
    assert f_hz[k] == pytest.approx(k * df)
    assert psd[0, k] * df == pytest.approx(amp ** 2 / 2, rel=1e-12)
    # Every other bin holds only round-off (the cosine is periodic in the segment).
    assert np.max(np.delete(psd[0], k)) < 1e-20 * psd[0, k]


def test_white_noise_density_integrates_to_variance():
    # Parseval: the one-sided density integrates to the variance.  For 389 Hann windows at
    # 50 % overlap of white Gaussian noise the integral's relative standard deviation is
    # sqrt(2 (K sum w^4 + 2 (K-1) sum w_n^2 w_(n+L/2)^2)) / (K sum w^2) = 0.65 %, so 3 % is a
    # 4.6 sigma bound (this seed gives -1.8 %).
    rng = np.random.default_rng(3)
    x = 2.0 * rng.standard_normal(50000)
    f_hz, psd = auto_spectral_density(x, WelchConfig(FS_HZ, 256))
    assert np.trapezoid(psd[0], f_hz) == pytest.approx(4.0, rel=0.03)


def test_spectral_matrix_structure():
    x, y = _signals(4)
    s = cross_spectra(x, y, CONFIGS[0])
    np.testing.assert_array_equal(s.sxx, s.sxx.conj().transpose(0, 2, 1))
    assert np.all(np.diagonal(s.sxx, axis1=1, axis2=2).imag == 0.0)
    assert np.all(s.syy >= 0.0) and s.syy.dtype == np.float64
    assert (s.n_inputs, s.n_outputs) == (3, 2)
    with pytest.raises(ValueError):
        s.sxx[0, 0, 0] = 1.0  # arrays of a frozen result are read-only
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.n_windows = 3


def test_chunking_does_not_change_the_result(monkeypatch):
    # Windows are processed in chunks; a chunk size of a few windows (with a partial last
    # chunk) must give the single-chunk answer up to summation-order round-off.
    x, y = _signals(5, n=20000)
    config = WelchConfig(FS_HZ, 128, 0.5)
    whole = cross_spectra(x, y, config)
    monkeypatch.setattr(spectra_mod, '_CHUNK_BYTES', 7 * 5 * 128 * 8)
    chunked = cross_spectra(x, y, config)
    assert whole.n_windows == chunked.n_windows == 311
    np.testing.assert_allclose(chunked.sxx, whole.sxx, rtol=0, atol=1e-13 * abs(whole.sxx).max())
    np.testing.assert_allclose(chunked.syx, whole.syx, rtol=0, atol=1e-13 * abs(whole.syx).max())
    np.testing.assert_allclose(chunked.syy, whole.syy, rtol=1e-13)


def test_products_batched_across_chunks_and_segments_equal_window_by_window(monkeypatch):
    # Long windows: one window per chunk, and segments of one to three windows; the products
    # gather 8 windows across them (_PRODUCT_WINDOWS), with a partial last batch.
    x, y = _signals(5, n=6000)
    config = WelchConfig(FS_HZ, 256, 0.5)
    cuts = [(0, 256), (256, 768), (768, 1024), (1024, 1536), (1536, 2048), (2048, 4100)]
    pairs = [(x[:, a:b], y[:, a:b]) for a, b in cuts]
    monkeypatch.setattr(spectra_mod, '_CHUNK_BYTES', 5 * 256 * 8)
    batched = pooled_cross_spectra(pairs, config)
    monkeypatch.setattr(spectra_mod, '_PRODUCT_WINDOWS', 1)
    single = pooled_cross_spectra(pairs, config)
    assert batched.n_windows == single.n_windows == 1 + 3 + 1 + 3 + 3 + 15
    for field in ('sxx', 'syx', 'syy'):
        want = getattr(single, field)
        np.testing.assert_allclose(getattr(batched, field), want, rtol=0,
                                   atol=1e-13 * abs(want).max())


def test_memory_does_not_grow_with_record_length():
    # 24 channels x 400k samples is 77 MB of data; the spectra need a 4 MiB chunk, its FFT and
    # the (nf, 24, 24) accumulator.  A copy of the record would show up as >= 77 MB.
    rng = np.random.default_rng(6)
    x = rng.standard_normal((12, 400_000))
    y = rng.standard_normal((12, 400_000))
    tracemalloc.start()
    try:
        cross_spectra(x, y, WelchConfig(512.0, 1024))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 40e6


def test_combine_equals_welch_over_the_union_of_windows():
    x, y = _signals(7, n=6000)
    config = WelchConfig(FS_HZ, 256, 0.5)
    a = cross_spectra(x[:, :2000], y[:, :2000], config, 'a')
    b = cross_spectra(x[:, 2000:], y[:, 2000:], config, 'b')
    both = combine_spectra([a, b])
    assert both.n_windows == a.n_windows + b.n_windows == 14 + 30
    # Independent reference for the autos: scipy's per-window densities of each segment,
    # pooled, then averaged.
    kw = {'fs': FS_HZ, 'window': 'hann', 'nperseg': 256, 'noverlap': 128, 'detrend': 'constant',
          'scaling': 'density', 'mode': 'psd'}
    _, _, pa = scipy.signal.spectrogram(y[:, :2000], **kw)
    _, _, pb = scipy.signal.spectrogram(y[:, 2000:], **kw)
    pooled = np.concatenate([pa, pb], axis=-1).mean(axis=-1)
    assert _close(both.syy, pooled.T)
    # Cross terms: scipy.csd of each segment weighted by its window count.
    kw = {'fs': FS_HZ, 'window': 'hann', 'nperseg': 256, 'noverlap': 128}
    _, ca = scipy.signal.csd(x[1, :2000], y[0, :2000], **kw)
    _, cb = scipy.signal.csd(x[1, 2000:], y[0, 2000:], **kw)
    assert _close(both.syx[:, 0, 1], (14 * ca + 30 * cb) / 44)
    _, ca = scipy.signal.csd(x[0, :2000], x[2, :2000], **kw)
    _, cb = scipy.signal.csd(x[0, 2000:], x[2, 2000:], **kw)
    assert _close(both.sxx[:, 0, 2], (14 * ca + 30 * cb) / 44)
    single = combine_spectra([a])
    assert single.n_windows == a.n_windows and np.array_equal(single.sxx, a.sxx)


def test_pooled_equals_combined_per_segment_spectra():
    # pooled_cross_spectra accumulates one set of matrices for several segments: the same
    # numbers as combining each segment's own (the union of their windows), shorter
    # segments and a segment of exactly one window included.
    x, y = _signals(11, n=6000)
    config = WelchConfig(FS_HZ, 256, 0.5)
    cuts = [(0, 2000), (2000, 2256), (2256, 6000)]
    pooled = pooled_cross_spectra([(x[:, a:b], y[:, a:b]) for a, b in cuts], config, 'pooled')
    combined = combine_spectra([cross_spectra(x[:, a:b], y[:, a:b], config) for a, b in cuts])
    assert pooled.n_windows == combined.n_windows == 14 + 1 + 28
    for field in ('sxx', 'syx', 'syy'):
        assert _close(getattr(pooled, field), getattr(combined, field))
    assert np.array_equal(pooled.sxx, pooled.sxx.conj().transpose(0, 2, 1))
    with pytest.raises(ShapeError, match='segment 1 has 2 inputs'):
        pooled_cross_spectra([(x, y), (x[:2], y)], config, 'pooled')
    with pytest.raises(InsufficientDataError, match=r'pooled \(segment 1\): 100 samples'):
        pooled_cross_spectra([(x, y), (x[:, :100], y[:, :100])], config, 'pooled')
    with pytest.raises(InsufficientDataError, match='no segment'):
        pooled_cross_spectra([], config, 'pooled')


def test_combine_avoids_the_join_artefact_of_concatenation():
    # Two recordings with different offsets and no common phase: concatenating them puts a
    # step inside the windows straddling the join, whose leakage floods the quiet high band.
    rng = np.random.default_rng(8)
    config = WelchConfig(FS_HZ, 256, 0.5)
    sos = scipy.signal.butter(8, 20.0, fs=FS_HZ, output='sos')
    parts = [scipy.signal.sosfilt(sos, rng.standard_normal((2, 4000))) + off
             for off in (50.0, -50.0)]
    x = [p[:1] for p in parts]
    y = [p[1:] for p in parts]
    combined = combine_spectra([cross_spectra(xi, yi, config) for xi, yi in zip(x, y)])
    joined = cross_spectra(np.hstack(x), np.hstack(y), config)
    high = combined.f_hz > 60.0
    # The 8th-order low-pass leaves the band above 60 Hz > 80 dB down; the step puts far more
    # there: the concatenation overestimates that band by orders of magnitude.
    assert np.median(joined.syy[high, 0] / combined.syy[high, 0]) > 100.0
    assert np.median(np.abs(joined.syx[high, 0, 0] / combined.syx[high, 0, 0])) > 100.0


@pytest.mark.parametrize('kwargs, match', [
    ({'fs_hz': 0.0}, 'fs_hz must be finite and > 0'),
    ({'fs_hz': 'fast'}, 'fs_hz must be a number'),
    ({'fs_hz': 100.0, 'segment_length': 7}, 'segment_length must be >= 8'),
    ({'fs_hz': 100.0, 'segment_length': 64.0}, 'segment_length must be an integer'),
    ({'fs_hz': 100.0, 'segment_length': True}, 'segment_length must be an integer'),
    ({'fs_hz': 100.0, 'overlap': 0.95}, r'overlap must be in \[0, 0.95\)'),
    ({'fs_hz': 100.0, 'overlap': -0.1}, r'overlap must be in \[0, 0.95\)'),
    ({'fs_hz': 100.0, 'overlap': None}, 'overlap must be a number'),
    ({'fs_hz': 100.0, 'window': 'no_such_window'}, "window 'no_such_window' is not a scipy"),
    ({'fs_hz': 100.0, 'window': 3}, 'window must be a window name'),
    ({'fs_hz': 100.0, 'detrend': 'quadratic'}, 'detrend must be one of'),
])
def test_welch_config_rejects(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        WelchConfig(**kwargs)


def test_welch_config_derived_values():
    c = WelchConfig(512.0, 1024, 0.5)
    assert (c.overlap_samples, c.step_samples) == (512, 512)
    assert c.f_hz[1] == 0.5 and c.f_hz[-1] == 256.0
    assert c.n_windows(1023) == 0 and c.n_windows(1024) == 1 and c.n_windows(2047) == 2
    assert WelchConfig(512.0, window=['tukey', 0.5]).window == ('tukey', 0.5)
    assert c == WelchConfig(512, 1024, 0.5, 'hann', 'constant')


def test_too_short_names_the_recording_and_counts():
    x, y = _signals(9, n=200)
    with pytest.raises(InsufficientDataError,
                       match=r'run7.bag: 200 samples, shorter than one Welch segment of 256'):
        cross_spectra(x, y, WelchConfig(FS_HZ, 256), 'run7.bag')
    with pytest.raises(InsufficientDataError, match=r'accel: 200 samples, .* 256 samples'):
        auto_spectral_density(x, WelchConfig(FS_HZ, 256), 'accel')


def test_non_finite_is_rejected_with_channel_and_sample():
    x, y = _signals(10, n=1000)
    x[1, 321] = np.nan
    with pytest.raises(NonFiniteError, match='inputs of seg2: .*nan.* channel 1 at sample 321'):
        cross_spectra(x, y, WelchConfig(FS_HZ, 256), 'seg2')
    x[1, 321] = 0.0
    y[0, 5] = np.inf
    with pytest.raises(NonFiniteError, match='outputs of seg2: .*inf.* channel 0 at sample 5'):
        cross_spectra(x, y, WelchConfig(FS_HZ, 256), 'seg2')
    with pytest.raises(NonFiniteError, match='channel 0 at sample 5'):
        auto_spectral_density(y, WelchConfig(FS_HZ, 256))


def test_shape_errors():
    x, y = _signals(11, n=1000)
    with pytest.raises(ShapeError, match='inputs have 1000 samples but outputs have 999'):
        cross_spectra(x, y[:, :999], WelchConfig(FS_HZ, 256), 'seg')
    with pytest.raises(ShapeError, match='expected shape'):
        cross_spectra(x[np.newaxis], y, WelchConfig(FS_HZ, 256))
    with pytest.raises(ShapeError, match='at least one input and one output'):
        cross_spectra(x, y[:0], WelchConfig(FS_HZ, 256))
    with pytest.raises(ConfigError, match='config must be a WelchConfig'):
        cross_spectra(x, y, {'fs_hz': FS_HZ})
    with pytest.raises(ConfigError, match='config must be a WelchConfig'):
        auto_spectral_density(x, None)


def test_combine_rejects_mismatches():
    x, y = _signals(12, n=2000)
    a = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    with pytest.raises(InsufficientDataError, match='no spectra'):
        combine_spectra([])
    with pytest.raises(ConfigError, match='item 1 was computed with'):
        combine_spectra([a, cross_spectra(x, y, WelchConfig(FS_HZ, 256, window='hamming'))])
    with pytest.raises(ConfigError, match='item 1 was computed with'):
        combine_spectra([a, cross_spectra(x, y, WelchConfig(2 * FS_HZ, 256))])
    with pytest.raises(ShapeError, match='item 1 has 2 inputs and 2 outputs, item 0 has 3'):
        combine_spectra([a, cross_spectra(x[:2], y, WelchConfig(FS_HZ, 256))])
    with pytest.raises(ShapeError, match='item 1 has 3 inputs and 1 outputs'):
        combine_spectra([a, cross_spectra(x, y[:1], WelchConfig(FS_HZ, 256))])
    with pytest.raises(ConfigError, match='item 1 is not a CrossSpectra'):
        combine_spectra([a, a.sxx])


def test_cross_spectra_validates_its_fields():
    x, y = _signals(13, n=2000)
    s = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    fields = {'f_hz': s.f_hz, 'sxx': s.sxx, 'syx': s.syx, 'syy': s.syy, 'n_windows': s.n_windows,
              'config': s.config}
    with pytest.raises(ShapeError, match='sxx must be'):
        CrossSpectra(**{**fields, 'sxx': s.sxx[:, :2]})
    with pytest.raises(ShapeError, match='syx must be'):
        CrossSpectra(**{**fields, 'syx': s.syx[:, :, :2]})
    with pytest.raises(ShapeError, match='syy must be'):
        CrossSpectra(**{**fields, 'syy': s.syy[:-1]})
    with pytest.raises(ConfigError, match='n_windows must be an integer >= 1'):
        CrossSpectra(**{**fields, 'n_windows': 0})
    with pytest.raises(ConfigError, match='config must be a WelchConfig'):
        CrossSpectra(**{**fields, 'config': 'hann'})
    mine = s.sxx.copy()
    CrossSpectra(**{**fields, 'sxx': mine})
    mine[0, 0, 0] = 1.0  # the frozen result keeps its own copy; the caller's stays writable


def test_power_quantile_hand_values():
    from wheel_force_estimator.core.spectra import power_quantile_hz
    f = np.array([0.0, 1.0, 2.0, 3.0])
    power = np.array([0.0, 1.0, 1.0, 2.0])          # cumulative 0, 1, 2, 4
    assert power_quantile_hz(f, power, 0.5) == 2.0
    assert power_quantile_hz(f, power, 0.51) == 3.0
    assert power_quantile_hz(f, power, 0.25) == 1.0
    assert power_quantile_hz(f, np.zeros(4), 0.99) is None
