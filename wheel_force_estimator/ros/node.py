# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel_force_node``: the live virtual wheel force transducer.

An ``rclpy`` lifecycle node (``docs/logger_graph.md``): ``__init__`` declares the parameters
and the services (``~/reset_damage``, ``~/reload_model``), ``configure`` loads the model and
makes the publishers, ``activate`` the subscriptions and timers, ``deactivate`` completes and
publishes what is in flight, ``cleanup`` releases; ``autostart`` (default) runs configure and
activate at start.  Every publisher and subscription takes ``qos_overrides.*``.  Wiring
(callbacks stay tiny):

* four ``sensor_msgs/Imu`` subscriptions, ``raw=True``, on relative topic names (they move with
  the node's namespace): a callback only appends the serialized bytes to its corner's list.
  Batches are decoded with numpy (:mod:`.conversions`), checked (malformed, wrong
  ``frame_id``, NaN/inf: dropped and counted), aligned on ``header.stamp`` (:mod:`.aligner`)
  and fed to the shared :class:`~wheel_force_estimator.core.predict.Predictor` in blocks
  (:mod:`.stream`).  A batch is processed as soon as the buffered messages could complete a
  block, else by the housekeeping timer.
* with a model that has wheel spin inputs (six components), a ``sensor_msgs/JointState``
  subscription on ``travel_topic``: the ``{corner}_wheel`` velocities (:mod:`.joints`;
  a message without them or with a NaN/inf one is dropped and counted) are a fifth stream
  of the same alignment, and :mod:`.stream` differentiates them exactly as the offline
  reader does (one more sample of latency).
* four ``geometry_msgs/WrenchStamped`` publishers (RELIABLE, KEEP_LAST 1024 by default),
  one message per input sample per corner, stamped with the estimated input sample's stamp.
  **Steady output**: a finished block is not published in one burst (a reliable keep-last-5
  subscriber such as ``ros2 topic echo`` would lose most of it) but paced at the input
  rate (:mod:`.pacing`): every input message earns a quarter of an output sample (four
  corners), so the estimates leave at the rhythm the samples came in, spread over the next
  block; and the output rate is bounded on the steady clock (at most twice the measured input
  rate, 2 ms of it at once), so input that arrives in a burst after a stall is not sent on as
  a burst but caught up over about the stall's length.  The wait this adds is at most about
  one block in steady running; beyond two blocks waiting the catch-up doubles, beyond four
  the rest leaves at once.  It is measured and reported (``/diagnostics``, shutdown
  summary).  Without input (a stall, the end of a replay), what waits leaves one sample per
  sample period of the model.
* the running pseudo damage on ``damage_topic`` every ``damage_publish_period_s`` of **data
  time** (sample stamps, :mod:`.stream`), so a replay at any rate or under sim time gives the
  same messages; a last one when the input stops and at shutdown.
* health on ``/diagnostics`` (:mod:`.diagnostics`) every :data:`DIAGNOSTICS_PERIOD_S`.

Timers run on the **steady clock**, not the ROS clock: with ``use_sim_time`` and a paused or
absent ``/clock``, stall detection and health still run.

**Continuity is judged in data time.**  Corner stamps within ``sync_tolerance_s`` are one
sample (:mod:`.aligner`, stamped by their median).  A pause of the input with no gap in the
stamps (a paused replay, a DAQ hiccup) keeps the filter and its look-ahead: the held estimates
leave when the data resumes, exactly as offline.  The stall only marks the inputs stale and
publishes the damage so far.  The look-ahead is completed only at a gap in the stamps, at a
stamp jump, and at shutdown.

At SIGINT/SIGTERM (:meth:`WheelForceNode.finish`, called by :mod:`.run`, the process around
the node) the look-ahead is completed, the remaining estimates leave paced (at most
:data:`SHUTDOWN_TAIL_S`), a final damage message is published and the acknowledgements are
awaited against one deadline (:data:`SHUTDOWN_ACK_S`).

Faults never stop the node: they are counted, shown in the diagnostics, logged (gaps one line
each, with the stamps either side; repeated faults with a throttled warning) and summarised at
shutdown.

Collaborators: the model's estimation chain is built by :mod:`.chain`, the waiting estimates
are published by :class:`.pacing.PacedOutput`, and what the node reports is
:class:`.health.NodeHealth`'s.
"""
import dataclasses
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode
from rclpy.lifecycle import LifecycleState
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.qos import HistoryPolicy
from rclpy.qos import QoSPolicyKind
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from sensor_msgs.msg import Imu
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio.cdr import encode_wrench
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.ros.aligner import AlignedSamples
from wheel_force_estimator.ros.aligner import OutOfTolerance
from wheel_force_estimator.ros.chain import load_chain
from wheel_force_estimator.ros.health import NodeHealth
from wheel_force_estimator.ros.health import WARN_THROTTLE_S
from wheel_force_estimator.ros.intake import Intake
from wheel_force_estimator.ros.pacing import PacedOutput
from wheel_force_estimator.ros.params import declare_node_parameters
from wheel_force_estimator.ros.params import default as _default
from wheel_force_estimator.ros.params import DEPRECATED_QOS_PARAMETERS
from wheel_force_estimator.ros.params import unknown_parameters

NODE_NAME = 'wheel_force_node'
#: The ROS-wide health topic (absolute: never moves with the namespace).
DIAGNOSTICS_TOPIC = '/diagnostics'
#: Steady-clock timer that processes buffered messages, paces idle output, detects stalls [s].
HOUSEKEEPING_PERIOD_S = 0.02
#: Steady-clock period of the /diagnostics health message [s].
DIAGNOSTICS_PERIOD_S = 1.0
#: How long a shutdown waits, in all, for reliable subscribers to acknowledge the last
#: messages (one deadline for every publisher) [s].
SHUTDOWN_ACK_S = 2.0
#: Longest a shutdown spends publishing the tail (paced at the model's sample rate, faster
#: when more waits) [s].  With the drain and the acknowledgements, a stop stays within the 5 s
#: after which ``ros2 launch`` escalates to SIGTERM.
SHUTDOWN_TAIL_S = 1.0
#: Longest single acknowledgement wait at shutdown (signals are handled between them) [s].
_ACK_SLICE_S = 0.05
#: QoS policies settable through ``qos_overrides.<topic>.<publisher|subscription>.<policy>``.
QOS_OVERRIDE_POLICIES = (QoSPolicyKind.HISTORY, QoSPolicyKind.DEPTH,
                         QoSPolicyKind.RELIABILITY, QoSPolicyKind.DURABILITY)


class WheelForceNode(NodeHealth, LifecycleNode):
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
        # Every override is declared at once, so that the node can tell which names it was
        # given (public API); its own parameters are then declared again with descriptors.
        super().__init__(NODE_NAME, automatically_declare_parameters_from_overrides=True,
                         **node_options)
        given = tuple(self.list_parameters([], 0).names)
        try:
            self._params = params = declare_node_parameters(self)
        except WheelForceError:
            self.destroy_node()
            raise
        if params.flush_timeout_s != _default('flush_timeout_s'):
            self.get_logger().warning(
                'parameter flush_timeout_s is deprecated and ignored: a pause of the input '
                'keeps the filter (the look-ahead is completed at a gap in the stamps, a stamp '
                'jump, deactivate or shutdown); stale input is stale_timeout_samples')
        for name in DEPRECATED_QOS_PARAMETERS:
            if getattr(params, name) != _default(name):
                self.get_logger().warning(
                    f'parameter {name} is deprecated: use the standard '
                    f'qos_overrides.<topic>.<publisher|subscription>.<policy> parameters '
                    f'(they win where both are given)')
        entities = ([(self.resolve_topic_name(t), 'subscription')
                     for t in params.imu_topics + (params.event_topic, params.travel_topic)]
                    + [(self.resolve_topic_name(t), 'publisher')
                       for t in params.output_topics + (params.damage_topic,
                                                        DIAGNOSTICS_TOPIC)])
        #: Names the node was given that mean nothing to it (typos), warned at start.
        self.unknown_parameters = unknown_parameters(given, entities)
        for name in self.unknown_parameters:
            self.get_logger().warning(
                f'parameter {name!r} (params file or -p) is not a parameter of this node: '
                f'ignored (typo?)')
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        #: Why the last configure failed (``None`` after a success).
        self.configure_error = None
        #: Imu messages taken from DDS (all corners).
        self.messages_taken = 0
        self._active = False
        self._starting = False
        self._model = None
        self._subs = []
        self._own_timers = []
        self._trigger_services = [
            self.create_service(Trigger, '~/reset_damage', self._on_reset_damage),
            self.create_service(Trigger, '~/reload_model', self._on_reload_model)]

    # -- life cycle --------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load and check the model, make the estimation chain and the publishers."""
        try:
            model, layout, stream = self._load(self._params.model_path)
        except WheelForceError as err:
            self.configure_error = err
            if not self._starting:          # at start, main() says it in one line
                self.get_logger().error(f'configure failed: {err}')
            return TransitionCallbackReturn.FAILURE
        self.configure_error = None
        self._setup(model, layout, stream)
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Subscribe the inputs and start the timers."""
        self._subscribe()
        self._active = True
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Complete the estimates in flight, publish them and the damage, unsubscribe."""
        self._stop()
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release the model and the publishers."""
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Finish as a deactivate would, then release."""
        if self._active:
            self._stop()
        if self._model is not None:
            self._release()
        return TransitionCallbackReturn.SUCCESS

    @property
    def active(self) -> bool:
        """Return whether the node is in the active state (subscribed and publishing)."""
        return self._active

    def start(self) -> bool:
        """
        Configure and activate (``autostart``).

        Returns
        -------
        bool
            False when configure failed (:attr:`configure_error` says why).

        """
        self._starting = True
        try:
            configured = self.trigger_configure() == TransitionCallbackReturn.SUCCESS
        finally:
            self._starting = False
        if configured:
            self.trigger_activate()
        return configured

    def _load(self, model_path: str):
        """Return (model, layout, stream) for ``model_path``, checked; raise WheelForceError."""
        model, layout, stream = load_chain(self._params, model_path)
        if stream.fallback:
            # Once per load: the model predates the live estimator (issue 16).
            self.get_logger().warning(f'{model_path}: {stream.fallback}')
        return model, layout, stream

    def _setup(self, model, layout, stream):
        params = self._params
        self._layout = layout
        self._stream = stream
        self._fs_hz = model.fs_hz
        self._model = model
        # with spin inputs a fifth stream: the JointState wheel spin rates (4 values)
        self._spin = layout.spin
        n = len(CORNERS)
        self._imu_names = [self.resolve_topic_name(t) for t in params.imu_topics]
        # names of the aligned streams, for messages (the Imu topics, then the JointState one)
        self._input_names = self._imu_names + (
            [self.resolve_topic_name(params.travel_topic)] if layout.spin else [])
        self._intake = Intake(layout, params, model.fs_hz, self._input_names, self.get_logger())
        # the subscriptions' callbacks append the serialized messages here
        self._raw = self._intake.raw
        self._stale_s = params.stale_timeout_samples / model.fs_hz
        self._queued = 0                  # stream samples waiting for their block
        self._last_input_s = None
        self._input_since_tick = False
        self._final_sent_for = None       # samples_out at the last end-of-stream report
        self._paused_at = None            # samples_out when the input was last seen stopping
        # worst offset out of tolerance per stream
        self._sync_offset_ns = np.zeros(len(self._input_names), dtype=np.int64)
        self._off_reported = np.zeros(n, dtype=np.int64)     # out-of-tolerance at last health
        self._damage_messages = 0
        self._wrong_types = [''] * n
        self._event = ''
        # Without moments in the model the torque is unknown: 0 (default) or NaN.
        self._nan_torque = layout.torque_rows is None and params.unknown_torque == 'nan'
        out_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=params.output_qos_depth,
                             reliability=ReliabilityPolicy.RELIABLE)
        # Every publisher and subscription takes the standard qos_overrides.* parameters.
        qos_opts = QoSOverridingOptions(policy_kinds=QOS_OVERRIDE_POLICIES)
        self._pubs = [self.create_publisher(WrenchStamped, topic, out_qos,
                                            qos_overriding_options=qos_opts)
                      for topic in params.output_topics]
        self._output = PacedOutput([pub.publish for pub in self._pubs], model.fs_hz,
                                   2 * params.block_size)
        self._damage_pub = self.create_publisher(DiagnosticArray, params.damage_topic, 10,
                                                 qos_overriding_options=qos_opts)
        self._health_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10,
                                                 qos_overriding_options=qos_opts)
        delay = stream.delay_samples
        self.get_logger().info(
            f'{self.get_fully_qualified_name()}: model {params.model_path}: '
            f'{model.fs_hz:g} Hz, block {params.block_size} samples '
            f'({params.block_size / model.fs_hz * 1e3:.0f} ms), look-ahead {delay} samples '
            f'({delay / model.fs_hz * 1e3:.0f} ms), sync tolerance '
            f'{layout.sync_tolerance_ns * 1e-6:.3f} ms; inputs {", ".join(self._input_names)} '
            f'({params.input_reliability} unless qos_overrides); outputs '
            f'{", ".join(pub.topic_name for pub in self._pubs)} (frames '
            f'{", ".join(params.frame_ids)}); damage {self._damage_pub.topic_name}; '
            f'events {self.resolve_topic_name(params.event_topic)}; '
            f'health {self._health_pub.topic_name}')

    def _subscribe(self):
        params = self._params
        in_qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=params.input_qos_depth,
            reliability=(ReliabilityPolicy.RELIABLE if params.input_reliability == 'reliable'
                         else ReliabilityPolicy.BEST_EFFORT))
        qos_opts = QoSOverridingOptions(policy_kinds=QOS_OVERRIDE_POLICIES)
        self._subs = [self.create_subscription(Imu, topic, self._imu_callback(c), in_qos,
                                               raw=True, qos_overriding_options=qos_opts)
                      for c, topic in enumerate(params.imu_topics)]
        if self._spin:
            self._subs.append(self.create_subscription(
                JointState, params.travel_topic, self._on_joint_state, in_qos,
                qos_overriding_options=qos_opts))
        # Best effort matches reliable and best-effort event publishers alike.
        self._subs.append(self.create_subscription(
            String, params.event_topic, self._on_event,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
            qos_overriding_options=qos_opts))
        self._housekeeping = self.create_timer(HOUSEKEEPING_PERIOD_S, self._on_housekeeping,
                                               clock=self._steady)
        self._health_timer = self.create_timer(DIAGNOSTICS_PERIOD_S, self._publish_health,
                                               clock=self._steady)
        # Paces what waits when no input arrives (a tail): one sample per sample period.
        self._idle_timer = self.create_timer(1.0 / self._fs_hz, self._on_idle_tick,
                                             clock=self._steady, autostart=False)
        self._own_timers = [self._housekeeping, self._health_timer, self._idle_timer]
        self.get_logger().info('active: inputs subscribed')

    def _stop(self):
        """Deactivate: take what is buffered, complete and publish everything, unsubscribe."""
        for sub in self._subs:
            self.destroy_subscription(sub)
        for timer in self._own_timers:
            self.destroy_timer(timer)
        self._subs, self._own_timers = [], []
        if any(self._raw):
            self._process(time.monotonic())
        self._end_of_stream('deactivated', always=True)
        self._output.drain(SHUTDOWN_TAIL_S)
        self._publish_health()
        self._active = False

    def _release(self):
        for pub in self._pubs + [self._damage_pub, self._health_pub]:
            self.destroy_publisher(pub)
        self._pubs = []
        self._model = self._stream = self._output = None
        self.get_logger().info('cleaned up: model released')

    # -- services ----------------------------------------------------------------------------

    def _on_reset_damage(self, request, response):
        """``~/reset_damage``: publish the final damage of the run, then count from zero."""
        if not self._active:
            response.success = False
            response.message = 'not active: nothing changed'
            return response
        if any(self._raw):
            self._process(time.monotonic())
        final = self._stream.reset_damage()
        if final is not None:
            self._publish_damage(final)
        self._final_sent_for = None
        response.success = True
        response.message = ('damage run ended at ' + (
            f'{final.stamp_ns} ns after {final.n_samples} estimate(s) (published on '
            f'{self._damage_pub.topic_name})' if final is not None else 'no estimate yet')
            + '; counting from zero')
        self.get_logger().info(f'reset_damage: {response.message}')
        return response

    def _on_reload_model(self, request, response):
        """``~/reload_model``: read ``model_path`` again; keep the old model on failure."""
        if self._model is None:
            response.success = False
            response.message = 'not configured: configure loads the model'
            return response
        path = str(self.get_parameter('model_path').value)
        try:
            model, layout, stream = self._load(path)
            if model.fs_hz != self._fs_hz:
                raise ModelFileError(f'{path}: sample rate {model.fs_hz:g} Hz differs from '
                                     f'that of the running model, {self._fs_hz:g} Hz: '
                                     f'reconfigure')
            if layout.inputs != self._layout.inputs:
                # the subscriptions and the alignment are made for the running model's inputs
                raise ModelFileError(
                    f'{path}: its inputs (angular rates: {layout.rates}, wheel spin: '
                    f'{layout.spin}) differ from those of the running model (angular rates: '
                    f'{self._layout.rates}, wheel spin: {self._layout.spin}): reconfigure')
        except WheelForceError as err:
            response.success = False
            response.message = f'{err}; the old model keeps running'
            self.get_logger().error(f'reload_model: {response.message}')
            return response
        if any(self._raw):
            self._process(time.monotonic())
        # The old model completes what it has in flight; the new one starts afresh.
        self._end_of_stream(f'reload_model {path}', always=True)
        self._params = dataclasses.replace(self._params, model_path=path)
        self._model, self._layout, self._stream = model, layout, stream
        self._nan_torque = (layout.torque_rows is None
                            and self._params.unknown_torque == 'nan')
        self._final_sent_for = None
        response.success = True
        response.message = f'model {path} loaded; estimates in flight completed by the old one'
        self.get_logger().info(f'reload_model: {response.message}')
        return response

    # -- callbacks ---------------------------------------------------------------------------

    def _imu_callback(self, corner: int):
        buf = self._raw[corner]
        raws = self._raw
        block = self._params.block_size

        def on_imu(raw: bytes):
            buf.append(raw)
            self.messages_taken += 1
            self._input_since_tick = True
            # A block can only complete once every corner has delivered enough messages.
            if self._queued + min(map(len, raws)) >= block:
                self._process(time.monotonic())
            if self._output.waiting:
                self._output.on_message(time.monotonic())
        return on_imu

    def _on_joint_state(self, msg: JointState):
        raws = self._raw
        raws[-1].append(msg)
        self.messages_taken += 1
        self._input_since_tick = True
        # not paced here: the pacing credits a quarter sample per Imu message
        if self._queued + min(map(len, raws)) >= self._params.block_size:
            self._process(time.monotonic())

    def _on_event(self, msg: String):
        self._event = msg.data
        if not self._params.damage_per_event:
            return
        # The event carries no stamp: the new run starts after the newest sample received.
        if any(self._raw):
            self._process(time.monotonic())
        lasts = [self._intake.aligner.last_stamp_ns(c) for c in range(len(CORNERS))]
        newest = max((t for t in lasts if t is not None), default=None)
        if newest is None:
            self._stream.split_damage(-1, msg.data)     # before any data: the first run
        else:
            self._stream.split_damage(newest + self._layout.sync_tolerance_ns, msg.data)

    def _on_housekeeping(self):
        now = time.monotonic()
        had_input, self._input_since_tick = self._input_since_tick, False
        if any(self._raw):
            self._process(now)
        # the Imu messages set the output rhythm (four per sample; not the JointState ones)
        self._output.measure(now, int(self._intake.received[:len(CORNERS)].sum()))
        if (self._last_input_s is not None and now - self._last_input_s > self._stale_s
                and self._paused_at != self._stream.counts['samples_in']):
            self._on_pause(now - self._last_input_s)
        if self._output.waiting and not had_input and self._idle_timer.is_canceled():
            # No input to pace by (end of a replay, a stall): the model's sample rate.
            self._idle_timer.reset()

    def _on_idle_tick(self):
        if self._output.waiting and not self._input_since_tick:
            self._output.on_idle(time.monotonic())
        else:
            self._idle_timer.cancel()

    # -- processing --------------------------------------------------------------------------

    def _process(self, now: float):
        for event in self._intake.take(now):
            if isinstance(event, AlignedSamples):
                self._stream.feed(event.stamp_ns, self._intake.model_inputs(event.accel_mps2))
                self._last_input_s = now
            elif isinstance(event, OutOfTolerance):
                self._on_out_of_tolerance(event)
            else:
                self.get_logger().warning(
                    f'stamps went back to {event.stamp_ns} ns (recording restarted?): '
                    f'estimates in flight completed, filter and damage restarted')
                self._stream.restart()
        self._queued = self._stream.queued
        self._collect(now)

    def _collect(self, now: float, tail: bool = False):
        """Queue what the stream emitted; log its breaks; publish its damage reports."""
        for brk in self._stream.take_breaks():
            self.get_logger().warning(
                f'input {"gap" if brk.kind == "gap" else "clock fault"}: {brk}; estimates in '
                f'flight completed, filter restarted')
        self._enqueue(*self._stream.take(), now, tail)
        for report in self._stream.take_damage_reports():
            self._publish_damage(report)

    def _on_out_of_tolerance(self, event: OutOfTolerance):
        c = event.corner
        self._sync_offset_ns[c] = max(self._sync_offset_ns[c], event.offset_ns)
        total = int(self._intake.aligner.counters()['out_of_tolerance'][c])
        self.get_logger().warning(
            f'{self._input_names[c]}: dropped {event.n_messages} message(s) whose stamps no '
            f'other corner matched within sync_tolerance_s '
            f'({self._layout.sync_tolerance_ns * 1e-9:g} s), first stamped '
            f'{event.first_stamp_ns} ns, offset {event.offset_ns * 1e-6:.3f} ms from the '
            f'nearest sample of the others (total {total}): are the loggers clocks '
            f'synchronised?', throttle_duration_sec=WARN_THROTTLE_S)

    def _on_pause(self, silent_s: float):
        """
        No input for ``stale_timeout_samples``: report the damage so far, keep the filter.

        The look-ahead stays in the filter: the data may resume without a gap in the stamps
        (a paused replay, a DAQ hiccup), and then every estimate is exactly the offline one.
        """
        self._paused_at = self._stream.counts['samples_in']
        samples_out = self._stream.counts['samples_out']
        if self._final_sent_for != samples_out:
            self._final_sent_for = samples_out
            final = self._stream.final_damage_report()
            if final is not None:
                self._publish_damage(final)
        self.get_logger().info(
            f'no input for {silent_s:.2f} s: {self._stream.in_flight} estimate(s) held for '
            f'the look-ahead until the data resumes (a gap in the stamps, a stamp jump, '
            f'deactivate or shutdown completes them); {self.summary()}')

    def _end_of_stream(self, why: str = '', always: bool = False):
        """Input stopped (or shutdown): flush the look-ahead, report damage, log counters."""
        self._stream.flush()
        self._queued = self._stream.queued
        self._collect(time.monotonic(), tail=True)
        samples_out = self._stream.counts['samples_out']
        if always or self._final_sent_for != samples_out:
            self._final_sent_for = samples_out
            final = self._stream.final_damage_report()
            if final is not None:
                self._publish_damage(final)
            if why:
                self.get_logger().info(f'{why}: estimates in flight completed; '
                                       f'{self.summary()}')

    def _enqueue(self, stamp_ns: np.ndarray, force_n: np.ndarray, ready_s: float,
                 tail: bool):
        if stamp_ns.size == 0:
            return
        layout = self._layout
        blobs = []
        for c, frame in enumerate(self._params.frame_ids):
            if layout.torque_rows is not None:
                torque = force_n[list(layout.torque_rows[c])]
            elif self._nan_torque:
                torque = np.full((3, stamp_ns.size), np.nan)
            else:
                torque = None
            blobs.append(encode_wrench(stamp_ns, force_n[list(layout.force_rows[c])], frame,
                                       torque))
        # A tail (flushed after the input stopped) has no input to pace it: it leaves at the
        # model's rate and is left out of the pacing latency, which measures steady running.
        self._output.add(blobs, None if tail else ready_s)

    def finish(self):
        """
        Shutdown: take what is buffered, flush, publish everything, wait for the acks.

        The tail leaves paced, at the model's sample rate or faster so that it takes at most
        :data:`SHUTDOWN_TAIL_S`; then every publisher's acknowledgements are awaited against
        one deadline, :data:`SHUTDOWN_ACK_S` in all.
        """
        if self._active:
            self._stop()
        if self._model is None:
            return
        deadline = time.monotonic() + SHUTDOWN_ACK_S
        pending = self._pubs + [self._damage_pub, self._health_pub]
        while pending and time.monotonic() < deadline:
            # Short slices: a second SIGINT is handled between them, not after the wait.
            pending = [pub for pub in pending
                       if not pub.wait_for_all_acked(Duration(seconds=_ACK_SLICE_S))]
        if pending:
            self.get_logger().warning(
                f'{", ".join(pub.topic_name for pub in pending)}: not every subscriber '
                f'acknowledged the last messages within {SHUTDOWN_ACK_S:g} s (a stalled '
                f'reliable subscriber?)')

    @property
    def waiting(self) -> int:
        """Return the estimates not published yet: held for the look-ahead or paced [samples]."""
        if self._model is None:
            return 0
        return self._stream.in_flight + self._output.waiting
