# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Known-answer sim/real pairs for tests and benchmarks (no vehicle simulator needed).

Two corners (``lf``, ``rf``) of a force-from-motion law ``F = F0 + k x + c v + m a`` driven by
independent random band-limited displacements; the "real" recordings add ONE effect of the
vocabulary on the left corner (``anti_roll_bar``: both corners, antisymmetric) plus force
noise.  Each effect is *concealed*: it either acts on fewer than 5 % of the samples or its RMS
is below the noise RMS (``concealment`` reports which, measured).
"""
from dataclasses import dataclass
from typing import Dict, Tuple

import numpy as np

from wheel_force_estimator import GRAVITY_MPS2
from wheel_force_estimator.core import physics as ph
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.diagnosis.recording import MotionRecording

INPUTS = ('lf_az', 'rf_az')
OUTPUTS = ('lf_fz', 'rf_fz')
EFFECTS = ('none', 'offset_drift', 'bump_stop', 'rebound_stop', 'cubic_stiffness',
           'damper_asymmetry', 'coulomb_friction', 'backlash', 'tire_lift_off',
           'anti_roll_bar', 'time_delay', 'sensor_saturation', 'mass_error',
           'stiffness_error', 'damping_error')
MASS_KG, DAMPING_NS_PER_M, STIFFNESS_N_PER_M, STATIC_N = 30.0, 1500.0, 2.0e4, 3000.0
SATURATION_LIMIT_MPS2 = 105.0


@dataclass(frozen=True)
class Motion:
    """True displacement [m], velocity [m/s], acceleration [m/s**2] of both corners."""

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray


def random_motion(rng: np.random.Generator, n: int, fs_hz: float, rms_m: float = 0.01
                  ) -> Motion:
    """Band-limited (about 1-25 Hz) random displacement of two corners, exact derivatives."""
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    shape = (f > 0.5) * (f < 25.0) / np.maximum(f, 2.0) / (1.0 + (1.5 / np.maximum(f, 1e-9)) ** 4)
    spec = (rng.standard_normal((2, f.size)) + 1j * rng.standard_normal((2, f.size))) * shape
    w = 2j * np.pi * f
    x = np.fft.irfft(spec, n)
    scale = rms_m / x.std(axis=1, keepdims=True)
    return Motion(x * scale, np.fft.irfft(spec * w, n) * scale,
                  np.fft.irfft(spec * w * w, n) * scale)


def linear_force(m: Motion) -> np.ndarray:
    """Return the nominal force law both sim and real share [N]."""
    return STATIC_N + STIFFNESS_N_PER_M * m.x + DAMPING_NS_PER_M * m.v + MASS_KG * m.a


def effect_force(name: str, m: Motion, lin: np.ndarray, fs_hz: float) -> np.ndarray:
    """Extra force of ``name`` on both corners (zero where it does not act) [N]."""
    e = np.zeros_like(lin)
    x, v, a = m.x[0], m.v[0], m.a[0]
    if name == 'bump_stop':
        e[0] = ph.bump_stop_force(x, float(np.quantile(x, 0.97)), 3e5, 2.0)
    elif name == 'rebound_stop':
        e[0] = ph.rebound_stop_force(x, float(-np.quantile(x, 0.03)), 3e5, 2.0)
    elif name == 'cubic_stiffness':
        e[0] = ph.cubic_stiffness_force(x, 1.5e7)
    elif name == 'damper_asymmetry':
        e[0] = ph.damper_asymmetry_force(v, 500.0)
    elif name == 'coulomb_friction':
        e[0] = ph.coulomb_friction_force(v, 60.0, 0.01)
    elif name == 'backlash':
        e[0] = ph.backlash_force(np.clip(x, -0.003, 0.003), 1.5e4)
    elif name == 'anti_roll_bar':
        e[0] = ph.anti_roll_bar_force(m.x[0], m.x[1], 4000.0)
        e[1] = -e[0]
    elif name == 'time_delay':
        e[0] = np.interp(np.arange(x.size) - 0.1, np.arange(x.size), lin[0]) - lin[0]
    elif name == 'mass_error':
        e[0] = ph.mass_error_force(a, 1.5)
    elif name == 'stiffness_error':
        e[0] = ph.stiffness_error_force(x, 6000.0)
    elif name == 'damping_error':
        e[0] = ph.damping_error_force(v, 150.0)
    elif name == 'offset_drift':
        # A slow sensor zero drift and a 0.3 % gain drift: no physics to name.
        e[0] = np.linspace(0.0, 60.0, x.size) + 0.003 * (lin[0] - STATIC_N)
    return e


def friction_rig(rng: np.random.Generator, seconds: float, fs_hz: float = 200.0
                 ) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return one displacement-driven rig record: (x [m], force [N]).

    Broadband motion (0.3-4 Hz, 10 mm RMS), a linear spring (2e4 N/m), Coulomb friction
    (300 N, smoothed over 2 mm/s) and 15 N of noise, drawn from ``rng`` in that order.
    """
    import scipy.signal
    b, a = scipy.signal.butter(2, [0.3, 4.0], 'bandpass', fs=fs_hz)
    x = scipy.signal.lfilter(b, a, rng.standard_normal(int(seconds * fs_hz)))
    x *= 0.01 / x.std()
    v = np.gradient(x, 1 / fs_hz)
    force = 2e4 * x + 300.0 * np.tanh(v / 0.002) + 15.0 * rng.standard_normal(x.size)
    return x, force


def make_recording(effect: str, seed: int, duration_s: float = 60.0, fs_hz: float = 256.0,
                   noise: float = 0.05, name: str = 'real') -> Tuple[MotionRecording, Dict]:
    """
    One recording with ``effect`` (``'none'`` for the simulation) and its concealment.

    ``noise`` is the force noise RMS relative to the RMS of the dynamic linear force.
    Returns the recording and ``{'active_fraction', 'effect_to_noise'}`` of the left corner.
    """
    if effect not in EFFECTS:
        raise ConfigError(f'unknown synthetic effect {effect!r} (known: {list(EFFECTS)})')
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * fs_hz))
    m = random_motion(rng, n, fs_hz)
    lin = linear_force(m)
    static = STATIC_N
    if effect == 'tire_lift_off':
        # Static load ~1.9 dynamic RMS: the linear law would pull on the road on ~3 % samples.
        static = 1.9 * float(np.std(lin[0]))
        lin = lin - STATIC_N + static
    e = effect_force(effect, m, lin, fs_hz)
    if effect == 'tire_lift_off':
        e[0] = np.maximum(lin[0], 0.0) - lin[0]
    noise_n = noise * np.std(lin - static, axis=1, keepdims=True)
    force = lin + e + noise_n * rng.standard_normal(lin.shape)
    accel = m.a + GRAVITY_MPS2
    if effect == 'sensor_saturation':
        # One sensor range for every recording (about 2.3 dynamic RMS above gravity).
        limit = SATURATION_LIMIT_MPS2
        accel = accel.copy()
        accel[0] = np.clip(accel[0], -limit, limit)
    rec = MotionRecording(f'{name}{seed}', fs_hz, accel, force, INPUTS, OUTPUTS)
    active = np.abs(e[0]) > 1e-9 * max(float(np.abs(e[0]).max()), 1e-300)
    if effect == 'sensor_saturation':
        active = np.abs(accel[0]) >= limit
    return rec, {'active_fraction': float(active.mean()),
                 'effect_to_noise': float(np.std(e[0]) / max(noise_n[0, 0], 1e-300))}


def synthetic_pair(effect: str, seed: int = 0, duration_s: float = 60.0,
                   fs_hz: float = 256.0, noise: float = 0.05):
    """
    Return ``(sim, real, holdout, concealment)`` for one effect.

    The simulation is noise-free and effect-free; real and holdout share the effect and the
    noise level but not the random motion.
    """
    sim = [make_recording('none', 1000 * seed + k, duration_s, fs_hz, 0.0, 'sim')[0]
           for k in (1, 2)]
    real, info = zip(*(make_recording(effect, 1000 * seed + k, duration_s, fs_hz, noise)
                       for k in (3, 4)))
    holdout = [make_recording(effect, 1000 * seed + 5, duration_s, fs_hz, noise, 'holdout')[0]]
    return sim, list(real), holdout, info[0]


#: Cases of :func:`structure_recording`.
STRUCTURES = ('linear, 1 input', 'linear, 3 inputs', 'hardening in the loop',
              'friction in the loop')
#: RMS relative displacement of the 8 Hz mode of :func:`structure_recording` [m].
_STRUCTURE_RMS_M = 5.4e-4


def _mode_force(u, fs_hz: float, fn_hz: float, zeta: float, restoring=None) -> np.ndarray:
    """
    Return the base force of one mode excited by base acceleration ``u`` [N].

    ``m r'' + c r' + k r + restoring(r, r', k) = -m u''``, ``F = c r' + k r + restoring``
    (``r`` the mass's motion relative to the base): linear by ``scipy.signal.lsim``, with a
    restoring force by classical RK4 at the sample rate (a loop: the state is nonlinear).
    """
    from scipy import signal
    m, wn = 100.0, 2 * np.pi * fn_hz
    k, c, dt = m * wn ** 2, 2 * zeta * m * wn, 1.0 / fs_hz
    if restoring is None:
        sys_ = signal.lti([-c, -k], [1.0, 2 * zeta * wn, wn ** 2])
        return signal.lsim(sys_, u, np.arange(u.size) * dt)[1]

    def deriv(r, v, ua):
        f = c * v + k * r + restoring(r, v, k)
        return -f / m - ua, f
    r = v = 0.0
    force = np.empty(u.size)
    for i, ua in enumerate(u):
        a1, force[i] = deriv(r, v, ua)
        a2, _ = deriv(r + 0.5 * dt * v, v + 0.5 * dt * a1, ua)
        a3, _ = deriv(r + 0.5 * dt * (v + 0.5 * dt * a1), v + 0.5 * dt * a2, ua)
        a4, _ = deriv(r + dt * (v + 0.5 * dt * a2), v + dt * a3, ua)
        r, v = (r + dt * (v + dt * (a1 + a2 + a3) / 6),
                v + dt * (a1 + 2 * a2 + 2 * a3 + a4) / 6)
    return force


def structure_recording(case: str, seed: int, seconds: float = 60.0,
                        fs_hz: float = 512.0, strength: float = 1.0) -> MotionRecording:
    """
    One run of a lightly damped base-excited structure: base accelerations in, base forces out.

    Band-limited (1-40 Hz) random base acceleration, 2 % force noise.  ``'linear, 1 input'``:
    one 8 Hz mode with 5 % damping; ``'linear, 3 inputs'``: two outputs mixing 5-13 Hz modes
    of three inputs; ``'hardening in the loop'`` / ``'friction in the loop'``: the 8 Hz mode
    with a cubic spring (5 % of the linear force at the RMS deflection) or a friction joint
    (10 % of it, regularised at 1 mm/s) between base and mass: the element acts on the
    unmeasured relative motion, inside the structure; ``strength`` scales that element.
    """
    from scipy import signal
    if case not in STRUCTURES:
        raise ConfigError(f'unknown structure case {case!r} (known: {list(STRUCTURES)})')
    rng = np.random.default_rng(seed)
    n = int(seconds * fs_hz)
    b, a = signal.butter(4, [1.0 / (fs_hz / 2), 40.0 / (fs_hz / 2)], 'bandpass')
    n_in = 3 if case == 'linear, 3 inputs' else 1
    accel = 2.0 * signal.lfilter(b, a, rng.standard_normal((n_in, n)), axis=1)
    accel *= 0.7 + 0.15 * (seed % 5)
    rs = _STRUCTURE_RMS_M
    restoring = {'hardening in the loop':
                 lambda r, v, k: strength * 0.05 * k / rs ** 2 * r ** 3,
                 'friction in the loop':
                 lambda r, v, k: strength * 0.1 * k * rs * np.tanh(v / 1e-3)}.get(case)
    if n_in == 1:
        force = _mode_force(accel[0], fs_hz, 8.0, 0.05, restoring)[None]
    else:
        force = np.stack([_mode_force(accel[0], fs_hz, 8.0, 0.02)
                          + 0.5 * _mode_force(accel[1], fs_hz, 13.0, 0.05),
                          _mode_force(accel[2], fs_hz, 11.0, 0.03)
                          + 0.3 * _mode_force(accel[0], fs_hz, 5.0, 0.05)])
    force += 0.02 * force.std(axis=1, keepdims=True) * rng.standard_normal(force.shape)
    return MotionRecording(f'{case} run {seed}', fs_hz, accel, force,
                           tuple(f'a{i}' for i in range(n_in)),
                           tuple(f'f{o}' for o in range(force.shape[0])))
