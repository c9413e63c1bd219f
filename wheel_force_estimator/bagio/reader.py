# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Read recordings (rosbag2 mcap/sqlite3 directories, ROS 1 ``.bag`` files) into aligned arrays.

The needed topics are decoded by :mod:`.decode` (bulk numpy path, or the fallback through
rosbags' deserialiser; both give identical results); every other topic, of any type or
encoding, is skipped and listed in the read summary.  Samples are put in ``header.stamp``
order (:mod:`.order`: late deliveries are moved and counted) and aligned on it, never on the
bag receive time; the optional suspension travel topic joins them on the same clock
(:mod:`.travel`).
"""
from dataclasses import dataclass
from dataclasses import field
from dataclasses import replace
from pathlib import Path
from typing import Dict, Optional, Tuple

import numpy as np

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import travel as travel_io
from wheel_force_estimator.bagio.align import align
from wheel_force_estimator.bagio.align import check_same_clock
from wheel_force_estimator.bagio.align import check_series
from wheel_force_estimator.bagio.align import Gap
from wheel_force_estimator.bagio.align import RATE_TOLERANCE
from wheel_force_estimator.bagio.align import Segment
from wheel_force_estimator.bagio.align import stack_corners
from wheel_force_estimator.bagio.align import stamp_text
from wheel_force_estimator.bagio.align import TopicSeries
from wheel_force_estimator.bagio.cdr import IMU_RATE
from wheel_force_estimator.bagio.cdr import IMU_RATE_COVARIANCE
from wheel_force_estimator.bagio.cdr import WRENCH_TORQUE
from wheel_force_estimator.bagio.decode import Decoded
from wheel_force_estimator.bagio.decode import jazzy_typestore
from wheel_force_estimator.bagio.decode import read_topics
from wheel_force_estimator.bagio.fastcdr import IMU_TYPE
from wheel_force_estimator.bagio.fastcdr import STRING_TYPE
from wheel_force_estimator.bagio.fastcdr import WRENCH_TYPE
from wheel_force_estimator.bagio.order import order_by_stamp
from wheel_force_estimator.bagio.topics import default_topic_config
from wheel_force_estimator.core.errors import BagError
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields, not objects
class Recording:
    """
    An aligned recording: segments on one sample clock plus what the read found.

    Attributes
    ----------
    path : pathlib.Path
        The bag.
    fs_hz : float
        Sample rate from the median stamp step [Hz].
    segments : tuple of Segment
        Contiguous parts (split at gaps), each with at least 2 samples.
    events : tuple of (int, str)
        ``(stamp_ns, name)`` from the event topic (bag timestamp; std_msgs/String has no
        header), empty when the topic is absent.
    n_read : dict of str to int
        Messages read per sample topic.
    n_used : int
        Samples in ``segments``.
    gaps : tuple of Gap
        Places where every topic misses samples (segment boundaries).
    short_segments : tuple of (int, int)
        ``(first_stamp_ns, n_samples)`` of parts shorter than 2 samples, left out of
        ``segments`` and reported here.
    step_range_ns : tuple of (int, int)
        Smallest and largest stamp step inside segments (clock jitter).
    n_bulk : int
        Messages decoded by the bulk numpy path (the rest by rosbags' deserialiser).
    n_messages : int
        All messages decoded (sample topics and events).
    n_reordered : dict of str to int
        Messages per sample topic stored after a later-stamped one and put back in stamp
        order (:mod:`.order`); topics with none are left out.
    skipped_topics : tuple of (str, str)
        ``(topic, type)`` of the topics in the bag that were not needed, hence not decoded.
    travel_topic : str or None
        The suspension travel topic when the bag carries it (``Segment.travel_m`` is set).
    travel_dropped : tuple of (int, int)
        Samples dropped from every channel for want of travel: ``(missing, not finite)``.

    """

    path: Path
    fs_hz: float
    segments: Tuple[Segment, ...]
    events: Tuple[Tuple[int, str], ...]
    n_read: Dict[str, int]
    n_used: int
    gaps: Tuple[Gap, ...]
    short_segments: Tuple[Tuple[int, int], ...] = ()
    step_range_ns: Tuple[int, int] = (0, 0)
    n_bulk: int = 0
    n_messages: int = 0
    n_reordered: Dict[str, int] = field(default_factory=dict)
    skipped_topics: Tuple[Tuple[str, str], ...] = ()
    travel_topic: Optional[str] = None
    travel_dropped: Tuple[int, int] = (0, 0)

    def summary(self) -> str:
        """Describe what was read, used and left out, for logs and reports."""
        n_samples = max(self.n_read.values()) if self.n_read else 0
        lines = [
            f'{self.path}: used {self.n_used} of {n_samples} samples read '
            f'({self.fs_hz:.6g} Hz, {len(self.segments)} segment(s), '
            f'{self.n_used / self.fs_hz:.3f} s)',
            '  messages read: ' + ', '.join(f'{t} {n}' for t, n in self.n_read.items()),
            f'  decoded in bulk: {self.n_bulk} of {self.n_messages} messages',
            '  put back in stamp order (stored late): ' + (', '.join(
                f'{t} {n}' for t, n in self.n_reordered.items()) or 'none'),
            '  skipped (not needed, not decoded): ' + (', '.join(
                f'{t} ({m})' for t, m in self.skipped_topics) or 'none'),
            f'  stamp step inside segments: {self.step_range_ns[0]}..{self.step_range_ns[1]} '
            f'ns (nominal {1e9 / self.fs_hz:.0f} ns)',
        ]
        if self.gaps:
            lines.append(f'  gaps ({len(self.gaps)}):')
            lines.extend(f'    {g}' for g in self.gaps)
        else:
            lines.append('  gaps: none')
        for stamp, n in self.short_segments:
            lines.append(f'  left out: segment of {n} sample(s) at {stamp_text(stamp)} '
                         '(too short)')
        lines.append(f'  events: {len(self.events)}')
        if self.travel_topic is not None:
            missing, bad = self.travel_dropped
            lines.append(f'  suspension travel ({self.travel_topic}): {missing + bad} sample(s) '
                         f'dropped from every channel ({missing} without travel, {bad} not '
                         'finite)')
        return '\n'.join(lines)


def _check_path(path) -> Path:
    path = Path(path)
    if not path.exists():
        raise BagError(f'{path}: no such bag (file or rosbag2 directory)')
    if path.is_file() and path.suffix not in ('.bag', '.mcap', '.db3'):
        raise BagError(f'{path}: not a bag: expected a rosbag2 directory or a .bag, .mcap or '
                       '.db3 file')
    return path


def _series(path, decoded: Decoded, topic: str, channels,
            reordered: Optional[Dict[str, int]] = None) -> TopicSeries:
    """One topic in stamp order; late deliveries counted into ``reordered``."""
    stamp, values, n_late = order_by_stamp(path, topic, decoded.stamp_ns[topic],
                                           decoded.values[topic])
    if n_late and reordered is not None:
        reordered[topic] = n_late
    return TopicSeries(topic, stamp, values, tuple(channels))


def read_recording(path, topics=None, require_wft: bool = True,
                   expected_fs_hz: Optional[float] = None, *, bulk: bool = True,
                   travel: bool = False, extras: Tuple[str, ...] = ()) -> Recording:
    """
    Read a recording and align its topics on ``header.stamp``.

    Parameters
    ----------
    path : str or pathlib.Path
        rosbag2 directory (mcap or sqlite3 storage) or ROS 1 ``.bag`` file.
    topics : TopicConfig, optional
        Topic names (defaults: DESIGN.md).
    require_wft : bool
        Read the four WrenchStamped ground-truth topics (training / evaluation bags).  When
        False they are not read and ``Segment.force_n`` is None.
    expected_fs_hz : float, optional
        Reject the recording unless its sample rate is within 0.1 % of this [Hz].
    bulk : bool
        Use the bulk decoder where possible (False forces rosbags' per-message path; both
        give identical results).
    travel : bool
        Also read the suspension travel topic (``topics.travel_topic``) when the bag carries
        it: ``Segment.travel_m`` is set, and samples without finite travel are dropped from
        every channel and counted.  False (fit, predict, evaluate) leaves it unread.
    extras : tuple of str
        Six-component groups to read as well (:data:`EXTRAS`): ``'moments'`` (the WFT
        ``wrench.torque``, needs ``require_wft``), ``'rates'`` (``Imu.angular_velocity``;
        refused, per topic, where its covariance says "not provided"), ``'spin'`` (velocity
        of the ``{corner}_wheel`` joints on ``topics.travel_topic``).  Each must be on every
        sample of the segments; nothing is filled in.

    Returns
    -------
    Recording

    Raises
    ------
    BagError
        Bad path, corrupt or truncated bag, missing topic (topics present listed), wrong
        type, unequal counts or stamps across topics, duplicate or decreasing stamps, rate
        mismatch, or no segment of at least 2 samples.
    NonFiniteError
        NaN or infinity in a message (topic, channel and stamp named).

    """
    topics = default_topic_config(topics)
    if expected_fs_hz is not None and not (np.isfinite(expected_fs_hz) and expected_fs_hz > 0):
        raise ConfigError(f'expected_fs_hz must be finite and > 0, got {expected_fs_hz!r}')
    path = _check_path(path)
    required = {t: IMU_TYPE for t in topics.imu_topics}
    if require_wft:
        required.update({t: WRENCH_TYPE for t in topics.wft_topics})
    optional = {topics.event_topic: STRING_TYPE}
    if travel:
        optional[topics.travel_topic] = travel_io.TRAVEL_TYPE
    decoded = read_topics(path, required, optional, bulk=bulk,
                          stacked=(topics.imu_topics, topics.wft_topics))
    reordered: Dict[str, int] = {}
    imu = [_series(path, decoded, t, INPUT_CHANNELS[3 * i:3 * i + 3], reordered)
           for i, t in enumerate(topics.imu_topics)]
    wft = ([_series(path, decoded, t, OUTPUT_CHANNELS[3 * i:3 * i + 3], reordered)
            for i, t in enumerate(topics.wft_topics)] if require_wft else None)
    on_clock = None
    dropped = (0, 0)
    if travel and topics.travel_topic in decoded.stamp_ns:
        imu, wft, on_clock, dropped = _with_travel(path, topics.travel_topic, decoded, imu,
                                                   wft, reordered)
    result = align(path, imu, wft, expected_fs_hz)
    if not result.segments:
        raise BagError(f'{path}: no segment of at least 2 samples between gaps '
                       f'({len(result.gaps)} gaps in {imu[0].stamp_ns.size} samples)')
    segments = result.segments
    if on_clock is not None:
        clock, travel_m = on_clock
        segments = tuple(replace(seg, travel_m=np.ascontiguousarray(
            travel_m[:, np.searchsorted(clock, seg.stamp_ns)])) for seg in segments)
    if extras:
        segments = _with_extras(path, topics, segments, tuple(extras), require_wft, bulk)
    events = tuple((int(s), str(name)) for s, name in
                   decoded.strings.get(topics.event_topic, ()))
    n_read = {t: int(decoded.stamp_ns[t].size) for t in required}
    if on_clock is not None:
        n_read[topics.travel_topic] = int(decoded.stamp_ns[topics.travel_topic].size)
    return Recording(
        path=path,
        fs_hz=result.fs_hz,
        segments=segments,
        events=events,
        n_read=n_read,
        n_used=sum(s.n_samples for s in result.segments),
        gaps=result.gaps,
        short_segments=result.short_segments,
        step_range_ns=result.step_range_ns,
        n_bulk=decoded.n_bulk,
        n_messages=decoded.n_messages,
        n_reordered=reordered,
        skipped_topics=decoded.skipped,
        travel_topic=topics.travel_topic if on_clock is not None else None,
        travel_dropped=dropped,
    )


#: Six-component groups :func:`read_recording` can add (``extras``).
EXTRAS = ('moments', 'rates', 'spin')


def _on_segments(path, topic: str, stamp_ns, values, segments, what: str):
    """Rows of ``values`` (n, k) at every segment stamp; refuse any that is missing."""
    out = []
    for seg in segments:
        at = np.searchsorted(stamp_ns, seg.stamp_ns)
        ok = at < stamp_ns.size
        ok[ok] = stamp_ns[at[ok]] == seg.stamp_ns[ok]
        if not ok.all():
            i = int(np.argmin(ok))
            raise BagError(f'{path}: {topic}: no {what} at {stamp_text(seg.stamp_ns[i])} '
                           f'({int((~ok).sum())} sample(s) of {seg.source} without it); '
                           'nothing is filled in')
        rows = np.ascontiguousarray(values[at].T)
        bad = ~np.isfinite(rows)
        if bad.any():
            j = int(np.argmax(bad.any(axis=0)))
            raise NonFiniteError(f'{path}: {topic}: {what} not finite at '
                                 f'{stamp_text(seg.stamp_ns[j])}')
        out.append(rows)
    return out


def _with_extras(path, topics, segments, extras, require_wft: bool, bulk: bool):
    """Return the segments with the six-component groups ``extras`` read and attached."""
    unknown = [e for e in extras if e not in EXTRAS]
    if unknown:
        raise ConfigError(f'extras must be among {EXTRAS}, got {unknown}')
    if 'moments' in extras and not require_wft:
        raise ConfigError('extras: moments are read with the WFT topics (require_wft)')
    parts = {}
    if 'moments' in extras:
        got = read_topics(path, dict.fromkeys(topics.wft_topics, WRENCH_TYPE), {}, bulk=bulk,
                          fields=dict.fromkeys(topics.wft_topics, WRENCH_TORQUE))
        parts['moment_nm'] = _corner_rows(path, got, topics.wft_topics, segments, 'torque')
    if 'rates' in extras:
        imu = dict.fromkeys(topics.imu_topics, IMU_TYPE)
        cov = read_topics(path, imu, {}, bulk=bulk,
                          fields=dict.fromkeys(topics.imu_topics, IMU_RATE_COVARIANCE))
        missing = [f'{t} ({int((cov.values[t][:, 0] == -1.0).sum())} of '
                   f'{cov.values[t].shape[0]} messages)' for t in topics.imu_topics
                   if (cov.values[t][:, 0] == -1.0).any()]
        if missing:
            raise BagError(f'{path}: angular velocity not provided (REP-145 covariance[0] = -1)'
                           f' on {", ".join(missing)}: the model needs the spindle angular '
                           'rates; nothing is filled in')
        got = read_topics(path, imu, {}, bulk=bulk,
                          fields=dict.fromkeys(topics.imu_topics, IMU_RATE))
        parts['rate_radps'] = _corner_rows(path, got, topics.imu_topics, segments,
                                           'angular velocity')
    if 'spin' in extras:
        topic = topics.travel_topic
        got = read_topics(path, {topic: travel_io.TRAVEL_TYPE}, {}, bulk=bulk,
                          fields={topic: travel_io.SPIN_FIELD})
        stamp, values, _ = order_by_stamp(path, topic, got.stamp_ns[topic], got.values[topic])
        parts['spin_radps'] = _on_segments(path, topic, stamp, values, segments,
                                           'wheel spin (velocity of '
                                           f'{", ".join(travel_io.WHEEL_JOINT_NAMES)})')
    return tuple(replace(seg, **{k: v[i] for k, v in parts.items()})
                 for i, seg in enumerate(segments))


def available_extras(path, topics=None, *, bulk: bool = True) -> Tuple[str, ...]:
    """
    Return the six-component groups a recording carries (what ``fit`` fits by default).

    * ``'moments'``: the WFT messages' ``wrench.torque`` is not zero throughout
      (WrenchStamped has no "not provided" flag: a logger that leaves the moments out
      writes zeros);
    * ``'rates'``: every Imu message's angular-velocity covariance is provided
      (``covariance[0] != -1``, REP-145) and the rates are not zero throughout on any Imu
      topic (a default-constructed field: a driver or tool that fills only the linear
      acceleration leaves zeros with a zero covariance);
    * ``'spin'``: the travel topic exists and carries the ``{corner}_wheel`` joints with
      velocities.

    Raises
    ------
    BagError
        Bad path or corrupt bag.

    """
    topics = default_topic_config(topics)
    path = _check_path(path)
    found = []
    try:
        got = read_topics(path, dict.fromkeys(topics.wft_topics, WRENCH_TYPE), {}, bulk=bulk,
                          fields=dict.fromkeys(topics.wft_topics, WRENCH_TORQUE))
        if any(np.any(got.values[t] != 0.0) for t in topics.wft_topics):
            found.append('moments')
    except BagError:
        pass  # no WFT topics: no moments either
    cov = read_topics(path, dict.fromkeys(topics.imu_topics, IMU_TYPE), {}, bulk=bulk,
                      fields=dict.fromkeys(topics.imu_topics, IMU_RATE_COVARIANCE))
    if all(cov.values[t].size and np.all(cov.values[t][:, 0] != -1.0)
           for t in topics.imu_topics):
        rates = read_topics(path, dict.fromkeys(topics.imu_topics, IMU_TYPE), {}, bulk=bulk,
                            fields=dict.fromkeys(topics.imu_topics, IMU_RATE))
        if all(np.any(rates.values[t] != 0.0) for t in topics.imu_topics):
            found.append('rates')
    try:
        read_topics(path, {topics.travel_topic: travel_io.TRAVEL_TYPE}, {}, bulk=bulk,
                    fields={topics.travel_topic: travel_io.SPIN_FIELD})
        found.append('spin')
    except BagError:
        pass  # no travel topic, or one without the wheel joints
    return tuple(found)


def _corner_rows(path, decoded: Decoded, names, segments, what: str):
    """Four corners' (n, 3) values of ``decoded`` on the segments: [(12, n) per segment]."""
    per_topic = []
    for topic in names:
        stamp, values, _ = order_by_stamp(path, topic, decoded.stamp_ns[topic],
                                          decoded.values[topic])
        per_topic.append(_on_segments(path, topic, stamp, values, segments, what))
    return [np.ascontiguousarray(np.concatenate([p[i] for p in per_topic]))
            for i in range(len(segments))]


def _with_travel(path, topic: str, decoded: Decoded, imu, wft, reordered):
    """
    Put the travel topic on the Imu clock; drop samples without finite travel everywhere.

    Returns the (filtered) series, ``(clock, travel_m (4, n))`` and ``(missing, not finite)``.
    """
    stamp, values, n_late = order_by_stamp(path, topic, decoded.stamp_ns[topic],
                                           decoded.values[topic])
    if n_late:
        reordered[topic] = n_late
    clock = imu[0].stamp_ns
    travel_m, missing, bad = travel_io.on_clock(path, topic, clock, stamp, values,
                                                RATE_TOLERANCE)
    keep = travel_io.usable(travel_m)
    if not keep.all():
        # the same samples leave every topic (a gap where any is missing: nothing filled)
        drop = clock[~keep]

        def cut(series):
            mask = ~np.isin(series.stamp_ns, drop)
            return replace(series, stamp_ns=series.stamp_ns[mask], values=series.values[mask])
        imu = [cut(s) for s in imu]
        wft = None if wft is None else [cut(s) for s in wft]
        clock, travel_m = clock[keep], travel_m[:, keep]
    return imu, wft, (clock, travel_m), (missing, bad)


def read_imu_topic(path, topic: str, *, bulk: bool = True):
    """
    Read one sensor_msgs/Imu topic of any bag (e.g. a ROS 1 robot's ``/imu/data``).

    Parameters
    ----------
    path : str or pathlib.Path
        rosbag2 directory or ROS 1 ``.bag`` file.
    topic : str
        Imu topic name.
    bulk : bool
        Allow the bulk decoder (rosbag2 only).

    Returns
    -------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` in bag order (checked strictly increasing).
    accel_mps2 : numpy.ndarray, shape (3, n), float64
        linear_acceleration x, y, z.

    Raises
    ------
    BagError
        Bad path, corrupt bag, missing topic or wrong type, duplicate/decreasing stamps.
    NonFiniteError
        NaN or infinity in a message.

    """
    path = _check_path(path)
    decoded = read_topics(path, {topic: IMU_TYPE}, {}, bulk=bulk)
    series = _series(path, decoded, topic, ('ax', 'ay', 'az'))
    check_series(path, series)
    return series.stamp_ns, np.ascontiguousarray(series.values.T)


def read_wrench_topics(path, topics, *, bulk: bool = True):
    """
    Read four WrenchStamped topics on one sample clock (e.g. the node's recorded output).

    Unlike :func:`read_recording` there is no segmentation: stamps are returned as they are,
    so gaps stay visible in ``stamp_ns``.

    Parameters
    ----------
    path : str or pathlib.Path
        rosbag2 directory or ROS 1 ``.bag`` file.
    topics : sequence of 4 str
        WrenchStamped topics in corner order (e.g. ``TopicConfig.output_topics``).
    bulk : bool
        Allow the bulk decoder.

    Returns
    -------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp``, strictly increasing, shared by the four topics.
    force_n : numpy.ndarray, shape (12, n), float64
        wrench.force in ``OUTPUT_CHANNELS`` order [N].

    Raises
    ------
    BagError
        Bad path, corrupt bag, missing topic or wrong type, duplicate/decreasing stamps, or
        stamps that differ between the topics.
    NonFiniteError
        NaN or infinity in a message.

    """
    topics = tuple(topics)
    if len(topics) != 4:
        raise ConfigError(f'read_wrench_topics needs 4 topics (lf, rf, lr, rr), got {topics}')
    path = _check_path(path)
    decoded = read_topics(path, dict.fromkeys(topics, WRENCH_TYPE), {}, bulk=bulk)
    series = [_series(path, decoded, t, OUTPUT_CHANNELS[3 * i:3 * i + 3])
              for i, t in enumerate(topics)]
    for s in series:
        check_series(path, s)
    for s in series[1:]:
        check_same_clock(path, series[0], s)
    return series[0].stamp_ns, stack_corners(series)


def read_string_topic(path, topic: str, *, bulk: bool = True) -> Tuple[Tuple[int, str], ...]:
    """
    Read one std_msgs/String topic: ``((bag_time_ns, text), ...)`` in bag order.

    Raises
    ------
    BagError
        Bad path, corrupt bag, missing topic or wrong type.

    """
    path = _check_path(path)
    decoded = read_topics(path, {topic: STRING_TYPE}, {}, bulk=bulk)
    return tuple((int(s), str(t)) for s, t in decoded.strings[topic])


__all__ = ['EXTRAS', 'Recording', 'available_extras', 'jazzy_typestore', 'read_imu_topic',
           'read_recording', 'read_string_topic', 'read_wrench_topics']
