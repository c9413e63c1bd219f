# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``diagnostic_msgs/DiagnosticArray`` messages of the node (DESIGN.md).

**Damage** (the node's damage topic, one message per ``damage_publish_period_s`` of data
time): one ``DiagnosticStatus`` per corner, ``name`` = ``virtual_wft/{corner}``,
``hardware_id`` = the node's fully qualified name, ``values`` = the accumulated pseudo damage
of each output channel of the corner (``fx``, ``fy``, ``fz`` [, ``mx`` ...], ``repr`` of the
float so it reads back exactly), then ``damage_rate_per_s``.  The header stamp is the
data-time boundary the damage is counted up to.  Level: ERROR when a channel exceeds the
damage budget, WARN from :data:`BUDGET_WARN_FRACTION` of it or when the corner's input is
stale, else OK.

**Health** (``/diagnostics``, what ``diagnostic_aggregator`` and ``rqt_robot_monitor`` read,
on a steady-clock period): one status per corner, ``name`` = ``{node}: {corner}``, with the
input topic, the counters and staleness, and one status ``{node}`` for the node itself
(model, latency, totals); ``{node}`` is the node's **fully qualified** name
(``/car2/wheel_force_node``), so two cars launched from one launch file never share a status
name in the aggregator.  ``hardware_id`` is the same name.  A corner's level is the damage
budget's (as on the damage topic), WARN when its input is stale or stamps fell outside the
sync tolerance since the last message; the node's is ERROR when a corner exceeds the
budget.  The header stamp is the ROS time, or the steady clock while the ROS clock is not
running (``use_sim_time`` before the first ``/clock``).
"""
from dataclasses import dataclass
from typing import Mapping, Sequence, Tuple

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue

#: Fraction of ``damage_budget`` from which a corner is reported WARN.
BUDGET_WARN_FRACTION = 0.8
OK, WARN, ERROR = 0, 1, 2
_LEVEL_BYTES = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN,
                ERROR: DiagnosticStatus.ERROR}


@dataclass(frozen=True)
class CornerReport:
    """
    What one corner's status says.

    Attributes
    ----------
    corner : str
        Corner name (``lf`` ...).
    damage : tuple of (str, float)
        ``(key, pseudo damage)`` per output channel of the corner (``fx`` ...) [N^k].
    rate_per_s : float
        Highest channel damage increase per second of signal over the last period [N^k/s].
    stale : str
        Why the input is stale, or ``''``.
    counters : tuple of (str, int or str)
        Further key/value pairs, in order (the damage message: ``samples``, the number of
        estimates the damage covers).

    """

    corner: str
    damage: Tuple[Tuple[str, float], ...]
    rate_per_s: float
    stale: str
    counters: Tuple[Tuple[str, object], ...]


def corner_level(damage: Sequence[Tuple[str, float]], budget: float,
                 stale: str) -> Tuple[int, str]:
    """
    Return the diagnostic level and message of one corner.

    Parameters
    ----------
    damage : sequence of (str, float)
        Pseudo damage per channel key.
    budget : float
        Damage budget per channel; 0 disables the check.
    stale : str
        Reason the input is stale, ``''`` when it is not.

    Returns
    -------
    level : int
        ``OK`` (0), ``WARN`` (1) or ``ERROR`` (2).
    message : str
        Human-readable summary.

    """
    level, parts = OK, []
    if budget > 0.0 and damage:
        key, worst = max(damage, key=lambda kv: kv[1])
        if worst > budget:
            level = ERROR
            parts.append(f'damage budget exceeded: {key} {worst:.4g} > {budget:.4g}')
        elif worst >= BUDGET_WARN_FRACTION * budget:
            level = WARN
            parts.append(f'damage at {100.0 * worst / budget:.0f} % of budget ({key})')
    if stale:
        level = max(level, WARN)
        parts.append(f'stale input: {stale}')
    return level, '; '.join(parts) if parts else 'ok'


def build_damage_array(reports: Sequence[CornerReport], hardware_id: str, stamp_ns: int,
                       budget: float) -> DiagnosticArray:
    """
    Build the damage message.

    Parameters
    ----------
    reports : sequence of CornerReport
        One per corner, in corner order.
    hardware_id : str
        The node's fully qualified name.
    stamp_ns : int
        ``header.stamp`` [ns]: the data-time boundary of the damage.
    budget : float
        ``damage_budget`` (0 = off).

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray

    """
    msg = DiagnosticArray()
    msg.header.stamp = Time(sec=int(stamp_ns // 1_000_000_000),
                            nanosec=int(stamp_ns % 1_000_000_000))
    for report in reports:
        level, text = corner_level(report.damage, budget, report.stale)
        values = [KeyValue(key=key, value=repr(float(value))) for key, value in report.damage]
        values.append(KeyValue(key='damage_rate_per_s', value=repr(float(report.rate_per_s))))
        values.extend(KeyValue(key=key, value=str(value)) for key, value in report.counters)
        msg.status.append(DiagnosticStatus(
            level=_LEVEL_BYTES[level], name=f'virtual_wft/{report.corner}', message=text,
            hardware_id=hardware_id, values=values))
    return msg


def build_health_array(node_name: str, stamp_ns: int,
                       corners: Sequence[Tuple[str, int, str, Sequence[Tuple[str, object]]]],
                       node_status: Tuple[int, str, Sequence[Tuple[str, object]]]
                       ) -> DiagnosticArray:
    """
    Build the ``/diagnostics`` message.

    Parameters
    ----------
    node_name : str
        The node's fully qualified name: status names are ``{node_name}: {corner}`` and
        ``{node_name}``, ``hardware_id`` is ``node_name``.
    stamp_ns : int
        ``header.stamp`` [ns].
    corners : sequence of (corner, level, message, values)
        One per corner; ``level`` OK/WARN/ERROR (0/1/2), ``values`` key/value pairs.
    node_status : (level, message, values)
        The node's own status.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray

    """
    msg = DiagnosticArray()
    msg.header.stamp = Time(sec=int(stamp_ns // 1_000_000_000),
                            nanosec=int(stamp_ns % 1_000_000_000))
    entries = [(f'{node_name}: {corner}', level, text, values)
               for corner, level, text, values in corners]
    entries.append((node_name,) + tuple(node_status))
    for name, level, text, values in entries:
        msg.status.append(DiagnosticStatus(
            level=_LEVEL_BYTES[level], name=name, message=text, hardware_id=node_name,
            values=[KeyValue(key=str(k), value=str(v)) for k, v in values]))
    return msg


def status_values(status: DiagnosticStatus) -> Mapping[str, str]:
    """Return the key/value pairs of a status as a dict (for tools and tests)."""
    return {kv.key: kv.value for kv in status.values}
