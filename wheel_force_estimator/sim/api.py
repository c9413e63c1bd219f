# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Simulator façade: ``simulate`` (arrays) and ``simulate_pair`` (sim / real / holdout bags).

``simulate`` builds the course (driver plan + road), envelopes the road with the tyre contact
length, integrates the vehicle (:mod:`~wheel_force_estimator.sim.dynamics`) at
``substeps x fs_hz`` in chunks, decimates to ``fs_hz`` through the zero-phase anti-alias FIR,
then adds sensor noise and the sensor effects (:mod:`~wheel_force_estimator.sim.sensors`).
Roads and noise come from separate streams of the seed, so two cars driven with the same seed
see the same roads, manoeuvres and noise samples whatever their effects.
"""
from dataclasses import dataclass
import json
from pathlib import Path
import sys
from types import MappingProxyType
from typing import Dict, Mapping, Optional, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import SimulationError
from wheel_force_estimator.sim import dynamics
from wheel_force_estimator.sim.courses import build_course
from wheel_force_estimator.sim.effects import apply_parameter_effects
from wheel_force_estimator.sim.effects import loop_effect_arrays
from wheel_force_estimator.sim.effects import resolve_effects
from wheel_force_estimator.sim.roads import envelope
from wheel_force_estimator.sim.sensors import add_noise
from wheel_force_estimator.sim.sensors import Decimator
from wheel_force_estimator.sim.sensors import DelayLine
from wheel_force_estimator.sim.sensors import saturate
from wheel_force_estimator.sim.vehicle import corner_layout
from wheel_force_estimator.sim.vehicle import vehicle_to_dict
from wheel_force_estimator.sim.vehicle import VehicleParams

#: 2026-01-01T00:00:00Z: stamps of simulated recordings start here.
DEFAULT_START_NS = 1_767_225_600 * 1_000_000_000
_CHUNK_STEPS = 1 << 15
# spawn key of the noise stream (roads use the children of SeedSequence(seed))
_NOISE_KEY = 0x5E450
# spawn key of the six-component sensors' noise (its own stream: the force and acceleration
# noise samples stay what they were before the moments were simulated)
_NOISE6_KEY = 0x5E456


@dataclass(frozen=True, eq=False)
class SimResult:
    """
    One simulated recording.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (n,), int64
        Sample stamps.
    accel_mps2 : numpy.ndarray, shape (12, n)
        Spindle specific force, ``INPUT_CHANNELS`` order (noise and sensor effects included).
    force_n : numpy.ndarray, shape (12, n)
        WFT forces, ``OUTPUT_CHANNELS`` order (noise and sensor effects included).
    events : tuple of (int, str)
        Event start stamp (first sample at or after the start) and name.
    fs_hz : float
        Output sample rate.
    states : Mapping[str, numpy.ndarray]
        Noise-free internal signals at the output rate: ``suspension_compression_m`` (4, n,
        + jounce), ``tyre_force_n`` (12, n, world frame, contact patch), ``road_m`` (4, n,
        enveloped road under each wheel), ``body_heave_m``, ``body_pitch_rad``,
        ``body_roll_rad``, ``speed_mps`` (n,), and ``static_force_n`` (12,): what the WFTs
        read at rest.
    physics : tuple of str
        Effects of the simulated car.
    effect_params : Mapping
        Their parameters.
    vehicle : VehicleParams
        The simulated car (parameter-error effects applied).
    moment_nm : numpy.ndarray, shape (12, n)
        WFT moments, ``MOMENT_CHANNELS`` order (``lf_mx`` ... ``rr_mz``) [N m], same frame,
        noise and stream delay as the forces (:func:`.dynamics._record_six` states the
        physics).
    rate_radps : numpy.ndarray, shape (12, n)
        Spindle angular rates in the non-rotating wheel-centre frame, ``RATE_CHANNELS``
        order (``lf_wx`` ... ``rr_wz``) [rad/s], with gyro noise.
    spin_radps : numpy.ndarray, shape (4, n)
        Wheel spin rate per corner (``SPIN_CHANNELS``) [rad/s], positive rolling forward.

    """

    stamp_ns: np.ndarray
    accel_mps2: np.ndarray
    force_n: np.ndarray
    events: Tuple[Tuple[int, str], ...]
    fs_hz: float
    states: Mapping[str, np.ndarray]
    physics: Tuple[str, ...]
    effect_params: Mapping
    vehicle: VehicleParams
    moment_nm: Optional[np.ndarray] = None
    rate_radps: Optional[np.ndarray] = None
    spin_radps: Optional[np.ndarray] = None

    @property
    def duration_s(self) -> float:
        """Return the recorded duration [s]."""
        return self.stamp_ns.size / self.fs_hz


def _check_args(fs_hz, substeps, vehicle):
    if vehicle is None:
        vehicle = VehicleParams()
    elif not isinstance(vehicle, VehicleParams):
        raise ConfigError(f'vehicle must be a VehicleParams, got {type(vehicle).__name__}')
    try:
        fs = float(fs_hz)
    except (TypeError, ValueError) as err:
        raise ConfigError(f'fs_hz must be a number, got {fs_hz!r}') from err
    if not np.isfinite(fs) or fs < 50.0:
        raise ConfigError(f'fs_hz must be >= 50 Hz (the wheel modes reach ~60 Hz), got {fs_hz!r}')
    if isinstance(substeps, bool) or int(substeps) != substeps or substeps < 1:
        raise ConfigError(f'substeps must be a positive integer, got {substeps!r}')
    if fs * substeps < 1000.0:
        raise ConfigError(f'integration rate fs_hz * substeps = {fs * substeps:g} Hz is too '
                          f'low for the hub modes; use at least 1000 Hz')
    return vehicle, fs, int(substeps)


def _progress_bar(enabled: bool, total: int):
    if not enabled or not sys.stderr.isatty():
        return None
    from tqdm import tqdm
    return tqdm(total=total, desc='simulating', unit='s', leave=False)


def simulate(course='proving_ground', physics=(), seed: int = 0, duration_scale: float = 1.0,
             fs_hz: float = 512.0, vehicle: Optional[VehicleParams] = None,
             effect_params: Optional[Mapping] = None, *, substeps: int = 4,
             start_ns: int = DEFAULT_START_NS, progress: bool = False) -> SimResult:
    """
    Drive the simulated car over a course.

    Parameters
    ----------
    course : str or sequence
        Course name (``courses.COURSES``: ``'proving_ground'``, ``'flat'``, or one event
        name) or a sequence of ``EventSpec`` / ``(name, duration_s)``.
    physics : str or sequence of str
        Effects of the car (DESIGN.md vocabulary); empty = the nominal model.
    seed : int
        Roads and sensor noise.
    duration_scale : float
        Shortens (< 1) or lengthens every event proportionally.
    fs_hz : float
        Output sample rate.
    vehicle : VehicleParams, optional
        Nominal car (default: the paper-like compact car).
    effect_params : mapping, optional
        ``{effect: {param: value}}`` overriding the effect defaults.
    substeps : int
        Integration steps per output sample (RK4 at ``substeps * fs_hz``).
    start_ns : int
        Stamp of the first sample.
    progress : bool
        tqdm bar on stderr when it is a terminal.

    Returns
    -------
    SimResult

    Raises
    ------
    ConfigError
        Unknown course / effect / parameter, invalid rate or vehicle.
    SimulationError
        The integration diverged (time and event named).

    """
    vehicle, fs, substeps = _check_args(fs_hz, substeps, vehicle)
    effects = resolve_effects(physics, effect_params)
    car = apply_parameter_effects(vehicle, effects)
    fs_int = fs * substeps
    dec = Decimator(substeps, dynamics.N_OUT)
    pad_s = (dec.delay + 4 * substeps) / fs_int
    plan = build_course(course, seed, duration_scale, fs_int, pad_s)
    n_out = int(np.floor(plan.duration_s * fs + 1e-9))
    if n_out < 1:
        raise ConfigError(f'course too short: {plan.duration_s:g} s at {fs:g} Hz')
    n_steps = n_out * substeps + dec.delay
    road = envelope(plan.road_raw, plan.road_dx_m, car.tyre_contact_length_m)
    packed = dynamics.pack(car)
    eon, ep = loop_effect_arrays(effects)
    ax, ay = plan.accel_x_mps2, plan.accel_y_mps2
    if not car.horizontal_dynamics:
        ax, ay = np.zeros_like(ax), np.zeros_like(ay)
    lag = int(round(effects.get('time_delay', 'delay_s') * fs_int)) \
        if 'time_delay' in effects else 0
    delay = DelayLine(lag, 12)
    moment_delay = DelayLine(lag, 12)  # the WFT stream: moments lag as the forces do
    state = np.zeros(dynamics.N_STATE)
    pieces = []
    bar = _progress_bar(progress, int(np.ceil(n_steps / fs_int)))
    out = np.empty((min(_CHUNK_STEPS, n_steps), dynamics.N_OUT))
    k0 = 0
    while k0 < n_steps:
        n = min(_CHUNK_STEPS, n_steps - k0)
        bad = dynamics.integrate(state, k0, n, 1.0 / fs_int, plan.speed_mps, ax, ay, plan.x_m,
                                 road, plan.road_x0_m, 1.0 / plan.road_dx_m, packed.body_map,
                                 packed.body_mass, packed.corner, packed.glob, eon, ep, out)
        if bad >= 0:
            t = (k0 + bad) / fs_int
            name = [e[1] for e in plan.events if e[0] <= t][-1]
            raise SimulationError(f'integration diverged at t = {t:.3f} s (event {name}) with '
                                  f'physics {list(effects.names)}: check the effect and vehicle '
                                  f'parameters')
        chunk = out[:n].copy()
        s = slice(dynamics.O_FORCE, dynamics.O_FORCE + 12)
        chunk[:, s] = delay.process(chunk[:, s])
        s = slice(dynamics.O_MOMENT, dynamics.O_MOMENT + 12)
        chunk[:, s] = moment_delay.process(chunk[:, s])
        pieces.append(dec.process(chunk))
        if bar is not None:
            bar.update(n / fs_int)
        k0 += n
    if bar is not None:
        bar.close()
    rec = np.concatenate(pieces, axis=0)[:n_out].T.copy()
    if rec.shape[1] != n_out:
        raise SimulationError(f'decimator produced {rec.shape[1]} of {n_out} samples')
    accel = rec[dynamics.O_ACC:dynamics.O_ACC + 12].copy()
    force = rec[dynamics.O_FORCE:dynamics.O_FORCE + 12].copy()
    noise_rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_NOISE_KEY,)))
    add_noise(noise_rng, accel, force, car.accel_noise_mps2, car.force_noise_n)
    if 'sensor_saturation' in effects:
        accel = saturate(accel, effects.get('sensor_saturation', 'limit_mps2'))
    moment = rec[dynamics.O_MOMENT:dynamics.O_MOMENT + 12].copy()
    rate = rec[dynamics.O_GYRO:dynamics.O_GYRO + 12].copy()
    spin = rec[dynamics.O_SPIN:dynamics.O_SPIN + 4].copy()
    rng6 = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_NOISE6_KEY,)))
    moment += rng6.normal(0.0, car.moment_noise_nm, moment.shape)
    rate += rng6.normal(0.0, car.gyro_noise_radps, rate.shape)
    spin += rng6.normal(0.0, car.spin_noise_radps, spin.shape)
    period_ns = 1e9 / fs
    stamp = int(start_ns) + np.round(np.arange(n_out) * period_ns).astype(np.int64)
    events = []
    for t_s, name in plan.events:
        idx = int(np.ceil(t_s * fs - 1e-6))
        if idx < n_out:
            events.append((int(stamp[idx]), name))
    static = np.zeros(12)
    static[2::3] = corner_layout(car).wft_load_n
    states = {
        'suspension_compression_m': rec[dynamics.O_COMP:dynamics.O_COMP + 4],
        'tyre_force_n': rec[dynamics.O_TYRE:dynamics.O_TYRE + 12],
        'road_m': rec[dynamics.O_ROAD:dynamics.O_ROAD + 4],
        'body_heave_m': rec[dynamics.O_BODY],
        'body_pitch_rad': rec[dynamics.O_BODY + 1],
        'body_roll_rad': rec[dynamics.O_BODY + 2],
        'speed_mps': rec[dynamics.O_SPEED],
        'static_force_n': static,
    }
    return SimResult(stamp_ns=stamp, accel_mps2=accel, force_n=force, events=tuple(events),
                     fs_hz=fs, states=MappingProxyType(states), physics=effects.names,
                     effect_params=MappingProxyType(effects.to_dict()), vehicle=car,
                     moment_nm=moment, rate_radps=rate, spin_radps=spin)


def write_result(path, result: SimResult, storage: str = 'mcap', topics=None,
                 travel: bool = False, six: bool = False, spin: bool = True) -> Path:
    """
    Write a :class:`SimResult` as a rosbag2 (accelerations, WFT forces, events).

    With ``travel`` the suspension compression (``states['suspension_compression_m']``,
    positive in bump) is written too, as the ``suspension/joint_states`` topic.  With ``six``
    the WFT messages carry the moments (``wrench.torque``), the Imu messages the angular
    rates (``angular_velocity``, covariance filled) and, with ``spin``, the
    ``suspension/joint_states`` messages the wheel spin (``{corner}_wheel`` velocity).
    """
    from wheel_force_estimator.bagio import write_recording
    travel_m = result.states['suspension_compression_m'] if travel else None
    extras = {}
    if six:
        extras = {'torque_nm': result.moment_nm, 'rate_radps': result.rate_radps,
                  'rate_variance': result.vehicle.gyro_noise_radps ** 2,
                  'spin_radps': result.spin_radps if spin else None}
    return write_recording(path, result.stamp_ns, result.accel_mps2, result.force_n,
                           topics=topics, events=result.events, storage=storage,
                           travel_m=travel_m, **extras)


def simulate_pair(outdir, physics, seed: int = 0, holdout_seed: Optional[int] = None,
                  duration_scale: float = 1.0, storage: str = 'mcap', *,
                  course='proving_ground', vehicle: Optional[VehicleParams] = None,
                  effect_params: Optional[Mapping] = None, fs_hz: float = 512.0,
                  topics=None, progress: bool = False,
                  travel: bool = False) -> Dict[str, Path]:
    """
    Write ``sim/`` (nominal car), ``real/`` (car with the effects) and ``holdout/`` bags.

    ``sim`` and ``real`` share the seed (same roads, manoeuvres and noise samples); ``holdout``
    is the real car on ``holdout_seed`` (default ``seed + 1``).  ``simulation.json`` beside
    them records what was simulated (the ground truth of a diagnosis benchmark).  With
    ``travel`` every bag also carries the suspension travel topic.

    Returns
    -------
    dict
        ``{'sim': Path, 'real': Path, 'holdout': Path, 'truth': Path}``.

    Raises
    ------
    ConfigError, SimulationError, BagError
        Bad arguments, divergence, or a bag that exists already / cannot be written.

    """
    from wheel_force_estimator.core.errors import BagError
    outdir = Path(outdir)
    holdout_seed = int(seed) + 1 if holdout_seed is None else int(holdout_seed)
    if holdout_seed == int(seed):
        raise ConfigError(f'holdout_seed must differ from seed ({seed})')
    resolve_effects(physics, effect_params)  # fail before any simulation
    for name in ('sim', 'real', 'holdout', 'simulation.json'):
        if (outdir / name).exists():
            raise BagError(f'{outdir / name}: exists already, not overwriting')
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise BagError(f'{outdir}: cannot create directory: {err.strerror or err}') from err
    runs = (('sim', (), seed), ('real', physics, seed), ('holdout', physics, holdout_seed))
    paths, truth = {}, {}
    for name, phys, run_seed in runs:
        result = simulate(course, phys, run_seed, duration_scale, fs_hz, vehicle, effect_params,
                          progress=progress)
        paths[name] = write_result(outdir / name, result, storage, topics, travel)
        truth[name] = {'seed': run_seed, 'physics': list(result.physics),
                       'effect_params': {k: dict(v) for k, v in result.effect_params.items()},
                       'duration_s': result.duration_s,
                       'vehicle': vehicle_to_dict(result.vehicle)}
        del result
    doc = {'course': course if isinstance(course, str) else 'custom',
           'duration_scale': duration_scale, 'fs_hz': fs_hz, 'runs': truth}
    paths['truth'] = outdir / 'simulation.json'
    paths['truth'].write_text(json.dumps(doc, indent=2) + '\n')
    return paths
