# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
MIMO frequency response estimation (H1 and regularised H1) from Welch spectra.

Model: ``Y_o = sum_i H[o, i] X_i + N_o`` with noise ``N`` uncorrelated with the inputs.  With
the spectra of :mod:`wheel_force_estimator.core.spectra` (``sxx[i, j] = E[conj(X_i) X_j]``,
``syx[o, i] = E[conj(X_i) Y_o]``) the normal equations are ``syx = H conj(sxx)``, i.e.
``H^T = sxx^-1 syx^T`` per frequency (``sxx`` is Hermitian), solved in one batched call.

Estimators
----------
``'h1'``
    Plain H1.  Where ``sxx`` is singular to working precision (smallest eigenvalue below
    ``n_in * eps`` times the largest, or no input power at all) the inputs do not determine
    ``H``; rather than return numbers dominated by round-off, :func:`estimate_frf` raises
    :class:`InsufficientDataError` naming the frequency.  ``regularisation`` is ignored.
    (A boxcar window with ``detrend='constant'`` leaves only round-off in the 0 Hz line, which
    plain H1 may therefore refuse; the default Hann window does not.)
``'h1_tikhonov'``
    ``H^T = (sxx + lambda I)^-1 syx^T`` with ``lambda = regularisation * trace(sxx) / n_in``
    per frequency, i.e. relative to the mean input power at that frequency.  Directions of
    the input space with power far below ``lambda`` (collinear inputs, such as left and right
    vertical on a symmetric road) get a response shrunk towards zero, so the estimate is the
    smallest-norm ``H`` that reproduces the outputs for inputs with that correlation.
``'h1_tsvd'``
    Truncated eigen (= singular value) decomposition of the Hermitian ``sxx``: eigenvalues below
    ``regularisation * s_max`` (and always those below ``n_in * eps * s_max``) are dropped,
    the remaining subspace is inverted exactly.

For both regularised estimators a frequency with no input power at all gets ``H = 0`` (the
limit of the regularised solution; ``syx`` is then zero too).

Water level (``water_level`` > 0, both regularised estimators): the classic guard of spectral
division (water-level deconvolution).  ``lambda`` is at least ``water_level`` times the largest
mean input power over all frequencies above 0 Hz (Tikhonov), and eigenvalues below
``water_level`` times the largest one over them are dropped (TSVD).  The 0 Hz line is not a
reference: without detrending it holds the sensors' offsets (gravity), and ``FitConfig``
refuses a water level with undetrended windows.  A frequency where the inputs hold almost no
power was not excited: its ``sxx`` and ``syx`` are sensor noise or window leakage
from the excited band, their ratio is not the system's response, and the coherence does not
reveal it (leakage is coherent, and few long windows make chance coherence high).  Measured on
the known-answer pairs of ``test/support/diagnosis_synthetic.py`` (excited 0.5-25 Hz, inputs
132 dB down below 0.5 Hz): without it the fitted gain there was 1.7e5 N per m/s² against
about 200 for the noise-free fit of the same system, and the FIR's response to a record's first
sample dominated the whole-record RMSE (240-5772 %).
"""
from dataclasses import dataclass

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.spectra import CrossSpectra
from wheel_force_estimator.core.validation import read_only_array

ESTIMATORS = ('h1', 'h1_tikhonov', 'h1_tsvd')


@dataclass(frozen=True)
class FrfConfig:
    """
    How the FRF is estimated from the spectral matrices.

    Parameters
    ----------
    estimator : str
        One of ``'h1'``, ``'h1_tikhonov'``, ``'h1_tsvd'`` (see the module docstring).
    regularisation : float
        Relative regularisation, finite and >= 0 (dimensionless).  Tikhonov:
        ``lambda = regularisation * trace(sxx) / n_in``; TSVD: eigenvalues below
        ``regularisation * s_max`` are dropped (so <= 1).  Ignored by ``'h1'``.
    water_level : float
        Fraction of the strongest frequency's input power below which a frequency counts as
        not excited (see the module notes), in [0, 1); 0 = off.  Ignored by ``'h1'``.

    Raises
    ------
    ConfigError
        Unknown estimator or regularisation out of range.

    """

    estimator: str = 'h1_tikhonov'
    regularisation: float = 1e-4
    water_level: float = 0.0

    def __post_init__(self):
        if self.estimator not in ESTIMATORS:
            raise ConfigError(
                f'FrfConfig.estimator must be one of {ESTIMATORS}, got {self.estimator!r}')
        try:
            reg = float(self.regularisation)
        except (TypeError, ValueError) as err:
            raise ConfigError(f'FrfConfig.regularisation must be a number, '
                              f'got {self.regularisation!r}') from err
        if not np.isfinite(reg) or reg < 0.0:
            raise ConfigError(
                f'FrfConfig.regularisation must be finite and >= 0, got {self.regularisation!r}')
        if self.estimator == 'h1_tsvd' and reg > 1.0:
            raise ConfigError(f'FrfConfig.regularisation must be <= 1 for h1_tsvd (it is '
                              f'relative to the largest singular value), got {reg!r}')
        object.__setattr__(self, 'regularisation', reg)
        try:
            water = float(self.water_level)
        except (TypeError, ValueError) as err:
            raise ConfigError(f'FrfConfig.water_level must be a number, '
                              f'got {self.water_level!r}') from err
        if not 0.0 <= water < 1.0:
            raise ConfigError(f'FrfConfig.water_level must be in [0, 1), got {water!r}')
        object.__setattr__(self, 'water_level', water)


@dataclass(frozen=True)
class FrfEstimate:
    """
    Estimated MIMO FRF with its quality indicators.

    Parameters
    ----------
    f_hz : numpy.ndarray, shape (nf,)
        Frequency axis in Hz.
    h : numpy.ndarray, shape (nf, n_out, n_in), complex128
        ``h[f, o, i]`` in output unit per input unit (e.g. N per m/s²).
    coherence_ordinary : numpy.ndarray, shape (nf, n_out, n_in)
        ``|syx|² / (sxx_ii syy_o)`` in [0, 1]; 0 where the input or output has no power.
    coherence_multiple : numpy.ndarray, shape (nf, n_out)
        ``Re(sum_i h[o, i] conj(syx[o, i])) / syy_o`` in [0, 1]: the fraction of output power
        explained by this estimate.  Exact multiple coherence for ``'h1'``; for the
        regularised estimators it is a lower bound of it.  0 where the output has no power.
    cond_sxx : numpy.ndarray, shape (nf,)
        Condition number of ``sxx`` (largest over smallest eigenvalue magnitude); ``inf``
        where an eigenvalue is exactly 0, ~1e16 or more where singular up to round-off.
    config : FrfConfig
        Estimator used.

    Raises
    ------
    ShapeError
        Inconsistent array shapes.
    ConfigError
        ``config`` is not a :class:`FrfConfig`.

    """

    f_hz: np.ndarray
    h: np.ndarray
    coherence_ordinary: np.ndarray
    coherence_multiple: np.ndarray
    cond_sxx: np.ndarray
    config: FrfConfig

    def __post_init__(self):
        if not isinstance(self.config, FrfConfig):
            raise ConfigError(f'FrfEstimate.config must be a FrfConfig, got {self.config!r}')
        # Read-only, copied unless already frozen: freezing never touches a caller's array.
        f_hz = read_only_array(self.f_hz, np.float64)
        h = read_only_array(self.h, np.complex128)
        coh = read_only_array(self.coherence_ordinary, np.float64)
        mcoh = read_only_array(self.coherence_multiple, np.float64)
        cond = read_only_array(self.cond_sxx, np.float64)
        nf = f_hz.shape[0] if f_hz.ndim == 1 else -1
        if nf < 1 or h.ndim != 3 or h.shape[0] != nf:
            raise ShapeError(f'FrfEstimate: h must be (nf, n_out, n_in) with nf = len(f_hz), '
                             f'got f_hz {f_hz.shape}, h {h.shape}')
        expected = {'coherence_ordinary': (coh, h.shape),
                    'coherence_multiple': (mcoh, h.shape[:2]),
                    'cond_sxx': (cond, (nf,))}
        for name, (arr, shape) in expected.items():
            if arr.shape != shape:
                raise ShapeError(f'FrfEstimate: {name} must have shape {shape}, got {arr.shape}')
        for name, arr in (('f_hz', f_hz), ('h', h), ('coherence_ordinary', coh),
                          ('coherence_multiple', mcoh), ('cond_sxx', cond)):
            object.__setattr__(self, name, arr)

    @property
    def n_inputs(self) -> int:
        """Return the number of input channels."""
        return self.h.shape[2]

    @property
    def n_outputs(self) -> int:
        """Return the number of output channels."""
        return self.h.shape[1]


def _raise_singular(f_hz, bad, cond, limit, hint):
    k = int(np.flatnonzero(bad)[0])
    raise InsufficientDataError(
        f'estimate_frf: the input cross-spectral matrix Sxx is singular to working precision '
        f'at {int(bad.sum())} of {bad.size} frequencies, first at {f_hz[k]:g} Hz (condition '
        f'number {cond[k]:.3g}, limit {limit:.3g}): inputs are linearly dependent or have no '
        f'power there; {hint}')


def _solve_hermitian(a, syx):
    """Return ``h`` with ``h^T = a^-1 syx^T`` for a stack of Hermitian ``a``."""
    return np.linalg.solve(a, syx.transpose(0, 2, 1)).transpose(0, 2, 1)


def estimate_frf(spectra: CrossSpectra, config: FrfConfig = FrfConfig()) -> FrfEstimate:
    """
    Estimate the MIMO FRF, its coherences and the conditioning of the inputs.

    Parameters
    ----------
    spectra : CrossSpectra
        Welch spectral matrices (possibly combined over several recordings).
    config : FrfConfig
        Estimator and regularisation.

    Returns
    -------
    FrfEstimate
        ``h[f, o, i]`` in output unit per input unit.  The rows of ``h`` do not depend on which
        other outputs are present (each output is estimated independently from the same
        ``sxx``).

    Raises
    ------
    InsufficientDataError
        Estimator ``'h1'`` (or ``'h1_tikhonov'`` with a regularisation too small to matter)
        and ``sxx`` singular to working precision at some frequency (frequency and condition
        number named).
    ConfigError
        ``spectra`` is not a :class:`CrossSpectra` or ``config`` not a :class:`FrfConfig`.

    """
    if not isinstance(spectra, CrossSpectra):
        raise ConfigError(f'estimate_frf: spectra must be a CrossSpectra, got {type(spectra)}')
    if not isinstance(config, FrfConfig):
        raise ConfigError(f'estimate_frf: config must be a FrfConfig, got {config!r}')
    sxx, syx, syy, f_hz = spectra.sxx, spectra.syx, spectra.syy, spectra.f_hz
    n_in = sxx.shape[1]
    eps_rank = np.finfo(np.float64).eps * n_in
    # The same eigenvalue routine for every estimator so cond_sxx does not depend on it.
    eig = np.linalg.eigvalsh(sxx)
    mag = np.abs(eig)
    s_max = mag.max(axis=1)
    s_min = mag.min(axis=1)
    cond = np.full(s_max.shape, np.inf)
    np.divide(s_max, s_min, out=cond, where=s_min > 0.0)
    dead = s_max <= 0.0
    h = np.zeros(syx.shape, dtype=np.complex128)
    if config.estimator == 'h1':
        # eigvalsh is ascending; a negative smallest eigenvalue is round-off of a singular
        # (positive semi-definite) matrix.
        bad = eig[:, 0] <= eps_rank * s_max
        if bad.any():
            _raise_singular(f_hz, bad, cond, 1.0 / eps_rank,
                            "use estimator 'h1_tikhonov' or 'h1_tsvd'")
        h = _solve_hermitian(sxx, syx)
    elif config.estimator == 'h1_tikhonov':
        power = np.trace(sxx, axis1=1, axis2=2).real / n_in
        lam = config.regularisation * power
        if config.water_level > 0.0 and power.size:
            lam = np.maximum(lam, config.water_level * _strongest(power, f_hz))
        bad = ~dead & (eig[:, 0] + lam <= eps_rank * (s_max + lam))
        if bad.any():
            _raise_singular(f_hz, bad, cond, 1.0 / eps_rank,
                            f'regularisation {config.regularisation:g} is too small to help')
        live = ~dead
        a = sxx[live] + lam[live, np.newaxis, np.newaxis] * np.eye(n_in)
        h[live] = _solve_hermitian(a, syx[live])
    else:
        eig, vec = np.linalg.eigh(sxx)
        keep = (eig >= config.regularisation * s_max[:, np.newaxis]) & (
            eig > eps_rank * s_max[:, np.newaxis])
        if config.water_level > 0.0 and s_max.size:
            keep &= eig >= config.water_level * _strongest(s_max, f_hz)
        inv = np.zeros(eig.shape)
        np.divide(1.0, eig, out=inv, where=keep)
        # h^T = V diag(1/s) V^H syx^T on the kept subspace only.
        proj = np.matmul(vec.conj().transpose(0, 2, 1), syx.transpose(0, 2, 1))
        h = np.matmul(vec, inv[:, :, np.newaxis] * proj).transpose(0, 2, 1)
    return FrfEstimate(f_hz, h, _ordinary_coherence(sxx, syx, syy),
                       _multiple_coherence(h, syx, syy), cond, config)


def bridge_unexcited(spectra: CrossSpectra, h: np.ndarray, water_level: float,
                     input_order: int = 0, below_as_displacement: bool = False) -> np.ndarray:
    """
    Return ``h`` with each input's unexcited lines inside its excited band interpolated.

    The water level damps the FRF towards zero where an input holds less than
    ``water_level`` times its strongest line's power (above 0 Hz): there the data say
    nothing.  Zero is the right answer above the band (nothing to predict, and a gain there
    only amplifies noise), but not between the excited lines of a sine test or a stepped
    sweep, nor below the lowest of them: a rig tested at 1 and 2 Hz and run at 0.5 Hz would
    then be given no response at all (measured on a displacement rig, 40 s sine records:
    94 % holdout RMSE).  The smoothest answer the data allow is taken instead, per input
    column: complex linear interpolation between the excited lines, and below the lowest
    one towards its real part at 0 Hz (the flat extrapolation ``keep_dc`` gives the DC line:
    a real system's DC gain is real), i.e. the stiffness held and the in-quadrature part
    shrinking with frequency, as a spring-damper's does.  Lines above an input's highest
    excited line keep the water level's damping.

    Between excited lines the interpolation runs on the response to displacement,
    ``h * (j 2 pi f)**input_order``: a mass-spring-damper's is a quadratic in ``j w`` (nearly
    straight between neighbouring lines) whatever quantity was recorded, while its response
    to acceleration, ``-(k + j w c - m w^2) / w^2``, bends like ``1 / f^2`` (linear
    interpolation between 1 and 2 Hz misses it by 40 % at 1.5 Hz).  Below the lowest excited
    line the rule above holds in the recorded quantity: the response of a velocity or
    acceleration input to quasi-static motion grows without bound towards 0 Hz, and
    extrapolating that would amplify every sensor offset and drift - unless
    ``below_as_displacement`` asks for it (a sine-tested rig recorded with an accelerometer,
    whose users want its quasi-static response and keep the sensor's drift out themselves).

    Parameters
    ----------
    spectra : CrossSpectra
        The spectra ``h`` was estimated from (``sxx`` gives each input's power per line).
    h : numpy.ndarray, shape (nf, n_out, n_in)
        FRF on ``spectra.f_hz``.
    water_level : float
        As in :class:`FrfConfig`; 0 returns ``h`` unchanged.
    input_order : int
        Time derivatives of displacement the inputs are: 0 displacement, 1 velocity,
        2 acceleration.
    below_as_displacement : bool
        Apply the rule below the lowest excited line to the response to displacement too
        (its response to the recorded quantity then grows like ``f**-input_order``).

    Returns
    -------
    numpy.ndarray
        A new array (``h`` itself when nothing is bridged).

    """
    f_hz = np.asarray(spectra.f_hz, dtype=np.float64)
    to_disp = (2j * np.pi * f_hz) ** input_order
    scale = to_disp if below_as_displacement else np.ones_like(to_disp)
    out = None
    for i, (excited, gap) in enumerate(_bridge_masks(spectra, water_level)):
        if not gap.any():
            continue
        f_ex = f_hz[excited]
        if out is None:
            out = np.array(h, dtype=np.complex128, copy=True)
        col = out[:, :, i]                                              # (nf, n_out) view
        below = gap & (f_hz < f_ex[0])
        inside = gap & ~below
        for o in range(col.shape[1]):
            known = col[excited, o]
            lo = f_hz[below]
            first = known[0] * scale[excited][0]
            col[below, o] = (np.interp(lo, [0.0, f_ex[0]], [first.real] * 2)
                             + 1j * np.interp(lo, [0.0, f_ex[0]], [0.0, first.imag])
                             ) / scale[below]
            disp = known * to_disp[excited]
            col[inside, o] = (np.interp(f_hz[inside], f_ex, disp.real)
                              + 1j * np.interp(f_hz[inside], f_ex, disp.imag)
                              ) / to_disp[inside]
    return h if out is None else out


def _bridge_masks(spectra: CrossSpectra, water_level: float):
    """
    Per input: the lines it excited and the unexcited ones below its highest excited line.

    Empty gaps for an input with no power, and for every input when ``water_level`` is 0.
    """
    f_hz = np.asarray(spectra.f_hz, dtype=np.float64)
    above = f_hz > 0.0
    power = np.diagonal(spectra.sxx, axis1=1, axis2=2).real          # (nf, n_in)
    masks = []
    for i in range(power.shape[1]):
        strongest = power[above, i].max() if above.any() else 0.0
        if water_level <= 0.0 or not strongest > 0.0:
            masks.append((above, np.zeros(f_hz.shape, dtype=bool)))
            continue
        excited = above & (power[:, i] >= water_level * strongest)
        masks.append((excited, above & ~excited & (f_hz < f_hz[excited].max())))
    return masks


def bridged_line_counts(spectra: CrossSpectra, water_level: float,
                        below_hz: float = np.inf) -> list:
    """
    Return, per input, how many lines below ``below_hz`` :func:`bridge_unexcited` fills in.

    ``below_hz`` limits the count to the band an estimate is used in (the long-segment
    estimate of a two-resolution fit serves only below ``1.5 * crossover_hz``).
    """
    used = np.asarray(spectra.f_hz) < below_hz
    return [int((gap & used).sum()) for _, gap in _bridge_masks(spectra, water_level)]


def _strongest(power: np.ndarray, f_hz: np.ndarray) -> float:
    """
    Return the water level's reference: the largest ``power`` over the lines above 0 Hz.

    The 0 Hz line holds the sensors' offsets (gravity) unless the windows were detrended; it
    says nothing about how strongly the inputs were excited.
    """
    above = np.asarray(f_hz) > 0.0
    return float(power[above].max() if above.any() else power.max())


def _ordinary_coherence(sxx, syx, syy):
    """|syx|² / (sxx_ii syy_o); 0 where either power is zero (nothing to be coherent with)."""
    pxx = np.diagonal(sxx, axis1=1, axis2=2).real
    den = syy[:, :, np.newaxis] * pxx[:, np.newaxis, :]
    num = syx.real ** 2 + syx.imag ** 2
    coh = np.zeros(num.shape)
    np.divide(num, den, out=coh, where=den > 0.0)
    # Cauchy-Schwarz bounds it by 1 exactly; the clip only removes round-off excess.
    return np.clip(coh, 0.0, 1.0)


def _multiple_coherence(h, syx, syy):
    """Re(sum_i h conj(syx)) / syy; 0 where the output has no power."""
    num = np.einsum('foi,foi->fo', h.real, syx.real) + np.einsum('foi,foi->fo', h.imag,
                                                                 syx.imag)
    coh = np.zeros(num.shape)
    np.divide(num, syy, out=coh, where=syy > 0.0)
    # The spectral matrix of [x; y] is positive semi-definite, so the exact value lies in
    # [0, 1]; the clip only removes round-off (amplified by cond(sxx) for plain H1).
    return np.clip(coh, 0.0, 1.0)
