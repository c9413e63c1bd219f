# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Topic names and frame ids of a recording, read from the ROS 2 params file.

The offline commands read the same ``/**: ros__parameters:`` section as the live node, so a
remapped topic is remapped everywhere.  Only the topic/frame keys are interpreted here; the
other node parameters are recognised (so a typo is still reported) and left to the node.

Names are relative by default (DESIGN.md), so a node started in a namespace moves with it.
Bags record resolved (absolute) names: the offline commands resolve relative names against a
namespace (``--namespace``, default ``/``) with :func:`resolve_name`, ROS 2's rule.
:class:`TopicConfig`'s defaults are the one home of the default names; the node declares its
parameters with them.
"""
from dataclasses import dataclass
from pathlib import Path
import re
from typing import Optional, Tuple


from wheel_force_estimator import CORNERS
from wheel_force_estimator.core.errors import ConfigError
import yaml

NODE_SECTION = 'wheel_force_node'
WILDCARD_SECTION = '/**'
# ROS 2 params files may address the node by the wildcard, plain or absolute name; like rcl,
# a section naming the node overrides the wildcard's values.
_SECTION_NAMES = (WILDCARD_SECTION, NODE_SECTION, '/' + NODE_SECTION)

# Node parameters that are valid in the section but not used by bagio.  Keep in sync with
# the node's declarations (ros/params.py PARAMETERS; test_bagio_topics checks it when rclpy is
# importable): an unknown key is reported as a typo.
NODE_ONLY_KEYS = frozenset({
    'model_path', 'imu_frame_ids', 'block_size', 'live_look_ahead_s', 'sn_slope',
    'damage_publish_period_s', 'damage_budget', 'stale_timeout_samples', 'input_qos_depth',
    'input_reliability', 'output_qos_depth', 'flush_timeout_s', 'sample_rate_hz',
    'unknown_torque', 'travel_topic', 'use_sim_time',
})

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
    Topic names (one per corner, order lf, rf, lr, rr) and output frame ids.

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
    frame_ids : tuple of str
        ``header.frame_id`` of the output wrenches, one per corner.

    """

    imu_topics: Tuple[str, ...] = tuple(f'spindle/{c}/imu' for c in CORNERS)
    wft_topics: Tuple[str, ...] = tuple(f'wft/{c}/wrench' for c in CORNERS)
    output_topics: Tuple[str, ...] = tuple(f'virtual_wft/{c}/wrench' for c in CORNERS)
    damage_topic: str = 'virtual_wft/damage'
    event_topic: str = 'proving_ground/event'
    frame_ids: Tuple[str, ...] = tuple(f'{c}_wheel_center' for c in CORNERS)

    def __post_init__(self):
        """Validate names and reject a topic used for two purposes."""
        where = 'TopicConfig'
        for key in ('imu_topics', 'wft_topics', 'output_topics'):
            object.__setattr__(
                self, key, _validate_list(getattr(self, key), key, where, _validate_topic))
        object.__setattr__(
            self, 'frame_ids', _validate_list(self.frame_ids, 'frame_ids', where,
                                              _validate_frame))
        _validate_topic(self.damage_topic, 'damage_topic', where)
        _validate_topic(self.event_topic, 'event_topic', where)
        names = (self.imu_topics + self.wft_topics + self.output_topics
                 + (self.damage_topic, self.event_topic))
        seen = set()
        for name in names:
            if name in seen:
                raise ConfigError(f'{where}: topic {name!r} is used for two purposes')
            seen.add(name)

    def resolved(self, namespace: str = '/') -> 'TopicConfig':
        """Return the config with every topic name resolved against ``namespace``."""
        def res(name):
            return resolve_name(name, namespace)
        return TopicConfig(imu_topics=tuple(map(res, self.imu_topics)),
                           wft_topics=tuple(map(res, self.wft_topics)),
                           output_topics=tuple(map(res, self.output_topics)),
                           damage_topic=res(self.damage_topic),
                           event_topic=res(self.event_topic), frame_ids=self.frame_ids)


_TOPIC_LIST_KEYS = ('imu_topics', 'wft_topics', 'output_topics')
_TOPIC_KEYS = ('damage_topic', 'event_topic')


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
        return TopicConfig().resolved(namespace)
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
    section_name = ' + '.join(sections)
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
        return TopicConfig(**values).resolved(namespace)
    except ConfigError as err:
        raise ConfigError(f'{path}: {err}') from err


def default_topic_config(topics: Optional[TopicConfig]) -> TopicConfig:
    """
    Return ``topics`` or the defaults, resolved against ``/``.

    Relative names in a config built in code resolve as in the root namespace; configs from
    :func:`load_topic_config` are absolute already.  Anything but a TopicConfig is refused.
    """
    if topics is None:
        return TopicConfig().resolved()
    if not isinstance(topics, TopicConfig):
        raise ConfigError(f'topics must be a TopicConfig, got {type(topics).__name__}')
    return topics.resolved()
