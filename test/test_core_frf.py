# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Tests of core.frf: a known 12x12 system, collinear inputs, invariants and errors."""
import dataclasses

import numpy as np
import pytest
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.frf import estimate_frf
from wheel_force_estimator.core.frf import FrfConfig
from wheel_force_estimator.core.frf import FrfEstimate
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import CrossSpectra
from wheel_force_estimator.core.spectra import WelchConfig

FS_HZ = 512.0
N_IO = 12
DURATION_S = 240.0
WELCH = WelchConfig(FS_HZ, 1024, 0.5)
# Inputs are low-passed at 150 Hz (8th order); below 130 Hz every input is within 1 dB of its
# level, above ~180 Hz the outputs are mostly noise.
BAND_HZ = 130.0
ESTIMATORS = [FrfConfig('h1'), FrfConfig('h1_tikhonov', 1e-4), FrfConfig('h1_tsvd', 1e-4)]


def _random_system(rng):
    """
    Return b, a of shape (12, 12, 3): a stable 2nd-order IIR per (output, input) pair.

    Poles at radius 0.5-0.85 (impulse responses below 1 % after 28 samples, half-power
    bandwidth >= 24 Hz) and zeros within radius 0.5, so no pair has a deep notch.
    """
    b = np.empty((N_IO, N_IO, 3))
    a = np.empty((N_IO, N_IO, 3))
    for o in range(N_IO):
        for i in range(N_IO):
            r, th = rng.uniform(0.5, 0.85), rng.uniform(0.05, 0.6) * np.pi
            a[o, i] = [1.0, -2.0 * r * np.cos(th), r * r]
            rz, tz = rng.uniform(0.0, 0.5), rng.uniform(0.0, np.pi)
            gain = rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 2.0)
            b[o, i] = gain * np.array([1.0, -2.0 * rz * np.cos(tz), rz * rz])
    return b, a


def _true_frf(b, a, f_hz):
    h = np.empty((f_hz.size, N_IO, N_IO), dtype=complex)
    for o in range(N_IO):
        for i in range(N_IO):
            h[:, o, i] = scipy.signal.freqz(b[o, i], a[o, i], worN=f_hz, fs=FS_HZ)[1]
    return h


def _inputs(rng, n, collinear=None):
    """Independent coloured inputs; ``collinear=eps`` makes x1 = x0 + eps * std(x0) * noise."""
    sos = scipy.signal.butter(8, 150.0, fs=FS_HZ, output='sos')
    x = scipy.signal.sosfilt(sos, rng.standard_normal((N_IO, n + 1000)), axis=1)[:, 1000:]
    x *= rng.uniform(0.5, 2.0, (N_IO, 1))
    if collinear is not None:
        x[1] = x[0] + collinear * x[0].std() * rng.standard_normal(n)
    return x


def _outputs(rng, b, a, x, noise=0.003):
    """Exact IIR responses plus white noise of ``noise`` times each output's std."""
    y = np.zeros((N_IO, x.shape[1]))
    for o in range(N_IO):
        for i in range(N_IO):
            y[o] += scipy.signal.lfilter(b[o, i], a[o, i], x[i])
    y += noise * y.std(axis=1, keepdims=True) * rng.standard_normal(y.shape)
    return y


def _h1_random_error(spectra, coherence_multiple, h_abs, pxx=None):
    """
    Predicted 1-sigma relative random error of each H1 entry (per component).

    Bendat & Piersol, Random Data, eq. 9.90, q independent inputs:
    eps = sqrt((1 - g2) Syy / (2 (n_d - q) Sxx_ii |H_oi|^2)) with g2 the multiple coherence;
    Hann at 50 % overlap has n_d = n_windows / 1.056 independent averages (Welch 1967).
    """
    n_d = spectra.n_windows / 1.056 - N_IO
    if pxx is None:
        pxx = np.diagonal(spectra.sxx, axis1=1, axis2=2).real[:, np.newaxis, :]
    return np.sqrt((1.0 - coherence_multiple[:, :, np.newaxis]) * spectra.syy[:, :, np.newaxis]
                   / (2.0 * n_d * pxx * h_abs ** 2))


# Leakage and resolution bias of the H1 entries of these systems, see the known-answer test.
BIAS = 0.003


@pytest.fixture(scope='module')
def known_system():
    rng = np.random.default_rng(20260101)
    b, a = _random_system(rng)
    x = _inputs(rng, int(DURATION_S * FS_HZ))
    y = _outputs(rng, b, a, x)
    spectra = cross_spectra(x, y, WELCH, 'known system')
    return spectra, _true_frf(b, a, spectra.f_hz)


def test_known_12x12_system_is_recovered(known_system):
    spectra, h_true = known_system
    est = estimate_frf(spectra, FrfConfig('h1'))
    rel_err = np.abs(est.h - h_true) / np.abs(h_true)
    # Bounds |H| relative error and phase error in rad (both <= the complex relative error).
    high = np.broadcast_to((est.coherence_multiple > 0.99)[:, :, np.newaxis], rel_err.shape)
    # Random error of one H1 entry: see _h1_random_error.  At g2 = 0.99 an entry carrying
    # 1/12 of its output's power has eps ~ 1.6 % with the 239 windows of 4 minutes, so "1 %
    # wherever g2 > 0.99" cannot hold entry by entry; it holds where eps <= 0.117 %: 6 eps (a
    # Rayleigh 6-sigma excursion, probability 1.5e-8 per entry) plus the bias allowance gives
    # 1 %.  Everywhere else with g2 > 0.99 the error must stay within 6 eps + bias.
    eps = _h1_random_error(spectra, est.coherence_multiple, np.abs(h_true))
    # Bias: the impulse responses decay below 1 % within 28 samples (2.7 % of a segment) and
    # the narrowest resonance is 24 Hz wide against a 0.75 Hz Hann bandwidth, so leakage and
    # resolution bias are ~(0.75 / 24)^2 / 3 = 0.03 %; 0.3 % is a generous allowance.
    bias = BIAS
    assert np.all(rel_err[high] <= 6.0 * eps[high] + bias)
    strict = high & (eps <= (0.01 - bias) / 6.0)
    assert strict.sum() > 0.15 * high.sum() > 0.15 * 0.5 * rel_err.size  # not vacuous
    assert rel_err[strict].max() < 0.01
    mag_err = np.abs(np.abs(est.h) / np.abs(h_true) - 1.0)
    phase_err_rad = np.abs(np.angle(est.h / h_true))
    assert mag_err[strict].max() < 0.01 and phase_err_rad[strict].max() < 0.01
    # In the excited band the outputs are explained almost entirely by the inputs.
    band = spectra.f_hz < BAND_HZ
    assert np.median(est.coherence_multiple[band]) > 0.999
    assert est.cond_sxx[band].max() < 100.0  # independent inputs of similar level


def test_regularised_estimators_agree_on_well_conditioned_data(known_system):
    spectra, h_true = known_system
    plain = estimate_frf(spectra, FrfConfig('h1'))
    band = spectra.f_hz < BAND_HZ
    for config in ESTIMATORS[1:]:
        est = estimate_frf(spectra, config)
        # cond(Sxx) < 100 in band: relative regularisation 1e-4 moves H by < 1e-4 * 100.
        rel = np.abs(est.h[band] - plain.h[band]) / np.abs(plain.h[band])
        assert rel.max() < 1e-2 and np.median(rel) < 1e-3
        # Fraction of output power explained by a regularised estimate never exceeds H1's.
        assert np.all(est.coherence_multiple <= plain.coherence_multiple + 1e-12)
        np.testing.assert_array_equal(est.cond_sxx, plain.cond_sxx)
    np.testing.assert_array_equal(est.coherence_ordinary, plain.coherence_ordinary)
    # With no regularisation every estimator is plain H1 (round-off amplified by cond < 1e4).
    for name in ('h1_tikhonov', 'h1_tsvd'):
        est = estimate_frf(spectra, FrfConfig(name, 0.0))
        np.testing.assert_allclose(est.h, plain.h, rtol=1e-10, atol=1e-12 * abs(plain.h).max())


@pytest.mark.parametrize('config', ESTIMATORS, ids=lambda c: c.estimator)
def test_all_channel_estimate_equals_per_output_estimate(config):
    rng = np.random.default_rng(5)
    b, a = _random_system(rng)
    x = _inputs(rng, 30 * int(FS_HZ))
    y = _outputs(rng, b, a, x)
    whole = estimate_frf(cross_spectra(x, y, WELCH), config)
    for o in (0, 7, 11):
        single = estimate_frf(cross_spectra(x, y[o:o + 1], WELCH), config)
        # Same Sxx up to BLAS summation order (1e-16) times cond(Sxx) < 1e3.
        np.testing.assert_allclose(single.h[:, 0], whole.h[:, o], rtol=1e-9,
                                   atol=1e-12 * abs(whole.h).max())
        np.testing.assert_allclose(single.coherence_multiple[:, 0],
                                   whole.coherence_multiple[:, o], rtol=1e-9, atol=1e-12)


def _prediction_error(h, spectra, band):
    """
    Band RMS of y - h x relative to the band RMS of y, per output, from a record's spectra.

    E|Y - h X|^2 = Syy - 2 Re(conj(h) . Syx) + conj(h) Sxx h^T, exact for the windows of the
    record, so no time-domain filter is needed to judge a prediction.
    """
    cross = np.einsum('foi,foi->fo', h.conj(), spectra.syx).real
    power = np.einsum('foi,fij,foj->fo', h.conj(), spectra.sxx, h).real
    resid = spectra.syy - 2.0 * cross + power
    return np.sqrt(resid[band].sum(axis=0) / spectra.syy[band].sum(axis=0))


def test_collinear_inputs_plain_h1_blows_up_regularised_predicts():
    # Inputs 0 and 1 nearly identical (left/right vertical on a symmetric road): the outputs
    # only see H[:, 0] + H[:, 1] (times x0); the split between the two entries is set by the
    # 1e-4 difference and therefore by noise.  What can honestly be asked of an estimate is
    # (a) the identifiable quantities H[:, 0] + H[:, 1] and H[:, 2:], and (b) predictions of
    # a fresh record with the same input correlation, and of one where x0 and x1 differ by 5 %
    # (a real road is never exactly symmetric).
    rng = np.random.default_rng(11)
    b, a = _random_system(rng)
    n = int(DURATION_S * FS_HZ)
    x = _inputs(rng, n, collinear=1e-4)
    fit = cross_spectra(x, _outputs(rng, b, a, x), WELCH)
    x = _inputs(rng, n, collinear=1e-4)
    fresh = cross_spectra(x, _outputs(rng, b, a, x), WELCH)
    x = _inputs(rng, n, collinear=0.05)
    differ = cross_spectra(x, _outputs(rng, b, a, x), WELCH)
    h_true = _true_frf(b, a, fit.f_hz)
    band = fit.f_hz < BAND_HZ

    plain = estimate_frf(fit, FrfConfig('h1'))
    # Sxx eigenvalues ~2 P (x0 + x1) and ~(1e-4)^2 P / 2 (x1 - x0): cond ~ 4e8.
    assert np.median(plain.cond_sxx[band]) > 1e7
    split_err = np.abs(plain.h[band][:, :, :2] - h_true[band][:, :, :2]) / np.abs(
        h_true[band][:, :, :2])
    assert np.median(split_err) > 1.0  # individual entries: errors of hundreds of percent
    # Plain H1 predicts the same-correlation record as well as the truth does (the wild split
    # meets a direction with no power), but not a record where x0 and x1 differ by 5 %: the
    # noise-fitted split H0 - H1, of variance ~ Snn / (n_d s_weak), then meets a direction
    # (5e-2 / 1e-4)^2 times stronger: error ~ sqrt(2.5e5 / n_d) ~ 30x the ~1 % noise floor
    # (this seed: 10-44 %).
    plain_fresh = _prediction_error(plain.h, fresh, band)
    assert plain_fresh.max() < 0.05
    assert np.median(_prediction_error(plain.h, differ, band)) > 0.05

    pair_true = h_true[:, :, :1] + h_true[:, :, 1:2]
    for config in ESTIMATORS[1:]:
        est = estimate_frf(fit, config)
        # The identifiable quantities are estimated as well as any H1 entry: within 6 sigma
        # of the random error plus bias (see test_known_12x12_system_is_recovered) where the
        # coherence is high, and within 1 % in median.
        high = np.broadcast_to((est.coherence_multiple > 0.99)[:, :, np.newaxis],
                               h_true.shape)
        pair = est.h[:, :, :1] + est.h[:, :, 1:2]
        pxx0 = fit.sxx[:, np.newaxis, :1, 0].real
        eps = _h1_random_error(fit, est.coherence_multiple, np.abs(pair_true), pxx0)
        pair_err = np.abs(pair - pair_true) / np.abs(pair_true)
        assert np.all(pair_err[high[:, :, :1]] <= 6.0 * eps[high[:, :, :1]] + BIAS)
        assert np.median(pair_err[high[:, :, :1]]) < 0.01
        eps = _h1_random_error(fit, est.coherence_multiple, np.abs(h_true[:, :, 2:]),
                               np.diagonal(fit.sxx, axis1=1, axis2=2).real[:, None, 2:])
        rest_err = np.abs(est.h[:, :, 2:] - h_true[:, :, 2:]) / np.abs(h_true[:, :, 2:])
        assert np.all(rest_err[high[:, :, 2:]] <= 6.0 * eps[high[:, :, 2:]] + BIAS)
        assert np.median(rest_err[high[:, :, 2:]]) < 0.01
        # The unidentifiable direction is shrunk towards the minimum-norm split H0 = H1
        # (Tikhonov leaves a trace ~ sqrt(Snn s_weak / 2 n_d) / lambda, a few % at worst).
        split = np.abs(est.h[band][:, :, 0] - est.h[band][:, :, 1]) / np.abs(
            est.h[band][:, :, 0] + est.h[band][:, :, 1])
        assert np.median(split) < 0.01
        for record in (fresh, differ):
            err = _prediction_error(est.h, record, band)
            assert err.max() < 0.05
        # Regularising costs nothing where plain H1 still predicts (same correlation).
        assert np.all(_prediction_error(est.h, fresh, band) <= 1.01 * plain_fresh)


def test_identical_inputs_plain_h1_raises_regularised_splits():
    rng = np.random.default_rng(12)
    x = rng.standard_normal((3, 20000))
    x[1] = x[0]
    y = np.vstack([2.0 * x[0] + 4.0 * x[1] - x[2], 0.5 * x[2]])
    spectra = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    with pytest.raises(InsufficientDataError,
                       match=r'Sxx is singular .* at 129 of 129 frequencies, first at 0 Hz '
                             r".*use estimator 'h1_tikhonov' or 'h1_tsvd'"):
        estimate_frf(spectra, FrfConfig('h1'))
    with pytest.raises(InsufficientDataError, match='regularisation 1e-18 is too small'):
        estimate_frf(spectra, FrfConfig('h1_tikhonov', 1e-18))
    # The minimum-norm split of H[0, 0] + H[0, 1] = 6 is 3 + 3, exact for TSVD; Tikhonov
    # shrinks by lambda / s = 1e-4 * trace / n_in / (2 P) ~ 1e-4 relative.
    expected = np.array([[3.0, 3.0, -1.0], [0.0, 0.0, 0.5]])
    tsvd = estimate_frf(spectra, FrfConfig('h1_tsvd', 1e-6))
    np.testing.assert_allclose(tsvd.h, np.broadcast_to(expected, tsvd.h.shape), atol=1e-9)
    tik = estimate_frf(spectra, FrfConfig('h1_tikhonov', 1e-4))
    # Tikhonov shifts H by ~ lambda / s_min(of the non-collinear part) ~ 1e-4 of |H| ~ 7,
    # mixing entries through the finite-sample correlation of the inputs.
    np.testing.assert_allclose(tik.h, np.broadcast_to(expected, tik.h.shape), rtol=0,
                               atol=3e-4 * np.abs(expected).sum())
    assert np.all(np.isinf(tsvd.cond_sxx) | (tsvd.cond_sxx > 1e13))
    np.testing.assert_allclose(tsvd.coherence_multiple, 1.0, atol=1e-9)


def test_coherence_of_identity_and_negation_is_one():
    rng = np.random.default_rng(13)
    x = rng.standard_normal((3, 8192))
    y = np.vstack([x[0], -x[1]])  # y = x and y = -x
    spectra = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    for config in ESTIMATORS:
        est = estimate_frf(spectra, config)
        np.testing.assert_allclose(est.coherence_ordinary[:, 0, 0], 1.0, atol=1e-12)
        np.testing.assert_allclose(est.coherence_ordinary[:, 1, 1], 1.0, atol=1e-12)
        # Independent white inputs over 63 windows: off-diagonal coherence ~ 1/63.
        assert est.coherence_ordinary[:, 0, 1].mean() < 0.05
        # Tikhonov loses lambda / s ~ 1e-4 of the explained power, the others nothing.
        tol = 2e-4 if config.estimator == 'h1_tikhonov' else 1e-12
        np.testing.assert_allclose(est.coherence_multiple, 1.0, atol=tol)
        h = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        np.testing.assert_allclose(est.h, np.broadcast_to(h, est.h.shape), atol=tol)


def test_zero_power_output_gives_zero_coherence_and_response():
    rng = np.random.default_rng(14)
    x = rng.standard_normal((2, 4096))
    y = np.vstack([x[0] + 0.1 * rng.standard_normal(4096), np.zeros(4096)])
    spectra = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    for config in ESTIMATORS:
        est = estimate_frf(spectra, config)
        assert np.all(est.h[:, 1] == 0.0)
        assert np.all(est.coherence_ordinary[:, 1] == 0.0)
        assert np.all(est.coherence_multiple[:, 1] == 0.0)
        assert np.all(np.isfinite(est.coherence_multiple))


def test_no_input_power_h1_raises_regularised_gives_zero():
    x = np.zeros((2, 2048))
    x[1] = np.random.default_rng(15).standard_normal(2048)
    y = np.vstack([3.0 * x[1]])
    spectra = cross_spectra(x, y, WelchConfig(FS_HZ, 256))
    with pytest.raises(InsufficientDataError, match='singular'):
        estimate_frf(spectra, FrfConfig('h1'))
    for config in ESTIMATORS[1:]:
        est = estimate_frf(spectra, config)
        assert np.all(est.h[:, 0, 0] == 0.0)  # a dead channel gets no response
        assert np.all(est.coherence_ordinary[:, 0, 0] == 0.0)
        np.testing.assert_allclose(est.h[:, 0, 1], 3.0, rtol=2e-4)
        assert np.all(np.isinf(est.cond_sxx))
    silent = cross_spectra(np.zeros((2, 2048)), y, WelchConfig(FS_HZ, 256))
    for config in ESTIMATORS[1:]:
        est = estimate_frf(silent, config)
        assert np.all(est.h == 0.0) and np.all(est.coherence_multiple == 0.0)


def _hand_spectra(sxx, syx):
    """Build CrossSpectra at 5 frequencies with the given (constant) matrices."""
    config = WelchConfig(4.0, 8)
    nf = config.f_hz.size
    sxx = np.broadcast_to(sxx, (nf,) + np.shape(sxx))
    syx = np.broadcast_to(syx, (nf,) + np.shape(syx))
    syy = np.full(syx.shape[:2], 100.0)
    return CrossSpectra(config.f_hz, sxx, syx, syy, 10, config)


def test_regularisation_formulas_by_hand():
    # One input: Tikhonov lambda = reg * sxx, so H = syx / (sxx (1 + reg)) = H1 / (1 + reg).
    s = _hand_spectra([[4.0]], [[8.0 - 4.0j]])
    est = estimate_frf(s, FrfConfig('h1_tikhonov', 0.25))
    np.testing.assert_allclose(est.h, (2.0 - 1.0j) / 1.25, rtol=1e-14)
    # Two inputs along a rotated basis with eigenvalues 1 and 1e-3; H1 = [2, 5].
    u = np.array([[1.0, 1.0j], [1.0j, 1.0]]) / np.sqrt(2.0)
    sxx = u @ np.diag([1.0, 1e-3]) @ u.conj().T
    h1 = np.array([[2.0, 5.0]])
    syx = h1 @ sxx.T  # syx = H conj(sxx) and conj(sxx) = sxx.T for Hermitian sxx
    s = _hand_spectra(sxx, syx)
    np.testing.assert_allclose(estimate_frf(s, FrfConfig('h1')).h[0], h1, rtol=1e-12)
    np.testing.assert_allclose(estimate_frf(s, FrfConfig('h1_tsvd', 1e-4)).h[0], h1,
                               rtol=1e-12)
    # reg 1e-2 drops the 1e-3 eigenvalue: H^T projected on the kept eigenvector u[:, 0].
    keep = u[:, :1] @ u[:, :1].conj().T
    np.testing.assert_allclose(estimate_frf(s, FrfConfig('h1_tsvd', 1e-2)).h[0],
                               (keep @ h1.T).T, atol=1e-14)
    lam = 0.1 * np.trace(sxx).real / 2
    expected = (u @ np.diag([1.0 / (1.0 + lam), 1e-3 / (1e-3 + lam)]) @ u.conj().T @ h1.T).T
    np.testing.assert_allclose(estimate_frf(s, FrfConfig('h1_tikhonov', 0.1)).h[0], expected,
                               rtol=1e-12)
    np.testing.assert_allclose(estimate_frf(s, FrfConfig('h1')).cond_sxx, 1e3, rtol=1e-10)


@pytest.mark.parametrize('kwargs, match', [
    ({'estimator': 'h2'}, 'estimator must be one of'),
    ({'regularisation': -1e-3}, 'regularisation must be finite and >= 0'),
    ({'regularisation': np.nan}, 'regularisation must be finite and >= 0'),
    ({'regularisation': 'small'}, 'regularisation must be a number'),
    ({'estimator': 'h1_tsvd', 'regularisation': 2.0}, 'must be <= 1 for h1_tsvd'),
])
def test_frf_config_rejects(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        FrfConfig(**kwargs)


def test_estimate_frf_rejects_wrong_types_and_estimate_validates():
    s = _hand_spectra([[4.0]], [[8.0]])
    with pytest.raises(ConfigError, match='spectra must be a CrossSpectra'):
        estimate_frf(s.sxx)
    with pytest.raises(ConfigError, match='config must be a FrfConfig'):
        estimate_frf(s, 'h1')
    est = estimate_frf(s)
    assert est.config == FrfConfig('h1_tikhonov', 1e-4)
    assert (est.n_outputs, est.n_inputs) == (1, 1)
    fields = {f.name: getattr(est, f.name) for f in dataclasses.fields(est)}
    with pytest.raises(ShapeError, match='h must be'):
        FrfEstimate(**{**fields, 'h': est.h[:-1]})
    with pytest.raises(ShapeError, match='coherence_multiple must have shape'):
        FrfEstimate(**{**fields, 'coherence_multiple': est.coherence_ordinary})
    with pytest.raises(ShapeError, match='cond_sxx must have shape'):
        FrfEstimate(**{**fields, 'cond_sxx': est.cond_sxx[:1]})
    with pytest.raises(ConfigError, match='config must be a FrfConfig'):
        FrfEstimate(**{**fields, 'config': None})
    with pytest.raises(ValueError):
        est.h[0, 0, 0] = 1.0  # read-only


def test_water_level_damps_only_the_lines_the_inputs_did_not_excite():
    # One input excited at 5-90 Hz only (exact zeros elsewhere, as a band-limited shaker
    # drive), a known 2nd-order system, 5 % output noise.  Outside the band sxx and syx are
    # window leakage and noise: their ratio is not the system's response.
    rng = np.random.default_rng(7)
    n = int(60 * FS_HZ)
    f = np.fft.rfftfreq(n, 1.0 / FS_HZ)
    spec = (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) * (
        (f > 5.0) & (f < 90.0))
    x = np.fft.irfft(spec, n)[np.newaxis]
    b, a = scipy.signal.butter(2, 40.0, fs=FS_HZ)
    y = scipy.signal.lfilter(b, a, x[0])
    y = (y + 0.05 * y.std() * rng.standard_normal(n))[np.newaxis]
    s = cross_spectra(x, y, WELCH)
    true = scipy.signal.freqz(b, a, worN=s.f_hz, fs=FS_HZ)[1]
    plain = estimate_frf(s, FrfConfig('h1_tikhonov', 1e-4)).h[:, 0, 0]
    water = estimate_frf(s, FrfConfig('h1_tikhonov', 1e-4, water_level=1e-6)).h[:, 0, 0]
    tsvd = estimate_frf(s, FrfConfig('h1_tsvd', 1e-4, water_level=1e-6)).h[:, 0, 0]
    band = (s.f_hz > 8.0) & (s.f_hz < 85.0)
    outside = (s.f_hz < 2.0) | (s.f_hz > 110.0)
    # In the band the water level changes nothing and both recover the system.
    np.testing.assert_allclose(water[band], plain[band], rtol=1e-6)
    np.testing.assert_allclose(water[band], true[band], rtol=0.05, atol=0.01)
    np.testing.assert_allclose(tsvd[band], true[band], rtol=0.05, atol=0.01)
    # Outside it the plain regularised estimate is leakage/noise ratios, many times the
    # system's largest gain; with the water level it is damped below that gain.
    assert np.abs(plain[outside]).max() > 10.0 * np.abs(true).max()
    assert np.abs(water[outside]).max() < np.abs(true).max()
    assert np.abs(tsvd[outside]).max() < np.abs(true).max()


@pytest.mark.parametrize('value', [-1e-6, 1.0, np.nan, 'low'])
def test_frf_config_rejects_a_water_level_outside_0_1(value):
    with pytest.raises(ConfigError, match='water_level must be'):
        FrfConfig(water_level=value)


def _sine_rig(f_hz, seconds, seed, fs_hz=256.0):
    """Displacement sine test of F = k x + c v + m a with 1 % force noise [m], [N]."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fs_hz)) / fs_hz
    w = 2 * np.pi * f_hz
    x = 0.01 * np.sin(w * t)
    force = RIG_K * x + RIG_C * 0.01 * w * np.cos(w * t) - RIG_M * w * w * x
    return x, force + 0.01 * force.std() * rng.standard_normal(t.size)


RIG_K, RIG_C, RIG_M = 2.0e4, 800.0, 5.0


def _rig_frf(f_hz):
    w = 2 * np.pi * np.asarray(f_hz)
    return RIG_K + 1j * w * RIG_C - RIG_M * w * w


def test_bridged_lines_give_a_sine_test_its_response_between_and_below_the_tested_ones():
    # Known answer: a spring-damper-mass rig (F/x = k + j w c - m w^2) sine-tested at 1 and
    # 2 Hz only.  Every other line is under the water level; zero there leaves a rig run at
    # 0.5 or 1.5 Hz with no response at all.  Bridged: complex interpolation between the
    # tested lines, and below the lowest towards its real part at 0 Hz (the stiffness held,
    # the damping part shrinking with frequency, exactly as this rig's).
    from wheel_force_estimator.core.frf import bridge_unexcited
    fs = 256.0
    welch = WelchConfig(fs, 2048, 0.5)
    pieces = [_sine_rig(1.0, 64, 1, fs), _sine_rig(2.0, 64, 2, fs)]
    s = combine_spectra([cross_spectra(x[None], y[None], welch) for x, y in pieces])
    damped = estimate_frf(s, FrfConfig('h1_tikhonov', 1e-4, water_level=1e-6)).h
    bridged = bridge_unexcited(s, damped, 1e-6)
    f = s.f_hz
    tested = np.isin(np.round(f, 6), (1.0, 2.0))
    np.testing.assert_allclose(damped[tested, 0, 0], _rig_frf(f[tested]), rtol=0.01)
    np.testing.assert_array_equal(bridged[tested], damped[tested])
    for f_off in (0.5, 0.25, 1.5):
        i = int(np.argmin(np.abs(f - f_off)))
        assert abs(damped[i, 0, 0]) < 0.01 * RIG_K, f_off
        # Linear in f between the knots: the rig's -m w^2 curvature (up to 0.75 % of k
        # below 1 Hz: the real part at 1 Hz is held) and the tested lines' own error (1 %,
        # checked above) remain.  Measured 1.3 / 1.9 / 0.3 % at 0.25 / 0.5 / 1.5 Hz.
        np.testing.assert_allclose(bridged[i, 0, 0], _rig_frf(f_off), rtol=0.0175 + 0.01)
    # Above the highest tested line (and its window leakage) nothing is invented.
    top = f > 3.0
    np.testing.assert_array_equal(bridged[top], damped[top])
    # No water level, nothing bridged: the same array back.
    assert bridge_unexcited(s, damped, 0.0) is damped


def test_bridging_between_lines_runs_on_the_response_to_displacement():
    # The same rig recorded with an accelerometer: F/a = -(k + j w c - m w^2) / w^2 bends
    # like 1/f^2 between the tested 1 and 2 Hz, while the response to displacement is nearly
    # straight.  Interpolated in the recorded quantity, the bridge misses by 36 / 39 / 14 %
    # at 1.25 / 1.5 / 1.75 Hz; on the response to displacement by 20 / 7 / 6 % (measured).
    # Not exact: the lines in a sine's window skirt carry the response at the sine's
    # frequency, not their own, and convert with their own frequency.
    from wheel_force_estimator.core.frf import bridge_unexcited
    fs = 256.0
    welch = WelchConfig(fs, 2048, 0.5)
    pieces = []
    for f_hz, seed in ((1.0, 1), (2.0, 2)):
        x, y = _sine_rig(f_hz, 64, seed, fs)
        pieces.append((-(2 * np.pi * f_hz) ** 2 * x, y))
    s = combine_spectra([cross_spectra(a[None], y[None], welch) for a, y in pieces])
    damped = estimate_frf(s, FrfConfig('h1_tikhonov', 1e-4, water_level=1e-6)).h
    same, disp = (bridge_unexcited(s, damped, 1e-6, order) for order in (0, 2))
    for f_off in (1.25, 1.5, 1.75):
        i = int(np.argmin(np.abs(s.f_hz - f_off)))
        true = _rig_frf(f_off) / -(2 * np.pi * f_off) ** 2
        err = [abs(b[i, 0, 0] - true) / abs(true) for b in (same, disp)]
        assert err[1] < 0.6 * err[0], (f_off, err)
    i = int(np.argmin(np.abs(s.f_hz - 1.5)))
    assert abs(disp[i, 0, 0] / (_rig_frf(1.5) / -(3 * np.pi) ** 2) - 1) < 0.1
    # Below the lowest tested line the rule stays in the recorded quantity (bounded).
    low = s.f_hz < 0.8
    np.testing.assert_array_equal(same[low], disp[low])


def test_bridging_changes_nothing_where_every_line_in_the_band_was_excited(known_system):
    from wheel_force_estimator.core.frf import bridge_unexcited
    s, _ = known_system
    h = estimate_frf(s, FrfConfig('h1_tikhonov', 1e-4, water_level=1e-6)).h
    assert bridge_unexcited(s, h, 1e-6) is h


def test_a_fitted_model_runs_a_sine_test_at_an_untested_frequency():
    # Through fit_model and the FIR, as `wheel-force fit` + `predict` do: tested at 1 and
    # 2 Hz, run at 0.5 Hz.  Measured: 2.2 % RMSE bridged (1 % noise), 94 % with
    # unexcited: zero (no response below 1 Hz at all).
    from wheel_force_estimator.core.pipeline import fit_model
    from wheel_force_estimator.core.pipeline import FitConfig
    from wheel_force_estimator.core.pipeline import TrainingSegment
    from wheel_force_estimator.core.predict import predict_forces
    fs = 256.0
    segs = [TrainingSegment(x[None], y[None], f'{f} Hz')
            for f, (x, y) in ((1.0, _sine_rig(1.0, 64, 1, fs)), (2.0, _sine_rig(2.0, 64, 2, fs)))]
    x, y = _sine_rig(0.5, 64, 3, fs)
    rmse = {}
    for mode in ('interpolate', 'zero'):
        model = fit_model(segs, fs, FitConfig(segment_length=2048, unexcited=mode), ['x'], ['f'])
        assert model.fit['unexcited'] == mode
        # said in the model (and by `fit`): 2048-sample lines of 0.125 Hz, excited near 1
        # and 2 Hz only
        if mode == 'zero':
            assert model.fit['bridged_lines'] == {}
        else:
            assert model.fit['bridged_lines']['x'] > 0
        p = predict_forces(model, x[None])[0]
        rmse[mode] = 100 * np.std(y - p) / np.std(y)
    assert rmse['interpolate'] < 5.0, rmse
    assert rmse['zero'] > 50.0, rmse


def test_spring_damper_mode_runs_a_velocity_sine_test_below_the_tested_band():
    # The rig recorded with a velocity transducer: F/v = c + k / (j w) + j w m grows like
    # 1/f below the tested 1 Hz.  The default rule holds the 1 Hz response there (bounded,
    # so sensor drift is not amplified) and misses the 0.5 Hz run; 'spring_damper' extends
    # the response to displacement instead.  Measured: 96.9 / 71.0 / 6.2 % for zero /
    # interpolate / spring_damper.
    from wheel_force_estimator.core.pipeline import fit_model
    from wheel_force_estimator.core.pipeline import FitConfig
    from wheel_force_estimator.core.pipeline import TrainingSegment
    from wheel_force_estimator.core.predict import predict_forces
    fs = 256.0

    def velocity_test(f_hz, seed):
        x, y = _sine_rig(f_hz, 64, seed, fs)
        w = 2 * np.pi * f_hz
        return 0.01 * w * np.cos(w * np.arange(x.size) / fs), y
    segs = [TrainingSegment(v[None], y[None], f'{f} Hz')
            for f, (v, y) in ((1.0, velocity_test(1.0, 1)), (2.0, velocity_test(2.0, 2)))]
    v, y = velocity_test(0.5, 3)
    rmse = {}
    for mode in ('zero', 'interpolate', 'spring_damper'):
        model = fit_model(segs, fs, FitConfig(segment_length=2048, unexcited=mode), ['v'],
                          ['f'], input_quantity='velocity')
        rmse[mode] = 100 * np.std(y - predict_forces(model, v[None])[0]) / np.std(y)
    assert rmse['spring_damper'] < 10.0 < 50.0 < rmse['interpolate'] < rmse['zero'], rmse


def test_fit_config_rejects_an_unknown_unexcited_mode():
    from wheel_force_estimator.core.pipeline import FitConfig
    with pytest.raises(ConfigError, match='unexcited must be one of'):
        FitConfig(unexcited='hold')
