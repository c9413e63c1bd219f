# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Proving-ground events and courses: what the driver does and what the road looks like.

An event (:class:`EventSpec`) is a named stretch of the course like the paper's Table 1/2:
a target speed (or a speed cycle: ``braking``, ``city_braking``), a lateral-acceleration demand
(``slalom``, ``figure_8``) and a road (random ISO 8608 roads, pavements, obstacles).  The default
``proving_ground`` course chains 15 events in ~10 min; ``duration_scale`` shortens every event
proportionally (fewer obstacles, fewer braking cycles).  The driver plan is built on a 100 Hz
grid: speed targets are rate-limited with the event's acceleration / deceleration, smoothed with
a 0.6 s triangular kernel (jerk), and interpolated to the integration rate.  The road is built
on a 1 cm distance grid: a class A base roughness everywhere except the ``flat`` /
``standstill`` events, plus each event's feature after the car has reached the event speed.
Deterministic for a seed: every event draws from its own child of ``SeedSequence(seed)``.
"""
from dataclasses import dataclass
from types import MappingProxyType
from typing import Callable, Optional, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.sim import roads

CONTROL_RATE_HZ = 100.0
ROAD_DX_M = 0.01
TRACK_M = 1.47
_SMOOTH_S = 0.3  # boxcar length, applied twice (triangular kernel)
_REAR_MARGIN_M = 8.0  # road before x = 0 for the rear axle


@dataclass(frozen=True)
class EventSpec:
    """
    One event of a course.

    Attributes
    ----------
    name : str
        Event kind (see :data:`EVENT_NAMES`); written to ``/proving_ground/event``.
    duration_s : float
        Duration before ``duration_scale``.
    speed_kph : float, optional
        Target speed; ``None`` uses the event's default.

    """

    name: str
    duration_s: float
    speed_kph: Optional[float] = None

    def __post_init__(self):
        """Reject unknown events and non-positive durations / negative speeds."""
        if self.name not in _KINDS:
            raise ConfigError(f'unknown course event {self.name!r} '
                              f'(known: {", ".join(EVENT_NAMES)})')
        if not np.isfinite(self.duration_s) or self.duration_s <= 0.0:
            raise ConfigError(f'event {self.name}: duration_s must be > 0, '
                              f'got {self.duration_s!r}')
        if self.speed_kph is not None and (not np.isfinite(self.speed_kph)
                                           or self.speed_kph < 0.0):
            raise ConfigError(f'event {self.name}: speed_kph must be >= 0, '
                              f'got {self.speed_kph!r}')

    @property
    def speed_mps(self) -> float:
        """Target speed [m/s]."""
        kph = _KINDS[self.name].speed_kph if self.speed_kph is None else self.speed_kph
        return kph / 3.6


@dataclass(frozen=True, eq=False)
class CoursePlan:
    """
    Driver plan and raw road of one course, ready for the integrator.

    Attributes
    ----------
    fs_int_hz : float
        Integration rate of the plan arrays.
    duration_s : float
        Course duration (the arrays run ``pad_s`` longer so the decimator can flush).
    speed_mps, accel_x_mps2, accel_y_mps2, x_m : numpy.ndarray, shape (n_steps + 1,)
        Reference speed, its derivative, lateral acceleration demand and front-axle distance.
    road_x0_m, road_dx_m : float
        Distance grid of ``road_raw``.
    road_raw : numpy.ndarray, shape (4, n_x)
        Left height, right height [m], left cross slope, right cross slope [rad] (not
        enveloped).
    events : tuple of (float, str)
        Event start time [s] and name.

    """

    fs_int_hz: float
    duration_s: float
    speed_mps: np.ndarray
    accel_x_mps2: np.ndarray
    accel_y_mps2: np.ndarray
    x_m: np.ndarray
    road_x0_m: float
    road_dx_m: float
    road_raw: np.ndarray
    events: Tuple[Tuple[float, str], ...]


@dataclass
class _RoadContext:
    x: np.ndarray        # distance of each grid point [m]
    z: np.ndarray        # (2, n) heights left / right
    cross: np.ndarray    # (2, n) cross slopes left / right
    rng: np.random.Generator

    def span(self, lo_m: float, hi_m: float) -> slice:
        i0 = int(np.clip(np.searchsorted(self.x, lo_m), 0, self.x.size))
        i1 = int(np.clip(np.searchsorted(self.x, hi_m), i0, self.x.size))
        return slice(i0, i1)

    def add_random(self, sl: slice, road_class: str):
        n = sl.stop - sl.start
        if n < 16:
            return
        w = roads.taper(n, ROAD_DX_M)
        left, right = roads.random_road_pair(self.rng, n, ROAD_DX_M, road_class, TRACK_M)
        self.z[0, sl] += w * left
        self.z[1, sl] += w * right

    def obstacles(self, sl: slice, spacing_m: float, first_m: float = 2.0):
        """Yield obstacle start positions every ``spacing_m`` inside ``sl``."""
        if sl.stop <= sl.start:
            return []
        lo, hi = self.x[sl.start], self.x[sl.stop - 1]
        return list(np.arange(lo + first_m, hi - 4.0, spacing_m))


# ---- roads of the events --------------------------------------------------------------------

def _road_highway(ctx: _RoadContext, sl: slice):
    ctx.add_random(sl, 'B')


def _pavement(ctx, sl, block_m, height_m, tilt_rad, crown_m, undulation):
    n = sl.stop - sl.start
    if n < 16:
        return
    w = roads.taper(n, ROAD_DX_M, 1.0)
    for side in (0, 1):
        h, c = roads.block_pavement(ctx.rng, n, ROAD_DX_M, block_m, height_m, tilt_rad, crown_m)
        ctx.z[side, sl] += w * h
        ctx.cross[side, sl] += w * c
    ctx.add_random(sl, undulation)


def _road_belgian_block(ctx, sl):
    _pavement(ctx, sl, 0.18, 0.006, 0.03, 0.003, 'C')


def _road_cobblestone(ctx, sl):
    _pavement(ctx, sl, 0.11, 0.003, 0.02, 0.002, 'B')


def _road_washboard(ctx, sl):
    n = sl.stop - sl.start
    if n < 16:
        return
    # corrugation wavelength wanders +-5 % around 0.8 m (quasi-periodic, as on real tracks)
    slow = np.cumsum(ctx.rng.standard_normal(n // 500 + 2))
    slow = 0.05 * slow / max(np.max(np.abs(slow)), 1e-12)
    wander = 1.0 + np.interp(np.arange(n), np.linspace(0, n, slow.size), slow)
    phase = 2.0 * np.pi * np.cumsum(ROAD_DX_M / (0.8 * wander))
    w = roads.taper(n, ROAD_DX_M, 3.0)
    shift = int(round(0.15 / ROAD_DX_M))  # corrugations not quite square to the lane
    ctx.z[0, sl] += w * 0.008 * np.sin(phase)
    ctx.z[1, sl] += w * 0.008 * np.sin(np.roll(phase, shift))


def _road_pothole(ctx, sl):
    for x0 in ctx.obstacles(sl, 20.0):
        length = ctx.rng.uniform(0.3, 0.7)
        depth = ctx.rng.uniform(0.020, 0.035)
        sides = (0, 1, (0, 1))[ctx.rng.integers(3)]
        for side in np.atleast_1d(sides):
            ctx.z[side, sl] += roads.box(ctx.x[sl], x0, length, -depth)


def _road_manhole_cover(ctx, sl):
    for x0 in ctx.obstacles(sl, 18.0):
        height = ctx.rng.choice((-1.0, 1.0)) * ctx.rng.uniform(0.010, 0.020)
        side = int(ctx.rng.integers(2))
        ctx.z[side, sl] += roads.box(ctx.x[sl], x0, 0.6, height)


def _road_railway_crossing(ctx, sl):
    for x0 in ctx.obstacles(sl, 40.0):
        skew = ctx.rng.uniform(0.0, 0.5)
        for side, offset in ((0, 0.0), (1, skew)):
            for rail in (0.0, 1.5):
                start = x0 + offset + rail
                ctx.z[side, sl] += roads.box(ctx.x[sl], start, 0.065, -0.025)  # flangeway
                ctx.z[side, sl] += roads.box(ctx.x[sl], start + 0.065, 0.07, 0.008)  # rail head


def _road_speed_bump(ctx, sl):
    for k, x0 in enumerate(ctx.obstacles(sl, 30.0)):
        length, height = ((3.0, 0.07), (0.6, 0.04))[k % 2]  # hump, then a short bump
        bump = roads.cosine_bump(ctx.x[sl], x0, length, height)
        ctx.z[0, sl] += bump
        ctx.z[1, sl] += bump


def _road_driveway(ctx, sl):
    for x0 in ctx.obstacles(sl, 20.0):
        for side, offset in ((0, 0.0), (1, 0.9)):  # entered at an angle
            ctx.z[side, sl] += roads.ramp_plateau(ctx.x[sl], x0 + offset, 0.6, 2.5, 0.10)


def _road_variant_wave(ctx, sl):
    n = sl.stop - sl.start
    if n < 16:
        return
    u = np.linspace(0.0, 1.0, n)
    wavelength = 3.0 * 4.0 ** u  # 3 m -> 12 m
    phase = 2.0 * np.pi * np.cumsum(ROAD_DX_M / wavelength)
    lag = np.pi * 0.5 * (1.0 - np.cos(2.0 * np.pi * (ctx.x[sl] - ctx.x[sl.start]) / 60.0))
    w = roads.taper(n, ROAD_DX_M, 5.0)
    ctx.z[0, sl] += w * 0.02 * np.sin(phase)
    ctx.z[1, sl] += w * 0.02 * np.sin(phase - lag)


def _road_twist(ctx, sl):
    for x0 in ctx.obstacles(sl, 9.0, first_m=1.0):
        ctx.z[0, sl] += roads.cosine_bump(ctx.x[sl], x0, 4.5, 0.08)
        ctx.z[1, sl] += roads.cosine_bump(ctx.x[sl], x0 + 4.5, 4.5, 0.08)


def _road_city(ctx, sl):
    ctx.add_random(sl, 'B')


# ---- driver: speed cycles and lateral demand ------------------------------------------------

def _cycle(t_s, period_s, high_s, v_high, v_low):
    return np.where(np.mod(t_s, period_s) < high_s, v_high, v_low)


def _speed_braking(t_s, v):
    return _cycle(t_s, 15.0, 8.0, v, 10.0 / 3.6)


def _speed_city(t_s, v):
    return _cycle(t_s, 20.0, 13.0, v, 0.0)


def _lateral_slalom(t_s, v):
    start = np.clip(t_s / 4.0, 0.0, 1.0)  # amplitude builds up over the first cones
    return 4.0 * start * np.sin(2.0 * np.pi * 0.5 * t_s)


def _lateral_figure_8(t_s, v):
    radius = 20.0
    lap = 2.0 * np.pi * radius / max(float(np.median(v)), 1.0)
    return np.where(np.mod(t_s, 2.0 * lap) < lap, 1.0, -1.0) * v ** 2 / radius


@dataclass(frozen=True)
class _Kind:
    speed_kph: float
    duration_s: float
    road: Optional[Callable] = None
    base_roughness: bool = True
    accel_mps2: float = 2.0
    decel_mps2: float = 3.0
    speed_cycle: Optional[Callable] = None
    lateral: Optional[Callable] = None


_KINDS = MappingProxyType({
    'highway': _Kind(100.0, 60.0, _road_highway),
    'belgian_block': _Kind(30.0, 45.0, _road_belgian_block),
    'cobblestone': _Kind(40.0, 40.0, _road_cobblestone),
    'washboard': _Kind(30.0, 30.0, _road_washboard),
    'pothole': _Kind(30.0, 25.0, _road_pothole),
    'manhole_cover': _Kind(40.0, 25.0, _road_manhole_cover),
    'railway_crossing': _Kind(25.0, 25.0, _road_railway_crossing),
    'speed_bump': _Kind(20.0, 30.0, _road_speed_bump),
    'driveway': _Kind(10.0, 25.0, _road_driveway),
    'variant_wave': _Kind(40.0, 40.0, _road_variant_wave),
    'twist': _Kind(8.0, 45.0, _road_twist),
    'braking': _Kind(60.0, 60.0, None, accel_mps2=2.5, decel_mps2=6.5,
                     speed_cycle=_speed_braking),
    'slalom': _Kind(50.0, 40.0, None, lateral=_lateral_slalom),
    'figure_8': _Kind(30.0, 60.0, None, lateral=_lateral_figure_8),
    'city_braking': _Kind(50.0, 50.0, _road_city, accel_mps2=2.0, decel_mps2=3.5,
                          speed_cycle=_speed_city),
    'flat': _Kind(30.0, 10.0, None, base_roughness=False),
    'standstill': _Kind(0.0, 5.0, None, base_roughness=False),
})
EVENT_NAMES = tuple(_KINDS)
PROVING_GROUND_EVENTS = EVENT_NAMES[:15]
# one course per event (its default duration), then the composite courses ('flat' = standing
# still, then driving on a perfectly flat road: the static checks)
COURSES = MappingProxyType({
    **{n: (EventSpec(n, _KINDS[n].duration_s),) for n in EVENT_NAMES},
    'proving_ground': tuple(EventSpec(n, _KINDS[n].duration_s) for n in PROVING_GROUND_EVENTS),
    'flat': (EventSpec('standstill', 4.0), EventSpec('flat', 12.0)),
})


def course_events(course) -> Tuple[EventSpec, ...]:
    """
    Return the events of a named course or of a sequence of specs / (name, duration) pairs.

    Raises
    ------
    ConfigError
        Unknown course or event, empty course.

    """
    if isinstance(course, str):
        try:
            return COURSES[course]
        except KeyError as err:
            raise ConfigError(f'unknown course {course!r} (known: {", ".join(COURSES)})') \
                from err
    specs = []
    for item in course:
        if isinstance(item, EventSpec):
            specs.append(item)
        else:
            try:
                name, duration = item
            except (TypeError, ValueError) as err:
                raise ConfigError(f'course item {item!r} is neither an EventSpec nor a '
                                  f'(name, duration_s) pair') from err
            specs.append(EventSpec(str(name), float(duration)))
    if not specs:
        raise ConfigError('course has no events')
    return tuple(specs)


def _smooth(x: np.ndarray, n_box: int) -> np.ndarray:
    if n_box <= 1:
        return x
    kernel = np.ones(n_box) / n_box
    for _ in range(2):
        padded = np.concatenate((np.full(n_box, x[0]), x, np.full(n_box, x[-1])))
        x = np.convolve(padded, kernel, mode='same')[n_box:-n_box]
    return x


def _driver_plan(specs, durations, pad_s):
    dt = 1.0 / CONTROL_RATE_HZ
    starts = np.concatenate(([0.0], np.cumsum(durations)))
    total = starts[-1] + pad_s
    t = np.arange(int(np.ceil(total * CONTROL_RATE_HZ)) + 2) * dt
    k = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, len(specs) - 1)
    v_des = np.empty_like(t)
    ay = np.zeros_like(t)
    acc = np.empty_like(t)
    dec = np.empty_like(t)
    for i, spec in enumerate(specs):
        kind = _KINDS[spec.name]
        m = k == i
        local = t[m] - starts[i]
        v = np.full(local.size, spec.speed_mps)
        v_des[m] = kind.speed_cycle(local, spec.speed_mps) if kind.speed_cycle else v
        acc[m], dec[m] = kind.accel_mps2, kind.decel_mps2
    v = np.empty_like(t)
    v[0] = v_des[0]
    step_up, step_down = acc * dt, dec * dt
    for j in range(1, t.size):  # rate limiter: a sequential recursion, 100 Hz is cheap
        v[j] = v[j - 1] + min(max(v_des[j] - v[j - 1], -step_down[j]), step_up[j])
    n_box = int(round(_SMOOTH_S * CONTROL_RATE_HZ))
    v = np.maximum(_smooth(v, n_box), 0.0)
    settle = np.empty(len(specs))
    for i, spec in enumerate(specs):
        # the event proper starts once the car runs at the event speed (at the latest after a
        # quarter of the event): road features and steering begin there
        m = k == i
        near = np.flatnonzero(np.abs(v[m] - spec.speed_mps) < 0.3)
        settle[i] = min(near[0] * dt if near.size else np.inf, 0.25 * durations[i]) + 0.5
        kind = _KINDS[spec.name]
        if kind.lateral is not None:
            local = t[m] - starts[i] - settle[i]
            ay[m] = np.where(local >= 0.0, kind.lateral(np.maximum(local, 0.0), v[m]), 0.0)
    ay = _smooth(ay, n_box)
    return t, v, ay, starts, settle


def build_course(course='proving_ground', seed: int = 0, duration_scale: float = 1.0,
                 fs_int_hz: float = 2048.0, pad_s: float = 0.5) -> CoursePlan:
    """
    Build the driver plan and the raw road of a course.

    Parameters
    ----------
    course : str or sequence
        Course name (:data:`COURSES`) or events (:class:`EventSpec` or (name, duration_s)).
    seed : int
        Road seed.
    duration_scale : float
        Every event's duration is multiplied by this (> 0).
    fs_int_hz : float
        Rate of the plan arrays (the integration rate).
    pad_s : float
        Extra time after the course end (same road and speed) for the decimator to flush.

    Raises
    ------
    ConfigError
        Unknown course / event or invalid scale.

    """
    specs = course_events(course)
    if not np.isfinite(duration_scale) or duration_scale <= 0.0:
        raise ConfigError(f'duration_scale must be > 0, got {duration_scale!r}')
    durations = np.array([s.duration_s * duration_scale for s in specs])
    seeds = np.random.SeedSequence(int(seed)).spawn(len(specs) + 1)
    t_c, v_c, ay_c, starts, settle = _driver_plan(specs, durations, pad_s)
    duration = float(starts[-1])
    n_steps = int(np.ceil((duration + pad_s) * fs_int_hz))
    t = np.arange(n_steps + 1) / fs_int_hz
    v = np.interp(t, t_c, v_c)
    ax = np.interp(t, t_c, np.gradient(v_c, t_c))
    ay = np.interp(t, t_c, ay_c)
    x = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / fs_int_hz)))

    x0 = -_REAR_MARGIN_M
    n_x = int(np.ceil((x[-1] + 2.0 - x0) / ROAD_DX_M)) + 2
    grid = x0 + np.arange(n_x) * ROAD_DX_M
    ctx = _RoadContext(x=grid, z=np.zeros((2, n_x)), cross=np.zeros((2, n_x)),
                       rng=np.random.default_rng(seeds[-1]))
    base_rng = ctx.rng
    base_l, base_r = roads.random_road_pair(base_rng, n_x, ROAD_DX_M, 'A', TRACK_M)
    base_cross = [roads.random_cross_slope(base_rng, n_x, ROAD_DX_M, 'A') for _ in range(2)]
    weight = np.ones(n_x)
    x_start = np.interp(starts, t, x)
    for i, spec in enumerate(specs):
        kind = _KINDS[spec.name]
        lo, hi = x_start[i], (x_start[i + 1] if i + 1 < len(specs) else grid[-1] + 1.0)
        if i == 0:
            lo = grid[0]
        if not kind.base_roughness:
            weight[ctx.span(lo, hi)] = 0.0
        if kind.road is None:
            continue
        lo_feature = float(np.interp(starts[i] + settle[i], t, x))
        ctx.rng = np.random.default_rng(seeds[i])
        kind.road(ctx, ctx.span(lo_feature, hi))
    n_box = int(round(5.0 / ROAD_DX_M))  # base roughness fades in / out over 5 m
    weight = np.convolve(weight, np.ones(n_box) / n_box, mode='same')
    road_raw = np.empty((4, n_x))
    road_raw[0] = ctx.z[0] + weight * base_l
    road_raw[1] = ctx.z[1] + weight * base_r
    road_raw[2] = ctx.cross[0] + weight * base_cross[0]
    road_raw[3] = ctx.cross[1] + weight * base_cross[1]
    events = tuple((float(starts[i]), spec.name) for i, spec in enumerate(specs))
    return CoursePlan(fs_int_hz=float(fs_int_hz), duration_s=duration, speed_mps=v,
                      accel_x_mps2=ax, accel_y_mps2=ay, x_m=x, road_x0_m=float(x0),
                      road_dx_m=ROAD_DX_M, road_raw=road_raw, events=events)
