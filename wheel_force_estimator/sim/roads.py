# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Road profiles on a uniform distance grid: ISO 8608 random roads, pavements and obstacles.

Random roads follow ISO 8608: one-sided displacement PSD ``G_d(n) = G_d(n0) (n / n0)^-2``
(``n0 = 0.1`` cycle/m, class A = 16e-6 m^3, each class up x4), synthesised by FFT with random
phase.  The left and right tracks share the long waves and decorrelate at short wavelengths:
magnitude-squared coherence ``gamma^2(n) = exp(-2 n B)`` with ``B`` the track width (an
exponential model of the kind fitted by Ammon 1992 and Bogsjoe 2007: ~0.74 at 10 m wavelength,
~0.05 at 1 m).  Each track also carries a *cross slope* (road gradient across the track under
the tyre): the derivative of an independent profile with the same PSD, which is what an
isotropic surface gives.  Pavements are stones of random height and tilt with a slight crown;
obstacles (potholes, bumps, rails, ramps) are deterministic shapes with sharp edges.

Everything here is the *raw* surface; :func:`envelope` applies the tyre's contact-length
averaging (done once for the whole course by the simulator).
"""
from typing import Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError

ISO8608_N0_CYC_PER_M = 0.1
ISO8608_GD_N0_M3 = {'A': 16e-6, 'B': 64e-6, 'C': 256e-6, 'D': 1024e-6, 'E': 4096e-6,
                    'F': 16384e-6}
# Longest wave synthesised [cycle/m]: 100 m, beyond the ISO 8608 range (0.011 cycle/m)
# would only add slow drift of the whole car.
N_MIN_CYC_PER_M = 0.01
# Shortest wave of the random roads [cycle/m]: shorter texture is enveloped by the tyre anyway.
N_MAX_CYC_PER_M = 5.0
COHERENCE_DECAY = 2.0


def iso8608_psd(n_cyc_per_m: np.ndarray, road_class: str) -> np.ndarray:
    """
    Return the ISO 8608 displacement PSD [m^3] (m^2 per cycle/m) at spatial frequencies.

    Raises
    ------
    ConfigError
        Unknown road class.

    """
    try:
        gd0 = ISO8608_GD_N0_M3[road_class]
    except KeyError as err:
        raise ConfigError(f'unknown ISO 8608 road class {road_class!r} '
                          f'(known: {", ".join(ISO8608_GD_N0_M3)})') from err
    n = np.asarray(n_cyc_per_m, dtype=np.float64)
    with np.errstate(divide='ignore'):
        psd = gd0 * (n / ISO8608_N0_CYC_PER_M) ** -2.0
    return np.where(n > 0.0, psd, 0.0)


def coherence_sq(n_cyc_per_m: np.ndarray, track_m: float) -> np.ndarray:
    """Return the left/right magnitude-squared coherence of the random road model."""
    return np.exp(-COHERENCE_DECAY * np.asarray(n_cyc_per_m) * track_m)


def _spectral_weights(n_points: int, dx_m: float, road_class: str):
    n = np.fft.rfftfreq(n_points, dx_m)
    psd = iso8608_psd(n, road_class)
    band = (n >= N_MIN_CYC_PER_M) & (n <= N_MAX_CYC_PER_M)
    # E|Z_k|^2 = G N / (2 dx) for numpy's irfft scaling; Z_k = sqrt(G N / (4 dx)) (a + i b)
    amp = np.where(band, np.sqrt(psd * n_points / (4.0 * dx_m)), 0.0)
    return n, amp


def _complex_normal(rng: np.random.Generator, size: int) -> np.ndarray:
    return rng.standard_normal(size) + 1j * rng.standard_normal(size)


def random_road_pair(rng: np.random.Generator, n_points: int, dx_m: float, road_class: str,
                     track_m: float) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return left and right ISO 8608 profiles [m] with the coherence model of this module.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the random phases (consumed in a fixed order: deterministic for a seed).
    n_points : int
        Samples on the distance grid.
    dx_m : float
        Grid spacing [m].
    road_class : str
        ISO 8608 class 'A'..'F'.
    track_m : float
        Distance between the wheel tracks [m].

    """
    n, amp = _spectral_weights(n_points, dx_m, road_class)
    gamma = np.sqrt(coherence_sq(n, track_m))
    w1 = _complex_normal(rng, n.size)
    w2 = _complex_normal(rng, n.size)
    left = np.fft.irfft(amp * w1, n_points)
    right = np.fft.irfft(amp * (gamma * w1 + np.sqrt(1.0 - gamma ** 2) * w2), n_points)
    return left, right


def random_cross_slope(rng: np.random.Generator, n_points: int, dx_m: float,
                       road_class: str) -> np.ndarray:
    """Return a cross slope [rad] for one track: gradient of an independent ISO profile."""
    n, amp = _spectral_weights(n_points, dx_m, road_class)
    spectrum = amp * _complex_normal(rng, n.size) * (2j * np.pi * n)
    return np.fft.irfft(spectrum, n_points)


def taper(n_points: int, dx_m: float, length_m: float = 2.0) -> np.ndarray:
    """Return a window rising / falling with a half cosine over ``length_m`` at both ends."""
    w = np.ones(n_points)
    m = min(int(round(length_m / dx_m)), n_points // 2)
    if m > 0:
        ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(m) + 0.5) / m)
        w[:m] = ramp
        w[n_points - m:] = ramp[::-1]
    return w


def block_pavement(rng: np.random.Generator, n_points: int, dx_m: float, block_length_m: float,
                   height_std_m: float, tilt_std_rad: float, crown_m: float,
                   ) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return (height [m], cross slope [rad]) of a stone pavement along one track.

    Stones have a length uniform in ``block_length_m * [0.8, 1.2]``, a normal height offset
    (``height_std_m``) and tilt across the track (``tilt_std_rad``), and a parabolic crown of
    ``crown_m`` so the joints are grooves.
    """
    x = np.arange(n_points) * dx_m
    total = n_points * dx_m
    n_blocks = int(total / (0.8 * block_length_m)) + 2
    lengths = block_length_m * rng.uniform(0.8, 1.2, n_blocks)
    heights = rng.normal(0.0, height_std_m, n_blocks)
    tilts = rng.normal(0.0, tilt_std_rad, n_blocks)
    edges = np.concatenate(([0.0], np.cumsum(lengths))) - rng.uniform(0.0, block_length_m)
    idx = np.searchsorted(edges, x, side='right') - 1
    u = (x - edges[idx]) / lengths[idx]
    height = heights[idx] + crown_m * (1.0 - (2.0 * u - 1.0) ** 2)
    return height, tilts[idx]


def cosine_bump(x_m: np.ndarray, start_m: float, length_m: float, height_m: float) -> np.ndarray:
    """Return a one-period raised cosine of ``height_m`` over ``[start, start + length)``."""
    u = (x_m - start_m) / length_m
    inside = (u >= 0.0) & (u < 1.0)
    return np.where(inside, 0.5 * height_m * (1.0 - np.cos(2.0 * np.pi * u)), 0.0)


def box(x_m: np.ndarray, start_m: float, length_m: float, height_m: float) -> np.ndarray:
    """Return a rectangle of ``height_m`` (negative: a hole) with sharp edges."""
    inside = (x_m >= start_m) & (x_m < start_m + length_m)
    return np.where(inside, height_m, 0.0)


def ramp_plateau(x_m: np.ndarray, start_m: float, ramp_m: float, plateau_m: float,
                 height_m: float) -> np.ndarray:
    """Return a trapezoid: linear ramp up, plateau, linear ramp down."""
    u = x_m - start_m
    up = np.clip(u / ramp_m, 0.0, 1.0)
    down = np.clip((ramp_m + plateau_m + ramp_m - u) / ramp_m, 0.0, 1.0)
    return height_m * np.minimum(up, down) * (u >= 0.0)


def envelope(profile: np.ndarray, dx_m: float, contact_length_m: float) -> np.ndarray:
    """
    Return the profile averaged over the tyre contact length (last axis, centred).

    A centred moving average (odd window of ``round(contact_length / dx)`` points, at least 1)
    is the simplest enveloping model: steps become ramps over the contact length and waves
    shorter than the contact patch are filtered out.  The ends are averaged over the samples
    that exist, so the output has the input's length.
    """
    w = int(round(contact_length_m / dx_m))
    if w <= 1:
        return np.array(profile, dtype=np.float64, copy=True)
    if w % 2 == 0:
        w += 1
    h = w // 2
    p = np.asarray(profile, dtype=np.float64)
    csum = np.concatenate((np.zeros(p.shape[:-1] + (1,)), np.cumsum(p, axis=-1)), axis=-1)
    n = p.shape[-1]
    lo = np.clip(np.arange(n) - h, 0, n)
    hi = np.clip(np.arange(n) + h + 1, 0, n)
    return (csum[..., hi] - csum[..., lo]) / (hi - lo)
