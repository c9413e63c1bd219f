# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Known-answer and invariant tests of FIR design and overlap-add filtering."""
import numpy as np
import pytest
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import acausal_energy_fraction
from wheel_force_estimator.core.filtering import fir_from_frf
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import with_delay
from wheel_force_estimator.core.overlap_add import apply_fir
from wheel_force_estimator.core.overlap_add import OverlapAddFilter

FS_HZ = 512.0
N_FFT = 1024         # the production size: 2 s Welch segments at 512 Hz
NF = N_FFT // 2 + 1
F_HZ = np.arange(NF) * FS_HZ / N_FFT
DF_HZ = FS_HZ / N_FFT


def direct_convolution(taps, x):
    """Stream output of a causal MIMO FIR by numpy.convolve (zeros before the stream)."""
    n = x.shape[1]
    y = np.zeros((taps.shape[0], n))
    for o in range(taps.shape[0]):
        for i in range(taps.shape[1]):
            y[o] += np.convolve(x[i], taps[o, i])[:n]
    return y


def sines(f_hz, amp, n, rng):
    """Sum of sinusoids with random phases, one row per channel (time last)."""
    t_s = np.arange(n) / FS_HZ
    phase = rng.uniform(0.0, 2.0 * np.pi, size=amp.shape)
    arg = 2.0 * np.pi * f_hz[None, :, None] * t_s[None, None, :] + phase[..., None]
    return np.einsum('ck,ckn->cn', amp, np.sin(arg))


def random_fir(rng, n_out=3, n_in=2, n_taps=40, delay=13):
    return FirFilter(rng.standard_normal((n_out, n_in, n_taps)), delay, FS_HZ)


# --------------------------------------------------------------------------- FIR design


def test_frequency_sampling_is_exact_without_taper_or_transition():
    # With no taper and hard edges the design is pure frequency sampling: the FIR response at
    # the FRF bins equals H except at DC (forced to 0).  Only FFT rounding (~1e-15) remains.
    rng = np.random.default_rng(1)
    h = rng.standard_normal((NF, 3, 2)) + 1j * rng.standard_normal((NF, 3, 2))
    h[-1] = h[-1].real          # a real filter has a real Nyquist gain
    fir = fir_from_frf(F_HZ, h, FS_HZ, taper_fraction=0.0, transition_hz=0.0)
    assert fir.taps.shape == (3, 2, N_FFT) and fir.delay_samples == N_FFT // 2
    got = fir.frequency_response(F_HZ)
    np.testing.assert_allclose(got[1:], h[1:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[0], 0.0, atol=1e-12)


def test_identity_frf_without_taper_is_exact_on_periodic_zero_mean_input():
    # H = I (DC zeroed) without taper gives taps delta - 1/n: the output is the input minus
    # its running mean over n_taps samples, which is exactly 0 for a sum of bin-centred sines.
    # So away from the edges (full filter support inside the record) y == x to rounding.
    rng = np.random.default_rng(2)
    h = np.broadcast_to(np.eye(2), (NF, 2, 2)).astype(complex)
    fir = fir_from_frf(F_HZ, h, FS_HZ, taper_fraction=0.0, transition_hz=0.0)
    lag0 = np.zeros(N_FFT)
    lag0[fir.delay_samples] = 1.0
    np.testing.assert_allclose(fir.taps[0, 0], lag0 - 1.0 / N_FFT, atol=1e-15)
    np.testing.assert_array_equal(fir.taps[0, 1], 0.0)
    n = 6 * N_FFT
    x = sines(DF_HZ * np.array([1.0, 7.0, 40.0]), rng.uniform(1, 3, (2, 3)), n, rng)
    y = apply_fir(fir, x)
    inner = slice(N_FFT, n - N_FFT)
    np.testing.assert_allclose(y[:, inner], x[:, inner], rtol=0, atol=1e-12)


def test_identity_frf_default_design_error_bounded_by_its_response():
    # Default design (taper + 1 Hz DC transition).  In steady state each sinusoid is scaled by
    # the FIR response, so |y - x| <= sum_k A_k |H_fir(f_k) - 1| exactly; the design property
    # asserted first is that this is < 2e-4 above 10 Hz (measured 9e-5 for 1024 taps).
    rng = np.random.default_rng(3)
    fir = fir_from_frf(F_HZ, np.broadcast_to(np.eye(2), (NF, 2, 2)), FS_HZ)
    f_sig = np.array([10.3, 31.7, 77.1, 190.9])
    amp = rng.uniform(1.0, 3.0, (2, f_sig.size))
    err_gain = np.abs(fir.frequency_response(f_sig)[:, [0, 1], [0, 1]] - 1.0).T   # (ch, k)
    assert err_gain.max() < 2e-4
    n = 8 * N_FFT
    x = sines(f_sig, amp, n, rng)
    y = apply_fir(fir, x)
    inner = slice(N_FFT, n - N_FFT)
    bound = (amp * err_gain).sum(axis=1) + 1e-12
    assert np.all(np.abs(y[:, inner] - x[:, inner]).max(axis=1) <= bound)


def test_pure_delay_mimo_frf_reproduces_delayed_mixed_input():
    # H = A exp(-j w d): the output is A x[n - d] up to the DC-removal kernel, bounded as above.
    # A non-square A also checks the [out, in] index order end to end.
    rng = np.random.default_rng(4)
    d = 9
    a = rng.standard_normal((3, 2))
    h = a[None] * np.exp(-2j * np.pi * F_HZ * d / FS_HZ)[:, None, None]
    fir = fir_from_frf(F_HZ, h, FS_HZ)
    f_sig = np.array([12.5, 55.0, 121.0])
    amp = rng.uniform(1.0, 2.0, (2, f_sig.size))
    n = 8 * N_FFT
    x = sines(f_sig, amp, n, rng)
    y = apply_fir(fir, x)
    resp = fir.frequency_response(f_sig)                                   # (k, o, i)
    ideal = a[None] * np.exp(-2j * np.pi * f_sig * d / FS_HZ)[:, None, None]
    bound = np.einsum('koi,ik->o', np.abs(resp - ideal), amp) + 1e-12
    assert np.abs(resp - ideal).max() < 2e-4 * np.abs(a).max()
    inner = slice(N_FFT, n - N_FFT)
    expected = a @ x[:, inner.start - d:inner.stop - d]
    assert np.all(np.abs(y[:, inner] - expected).max(axis=1) <= bound)


def test_butterworth_frf_matches_lfilter():
    # 2nd-order 20 Hz lowpass: its impulse response decays to < 1e-20 within 128 taps, so
    # truncation and aliasing are negligible and the FIR differs from the IIR only by the DC
    # transition (< 1.5 Hz).  The input is white noise with bins below 5 Hz removed, where the
    # design error is < 1.2e-3 (measured on a fine grid below), so the RMS error is < 2e-3
    # relative.  Away from edges lfilter's zero initial state has been forgotten.
    rng = np.random.default_rng(5)
    b, a = scipy.signal.butter(2, 20.0, fs=FS_HZ)
    _, h = scipy.signal.freqz(b, a, worN=F_HZ, fs=FS_HZ)
    fir = fir_from_frf(F_HZ, h[:, None, None], FS_HZ)
    f_fine = np.linspace(5.0, FS_HZ / 2, 2000)
    _, h_fine = scipy.signal.freqz(b, a, worN=f_fine, fs=FS_HZ)
    assert np.abs(fir.frequency_response(f_fine)[:, 0, 0] - h_fine).max() < 1.2e-3
    n = 20 * N_FFT
    spec = np.fft.rfft(rng.standard_normal(n))
    spec[np.fft.rfftfreq(n, 1.0 / FS_HZ) < 5.0] = 0.0
    x = np.fft.irfft(spec, n)[None, :]
    y_fir = apply_fir(fir, x)[0]
    y_iir = scipy.signal.lfilter(b, a, x[0])
    inner = slice(2 * N_FFT, n - N_FFT)
    err = np.sqrt(np.mean((y_fir[inner] - y_iir[inner]) ** 2) / np.mean(y_iir[inner] ** 2))
    assert err < 2e-3


def test_constant_input_gives_zero_output_after_warm_up():
    # Gravity in specific force: every (out, in) pair has zero DC gain to rounding, so a
    # constant input gives 0 wherever the whole filter support lies inside the record.
    # Tolerance: rounding of a sum of n_taps products, 1e-12 of sum|taps| * offset.
    rng = np.random.default_rng(6)
    h = rng.standard_normal((NF, 2, 3)) + 1j * rng.standard_normal((NF, 2, 3))
    fir = fir_from_frf(F_HZ, h, FS_HZ, f_min_hz=0.7, f_max_hz=150.0)
    assert np.abs(fir.taps.sum(axis=-1)).max() <= 1e-14 * np.abs(fir.taps).sum(axis=-1).max()
    x = np.full((3, 4 * N_FFT), 9.81)
    y = apply_fir(fir, x)
    inner = slice(N_FFT - 1 - fir.delay_samples, x.shape[1] - fir.delay_samples)
    assert np.abs(y[:, inner]).max() <= 1e-12 * np.abs(fir.taps).sum(axis=-1).max() * 9.81
    assert np.abs(y[:, :inner.start]).max() > 1e-3      # the edge transient is real


def test_band_limits_zero_the_response_outside_the_band():
    # f_min/f_max zero the bins outside the band, so with hard edges and no taper the response
    # at those bins is exactly zero (frequency sampling), and 1 inside.
    fir = fir_from_frf(F_HZ, np.ones((NF, 1, 1)), FS_HZ, f_min_hz=10.0, f_max_hz=100.0,
                       taper_fraction=0.0, transition_hz=0.0)
    resp = np.abs(fir.frequency_response(F_HZ)[:, 0, 0])
    inside = (F_HZ >= 10.0) & (F_HZ <= 100.0)
    np.testing.assert_allclose(resp[inside], 1.0, atol=1e-12)
    np.testing.assert_allclose(resp[~inside], 0.0, atol=1e-12)


# --------------------------------------------------------------------------- look-ahead


def test_acausal_energy_and_causal_delay_on_hand_built_taps():
    # taps [1, 2, 0, 3, 1, 1] with lag zero at index 3: energies 1, 4, 0 | 9, 1, 1 (total 16).
    fir = FirFilter(np.array([[[1.0, 2.0, 0.0, 3.0, 1.0, 1.0]]]), 3, FS_HZ)
    assert acausal_energy_fraction(fir, 0) == pytest.approx(5 / 16, abs=1e-15)
    assert acausal_energy_fraction(fir, 1) == pytest.approx(5 / 16, abs=1e-15)
    assert acausal_energy_fraction(fir, 2) == pytest.approx(1 / 16, abs=1e-15)
    assert acausal_energy_fraction(fir, 3) == 0.0
    assert acausal_energy_fraction(fir, 10) == 0.0
    zero = FirFilter(np.zeros((1, 1, 4)), 2, FS_HZ)
    assert acausal_energy_fraction(zero, 0) == 0.0


def test_with_delay_truncates_look_ahead_and_keeps_response():
    # A causal lowpass delayed by 5 samples.  Its FIR is not causal: the zero-phase DC
    # transition (a symmetric kernel ~n_taps long) spreads over the look-ahead.  Truncating
    # that look-ahead changes the response mostly at low frequency, less the more is kept:
    # with <= 1e-4 of the energy discarded the change above 10 Hz is < 1e-3 of the unit peak
    # (measured 4.6e-4 for this design), and the error shrinks monotonically with look-ahead.
    b, a = scipy.signal.butter(2, 30.0, fs=FS_HZ)
    _, h = scipy.signal.freqz(b, a, worN=F_HZ, fs=FS_HZ)
    h = h * np.exp(-2j * np.pi * F_HZ * 5 / FS_HZ)
    fir = fir_from_frf(F_HZ, h[:, None, None], FS_HZ)
    f_chk = np.linspace(5.0, 200.0, 800)
    ref = fir.frequency_response(f_chk)
    errors = []
    for max_fraction in (1e-2, 1e-4, 1e-6):
        # the shortest look-ahead that discards at most max_fraction of the energy
        d = next(d for d in range(fir.delay_samples + 1)
                 if acausal_energy_fraction(fir, d) <= max_fraction)
        short = with_delay(fir, d)
        assert short.delay_samples == d
        assert short.n_taps == fir.n_taps - (fir.delay_samples - d)
        assert abs(short.taps.sum()) <= 1e-14 * np.abs(short.taps).sum()
        assert OverlapAddFilter(short).delay_samples == d
        errors.append(np.abs(short.frequency_response(f_chk) - ref)[:, 0, 0])
        if max_fraction == 1e-4:
            assert errors[-1][f_chk >= 10.0].max() < 1e-3
    assert errors[0].max() > errors[1].max() > errors[2].max()
    assert with_delay(fir, fir.delay_samples) is fir


# --------------------------------------------------------------------------- overlap-add


@pytest.mark.parametrize('n_taps, delay', [(40, 13), (1, 0), (97, 96)])
def test_overlap_add_equals_direct_convolution(n_taps, delay):
    # Exact algorithm; only FFT rounding differs: 1e-12 of the output scale.  The 3000-sample
    # block exceeds the internal segment length, so the multi-segment path is exercised.
    rng = np.random.default_rng(7)
    fir = random_fir(rng, n_taps=n_taps, delay=delay)
    x = rng.standard_normal((2, 4000))
    engine = OverlapAddFilter(fir)
    y = np.concatenate([engine.process(x[:, :3000]), engine.process(x[:, 3000:3001]),
                        engine.process(x[:, 3001:])], axis=1)
    expected = direct_convolution(fir.taps, x)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    assert engine.samples_processed == 4000


def test_streaming_random_blocks_equals_batch():
    # Any chunking (including empty and 1-sample calls) gives the batch result; the stream is
    # lagged by delay_samples.  1e-9 relative is the contract; rounding gives ~1e-15.
    rng = np.random.default_rng(8)
    fir = fir_from_frf(F_HZ, rng.standard_normal((NF, 3, 2)) + 0j, FS_HZ)
    n = 3000
    x = rng.standard_normal((2, n))
    y_batch = apply_fir(fir, x)
    engine = OverlapAddFilter(fir)
    sizes = [0, 1, 1, 0] + list(rng.integers(0, 700, size=40))
    out, start = [], 0
    for m in sizes:
        out.append(engine.process(x[:, start:start + m]))
        assert out[-1].shape == (3, x[:, start:start + m].shape[1])
        start += m
        if start >= n:
            break
    out.append(engine.process(x[:, start:]))
    out.append(engine.process(np.zeros((2, fir.delay_samples))))
    stream = np.concatenate(out, axis=1)
    scale = np.abs(y_batch).max()
    np.testing.assert_allclose(stream[:, fir.delay_samples:], y_batch, rtol=0, atol=1e-9 * scale)
    engine.reset()
    np.testing.assert_allclose(engine.process(x[:, :500]), stream[:, :500], atol=1e-12 * scale)


def test_apply_fir_block_size_and_short_records():
    # Block size bounds memory only; records shorter than the look-ahead still come out
    # time-aligned (compared with the direct convolution shifted by the delay).
    rng = np.random.default_rng(9)
    fir = random_fir(rng, n_taps=40, delay=25)
    for n in (1, 10, 300):
        x = rng.standard_normal((2, n))
        padded = np.concatenate([x, np.zeros((2, fir.delay_samples))], axis=1)
        expected = direct_convolution(fir.taps, padded)[:, fir.delay_samples:]
        for block in (None, 1, 7, 64):
            y = apply_fir(fir, x, block_size=block)
            assert y.shape == (3, n)
            np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_filters_over_one_frozen_taps_array_share_its_spectrum_and_stay_exact():
    # A model's read-only taps keep their identity through FirFilter, so every filter built
    # over them (one per prediction) reuses one transform; the results are unchanged.
    rng = np.random.default_rng(10)
    taps = rng.standard_normal((3, 2, 40))
    taps.flags.writeable = False
    first, second = FirFilter(taps, 13, FS_HZ), FirFilter(taps, 13, FS_HZ)
    assert first.taps is taps and second.taps is taps
    x = rng.standard_normal((2, 300))
    expected = direct_convolution(taps, x)
    a, b = OverlapAddFilter(first), OverlapAddFilter(second)
    y_a = a.process(x)
    np.testing.assert_allclose(y_a, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_array_equal(b.process(x), y_a)
    assert a._tap_spectrum(512) is b._tap_spectrum(512)
    # Writable taps are copied: changing the caller's array afterwards changes nothing.
    own = rng.standard_normal((3, 2, 40))
    fir = FirFilter(own, 13, FS_HZ)
    assert fir.taps is not own and not fir.taps.flags.writeable
    before = apply_fir(fir, x)
    own[:] = 0.0
    assert np.abs(before).max() > 0
    np.testing.assert_array_equal(apply_fir(FirFilter(fir.taps, 13, FS_HZ), x), before)


# --------------------------------------------------------------------------- errors


def test_errors_are_precise():
    rng = np.random.default_rng(10)
    fir = random_fir(rng)
    with pytest.raises(ShapeError, match=r'expected shape \(n_out, n_in, n_taps\)'):
        FirFilter(np.zeros((2, 3)), 0, FS_HZ)
    with pytest.raises(ConfigError, match=r'delay_samples must be in \[0, 4\)'):
        FirFilter(np.zeros((1, 1, 4)), 4, FS_HZ)
    with pytest.raises(NonFiniteError, match='output 0, input 0, tap 2'):
        FirFilter(np.array([[[0.0, 1.0, np.nan]]]), 0, FS_HZ)
    with pytest.raises(ConfigError, match='fs_hz'):
        FirFilter(np.zeros((1, 1, 4)), 0, 0.0)

    engine = OverlapAddFilter(fir)
    engine.process(rng.standard_normal((2, 5)))
    with pytest.raises(ShapeError, match=r'stream sample 5: expected shape \(2, m\)'):
        engine.process(np.zeros((3, 4)))
    bad = np.zeros((2, 8))
    bad[1, 6] = np.nan
    with pytest.raises(NonFiniteError, match='channel 1 at sample 6'):
        engine.process(bad)
    assert engine.samples_processed == 5          # a rejected block leaves the state alone

    with pytest.raises(ShapeError, match='accel: expected 2 channels, got 3'):
        apply_fir(fir, np.zeros((3, 10)), name='accel')
    with pytest.raises(NonFiniteError, match='channel 0 at sample 3'):
        apply_fir(fir, np.array([[0, 0, 0, np.inf], [0, 0, 0, 0]]))
    with pytest.raises(InsufficientDataError, match='0 samples'):
        apply_fir(fir, np.zeros((2, 0)))
    with pytest.raises(ConfigError, match='block_size must be >= 1'):
        apply_fir(fir, np.zeros((2, 10)), block_size=0)

    h = np.ones((NF, 1, 1))
    with pytest.raises(ConfigError, match='uniform from 0 Hz'):
        fir_from_frf(F_HZ ** 1.01, h, FS_HZ)
    with pytest.raises(ConfigError, match='uniform from 0 Hz'):
        fir_from_frf(F_HZ, h, 2 * FS_HZ)
    with pytest.raises(ShapeError, match=r'expected shape \(513, n_out, n_in\)'):
        fir_from_frf(F_HZ, np.ones((NF, 2)), FS_HZ)
    h_nan = h.copy()
    h_nan[3] = np.nan
    with pytest.raises(NonFiniteError, match=r'at 1.5 Hz \(bin 3\), output 0, input 0'):
        fir_from_frf(F_HZ, h_nan, FS_HZ)
    with pytest.raises(ConfigError, match='f_min_hz < f_max_hz'):
        fir_from_frf(F_HZ, h, FS_HZ, f_min_hz=50.0, f_max_hz=20.0)
    with pytest.raises(ConfigError, match='contains no FRF bin'):
        fir_from_frf(F_HZ, h, FS_HZ, f_min_hz=2.1, f_max_hz=2.4, transition_hz=0.0)
    with pytest.raises(ConfigError, match='delay_samples must be in'):
        fir_from_frf(F_HZ, h, FS_HZ, delay_samples=N_FFT)
    with pytest.raises(ConfigError, match=r'delay_samples must be in \[0, 13\]'):
        with_delay(fir, 14)
    with pytest.raises(ConfigError, match='delay_samples must be >= 0'):
        acausal_energy_fraction(fir, -1)
