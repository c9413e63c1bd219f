# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Stamp checks and segmentation of the per-corner topics onto one sample clock.

All eight topics of a training recording are sampled by one data logger: every Imu and
WrenchStamped message of a sample carries the same ``header.stamp``.  This module checks that
(rejecting anything else with the topic and the first offending stamp named) and splits the
record into contiguous :class:`Segment` s at gaps, i.e. where every topic misses the same
samples.  Nothing is interpolated, padded, resampled or dropped silently.
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator import SPIN_CHANNELS
from wheel_force_estimator.core.derived import ACCEL_DERIVED_CHANNELS
from wheel_force_estimator.core.derived import specific_force_parts
from wheel_force_estimator.core.derived import spin_acceleration
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.gaps import classify_steps
from wheel_force_estimator.core.gaps import MIN_STEP_FACTOR
from wheel_force_estimator.core.gaps import missing_samples

# Channel groups of a segment: names -> attribute (Segment.signals).
_GROUPS = ((INPUT_CHANNELS, 'accel_mps2'), (RATE_CHANNELS, 'rate_radps'),
           (SPIN_CHANNELS, 'spin_radps'), (OUTPUT_CHANNELS, 'force_n'),
           (MOMENT_CHANNELS, 'moment_nm'))
# Corner-to-corner / expected sample rate tolerance (relative).
RATE_TOLERANCE = 1e-3
_NS_PER_S = 1_000_000_000


def stamp_text(stamp_ns: int) -> str:
    """Format a stamp both as integer ns (exact) and seconds (readable)."""
    return f'{int(stamp_ns)} ns ({int(stamp_ns) / _NS_PER_S:.6f} s)'


@dataclass(frozen=True)
class TopicSeries:
    """
    Decoded samples of one topic: stamps and three values per message.

    Attributes
    ----------
    topic : str
        Topic name.
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` in message order.
    values : numpy.ndarray, shape (n, 3), float64
        x, y, z values.
    channels : tuple of str
        Names of the three channels (e.g. ``('lf_ax', 'lf_ay', 'lf_az')``).

    """

    topic: str
    stamp_ns: np.ndarray
    values: np.ndarray
    channels: Tuple[str, str, str]


@dataclass(frozen=True, eq=False)  # arrays: compare the fields, not the objects
class Segment:
    """
    A contiguous stretch of samples on one uniform clock.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (n,), int64
        Sample stamps (``header.stamp``), strictly increasing.
    accel_mps2 : numpy.ndarray, shape (12, n), float64
        Spindle accelerations in ``INPUT_CHANNELS`` order [m/s²].
    force_n : numpy.ndarray, shape (12, n), float64, or None
        Wheel forces in ``OUTPUT_CHANNELS`` order [N]; None when not read.
    source : str
        Where the samples come from (bag path and segment number).
    travel_m : numpy.ndarray, shape (4, n), float64, or None
        Suspension compression per corner [m], positive in bump (``bagio.travel``); None
        when the recording carries no travel topic.
    moment_nm : numpy.ndarray, shape (12, n), float64, or None
        Wheel moments (``wrench.torque``) in ``MOMENT_CHANNELS`` order [N m]; None when not
        read.
    rate_radps : numpy.ndarray, shape (12, n), float64, or None
        Spindle angular rates (``Imu.angular_velocity``) in ``RATE_CHANNELS`` order [rad/s].
    spin_radps : numpy.ndarray, shape (4, n), float64, or None
        Wheel spin rates (``{corner}_wheel`` joint velocity) [rad/s].

    """

    stamp_ns: np.ndarray
    accel_mps2: np.ndarray
    force_n: Optional[np.ndarray]
    source: str
    travel_m: Optional[np.ndarray] = None
    moment_nm: Optional[np.ndarray] = None
    rate_radps: Optional[np.ndarray] = None
    spin_radps: Optional[np.ndarray] = None

    def __post_init__(self):
        """Check dtypes and shapes so downstream code can rely on them."""
        stamp = np.asarray(self.stamp_ns)
        if stamp.ndim != 1 or stamp.dtype != np.int64:
            raise ShapeError(f'{self.source}: stamp_ns must be 1-D int64, got '
                             f'{stamp.dtype} {stamp.shape}')
        n = stamp.shape[0]
        for name, arr, rows in (('accel_mps2', self.accel_mps2, len(INPUT_CHANNELS)),
                                ('force_n', self.force_n, len(OUTPUT_CHANNELS)),
                                ('travel_m', self.travel_m, 4),
                                ('moment_nm', self.moment_nm, len(MOMENT_CHANNELS)),
                                ('rate_radps', self.rate_radps, len(RATE_CHANNELS)),
                                ('spin_radps', self.spin_radps, len(SPIN_CHANNELS))):
            if arr is None and name != 'accel_mps2':
                continue
            arr = np.asarray(arr)
            if arr.shape != (rows, n) or arr.dtype != np.float64:
                raise ShapeError(f'{self.source}: {name} must be float64 of shape ({rows}, {n}),'
                                 f' got {arr.dtype} {arr.shape}')

    @property
    def n_samples(self) -> int:
        """Return the number of samples."""
        return int(self.stamp_ns.shape[0])

    def signals(self, channels, fs_hz: Optional[float] = None) -> np.ndarray:
        """
        Return the declared channels stacked, ``(len(channels), n)`` float64.

        Channels are looked up by name in the groups (accelerations, angular rates, spin,
        forces, moments), so a model's declared inputs or outputs come out in its order; the
        spin accelerations (``SPIN_ACCEL_CHANNELS``) are derived from the spin rates on this
        segment (:func:`..core.derived.spin_acceleration`), the traction/braking and cornering
        splits (``SPLIT_CHANNELS``, ``CORNERING_CHANNELS``) from its accelerations
        (:func:`..core.derived.specific_force_parts`) with the low-pass designed at ``fs_hz``
        (the model's rate; ``None``: this segment's median sample rate).

        Raises
        ------
        BagError
            A channel of no group, or of a group this segment was read without.

        """
        channels = tuple(channels)
        for group, attr in _GROUPS:
            if channels == group and getattr(self, attr) is not None:
                return getattr(self, attr)  # a whole group: the array itself, no copy
        rows = []
        parts = [n for n in channels if n in ACCEL_DERIVED_CHANNELS]
        split = None
        for name in channels:
            if name in ACCEL_DERIVED_CHANNELS:  # derived: the splits of this segment's f_x, f_y
                if split is None:
                    rate = fs_hz if fs_hz is not None else _NS_PER_S / float(
                        np.median(np.diff(self.stamp_ns)))
                    split = specific_force_parts(self.accel_mps2, rate, parts)
                rows.append(split[parts.index(name)])
                continue
            if name in SPIN_ACCEL_CHANNELS:  # derived: d(spin)/dt on this segment
                if self.spin_radps is None:
                    raise BagError(f'{self.source}: channel {name} needs spin_radps, which '
                                   'was not read from this recording')
                k = SPIN_ACCEL_CHANNELS.index(name)
                rows.append(spin_acceleration(self.spin_radps[k:k + 1], self.stamp_ns)[0])
                continue
            for group, attr in _GROUPS:
                if name in group:
                    arr = getattr(self, attr)
                    if arr is None:
                        raise BagError(f'{self.source}: channel {name} needs {attr}, which '
                                       'was not read from this recording')
                    rows.append(arr[group.index(name)])
                    break
            else:
                raise BagError(f'{self.source}: unknown channel {name!r}')
        return np.ascontiguousarray(np.stack(rows)) if rows else np.zeros((0, self.n_samples))


@dataclass(frozen=True)
class Gap:
    """
    Samples missing from every topic between two consecutive stamps.

    Attributes
    ----------
    before_ns : int
        Last stamp before the gap.
    after_ns : int
        First stamp after the gap.
    missing_samples : int
        Number of nominal periods missing (rounded).

    """

    before_ns: int
    after_ns: int
    missing_samples: int

    def __str__(self) -> str:
        """Describe the gap for the read summary."""
        return (f'gap after {stamp_text(self.before_ns)}: {self.missing_samples} sample(s) '
                f'missing, {(self.after_ns - self.before_ns) / 1e6:.3f} ms step')


@dataclass(frozen=True)
class Alignment:
    """Result of :func:`align`: segments and what was found on the way."""

    fs_hz: float
    period_ns: int
    segments: Tuple[Segment, ...]
    gaps: Tuple[Gap, ...]
    short_segments: Tuple[Tuple[int, int], ...]
    step_range_ns: Tuple[int, int]


def check_series(path, series: TopicSeries):
    """Reject duplicate, decreasing and non-finite samples of one topic."""
    stamp = series.stamp_ns
    if stamp.size >= 2:
        step = np.diff(stamp)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            i = int(bad[0])
            what = 'duplicate stamp' if step[i] == 0 else 'stamp goes backwards'
            raise BagError(
                f'{path}: {series.topic}: {what} at message {i + 1}: '
                f'{stamp_text(stamp[i + 1])} after {stamp_text(stamp[i])}')
    finite = np.isfinite(series.values)
    if not finite.all():
        i, ch = (int(v) for v in np.argwhere(~finite)[0])
        raise NonFiniteError(
            f'{path}: {series.topic}: non-finite value {float(series.values[i, ch])!r} in channel '
            f'{series.channels[ch]} at message {i}, stamp {stamp_text(stamp[i])}')


def _median_period(path, series: TopicSeries) -> float:
    if series.stamp_ns.size < 2:
        raise BagError(f'{path}: {series.topic}: {series.stamp_ns.size} message(s); at least 2 '
                       'are needed to estimate the sample rate')
    return float(np.median(np.diff(series.stamp_ns)))


def check_same_clock(path, ref: TopicSeries, other: TopicSeries):
    """Reject ``other`` unless it has exactly the stamps of ``ref`` (first differences named)."""
    a, b = ref.stamp_ns, other.stamp_ns
    if a.shape == b.shape and np.array_equal(a, b):
        return
    # both are strictly increasing here (check_series), so set differences are exact
    only_ref = np.setdiff1d(a, b, assume_unique=True)
    only_other = np.setdiff1d(b, a, assume_unique=True)
    details = []
    if only_ref.size:
        details.append(f'stamp {stamp_text(only_ref[0])} is in {ref.topic} but not in '
                       f'{other.topic} ({only_ref.size} such)')
    if only_other.size:
        details.append(f'stamp {stamp_text(only_other[0])} is in {other.topic} but not in '
                       f'{ref.topic} ({only_other.size} such)')
    raise BagError(f'{path}: {other.topic} is not on the sample clock of {ref.topic} '
                   f'({ref.topic} has {a.size} messages, {other.topic} has {b.size}); first '
                   f'differences: {"; ".join(details)}')


def align(path, imu: Sequence[TopicSeries], wft: Optional[Sequence[TopicSeries]],
          expected_fs_hz: Optional[float] = None) -> Alignment:
    """
    Check that all topics share one sample clock and split it into segments at gaps.

    Parameters
    ----------
    path : str or pathlib.Path
        Recording, for messages and ``Segment.source``.
    imu : sequence of TopicSeries
        Four Imu topics (corner order); the first one is the reference clock.
    wft : sequence of TopicSeries or None
        Four WrenchStamped topics, or None when forces are not read.
    expected_fs_hz : float, optional
        Required sample rate [Hz]; checked to ``RATE_TOLERANCE``.

    Returns
    -------
    Alignment

    Raises
    ------
    BagError
        Duplicate / decreasing stamps, rate mismatch between topics or with
        ``expected_fs_hz``, stamps in one topic but not in another, or an irregular step.
    NonFiniteError
        NaN or infinity in a message (topic, channel and stamp named).

    """
    series = list(imu) + list(wft or ())
    for s in series:
        check_series(path, s)
    ref = series[0]
    ref_period = _median_period(path, ref)
    for s in series[1:]:
        period = _median_period(path, s)
        if abs(period - ref_period) > RATE_TOLERANCE * ref_period:
            raise BagError(
                f'{path}: sample rate of {s.topic} is {_NS_PER_S / period:.6g} Hz but '
                f'{ref.topic} runs at {_NS_PER_S / ref_period:.6g} Hz')
    fs_hz = _NS_PER_S / ref_period
    if (expected_fs_hz is not None
            and abs(fs_hz - expected_fs_hz) > RATE_TOLERANCE * expected_fs_hz):
        raise BagError(f'{path}: {ref.topic} is sampled at {fs_hz:.6g} Hz, expected '
                       f'{expected_fs_hz:.6g} Hz')
    for s in series[1:]:
        check_same_clock(path, ref, s)

    stamp = ref.stamp_ns
    step = np.diff(stamp)
    is_gap, too_short = classify_steps(step, ref_period)
    short = np.flatnonzero(too_short)
    if short.size:
        i = int(short[0])
        raise BagError(
            f'{path}: {ref.topic}: irregular sample clock: step of {int(step[i])} ns at '
            f'{stamp_text(stamp[i + 1])} is under {MIN_STEP_FACTOR} x the nominal period '
            f'{ref_period:.0f} ns')
    cut = np.flatnonzero(is_gap) + 1
    gaps = tuple(Gap(int(stamp[i - 1]), int(stamp[i]),
                     missing_samples(int(stamp[i] - stamp[i - 1]), ref_period)) for i in cut)
    inside = np.delete(step, cut - 1)
    step_range = (int(inside.min()), int(inside.max())) if inside.size else (0, 0)

    accel = stack_corners(imu)
    force = stack_corners(wft) if wft else None
    bounds = np.concatenate(([0], cut, [stamp.size]))
    segments: List[Segment] = []
    short_segments = []
    n_parts = len(bounds) - 1
    for k in range(n_parts):
        lo, hi = int(bounds[k]), int(bounds[k + 1])
        if hi - lo < 2:
            short_segments.append((int(stamp[lo]), hi - lo))
            continue
        segments.append(Segment(
            stamp_ns=stamp[lo:hi].copy(),
            accel_mps2=np.ascontiguousarray(accel[:, lo:hi]),
            force_n=None if force is None else np.ascontiguousarray(force[:, lo:hi]),
            source=f'{path} segment {k + 1}/{n_parts}'))
    return Alignment(fs_hz, int(round(ref_period)), tuple(segments), gaps,
                     tuple(short_segments), step_range)


def stack_corners(series: Sequence[TopicSeries]) -> np.ndarray:
    """Corner-major (12, n) C-contiguous array from four (n, 3) topics."""
    shared = _shared_stack(series)
    if shared is not None:
        return shared  # decoded in place already (decode._StackedValues): no copy
    out = np.empty((3 * len(series), series[0].values.shape[0]), np.float64)
    # row by row: concatenating the transposed views gives a Fortran-ordered array whose
    # C-ordered copy (and the transposed copy itself) cost ~15x more than these strided reads
    for i, s in enumerate(series):
        for k in range(3):
            out[3 * i + k] = s.values[:, k]
    return out


def _shared_stack(series: Sequence[TopicSeries]) -> Optional[np.ndarray]:
    """Return the array whose row triplets, in order, are exactly the series' values."""
    base = series[0].values.base
    n = series[0].values.shape[0]
    if not (isinstance(base, np.ndarray) and base.shape == (3 * len(series), n)
            and base.dtype == np.float64 and base.flags.c_contiguous):
        return None
    for k, s in enumerate(series):
        view = s.values
        if (view.base is not base or view.shape != (n, 3) or view.strides != base.T.strides
                or view.__array_interface__['data'][0]
                != base[3 * k].__array_interface__['data'][0]):
            return None
    return base
