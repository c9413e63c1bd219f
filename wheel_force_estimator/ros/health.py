# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
What ``wheel_force_node`` reports: counters, staleness, the damage and ``/diagnostics`` messages.

:class:`NodeHealth` is the reporting half of :class:`~.node.WheelForceNode` (a mixin: it reads
the node's state, never changes the estimation).  Message layouts are :mod:`.diagnostics`'s;
what each field means for a user is in ``docs/logger_graph.md``.
"""
import time

import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator.ros.diagnostics import build_damage_array
from wheel_force_estimator.ros.diagnostics import build_health_array
from wheel_force_estimator.ros.diagnostics import corner_level
from wheel_force_estimator.ros.diagnostics import CornerReport
from wheel_force_estimator.ros.diagnostics import ERROR
from wheel_force_estimator.ros.diagnostics import OK
from wheel_force_estimator.ros.diagnostics import WARN

IMU_TYPE = 'sensor_msgs/msg/Imu'
#: Throttle of repeated fault warnings [s].
WARN_THROTTLE_S = 5.0
#: Why a decoded message is dropped before alignment (per-corner counters).
DROP_REASONS = ('malformed', 'wrong_frame', 'nonfinite', 'no_angular_rate')


class NodeHealth:
    """Counters, staleness and the damage / health messages of the node (see the module)."""

    def stale_reasons(self, now: float):
        """Return, per corner, why its input is stale (``''`` when it is not)."""
        reasons = []
        aligner = self._intake.aligner
        lasts = [aligner.last_stamp_ns(c) for c in range(len(CORNERS))]
        newest = max((s for s in lasts if s is not None), default=None)
        limit_ns = self._params.stale_timeout_samples * 1e9 / self._fs_hz
        for c in range(len(CORNERS)):
            rx = self._intake.last_rx_s[c]
            wrong = (f' (publisher of type {self._wrong_types[c]} on the topic)'
                     if self._wrong_types[c] else '')
            if rx is None:
                reasons.append('no message received yet' + wrong)
            elif now - rx > self._stale_s:
                reasons.append(f'no message for {now - rx:.2f} s' + wrong)
            elif (newest is not None and lasts[c] is not None and not aligner.in_transition
                  and newest - lasts[c] > limit_ns):
                reasons.append(f'stamps {(newest - lasts[c]) * 1e-9:.2f} s behind the others')
            else:
                reasons.append('')
        return reasons

    def _stream_counters(self):
        """Return (received, dropped by reason, aligner counters) of every aligned stream."""
        align = self._intake.aligner.counters()
        dropped = {f'dropped_{reason}': self._intake.dropped[reason] for reason in DROP_REASONS}
        dropped['dropped_duplicate'] = align['duplicate']
        dropped['dropped_late'] = align['late']
        dropped['dropped_incomplete'] = align['incomplete']
        dropped['dropped_out_of_tolerance'] = align['out_of_tolerance']
        return self._intake.received, dropped, align

    def joint_state_counters(self):
        """
        Return the counters of the JointState wheel-spin stream, or ``{}`` without one.

        Keys: ``received``, ``dropped`` (all reasons) and ``dropped_<reason>`` of the
        reasons that apply to it (malformed, nonfinite, and the aligner's).
        """
        if not self._spin:
            return {}
        received, dropped, _ = self._stream_counters()
        k = len(CORNERS)
        out = {'received': int(received[k]),
               'dropped': int(sum(int(value[k]) for value in dropped.values()))}
        out.update({key: int(value[k]) for key, value in dropped.items()
                    if key not in ('dropped_wrong_frame', 'dropped_no_angular_rate')})
        return out

    def joint_state_stale(self, now: float) -> str:
        """Return why the JointState wheel-spin input is stale, ``''`` if not (or none)."""
        if not self._spin:
            return ''
        rx = self._intake.last_rx_s[len(CORNERS)]
        if rx is None:
            return 'no message received yet'
        return f'no message for {now - rx:.2f} s' if now - rx > self._stale_s else ''

    def counters(self):
        """Return the per-corner counters shown in the diagnostics (dict of name -> list)."""
        stream = self._stream.counts
        n = len(CORNERS)
        received, dropped, align = self._stream_counters()
        # the Imu corners; a JointState stream (spin models) has its own counters
        dropped = {key: value[:n] for key, value in dropped.items()}
        received = received[:n]
        align = {key: value[:n] for key, value in align.items()}
        total = sum(dropped.values())
        out = {'received': received, 'published': [self._output.published] * n,
               'dropped': total, 'gaps': [stream['gaps']] * n,
               'missing_samples': [stream['missing_samples']] * n,
               'short_steps': [stream['short_steps']] * n, 'resets': [stream['jumps']] * n}
        out.update(dropped)
        out.update({'aligned': align['aligned'], 'pending': align['pending'],
                    'sync_offset_max_us': self._sync_offset_ns[:n] // 1000,
                    'in_flight': [self._stream.in_flight + self._output.waiting] * n,
                    'flushes': [stream['flushes']] * n})
        return {key: [int(v) for v in value] for key, value in out.items()}

    def pacing_latency_ms(self):
        """Return (p50, p99, max) of the pacing latency [ms] (:meth:`.PacedOutput.latency_ms`)."""
        return self._output.latency_ms()

    def _corner_rows(self, corner: int):
        rows = list(self._layout.force_rows[corner])
        if self._layout.torque_rows is not None:
            rows += list(self._layout.torque_rows[corner])
        return rows

    def _corner_damage(self, corner: int, damage: np.ndarray):
        """Return ``((key, damage), ...)`` of one corner's channels (``fx`` ...)."""
        names = self._model.output_channels
        return tuple((names[r].split('_', 1)[1], float(damage[r]))
                     for r in self._corner_rows(corner))

    def _health_stamp_ns(self) -> int:
        """Return the ROS time, or the steady clock while the ROS clock is not running."""
        ros_ns = self.get_clock().now().nanoseconds
        return ros_ns if ros_ns > 0 else self._steady.now().nanoseconds

    def _publish_damage(self, report):
        stale = self.stale_reasons(time.monotonic())
        reports = []
        for c, corner in enumerate(CORNERS):
            rows = self._corner_rows(c)
            pairs = self._corner_damage(c, report.damage)
            extra = (('samples', report.n_samples),)
            if self._params.damage_per_event:
                extra += (('event', report.run),)
            reports.append(CornerReport(corner, pairs,
                                        float(max(report.rate_per_s[rows].max(), 0.0)),
                                        stale[c], extra))
        budget = float(self.get_parameter('damage_budget').value)
        self._damage_pub.publish(build_damage_array(
            reports, self.get_fully_qualified_name(), report.stamp_ns, budget))
        self._damage_messages += 1

    def _check_input_types(self):
        """Log once per topic and type when a publisher of another type uses an input topic."""
        for c, topic in enumerate(self._imu_names):
            try:
                infos = self.get_publishers_info_by_topic(topic)
            except RuntimeError:       # rclpy's RCLError: the graph is not available
                continue
            types = sorted({i.topic_type for i in infos} - {IMU_TYPE})
            found = ', '.join(types)
            if found and found != self._wrong_types[c]:
                self.get_logger().error(
                    f'{topic}: publisher(s) of type {found} found; this node subscribes '
                    f'{IMU_TYPE} there, so corner {CORNERS[c]} gets no data (reported stale; '
                    f'the other corners keep running). Remap the topic to the Imu one.')
            self._wrong_types[c] = found

    def _publish_health(self):
        self._check_input_types()
        now = time.monotonic()
        stale = self.stale_reasons(now)
        counters = self.counters()
        budget = float(self.get_parameter('damage_budget').value)
        damage = self._stream.damage()
        off_now = np.asarray(counters['dropped_out_of_tolerance'])
        off_new = off_now - self._off_reported
        self._off_reported = off_now
        corners = []
        for c, corner in enumerate(CORNERS):
            level, text = corner_level(self._corner_damage(c, damage), budget, stale[c])
            if off_new[c]:
                level = max(level, WARN)
                text = (f'{off_new[c]} stamp(s) outside sync_tolerance_s (worst offset '
                        f'{counters["sync_offset_max_us"][c] * 1e-3:.3f} ms)'
                        + ('' if text == 'ok' else '; ' + text))
            values = [('topic', self._imu_names[c]), ('stale', 'true' if stale[c] else 'false')]
            values += [(key, value[c]) for key, value in counters.items()]
            corners.append((corner, level, text, values))
        p50, p99, worst = self.pacing_latency_ms()
        stream = self._stream.counts
        if all(stale):
            node_level, node_text = WARN, 'no input'
        elif any(stale):
            node_level, node_text = WARN, 'input stale on ' + ', '.join(
                corner for corner, why in zip(CORNERS, stale) if why)
        else:
            node_level, node_text = OK, 'running'
        joint_stale = self.joint_state_stale(now)
        if joint_stale:
            # no spin, no sample: the model's wheel spin input is missing
            node_level = max(node_level, WARN)
            node_text = (f'wheel spin input {self._input_names[-1]} stale ({joint_stale})'
                         + ('' if node_text == 'running' else '; ' + node_text))
        over = [corner for corner, level, _, _ in corners if level == ERROR]
        if over:
            node_level = ERROR
            node_text = 'damage budget exceeded on ' + ', '.join(over)
        if any(self._wrong_types):
            node_level = ERROR
            node_text = 'input topic with the wrong message type'
        values = [('model', self._params.model_path), ('sample_rate_hz', f'{self._fs_hz:g}'),
                  ('block_size', self._params.block_size),
                  ('look_ahead_samples', self._stream.delay_samples),
                  ('sync_tolerance_s', f'{self._layout.sync_tolerance_ns * 1e-9:g}'),
                  ('samples_in', stream['samples_in']), ('samples_out', stream['samples_out']),
                  ('published', self._output.published), ('waiting', self._output.waiting),
                  ('gaps', stream['gaps']), ('missing_samples', stream['missing_samples']),
                  ('flushes', stream['flushes']), ('resets', stream['jumps']),
                  ('damage_messages', self._damage_messages), ('damage_budget', f'{budget:g}'),
                  ('pacing_latency_p50_ms', f'{p50:.2f}'),
                  ('pacing_latency_p99_ms', f'{p99:.2f}'),
                  ('pacing_latency_max_ms', f'{worst:.2f}'), ('event', self._event)]
        joints = self.joint_state_counters()
        if joints:
            values += [('joint_states_topic', self._input_names[-1])]
            values += [(f'joint_states_{key}', value) for key, value in joints.items()]
            # gap-free stretches of one sample: no spin derivative, no estimate
            values += [('single_samples', stream['single_samples'])]
        self._health_pub.publish(build_health_array(
            self.get_fully_qualified_name(), self._health_stamp_ns(), corners,
            (node_level, node_text, values)))
        if any(stale):
            self.get_logger().warning(
                'stale input: ' + '; '.join(f'{self._imu_names[c]} {why}'
                                            for c, why in enumerate(stale) if why),
                throttle_duration_sec=WARN_THROTTLE_S)

    def summary(self) -> str:
        """Return the counters and the pacing latency as one line."""
        if self._model is None:
            return 'not configured: no counters'
        counters = self.counters()
        text = ', '.join(f'{key}={value}' for key, value in counters.items())
        joints = self.joint_state_counters()
        if joints:
            text += '; JointState ' + ', '.join(f'{key}={value}'
                                                for key, value in joints.items())
        p50, p99, worst = self.pacing_latency_ms()
        return (f'counters per corner (lf, rf, lr, rr): {text}; pacing latency p50 '
                f'{p50:.1f} ms, p99 {p99:.1f} ms, max {worst:.1f} ms')
