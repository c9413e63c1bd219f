# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force replay``: play a recording's Imu topics to the node, optionally record it.

Six-component recordings: the spindle angular rates go out in the Imu messages, and the wheel
spin rates, where the recording has them, as ``sensor_msgs/JointState`` on the travel topic
(joints ``{corner}_wheel``, ``velocity`` [rad/s], the Imu stamps).

Like ``ros2 bag play`` (which has no PyPI wheel), but for this package's recordings: the four
corner topics are read with :mod:`wheel_force_estimator.bagio`, aligned, and published with
their original ``header.stamp`` at ``rate`` times real time (gaps between segments are waited
out at the same rate).  Messages are published RELIABLE, so both reliable and best-effort
subscribers match.  Events are published on the event topic when their stamp is reached.

With recording on, the node's wrench outputs (and damage diagnostics) are collected while
playing; when the outputs stop arriving the complete samples (all four corners) are returned
and can be written to a rosbag2 next to the inputs.
"""
from dataclasses import dataclass
import threading
import time
from typing import Callable, Optional, Sequence, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio.cdr import decode_wrench
from wheel_force_estimator.bagio.cdr import encode_imu
from wheel_force_estimator.bagio.topics import TopicConfig
from wheel_force_estimator.bagio.travel import WHEEL_JOINT_NAMES
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError

# Samples encoded per chunk: bounds memory for long recordings.
_ENCODE_CHUNK = 4096
# Samples published between two looks at the clock.
_PUBLISH_BURST = 32


@dataclass(frozen=True)
class ReplaySettings:
    """
    How to play.

    Parameters
    ----------
    rate : float
        Playback speed as a multiple of real time, > 0.
    topics : TopicConfig
        Topic names (inputs published, outputs and damage recorded).
    imu_frame_ids : tuple of str
        ``header.frame_id`` of the published Imu messages, one per corner.
    record : bool
        Collect the node's outputs.
    wait_subscribers_s : float
        Wait up to this long for a subscriber on every input topic before playing [s].
    match_delay_s : float
        Extra wait once every topic has a subscriber [s]: our side sees the subscriber
        before the subscriber sees us, and a best-effort reader drops what arrives earlier.
    settle_s : float
        After playing, wait at most this long for the reliable readers to acknowledge every
        message, then (recording) stop when no output arrived for this long [s].
    qos_depth : int
        History depth of the reliable publishers and recording subscriptions [messages].  A
        reliable KEEP_LAST writer drops a sample not yet acknowledged once its history is
        full, so the depth is how long a stall of the node (or a late match) the replay
        survives without losing data: 5000 is 2.4 s at 4x of 512 Hz.

    Raises
    ------
    ConfigError
        On an invalid value.

    """

    rate: float = 1.0
    topics: TopicConfig = TopicConfig()
    imu_frame_ids: Tuple[str, ...] = tuple(f'{c}_spindle' for c in CORNERS)
    record: bool = False
    wait_subscribers_s: float = 5.0
    match_delay_s: float = 0.5
    settle_s: float = 2.0
    qos_depth: int = 5000

    def __post_init__(self):
        """Validate."""
        if not (np.isfinite(self.rate) and self.rate > 0):
            raise ConfigError(f'replay rate must be a finite multiple of real time > 0, '
                              f'got {self.rate!r}')
        if len(self.imu_frame_ids) != len(CORNERS):
            raise ConfigError(f'imu_frame_ids must have {len(CORNERS)} entries, '
                              f'got {self.imu_frame_ids!r}')
        for name in ('wait_subscribers_s', 'match_delay_s', 'settle_s'):
            if not getattr(self, name) >= 0:
                raise ConfigError(f'{name} must be >= 0, got {getattr(self, name)!r}')
        if self.qos_depth < 1:
            raise ConfigError(f'qos_depth must be >= 1, got {self.qos_depth!r}')


@dataclass(frozen=True, eq=False)
class ReplayResult:
    """
    What was played and, when recording, what came back.

    Attributes
    ----------
    n_samples : int
        Samples published (each on all four topics).
    wall_s : float
        Time spent publishing [s].
    max_behind_s : float
        Largest delay of a publication behind its schedule [s] (the publisher's own limit).
    output_stamp_ns : numpy.ndarray, shape (m,), int64
        Stamps of complete output samples (all corners), increasing.
    output_force_n : numpy.ndarray, shape (12, m)
        Their forces in ``OUTPUT_CHANNELS`` order [N].
    output_counts : tuple of int
        Output messages received per corner.
    damage : DiagnosticArray or None
        The last damage message received.
    output_torque_nm : numpy.ndarray, shape (12, m)
        Their torques in ``MOMENT_CHANNELS`` order [N m] (what a model without moments
        leaves zero or NaN, ``unknown_torque``).

    """

    n_samples: int
    wall_s: float
    max_behind_s: float
    output_stamp_ns: np.ndarray
    output_force_n: np.ndarray
    output_counts: Tuple[int, ...]
    damage: Optional[DiagnosticArray]
    output_torque_nm: Optional[np.ndarray] = None


class _Collector:
    """Raw output messages and the latest damage message, filled by subscriptions."""

    def __init__(self):
        self.raw = [[] for _ in CORNERS]
        self.damage: Optional[DiagnosticArray] = None
        self.last_rx_s = time.monotonic()

    def wrench_callback(self, corner: int):
        buf = self.raw[corner]

        def on_wrench(raw: bytes):
            buf.append(raw)
            self.last_rx_s = time.monotonic()
        return on_wrench

    def on_damage(self, raw: bytes):
        self.damage = deserialize_message(raw, DiagnosticArray)

    def outputs(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Complete output samples (stamp present on all four corners), by stamp."""
        stamps, wrenches = [], []
        for raws in self.raw:
            s, w, bad = decode_wrench(list(raws))
            s, idx = np.unique(s[~bad], return_index=True)
            stamps.append(s)
            wrenches.append(w[:, ~bad][:, idx])
        common = stamps[0]
        for s in stamps[1:]:
            common = np.intersect1d(common, s, assume_unique=True)
        rows = [f[:, np.isin(s, common, assume_unique=True)] for s, f in zip(stamps, wrenches)]
        if not common.size:
            return common, np.empty((12, 0)), np.empty((12, 0))
        return (common, np.concatenate([r[:3] for r in rows], axis=0),
                np.concatenate([r[3:] for r in rows], axis=0))


def _check_samples(stamp_ns, accel_mps2) -> Tuple[np.ndarray, np.ndarray]:
    stamps = np.asarray(stamp_ns, dtype=np.int64)
    accel = np.asarray(accel_mps2, dtype=np.float64)
    if stamps.ndim != 1 or accel.shape != (3 * len(CORNERS), stamps.size) or stamps.size == 0:
        raise ShapeError(f'replay: {stamps.shape} stamps with accelerations {accel.shape}, '
                         f'expected ({3 * len(CORNERS)}, n >= 1)')
    if np.any(np.diff(stamps) <= 0):
        i = int(np.flatnonzero(np.diff(stamps) <= 0)[0]) + 1
        raise ShapeError(f'replay: stamps not increasing at sample {i}')
    return stamps, accel


def replay_samples(stamp_ns, accel_mps2, settings: ReplaySettings,
                   events: Sequence[Tuple[int, str]] = (), ros_args=None,
                   after_play: Optional[Callable[[], None]] = None,
                   rate_radps=None, spin_radps=None) -> ReplayResult:
    """
    Publish samples as the four Imu topics in (scaled) real time; collect the outputs.

    Parameters
    ----------
    stamp_ns : array_like, shape (n,), int
        Strictly increasing ``header.stamp`` values [ns].
    accel_mps2 : array_like, shape (12, n)
        Accelerations in ``INPUT_CHANNELS`` order [m/s²].
    settings : ReplaySettings
        Rate, topics, recording.
    events : sequence of (int, str)
        ``(stamp_ns, name)`` published on the event topic when reached.
    ros_args : list of str, optional
        Arguments for ``rclpy.init`` (e.g. ``['--ros-args', ...]``).
    after_play : callable, optional
        Called once everything is published and every reliable reader acknowledged it (or
        ``settings.settle_s`` passed), before the outputs are awaited.  The node
        holds the estimates of its look-ahead until more data, a gap, deactivate or shutdown
        (a pause is not the end of the data): e.g. stop the node here to collect them.
        The replay then also waits (up to ``settings.settle_s``) for the stopped node to
        leave the graph before it tears down its own (:func:`_wait_for_departure`).
    rate_radps : array_like, shape (12, n), optional
        Spindle angular rates in ``RATE_CHANNELS`` order [rad/s], published as the Imu
        angular velocity (else flagged "not provided").
    spin_radps : array_like, shape (4, n), optional
        Wheel spin rates, corners lf, rf, lr, rr [rad/s], published as the ``velocity`` of
        the ``{corner}_wheel`` joints of a JointState on ``settings.topics.travel_topic``.

    Returns
    -------
    ReplayResult

    Raises
    ------
    ShapeError
        Bad arrays.

    """
    stamps, accel = _check_samples(stamp_ns, accel_mps2)
    rate = None
    if rate_radps is not None:
        _, rate = _check_samples(stamps, rate_radps)
    spin = None
    if spin_radps is not None:
        spin = np.asarray(spin_radps, dtype=np.float64)
        if spin.shape != (len(CORNERS), stamps.size):
            raise ShapeError(f'replay: spin rates {spin.shape}, expected '
                             f'({len(CORNERS)}, {stamps.size})')
    context = Context()
    rclpy.init(args=ros_args, context=context)
    node = rclpy.create_node('wheel_force_replay', context=context)
    executor = EventsExecutor(context=context)
    stop = threading.Event()
    spinner = None
    try:
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=settings.qos_depth,
                         reliability=ReliabilityPolicy.RELIABLE)
        topics = settings.topics
        pubs = [node.create_publisher(Imu, t, qos) for t in topics.imu_topics]
        joint_pub = (None if spin is None
                     else node.create_publisher(JointState, topics.travel_topic, qos))
        event_pub = node.create_publisher(String, topics.event_topic, 10)
        collector = _Collector()
        subs = []
        if settings.record:
            subs = [node.create_subscription(WrenchStamped, t, collector.wrench_callback(c),
                                             qos, raw=True)
                    for c, t in enumerate(topics.output_topics)]
            subs.append(node.create_subscription(DiagnosticArray, topics.damage_topic,
                                                 collector.on_damage, 10, raw=True))
        executor.add_node(node)
        spinner = threading.Thread(target=_spin, args=(executor, stop), daemon=True)
        spinner.start()
        _wait_for_subscribers(pubs, settings.wait_subscribers_s, node)
        if joint_pub is not None:
            # only a node whose model has spin inputs subscribes (with its Imu topics): a
            # short wait, silent, so a replay to another node does not stall
            _until(lambda: joint_pub.get_subscription_count() > 0,
                   min(settings.wait_subscribers_s, 1.0))
        if settings.record:
            _wait_for_publishers(node, topics.output_topics, settings.wait_subscribers_s)
        time.sleep(settings.match_delay_s)
        wall_s, behind_s = _play(pubs, event_pub, stamps, accel, settings, events, rate,
                                 None if spin is None else (joint_pub, spin))
        # Published is not received: a busy node's reliable readers may still be behind.
        # Stopping it now (after_play) or leaving (the writers go) would lose that tail.
        _wait_for_acks(pubs + ([joint_pub] if joint_pub is not None else []),
                       settings.settle_s)
        if after_play is not None:
            after_play()
        if settings.record:
            _wait_for_outputs(collector, stamps.size, settings.settle_s)
        if after_play is not None:
            _wait_for_departure(pubs, subs, settings.settle_s)
        out_stamps, out_force, out_torque = collector.outputs()
        counts = tuple(len(r) for r in collector.raw)
        del subs
        return ReplayResult(stamps.size, wall_s, behind_s, out_stamps, out_force, counts,
                            collector.damage, out_torque)
    finally:
        stop.set()
        if spinner is not None:
            spinner.join()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _spin(executor, stop: threading.Event):
    while not stop.is_set():
        executor.spin_once(timeout_sec=0.05)


def _until(done: Callable[[], bool], timeout_s: float, poll_s: float = 0.02) -> bool:
    """Poll ``done`` every ``poll_s`` until it is true (True) or ``timeout_s`` ran out (False)."""
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll_s)
    return True


def _wait_for_acks(pubs, timeout_s: float):
    """Wait until every reliable reader acknowledged every message, one deadline for all."""
    deadline = time.monotonic() + timeout_s
    for pub in pubs:
        left = deadline - time.monotonic()
        if left <= 0.0 or not pub.wait_for_all_acked(Duration(seconds=left)):
            return False
    return True


def _wait_for_departure(pubs, subs, timeout_s: float):
    """
    Wait until the stopped node has left the graph (bounded by ``timeout_s``), then 0.2 s.

    Destroying this node while the stopped one's endpoints were being removed hung the
    replay for good (twice in about ten runs of the ROS tests): Fast DDS 2.14's participant
    teardown (``DomainParticipant::set_listener`` in
    ``rmw_fastrtps_shared_cpp::destroy_participant``) spun, holding the GIL, on a discovery
    callback in flight for a departing remote reader (gdb, 2026-12-02; eProsima/Fast-DDS
    #6513).  So the teardown waits until no remote reader or writer of the replay's topics
    is left (other nodes of the graph may stay) and the removals' callbacks have run.
    """
    _until(lambda: (all(p.get_subscription_count() == 0 for p in pubs)
                    and all(s.get_publisher_count() == 0 for s in subs)), timeout_s)
    time.sleep(0.2)


def _wait_for_subscribers(pubs, timeout_s: float, node):
    if _until(lambda: all(p.get_subscription_count() > 0 for p in pubs), timeout_s):
        return
    missing = [p.topic_name for p in pubs if p.get_subscription_count() == 0]
    if missing:
        node.get_logger().warning(f'no subscriber on {", ".join(missing)} after {timeout_s} s;'
                                  f' playing anyway')


def _wait_for_publishers(node, topics: Sequence[str], timeout_s: float):
    _until(lambda: all(node.count_publishers(t) > 0 for t in topics), timeout_s)


def _play(pubs, event_pub, stamps: np.ndarray, accel: np.ndarray, settings: ReplaySettings,
          events, rate: Optional[np.ndarray] = None, joints=None) -> Tuple[float, float]:
    """
    Publish on schedule; return (wall time spent, largest delay behind schedule).

    ``joints``: ``(publisher, spin (4, n))`` of the wheel spin JointState, or None.
    """
    due_s = (stamps - stamps[0]) * (1e-9 / settings.rate)
    pending_events = sorted((int(s), str(n)) for s, n in events)
    k_event = 0
    frames = settings.imu_frame_ids
    behind = 0.0
    start = time.monotonic()
    for lo in range(0, stamps.size, _ENCODE_CHUNK):
        hi = min(lo + _ENCODE_CHUNK, stamps.size)
        blobs = [encode_imu(stamps[lo:hi], accel[3 * c:3 * c + 3, lo:hi], frames[c],
                            None if rate is None else rate[3 * c:3 * c + 3, lo:hi])
                 for c in range(len(CORNERS))]
        i = lo
        while i < hi:
            wait = due_s[i] - (time.monotonic() - start)
            if wait > 0:
                time.sleep(wait)
            else:
                behind = max(behind, -wait)
            now = time.monotonic() - start
            j = min(max(int(np.searchsorted(due_s, now, side='right')), i + 1),
                    i + _PUBLISH_BURST, hi)
            while k_event < len(pending_events) and pending_events[k_event][0] <= stamps[j - 1]:
                event_pub.publish(String(data=pending_events[k_event][1]))
                k_event += 1
            for k in range(i - lo, j - lo):
                for c, pub in enumerate(pubs):
                    pub.publish(blobs[c][k])
            if joints is not None:
                _publish_spin(joints[0], stamps[i:j], joints[1][:, i:j])
            i = j
    return time.monotonic() - start, behind


def _publish_spin(pub, stamps: np.ndarray, spin: np.ndarray):
    """Publish one JointState per sample: the ``{corner}_wheel`` velocities."""
    for k, stamp in enumerate(stamps.tolist()):
        msg = JointState(name=list(WHEEL_JOINT_NAMES), velocity=spin[:, k].tolist())
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        pub.publish(msg)


def _wait_for_outputs(collector: _Collector, n_expected: int, settle_s: float):
    """Wait until every corner has ``n_expected`` outputs or none arrived for ``settle_s``."""
    collector.last_rx_s = max(collector.last_rx_s, time.monotonic())
    while True:
        if min(len(r) for r in collector.raw) >= n_expected:
            break
        if time.monotonic() - collector.last_rx_s > settle_s:
            break
        time.sleep(0.02)
    # The damage message made when the input stopped covers every output.
    n_out = min(len(r) for r in collector.raw)

    def covered() -> bool:
        damage = collector.damage
        return damage is not None and bool(damage.status) and _covered(damage) >= n_out

    _until(covered, settle_s)


def _covered(damage: DiagnosticArray) -> int:
    """Return how many estimates a damage message covers (its ``samples`` value)."""
    for kv in damage.status[0].values:
        if kv.key == 'samples':
            return int(kv.value)
    return -1


def replay_bag(path, settings: ReplaySettings, record_path=None, storage: str = 'mcap',
               ros_args=None, after_play: Optional[Callable[[], None]] = None):
    """
    Replay a recording (all its segments, in order); optionally write what came back.

    Parameters
    ----------
    path : str or pathlib.Path
        Recording readable by :func:`wheel_force_estimator.bagio.read_recording`.
    settings : ReplaySettings
        How to play (``record`` is forced on when ``record_path`` is given).
    record_path : str or pathlib.Path, optional
        New rosbag2 receiving the inputs and the node's outputs at the output stamps.
    storage : {'mcap', 'sqlite3'}
        Storage of ``record_path``.
    ros_args : list of str, optional
        Arguments for ``rclpy.init``.
    after_play : callable, optional
        As in :func:`replay_samples`.

    Returns
    -------
    recording : Recording
        What was read.
    result : ReplayResult
        What was played and received.

    Raises
    ------
    BagError
        Unreadable recording, or nothing came back to record.

    """
    import dataclasses

    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.bagio import write_recording
    from wheel_force_estimator.core.errors import BagError

    from wheel_force_estimator.bagio import available_extras

    # the angular rates and the wheel spin are published when the recording has them
    # (six-component models)
    extras = tuple(e for e in available_extras(path, settings.topics)
                   if e in ('rates', 'spin'))
    recording = read_recording(path, settings.topics, require_wft=False, extras=extras)
    stamps = np.concatenate([s.stamp_ns for s in recording.segments])
    accel = np.concatenate([s.accel_mps2 for s in recording.segments], axis=1)
    rate = (np.concatenate([s.rate_radps for s in recording.segments], axis=1)
            if 'rates' in extras else None)
    spin = (np.concatenate([s.spin_radps for s in recording.segments], axis=1)
            if 'spin' in extras else None)
    if record_path is not None and not settings.record:
        settings = dataclasses.replace(settings, record=True)
    result = replay_samples(stamps, accel, settings, recording.events, ros_args, after_play,
                            rate, spin)
    if record_path is not None:
        if result.output_stamp_ns.size == 0:
            raise BagError(f'{record_path}: nothing to record: no output on '
                           f'{", ".join(settings.topics.output_topics)} (is the node running?)')
        index = np.searchsorted(stamps, result.output_stamp_ns)
        index = np.minimum(index, stamps.size - 1)
        known = stamps[index] == result.output_stamp_ns
        write_recording(record_path, result.output_stamp_ns[known],
                        accel_mps2=accel[:, index[known]], force_n=result.output_force_n[:, known],
                        topics=settings.topics, events=recording.events, storage=storage,
                        imu_frame_ids=settings.imu_frame_ids, output=True)
    return recording, result


def imu_frame_ids_from_config(path=None) -> Tuple[str, ...]:
    """
    Return the Imu frame ids to publish: the node's ``imu_frame_ids`` where set.

    Corners the params file leaves open (``""``, or no file) get ``{corner}_spindle``, the
    frame ``bagio`` writes.

    Raises
    ------
    ConfigError
        Unreadable file or a malformed ``imu_frame_ids``.

    """
    from pathlib import Path

    import yaml

    default = tuple(f'{c}_spindle' for c in CORNERS)
    if path is None:
        return default
    try:
        doc = yaml.safe_load(Path(path).read_text(encoding='utf-8')) or {}
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f'{path}: cannot read params file: {err}') from err
    section = next((doc[k] for k in ('wheel_force_node', '/wheel_force_node', '/**')
                    if isinstance(doc, dict) and k in doc), None) or {}
    frames = (section.get('ros__parameters') or {}).get('imu_frame_ids', [''])
    if not isinstance(frames, list) or not all(isinstance(f, str) for f in frames):
        raise ConfigError(f'{path}: imu_frame_ids must be a list of strings, got {frames!r}')
    if frames == ['']:
        return default
    if len(frames) != len(CORNERS):
        raise ConfigError(f'{path}: imu_frame_ids must be [""] or {len(CORNERS)} frame ids, '
                          f'got {frames!r}')
    return tuple(f or d for f, d in zip(frames, default))
