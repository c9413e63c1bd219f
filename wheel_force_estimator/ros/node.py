# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel_force_node``: the live virtual wheel force transducer.

Wiring (all in ``WheelForceNode.__init__``; callbacks stay tiny):

* four ``sensor_msgs/Imu`` subscriptions, ``raw=True``: a callback only appends the serialized
  bytes to its corner's list.  Batches are decoded with numpy (:mod:`.conversions`), checked
  (malformed, wrong ``frame_id``, NaN/inf: dropped and counted), aligned on ``header.stamp``
  (:mod:`.aligner`) and fed to the shared :class:`~wheel_force_estimator.core.predict.Predictor`
  in blocks (:mod:`.stream`).  A batch is processed at once when the buffered messages could
  complete a block (samples waiting + the fewest messages buffered by any corner >=
  ``block_size``: nothing is published before that, so latency is unaffected), else by a
  :data:`HOUSEKEEPING_PERIOD_S` timer, which bounds memory and detects stalls.  At real time
  that is one batch per ~10 samples; under a fast replay one per block.
* four ``geometry_msgs/WrenchStamped`` publishers (RELIABLE, KEEP_LAST ``output_qos_depth``),
  one message per input sample per corner, stamped with the estimated input sample's stamp.
  A finished block is not published in one go (512 messages take ~4 ms, during which no input
  would be taken): :data:`PUBLISH_CHUNK_SAMPLES` samples at once, then
  :data:`PUMP_SAMPLES_PER_INPUT` more with every input message and the rest by the timer.  The
  samples deferred are those that waited least for their block, so the worst latency (the
  block's first sample, published first) is unchanged.
* a ``diagnostic_msgs/DiagnosticArray`` every ``damage_publish_period_s`` (:mod:`.diagnostics`).

Faults never stop the node: they are counted, shown in the diagnostics, logged with a
throttled warning and summarised at shutdown.  Run with the ``EventsExecutor`` spun with a
finite timeout (without one it busy-spins and runs nothing).
"""
import collections
import gc
import signal
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from wheel_force_estimator import CORNERS
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.core.model import load_model
from wheel_force_estimator.core.predict import Predictor
from wheel_force_estimator.ros.aligner import AlignedSamples
from wheel_force_estimator.ros.aligner import CornerAligner
from wheel_force_estimator.ros.conversions import decode_imu
from wheel_force_estimator.ros.conversions import encode_wrench
from wheel_force_estimator.ros.diagnostics import build_damage_array
from wheel_force_estimator.ros.diagnostics import CornerReport
from wheel_force_estimator.ros.params import declare_node_parameters
from wheel_force_estimator.ros.params import model_layout
from wheel_force_estimator.ros.stream import ForceStream

NODE_NAME = 'wheel_force_node'
#: Timer that processes buffered messages and checks for stalls [s].
HOUSEKEEPING_PERIOD_S = 0.02
#: Output samples (x4 messages) published right when a block is done.
PUBLISH_CHUNK_SAMPLES = 16
#: Output samples published with each input message while some are waiting.
PUMP_SAMPLES_PER_INPUT = 2
#: Throttle of repeated fault warnings [s].
WARN_THROTTLE_S = 5.0
_DROP_REASONS = ('malformed', 'wrong_frame', 'nonfinite')
_RCLError = rclpy_implementation.RCLError


class WheelForceNode(Node):
    """
    Virtual wheel force transducer node (see the module notes).

    Parameters
    ----------
    **node_options
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises
    ------
    WheelForceError
        ``ConfigError`` / ``ModelFileError`` when the parameters or the model are unusable.

    """

    def __init__(self, **node_options):
        super().__init__(NODE_NAME, **node_options)
        try:
            self._params = params = declare_node_parameters(self)
            model = load_model(params.model_path)
            self._layout = layout = model_layout(model, params)
            predictor = Predictor(model, layout.causal_delay_samples)
            if predictor.fallback:
                # Once, at start: the model predates the live estimator (issue 16).
                self.get_logger().warning(f'{params.model_path}: {predictor.fallback}')
            self._stream = ForceStream(predictor, params.block_size, params.sn_slope)
        except WheelForceError:
            self.destroy_node()
            raise
        self._fs_hz = model.fs_hz
        self._model = model
        self._input_order = np.asarray(layout.input_order)
        self._aligner = CornerAligner(len(CORNERS), 3, max(
            params.input_qos_depth, params.stale_timeout_samples, 64))
        self._stale_s = params.stale_timeout_samples / model.fs_hz
        self._check_frames = any(params.imu_frame_ids)
        n = len(CORNERS)
        self._raw = [[] for _ in range(n)]
        self._queued = 0                  # stream samples waiting for their block
        self._out = collections.deque()   # [per-corner serialized messages, next index]
        self._n_unpublished = 0
        self._published = 0
        self._received = np.zeros(n, dtype=np.int64)
        self._dropped = {reason: np.zeros(n, dtype=np.int64) for reason in _DROP_REASONS}
        self._last_rx_s = [None] * n
        self._last_sample_s = None
        self._event = ''
        self._rate_ref = (self._stream.counts['samples_out'], self._stream.damage(), 0)

        in_qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=params.input_qos_depth,
            reliability=(ReliabilityPolicy.RELIABLE if params.input_reliability == 'reliable'
                         else ReliabilityPolicy.BEST_EFFORT))
        out_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=params.output_qos_depth,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._subs = [self.create_subscription(Imu, topic, self._imu_callback(c), in_qos,
                                               raw=True)
                      for c, topic in enumerate(params.imu_topics)]
        self._pubs = [self.create_publisher(WrenchStamped, topic, out_qos)
                      for topic in params.output_topics]
        self._publish_fns = [pub.publish for pub in self._pubs]
        self._damage_pub = self.create_publisher(DiagnosticArray, params.damage_topic, 10)
        # Best effort matches reliable and best-effort event publishers alike.
        self._event_sub = self.create_subscription(
            String, params.event_topic, self._on_event,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
        self._housekeeping = self.create_timer(HOUSEKEEPING_PERIOD_S, self._on_housekeeping)
        self._damage_timer = self.create_timer(params.damage_publish_period_s,
                                               self._publish_damage)
        self.get_logger().info(
            f'model {params.model_path}: {model.fs_hz:g} Hz, block {params.block_size} '
            f'samples ({params.block_size / model.fs_hz * 1e3:.0f} ms), look-ahead '
            f'{self._stream.delay_samples} samples '
            f'({self._stream.delay_samples / model.fs_hz * 1e3:.0f} ms); inputs '
            f'{", ".join(params.imu_topics)} ({params.input_reliability})')

    # -- callbacks ---------------------------------------------------------------------------

    def _imu_callback(self, corner: int):
        buf = self._raw[corner]
        raws = self._raw
        block = self._params.block_size

        def on_imu(raw: bytes):
            buf.append(raw)
            if self._n_unpublished:
                self._pump(PUMP_SAMPLES_PER_INPUT)
            # A block can only complete once every corner has delivered enough messages.
            if self._queued + min(map(len, raws)) >= block:
                self._process(time.monotonic())
        return on_imu

    def _on_event(self, msg: String):
        self._event = msg.data

    def _on_housekeeping(self):
        now = time.monotonic()
        if any(self._raw):
            self._process(now)
        if (self._stream.in_flight and self._last_sample_s is not None
                and now - self._last_sample_s > self._params.flush_timeout_s):
            self._stream.flush()
            self._queued = self._stream.queued
            self._publish(*self._stream.take())
        if self._n_unpublished:
            self._pump(self._n_unpublished)

    # -- processing --------------------------------------------------------------------------

    def _process(self, now: float):
        batches = []
        for c, buf in enumerate(self._raw):
            batches.append(buf[:])
            buf.clear()
        counts = [len(b) for b in batches]
        if self._check_frames:
            decoded = [decode_imu(b, self._params.imu_frame_ids[c]) if b else None
                       for c, b in enumerate(batches)]
        else:
            whole = decode_imu([raw for b in batches for raw in b])
            decoded, lo = [], 0
            for n in counts:
                decoded.append(_slice(whole, lo, lo + n) if n else None)
                lo += n
        for c, d in enumerate(decoded):
            if d is None:
                continue
            self._received[c] += counts[c]
            self._last_rx_s[c] = now
            valid = d.valid
            if not valid.all():
                self._count_drops(c, d)
                self._aligner.push(c, d.stamp_ns[valid], d.accel_mps2[:, valid])
            else:
                self._aligner.push(c, d.stamp_ns, d.accel_mps2)
        for event in self._aligner.drain():
            if isinstance(event, AlignedSamples):
                self._stream.feed(event.stamp_ns, event.accel_mps2[self._input_order])
                self._last_sample_s = now
            else:
                self.get_logger().warning(
                    f'stamps went back to {event.stamp_ns} ns (recording restarted?): '
                    f'estimates in flight completed, filter and damage restarted')
                self._stream.restart()
        self._queued = self._stream.queued
        self._publish(*self._stream.take())

    def _count_drops(self, corner: int, decoded):
        topic = self._params.imu_topics[corner]
        for reason in _DROP_REASONS:
            mask = getattr(decoded, reason)
            n = int(mask.sum())
            if n:
                self._dropped[reason][corner] += n
                first = int(np.argmax(mask))
                self.get_logger().warning(
                    f'{topic}: dropped {n} {reason.replace("_", " ")} message(s), first '
                    f'stamped {int(decoded.stamp_ns[first])} ns (total '
                    f'{int(self._dropped[reason][corner])})',
                    throttle_duration_sec=WARN_THROTTLE_S)

    def _publish(self, stamp_ns: np.ndarray, force_n: np.ndarray):
        if stamp_ns.size == 0:
            return
        layout = self._layout
        blobs = []
        for c, frame in enumerate(self._params.frame_ids):
            torque = None if layout.torque_rows is None else force_n[list(layout.torque_rows[c])]
            blobs.append(encode_wrench(stamp_ns, force_n[list(layout.force_rows[c])], frame,
                                       torque))
        self._out.append([blobs, 0])
        self._n_unpublished += stamp_ns.size
        self._pump(PUBLISH_CHUNK_SAMPLES)

    def _pump(self, budget: int):
        """Publish up to ``budget`` waiting output samples, oldest first."""
        publishers = self._publish_fns
        while budget > 0 and self._out:
            entry = self._out[0]
            blobs, first = entry
            last = min(len(blobs[0]), first + budget)
            # Sample-major order: a subscriber sees the four corners of a sample together.
            for k in range(first, last):
                for publish, corner_blobs in zip(publishers, blobs):
                    publish(corner_blobs[k])
            n = last - first
            budget -= n
            self._published += n
            self._n_unpublished -= n
            if last == len(blobs[0]):
                self._out.popleft()
            else:
                entry[1] = last

    # -- diagnostics -------------------------------------------------------------------------

    def stale_reasons(self, now: float):
        """Return, per corner, why its input is stale (``''`` when it is not)."""
        reasons = []
        lasts = [self._aligner.last_stamp_ns(c) for c in range(len(CORNERS))]
        newest = max((s for s in lasts if s is not None), default=None)
        limit_ns = self._params.stale_timeout_samples * 1e9 / self._fs_hz
        for c in range(len(CORNERS)):
            rx = self._last_rx_s[c]
            if rx is None:
                reasons.append('no message received yet')
            elif now - rx > self._stale_s:
                reasons.append(f'no message for {now - rx:.2f} s')
            elif (newest is not None and lasts[c] is not None and not self._aligner.in_transition
                  and newest - lasts[c] > limit_ns):
                reasons.append(f'stamps {(newest - lasts[c]) * 1e-9:.2f} s behind the others')
            else:
                reasons.append('')
        return reasons

    def counters(self):
        """Return the per-corner counters shown in the diagnostics (dict of name -> list)."""
        align = self._aligner.counters()
        stream = self._stream.counts
        n = len(CORNERS)
        dropped = {f'dropped_{reason}': self._dropped[reason] for reason in _DROP_REASONS}
        dropped['dropped_duplicate'] = align['duplicate']
        dropped['dropped_late'] = align['late']
        dropped['dropped_incomplete'] = align['incomplete']
        total = sum(dropped.values())
        out = {'received': self._received, 'published': [self._published] * n,
               'dropped': total, 'gaps': [stream['gaps']] * n, 'resets': [stream['jumps']] * n}
        out.update(dropped)
        out.update({'aligned': align['aligned'], 'pending': align['pending'],
                    'in_flight': [self._stream.in_flight + self._n_unpublished] * n,
                    'flushes': [stream['flushes']] * n})
        return {key: [int(v) for v in value] for key, value in out.items()}

    def _publish_damage(self):
        if any(self._raw):
            self._process(time.monotonic())
        if self._n_unpublished:
            # The damage covers what was emitted: publish it all first so the two agree.
            self._pump(self._n_unpublished)
        damage = self._stream.damage()
        samples_out = self._stream.counts['samples_out']
        jumps = self._stream.counts['jumps']
        ref_out, ref_damage, ref_jumps = self._rate_ref
        if jumps != ref_jumps:
            ref_out, ref_damage = 0, np.zeros_like(damage)
        n_new = samples_out - ref_out
        rate = (damage - ref_damage) * self._fs_hz / n_new if n_new > 0 else damage * 0.0
        self._rate_ref = (samples_out, damage, jumps)
        stale = self.stale_reasons(time.monotonic())
        counters = self.counters()
        names = self._model.output_channels
        reports = []
        for c, corner in enumerate(CORNERS):
            rows = list(self._layout.force_rows[c])
            if self._layout.torque_rows is not None:
                rows += list(self._layout.torque_rows[c])
            pairs = tuple((names[r].split('_', 1)[1], float(damage[r])) for r in rows)
            extra = tuple((key, value[c]) for key, value in counters.items())
            extra += (('stale', 'true' if stale[c] else 'false'), ('event', self._event))
            reports.append(CornerReport(corner, pairs, float(max(rate[rows].max(), 0.0)),
                                        stale[c], extra))
        if any(stale):
            self.get_logger().warning(
                'stale input: ' + '; '.join(f'{self._params.imu_topics[c]} {why}'
                                            for c, why in enumerate(stale) if why),
                throttle_duration_sec=WARN_THROTTLE_S)
        budget = float(self.get_parameter('damage_budget').value)
        stamp_ns = self.get_clock().now().nanoseconds
        self._damage_pub.publish(build_damage_array(reports, self.get_name(), stamp_ns, budget))

    def summary(self) -> str:
        """Return the counters as one line (logged at shutdown)."""
        counters = self.counters()
        text = ', '.join(f'{key}={value}' for key, value in counters.items())
        return f'counters per corner (lf, rf, lr, rr): {text}'


def _slice(decoded, lo: int, hi: int):
    """Messages ``lo:hi`` of a decoded batch."""
    return type(decoded)(decoded.stamp_ns[lo:hi], decoded.accel_mps2[:, lo:hi],
                         decoded.malformed[lo:hi], decoded.wrong_frame[lo:hi],
                         decoded.nonfinite[lo:hi])


def spin(node: Node, timeout_s: float = 0.1, stop: threading.Event = None):
    """Spin ``node`` with an EventsExecutor until the context shuts down or ``stop`` is set."""
    executor = EventsExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok() and not (stop is not None and stop.is_set()):
            executor.spin_once(timeout_sec=timeout_s)
    finally:
        executor.remove_node(node)
        executor.shutdown()


def main(args=None) -> int:
    """Run the node until shutdown; return 0, or 1 when it refuses to start."""
    # SIGINT/SIGTERM only request a stop, checked between executor turns: rclpy's own handler
    # would raise KeyboardInterrupt inside whatever callback is running (a FATAL log line and
    # a half-processed block); this way the last block is finished and the counters logged.
    stop = threading.Event()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except _RCLError as err:
        # e.g. an unreadable --params-file: rcl refuses before any node exists.
        rclpy.logging.get_logger(NODE_NAME).fatal(f'refusing to start: {err}')
        return 1
    try:
        node = WheelForceNode()
    except WheelForceError as err:
        rclpy.logging.get_logger(NODE_NAME).fatal(f'refusing to start: {err}')
        rclpy.try_shutdown()
        return 1
    # Everything allocated so far (rclpy, numpy, scipy, numba, the model) lives for the whole
    # run: keep it out of the cyclic collector, whose full passes otherwise stall the executor
    # for ~80 ms (measured), long enough to overflow the input queues at a fast replay.
    gc.freeze()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        spin(node, stop=stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        summary = node.summary()
        node.destroy_node()
        rclpy.try_shutdown()
        # After destroy_node: the context may be gone (Ctrl-C), so no /rosout publication.
        rclpy.logging.get_logger(NODE_NAME).info(summary)
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
