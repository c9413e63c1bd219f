# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The wheel spin rates of ``sensor_msgs/JointState`` messages, for the node (six components).

A model with spin inputs needs the ``velocity`` of the joints ``{corner}_wheel`` [rad/s]
(DESIGN.md; the topic is the node's ``travel_topic``, ``suspension/joint_states``, which may
carry the ``{corner}_suspension`` travel joints as well).  Joints are matched by name, in any
order.  A message that cannot give all four is **malformed** (a wheel joint missing, a name
twice, fewer velocities than names) and one whose wheel velocities are NaN or infinite is
**nonfinite**: both are dropped and counted by the node, never repaired, and the node keeps
running (the aligner then finds that sample incomplete: a gap, as a missing Imu message
makes one).  The velocities of other joints are not looked at (a logger leaves the
suspension velocities NaN).
"""
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from wheel_force_estimator.bagio.travel import WHEEL_JOINT_NAMES

_NS_PER_S = 1_000_000_000


@dataclass(frozen=True, eq=False)
class DecodedSpin:
    """
    The wheel spin of a batch of JointState messages, in arrival order.

    Attributes
    ----------
    stamp_ns : numpy.ndarray, shape (n,), int64
        ``header.stamp`` [ns].
    spin_radps : numpy.ndarray, shape (4, n), float64
        ``velocity`` of ``lf_wheel`` ... ``rr_wheel`` [rad/s] (NaN where malformed).
    malformed : numpy.ndarray, shape (n,), bool
        A wheel joint missing, a joint named twice, or fewer velocities than names.
    nonfinite : numpy.ndarray, shape (n,), bool
        A well-formed message with a NaN or infinite wheel velocity.
    wrong_frame, no_angular_rate : None
        Not applicable (the node's drop reasons of an Imu message).

    """

    stamp_ns: np.ndarray
    spin_radps: np.ndarray
    malformed: np.ndarray
    nonfinite: np.ndarray
    wrong_frame: Optional[np.ndarray] = None
    no_angular_rate: Optional[np.ndarray] = None

    @property
    def valid(self) -> np.ndarray:
        """Messages that are usable samples."""
        return ~(self.malformed | self.nonfinite)

    def values(self) -> np.ndarray:
        """Return the spin rates, (4, n) [rad/s]."""
        return self.spin_radps


def decode_wheel_spin(msgs: Sequence) -> DecodedSpin:
    """
    Return the wheel spin of JointState messages (see the module notes).

    Parameters
    ----------
    msgs : sequence of sensor_msgs.msg.JointState
        Messages, in arrival order.

    Returns
    -------
    DecodedSpin

    """
    n = len(msgs)
    stamps = np.zeros(n, dtype=np.int64)
    spin = np.full((len(WHEEL_JOINT_NAMES), n), np.nan)
    malformed = np.zeros(n, dtype=bool)
    for i, msg in enumerate(msgs):
        stamp = msg.header.stamp
        stamps[i] = int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)
        names = list(msg.name)
        velocity = msg.velocity
        if len(velocity) < len(names) or len(set(names)) != len(names):
            malformed[i] = True
            continue
        try:
            spin[:, i] = [velocity[names.index(joint)] for joint in WHEEL_JOINT_NAMES]
        except ValueError:       # a wheel joint missing
            malformed[i] = True
    nonfinite = ~malformed & ~np.isfinite(spin).all(axis=0)
    return DecodedSpin(stamps, spin, malformed, nonfinite)
