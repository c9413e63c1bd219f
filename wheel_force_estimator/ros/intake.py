# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live node's inputs: serialized messages in, aligned model-input samples out.

The subscriptions' callbacks only append the serialized bytes of each message to its stream's
list in :attr:`Intake.raw` (the four ``sensor_msgs/Imu`` corners, then, for a model with wheel
spin inputs, the ``sensor_msgs/JointState`` messages).  :meth:`Intake.take` decodes what is
buffered with numpy (:mod:`..bagio.cdr`, :mod:`.joints`), drops and counts what is malformed,
has the wrong ``frame_id``, holds NaN/inf or lacks the angular rates a model needs (each with
a warning naming the topic, throttled), and aligns the streams on ``header.stamp``
(:class:`.aligner.CornerAligner`); :meth:`Intake.model_inputs` orders an aligned sample's
values as the model's input rows.
"""
import time

import numpy as np

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio.cdr import decode_imu
from wheel_force_estimator.ros.aligner import CornerAligner
from wheel_force_estimator.ros.health import DROP_REASONS
from wheel_force_estimator.ros.health import WARN_THROTTLE_S
from wheel_force_estimator.ros.joints import decode_wheel_spin


class Intake:
    """
    Buffered input messages, decoded, checked and aligned (see the module notes).

    Parameters
    ----------
    layout : ModelLayout
        What the model takes (:func:`.params.model_layout`): rates, spin, sync tolerance.
    params : NodeParams
        The node's parameters (frame ids, queue depth, stale timeout).
    fs_hz : float
        The model's sample rate [Hz].
    names : list of str
        The resolved topic of each stream, for messages.
    logger
        The node's logger (``warning`` / ``error`` with ``throttle_duration_sec``).

    Attributes
    ----------
    raw : list of list
        Per stream, the messages not taken yet (the callbacks append to these lists).
    aligner : CornerAligner
        The alignment on ``header.stamp`` (its counters and last stamps).
    received : numpy.ndarray of int64
        Messages taken per stream.
    dropped : dict of str to numpy.ndarray
        Messages dropped per stream, by reason (:data:`.health.DROP_REASONS`).
    last_rx_s : list
        Per stream, when messages were last taken (steady clock, ``None`` before any) [s].

    """

    def __init__(self, layout, params, fs_hz: float, names, logger):
        n = len(CORNERS)
        n_streams = n + (1 if layout.spin else 0)
        # with angular-rate inputs each corner's sample is 6 values: acceleration, then rates
        self._rates = layout.rates
        self._spin = layout.spin
        self._frame_ids = params.imu_frame_ids if any(params.imu_frame_ids) else None
        self._names = list(names)
        self._logger = logger
        self._rate_error_s = {}           # corner -> when its missing rates were last logged
        self.aligner = CornerAligner(
            n_streams, (6 if layout.rates else 3,) * n + ((n,) if layout.spin else ()),
            max(params.input_qos_depth, params.stale_timeout_samples, 64),
            tolerance_ns=layout.sync_tolerance_ns, period_ns=1e9 / fs_hz)
        self.raw = [[] for _ in range(n_streams)]
        self.received = np.zeros(n_streams, dtype=np.int64)
        self.dropped = {reason: np.zeros(n_streams, dtype=np.int64) for reason in DROP_REASONS}
        self.last_rx_s = [None] * n_streams

    def take(self, now: float) -> list:
        """
        Take every buffered message and return the aligner's events since the last call.

        ``now`` is the steady-clock time of the call [s].  Events: ``AlignedSamples``,
        ``OutOfTolerance`` and stamp jumps (:meth:`.aligner.CornerAligner.drain`).
        """
        batches = []
        for buf in self.raw:
            batches.append(buf[:])
            buf.clear()
        joint_msgs = batches.pop() if self._spin else []
        counts = [len(b) for b in batches]
        if self._frame_ids is not None:
            decoded = [decode_imu(b, self._frame_ids[c], self._rates) if b else None
                       for c, b in enumerate(batches)]
        else:
            whole = decode_imu([raw for b in batches for raw in b], rates=self._rates)
            decoded, lo = [], 0
            for n in counts:
                decoded.append(whole.sliced(lo, lo + n) if n else None)
                lo += n
        if joint_msgs:
            decoded.append(decode_wheel_spin(joint_msgs))
            counts.append(len(joint_msgs))
        for c, d in enumerate(decoded):
            if d is None:
                continue
            self.received[c] += counts[c]
            self.last_rx_s[c] = now
            valid = d.valid
            if not valid.all():
                self._count_drops(c, d)
                self.aligner.push(c, d.stamp_ns[valid], d.values()[:, valid])
            else:
                self.aligner.push(c, d.stamp_ns, d.values())
        return list(self.aligner.drain())

    def model_inputs(self, values: np.ndarray) -> np.ndarray:
        """
        Return the model's inputs from aligned corner values.

        Corner-major rows: 3 accelerations per corner, or 3 accelerations and 3 angular
        rates per corner for a model with rates, whose inputs are the 12 accelerations,
        then the 12 rates; then, for a model with spin, the 4 wheel spin rates (the stream
        differentiates them to the model's spin accelerations).
        """
        if not self._rates:
            return values
        n_imu = 6 * len(CORNERS)
        per = values[:n_imu].reshape(len(CORNERS), 6, -1)
        return np.concatenate([per[:, :3].reshape(12, -1), per[:, 3:].reshape(12, -1),
                               values[n_imu:]])

    def _count_drops(self, corner: int, decoded):
        topic = self._names[corner]
        for reason in DROP_REASONS:
            mask = getattr(decoded, reason)
            n = 0 if mask is None else int(mask.sum())
            if n and reason == 'no_angular_rate':
                self.dropped[reason][corner] += n
                # the model needs the rates: an error, never zeros (REP-145 "not provided");
                # throttled per topic, so every corner at fault is named
                now = time.monotonic()
                last = self._rate_error_s.get(corner)
                if last is None or now - last >= WARN_THROTTLE_S:
                    self._rate_error_s[corner] = now
                    self._logger.error(
                        f'{topic}: {n} message(s) without angular velocity (covariance[0] = '
                        f'-1, first stamped {int(decoded.stamp_ns[int(np.argmax(mask))])} ns);'
                        ' the model needs the spindle angular rates: those samples are dropped'
                        f' (total {int(self.dropped[reason][corner])})')
            elif n:
                self.dropped[reason][corner] += n
                first = int(np.argmax(mask))
                self._logger.warning(
                    f'{topic}: dropped {n} {reason.replace("_", " ")} message(s), first '
                    f'stamped {int(decoded.stamp_ns[first])} ns (total '
                    f'{int(self.dropped[reason][corner])})',
                    throttle_duration_sec=WARN_THROTTLE_S)
