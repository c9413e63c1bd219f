# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Topic names and frame ids of a recording, read from the ROS 2 params file.

The offline commands read the same ``/**: ros__parameters:`` section as the live node, so a
remapped topic is remapped everywhere.  Only the topic/frame keys are interpreted here; the
other node parameters are recognised (so a typo is still reported) and left to the node.

Names are relative by default (DESIGN.md), so a node started in a namespace moves with it.
Bags record resolved (absolute) names, so a :class:`TopicConfig` holds resolved names: it
resolves what it is given against its ``namespace`` (``--namespace``, default ``/``) with
:func:`resolve_name`, ROS 2's rule.  The ``DEFAULT_*`` constants here are the one home of the
default names; the node declares its parameters with them.
"""
from dataclasses import dataclass
from pathlib import Path
import re
from typing import Dict, Optional, Tuple


from wheel_force_estimator import CORNERS
from wheel_force_estimator.core.errors import ConfigError
import yaml

NODE_SECTION = 'wheel_force_node'
WILDCARD_SECTION = '/**'
#: The fit settings' section (read by cli/common.py); a file with only it is a valid config.
FIT_SECTION = 'wheel_force_fit'
# ROS 2 params files may address the node by the wildcard, plain or absolute name; like rcl,
# a section naming the node overrides the wildcard's values.
_SECTION_NAMES = (WILDCARD_SECTION, NODE_SECTION, '/' + NODE_SECTION)

# Node parameters that are valid in the section but not used by bagio.  Keep in sync with
# the node's declarations (ros/params.py PARAMETERS; test_bagio_topics checks it when rclpy is
# importable): an unknown key is reported as a typo.
NODE_ONLY_KEYS = frozenset({
    'model_path', 'imu_frame_ids', 'block_size', 'live_look_ahead_s', 'sn_slope',
    'sn_slope_moment',
    'damage_publish_period_s', 'damage_budget', 'stale_timeout_samples', 'input_qos_depth',
    'input_reliability', 'output_qos_depth', 'flush_timeout_s', 'sample_rate_hz',
    'unknown_torque', 'use_sim_time', 'sync_tolerance_s', 'autostart', 'damage_per_event',
})

DEFAULT_IMU_TOPICS = tuple(f'spindle/{c}/imu' for c in CORNERS)
DEFAULT_WFT_TOPICS = tuple(f'wft/{c}/wrench' for c in CORNERS)
DEFAULT_OUTPUT_TOPICS = tuple(f'virtual_wft/{c}/wrench' for c in CORNERS)
DEFAULT_DAMAGE_TOPIC = 'virtual_wft/damage'
DEFAULT_EVENT_TOPIC = 'proving_ground/event'
DEFAULT_TRAVEL_TOPIC = 'suspension/joint_states'
#: Non-rotating frames at the wheel centres, axes vehicle-aligned (x forward, y left, z up).
DEFAULT_FRAME_IDS = tuple(f'{c}_wheel_center' for c in CORNERS)

_TOPIC_RE = re.compile(r'^[~/]?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$')
_NAMESPACE_RE = re.compile(r'^/([A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*)?$')


def validate_namespace(namespace: str) -> str:
    """
    Return ``namespace`` as an absolute ROS namespace (``car2`` -> ``/car2``).

    Raises
    ------
    ConfigError
        Not a valid namespace (tokens of letters, digits and ``_``, separated by ``/``).

    """
    ns = namespace if namespace.startswith('/') else '/' + namespace
    ns = ns.rstrip('/') or '/'
    if not _NAMESPACE_RE.match(ns):
        raise ConfigError(f'namespace {namespace!r} is not a valid ROS namespace (e.g. /car2)')
    return ns


def resolve_name(name: str, namespace: str = '/', node_name: str = NODE_SECTION) -> str:
    """
    Resolve a topic name as ROS 2 does for a node ``node_name`` in ``namespace``.

    Absolute names (``/x``) stay; ``~/x`` is private to the node (``/ns/node/x``); any other
    name is relative to the namespace (``/ns/x``).

    Raises
    ------
    ConfigError
        An invalid namespace.

    """
    ns = validate_namespace(namespace)
    base = '' if ns == '/' else ns
    if name.startswith('/'):
        return name
    if name.startswith('~'):
        return f'{base}/{node_name}{name[1:]}'
    return f'{base}/{name}'


_FRAME_RE = re.compile(r'^[A-Za-z0-9_/.-]+$')


def _validate_topic(value, key: str, where: str) -> str:
    if not isinstance(value, str) or not _TOPIC_RE.match(value):
        raise ConfigError(f'{where}: {key} must be a valid ROS topic name, got {value!r}')
    return value


def _validate_list(value, key: str, where: str, check) -> Tuple[str, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != len(CORNERS):
        raise ConfigError(
            f'{where}: {key} must be a list of {len(CORNERS)} entries (corners '
            f'{", ".join(CORNERS)}), got {value!r}')
    return tuple(check(v, f'{key}[{i}] ({CORNERS[i]})', where) for i, v in enumerate(value))


def _validate_frame(value, key: str, where: str) -> str:
    if not isinstance(value, str) or not _FRAME_RE.match(value):
        raise ConfigError(f'{where}: {key} must be a non-empty frame id, got {value!r}')
    return value


@dataclass(frozen=True)
class TopicConfig:
    """
    Resolved topic names (one per corner, order lf, rf, lr, rr) and output frame ids.

    Names given relative (``spindle/lf/imu``) are resolved against ``namespace`` when the
    config is made, so every name it holds is absolute, as a bag records it.

    Attributes
    ----------
    imu_topics : tuple of str
        sensor_msgs/Imu input topics, one per corner.
    wft_topics : tuple of str
        geometry_msgs/WrenchStamped measured (ground truth) wheel force topics.
    output_topics : tuple of str
        geometry_msgs/WrenchStamped virtual wheel force topics (node / ``predict`` output).
    damage_topic : str
        diagnostic_msgs/DiagnosticArray pseudo damage topic.
    event_topic : str
        std_msgs/String proving-ground event topic (optional in a recording).
    travel_topic : str
        sensor_msgs/JointState suspension travel topic (optional in a recording).
    frame_ids : tuple of str
        ``header.frame_id`` of the output wrenches, one per corner.
    namespace : str
        Namespace relative names were resolved against (``/`` by default).

    Raises
    ------
    ConfigError
        An invalid name or namespace, or a topic used for two purposes.

    """

    imu_topics: Tuple[str, ...] = DEFAULT_IMU_TOPICS
    wft_topics: Tuple[str, ...] = DEFAULT_WFT_TOPICS
    output_topics: Tuple[str, ...] = DEFAULT_OUTPUT_TOPICS
    damage_topic: str = DEFAULT_DAMAGE_TOPIC
    event_topic: str = DEFAULT_EVENT_TOPIC
    travel_topic: str = DEFAULT_TRAVEL_TOPIC
    frame_ids: Tuple[str, ...] = DEFAULT_FRAME_IDS
    namespace: str = '/'

    def __post_init__(self):
        """Validate and resolve the names; reject a topic used for two purposes."""
        where = 'TopicConfig'
        ns = validate_namespace(self.namespace)
        object.__setattr__(self, 'namespace', ns)
        for key in ('imu_topics', 'wft_topics', 'output_topics'):
            names = _validate_list(getattr(self, key), key, where, _validate_topic)
            object.__setattr__(self, key, tuple(resolve_name(n, ns) for n in names))
        object.__setattr__(
            self, 'frame_ids', _validate_list(self.frame_ids, 'frame_ids', where,
                                              _validate_frame))
        for key in ('damage_topic', 'event_topic', 'travel_topic'):
            name = _validate_topic(getattr(self, key), key, where)
            object.__setattr__(self, key, resolve_name(name, ns))
        names = (self.imu_topics + self.wft_topics + self.output_topics
                 + (self.damage_topic, self.event_topic, self.travel_topic))
        seen = set()
        for name in names:
            if name in seen:
                raise ConfigError(f'{where}: topic {name!r} is used for two purposes')
            seen.add(name)


_TOPIC_LIST_KEYS = ('imu_topics', 'wft_topics', 'output_topics')
_TOPIC_KEYS = ('damage_topic', 'event_topic', 'travel_topic')


def node_parameters(path) -> Tuple[Dict[str, object], str]:
    """
    Return the node's ``ros__parameters`` from a params file and the sections they came from.

    The ``/**`` section, then ``wheel_force_node`` (then ``/wheel_force_node``): a key in a
    later, more specific section overrides the wildcard's.  A file with only the
    ``wheel_force_fit`` section gives ``({}, '')``.

    Raises
    ------
    ConfigError
        The file cannot be read or parsed, is not a mapping, has neither a node nor a fit
        section, or a section has no ``ros__parameters`` mapping (file and section named).

    """
    path = Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except OSError as err:
        raise ConfigError(f'{path}: cannot read params file: {err.strerror or err}') from err
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: invalid YAML: {err}') from err
    if not isinstance(doc, dict):
        raise ConfigError(f'{path}: expected a mapping with a {NODE_SECTION!r} section')
    sections = [n for n in _SECTION_NAMES if n in doc]
    if not sections and FIT_SECTION in doc:
        return {}, ''
    if not sections:
        raise ConfigError(f'{path}: no {WILDCARD_SECTION!r} or {NODE_SECTION!r} section '
                          f'(keys: {sorted(doc)})')
    params = {}
    for section_name in sections:
        section = doc[section_name]
        values = section.get('ros__parameters') if isinstance(section, dict) else None
        if not isinstance(values, dict):
            raise ConfigError(f'{path}: {section_name}: missing ros__parameters mapping')
        params.update(values)
    return params, ' + '.join(sections)


def load_topic_config(path=None, namespace: str = '/') -> TopicConfig:
    """
    Read the topic names of the node's section of a ROS 2 params file, resolved.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        Params YAML (``config/wheel_force.yaml`` layout).  ``None`` returns the DESIGN.md
        defaults.  Keys missing from the file keep their defaults.
    namespace : str
        Namespace relative names are resolved against (``--namespace``), default ``/``.

    Returns
    -------
    TopicConfig
        With absolute topic names (what a bag records).

    Raises
    ------
    ConfigError
        The file cannot be read or parsed, has no ``/**`` (or ``wheel_force_node``) section,
        a key is unknown or has an invalid value (file and key named), or the namespace is
        invalid.

    """
    if path is None:
        return TopicConfig(namespace=namespace)
    params, section_name = node_parameters(path)
    if not section_name:
        return TopicConfig(namespace=namespace)     # fit settings only: default topics
    known = set(_TOPIC_LIST_KEYS) | set(_TOPIC_KEYS) | {'frame_ids'} | NODE_ONLY_KEYS
    for key in params:
        if key not in known:
            raise ConfigError(
                f'{path}: {section_name}.ros__parameters.{key}: unknown parameter '
                f'(known: {", ".join(sorted(known))})')
    where = f'{path}: {section_name}.ros__parameters'
    values = {}
    for key in _TOPIC_LIST_KEYS:
        if key in params:
            values[key] = _validate_list(params[key], key, where, _validate_topic)
    for key in _TOPIC_KEYS:
        if key in params:
            values[key] = _validate_topic(params[key], key, where)
    if 'frame_ids' in params:
        values['frame_ids'] = _validate_list(params['frame_ids'], 'frame_ids', where,
                                             _validate_frame)
    try:
        return TopicConfig(**values, namespace=namespace)
    except ConfigError as err:
        raise ConfigError(f'{path}: {err}') from err


def default_topic_config(topics: Optional[TopicConfig]) -> TopicConfig:
    """Return ``topics`` or the defaults; reject anything that is not a TopicConfig."""
    if topics is None:
        return TopicConfig()
    if not isinstance(topics, TopicConfig):
        raise ConfigError(f'topics must be a TopicConfig, got {type(topics).__name__}')
    return topics
