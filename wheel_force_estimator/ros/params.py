# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Parameters of ``wheel_force_node``: declarations, validation and the model check.

Every key of the ``/**`` section of ``config/wheel_force.yaml`` is declared with a
``ParameterDescriptor`` whose description states the unit, with a numeric range where one
exists, read-only unless a live change makes sense: ``damage_budget`` (it affects the
diagnostics level, nothing else) and ``model_path`` (read again by ``~/reload_model``).
All values are then checked together in :class:`NodeParams`; any problem raises
:class:`ConfigError` naming the parameter, and the node refuses to start with that one
message.

Defaults have one home each: topic names and frame ids are :mod:`..bagio.topics`'s (shared
with the offline commands), everything else is in :data:`PARAMETERS`; the shipped params file is
checked against both by a test.  Topic names are relative (DESIGN.md), so the node moves
with its namespace.
"""
from dataclasses import dataclass
from typing import Any, Iterable, Optional, Tuple

from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterException

from wheel_force_estimator import CORNERS
from wheel_force_estimator.bagio import topics as topic_defaults
from wheel_force_estimator.bagio.topics import TopicConfig
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.live_estimator import DEFAULT_LIVE_LOOK_AHEAD_S
from wheel_force_estimator.core.predict import check_look_ahead
from wheel_force_estimator.core.spindle import MOMENT_CHANNELS  # noqa: F401 (public here)
from wheel_force_estimator.core.spindle import spindle_layout

RELIABILITIES = ('best_effort', 'reliable')
#: What the wrench torque holds when the model has no moments.
UNKNOWN_TORQUES = ('zero', 'nan')
_MAX_FLOAT = 1.0e300


@dataclass(frozen=True)
class _Spec:
    name: str
    default: Any
    description: str
    read_only: bool = True
    int_range: Optional[Tuple[int, int]] = None
    float_range: Optional[Tuple[float, float]] = None
    constraints: str = ''

    def descriptor(self) -> ParameterDescriptor:
        desc = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                   additional_constraints=self.constraints)
        if self.int_range is not None:
            desc.integer_range = [IntegerRange(from_value=self.int_range[0],
                                               to_value=self.int_range[1], step=0)]
        if self.float_range is not None:
            desc.floating_point_range = [FloatingPointRange(
                from_value=self.float_range[0], to_value=self.float_range[1], step=0.0)]
        return desc


_FOUR = 'list of 4, corners lf, rf, lr, rr'
PARAMETERS = (
    _Spec('model_path', '', 'model file (.npz) written by `wheel-force fit`; read at '
          'configure and by ~/reload_model [path]', read_only=False,
          constraints='required; channels and sample rate must match the node'),
    _Spec('imu_topics', list(topic_defaults.DEFAULT_IMU_TOPICS),
          'sensor_msgs/Imu input topics, relative to the node namespace [topic names]',
          constraints=_FOUR),
    _Spec('wft_topics', list(topic_defaults.DEFAULT_WFT_TOPICS),
          'measured wheel force topics (offline commands; not used live) [topic names]',
          constraints=_FOUR),
    _Spec('travel_topic', topic_defaults.DEFAULT_TRAVEL_TOPIC,
          'sensor_msgs/JointState topic: the node subscribes to it when the model has wheel '
          'spin inputs (velocity of the {corner}_wheel joints); the suspension travel on it '
          'is read by the offline commands only [topic name]'),
    _Spec('output_topics', list(topic_defaults.DEFAULT_OUTPUT_TOPICS),
          'geometry_msgs/WrenchStamped output topics [topic names]', constraints=_FOUR),
    _Spec('damage_topic', topic_defaults.DEFAULT_DAMAGE_TOPIC,
          'diagnostic_msgs/DiagnosticArray running pseudo damage topic [topic name]'),
    _Spec('event_topic', topic_defaults.DEFAULT_EVENT_TOPIC,
          'std_msgs/String proving-ground event topic (shown in diagnostics) [topic name]'),
    _Spec('frame_ids', list(topic_defaults.DEFAULT_FRAME_IDS),
          'header.frame_id of the output wrenches: non-rotating, vehicle-aligned frames at '
          'the wheel centres [frame ids]', constraints=_FOUR),
    _Spec('imu_frame_ids', [''],
          'accepted Imu header.frame_id per corner; other frames are dropped [frame ids]',
          constraints='[""] accepts any; otherwise ' + _FOUR + ' ("" = any)'),
    _Spec('block_size', 16, 'samples per Predictor call [samples]', int_range=(1, 8192)),
    _Spec('live_look_ahead_s', DEFAULT_LIVE_LOOK_AHEAD_S,
          'look-ahead of the live (causal) estimator [s]',
          float_range=(0.0, 60.0),
          constraints='a look-ahead the model has a live estimator for (models without one: '
                      "at most the offline FIR's look-ahead, fir_delay_samples / fs)"),
    _Spec('sn_slope', 5.0, 'Basquin exponent k of the pseudo damage [-]',
          float_range=(0.5, 50.0)),
    _Spec('sn_slope_moment', 5.0,
          'Basquin exponent k of the pseudo damage of the wheel moments (torsion) [-]',
          float_range=(0.5, 50.0)),
    _Spec('damage_publish_period_s', 1.0,
          'period of the damage messages, in data time (sample stamps) [s]',
          float_range=(0.01, 3600.0)),
    _Spec('damage_budget', 0.0,
          'pseudo damage per channel that raises ERROR (WARN from 80 %); 0 = off [N^k]',
          read_only=False, float_range=(0.0, _MAX_FLOAT)),
    _Spec('stale_timeout_samples', 64,
          'a corner silent (or lagging) this long is reported stale [sample periods]',
          int_range=(1, 10_000_000)),
    _Spec('input_qos_depth', 200, 'history depth of the Imu subscriptions [messages]',
          int_range=(50, 100_000)),
    _Spec('input_reliability', 'best_effort', 'reliability of the Imu subscriptions [-]',
          constraints='best_effort | reliable'),
    _Spec('output_qos_depth', 1024,
          'history depth of the reliable wrench publishers [messages]',
          int_range=(1, 1_000_000), constraints='>= 4 * block_size'),
    _Spec('flush_timeout_s', 0.5,
          'deprecated, ignored: a pause of the input no longer flushes the look-ahead (only '
          'a gap in the stamps, a stamp jump, deactivate and shutdown do); staleness is '
          'stale_timeout_samples [s]',
          float_range=(0.001, 3600.0)),
    _Spec('sync_tolerance_s', 0.0,
          'corner stamps at most this far apart are one sample, stamped by their median; '
          '0 = half a sample period of the model [s]',
          float_range=(0.0, 1.0),
          constraints='at most half a sample period of the model'),
    _Spec('sample_rate_hz', 0.0,
          "expected input sample rate; 0 = the model's; else must equal the model's [Hz]",
          float_range=(0.0, 1.0e6)),
    _Spec('autostart', True,
          'configure and activate at start (false: wait unconfigured for a lifecycle '
          'transition) [-]'),
    _Spec('damage_per_event', False,
          'each proving_ground/event message ends the damage run and starts a new one '
          'named after the event [-]'),
    _Spec('unknown_torque', 'zero',
          'wrench torque when the model estimates no moments: zero or NaN [-]',
          constraints='zero | nan'),
)


def default(name: str):
    """Return the default value of parameter ``name`` (its one home: :data:`PARAMETERS`)."""
    return next(spec.default for spec in PARAMETERS if spec.name == name)


#: Names of the declared parameters (and ``use_sim_time``, which rclpy declares).
PARAMETER_NAMES = frozenset(spec.name for spec in PARAMETERS) | {'use_sim_time'}
#: Parameters every rclpy node declares itself.
RCLPY_PARAMETER_NAMES = frozenset({'use_sim_time', 'start_type_description_service'})
#: Prefix of the standard QoS override parameters (``QoSOverridingOptions``).
QOS_OVERRIDES = 'qos_overrides'
#: Deprecated QoS parameters: they set the base profile, ``qos_overrides.*`` wins.
DEPRECATED_QOS_PARAMETERS = ('input_qos_depth', 'input_reliability', 'output_qos_depth')


@dataclass(frozen=True)
class NodeParams:
    """
    Validated node parameters (see :data:`PARAMETERS` for meaning and units).

    Raises
    ------
    ConfigError
        When a value is out of range or inconsistent (the parameter is named).

    """

    model_path: str
    imu_topics: Tuple[str, ...]
    wft_topics: Tuple[str, ...]
    travel_topic: str
    output_topics: Tuple[str, ...]
    damage_topic: str
    event_topic: str
    frame_ids: Tuple[str, ...]
    imu_frame_ids: Tuple[str, ...]
    block_size: int
    live_look_ahead_s: float
    sn_slope: float
    sn_slope_moment: float
    damage_publish_period_s: float
    damage_budget: float
    stale_timeout_samples: int
    input_qos_depth: int
    input_reliability: str
    output_qos_depth: int
    flush_timeout_s: float
    sync_tolerance_s: float
    sample_rate_hz: float
    autostart: bool
    damage_per_event: bool
    unknown_torque: str

    def __post_init__(self):
        """Check what descriptors cannot express; normalise ``imu_frame_ids`` to 4 entries."""
        if not self.model_path:
            raise ConfigError('parameter model_path is empty: set it to a model file '
                              '(-p model_path:=MODEL.npz or --model MODEL.npz)')
        try:
            TopicConfig(imu_topics=tuple(self.imu_topics), wft_topics=tuple(self.wft_topics),
                        output_topics=tuple(self.output_topics),
                        damage_topic=self.damage_topic, event_topic=self.event_topic,
                        travel_topic=self.travel_topic, frame_ids=tuple(self.frame_ids))
        except ConfigError as err:
            raise ConfigError(f'parameters: {err}'.replace('TopicConfig: ', '')) from err
        frames = tuple(self.imu_frame_ids)
        if frames == ('',):
            frames = ('',) * len(CORNERS)
        if len(frames) != len(CORNERS):
            raise ConfigError(f'parameter imu_frame_ids must be [""] (accept any) or a list of '
                              f'{len(CORNERS)} frame ids (lf, rf, lr, rr), got {list(frames)}')
        object.__setattr__(self, 'imu_frame_ids', frames)
        if self.unknown_torque not in UNKNOWN_TORQUES:
            raise ConfigError(f'parameter unknown_torque must be one of '
                              f'{", ".join(UNKNOWN_TORQUES)}, got {self.unknown_torque!r}')
        if self.input_reliability not in RELIABILITIES:
            raise ConfigError(f'parameter input_reliability must be one of '
                              f'{", ".join(RELIABILITIES)}, got {self.input_reliability!r}')
        if self.output_qos_depth < 4 * self.block_size:
            raise ConfigError(
                f'parameter output_qos_depth = {self.output_qos_depth} must hold at least 4 '
                f'blocks (4 * block_size = {4 * self.block_size} messages)')
        for name in ('block_size', 'stale_timeout_samples', 'input_qos_depth',
                     'output_qos_depth'):
            if getattr(self, name) < 1:
                raise ConfigError(f'parameter {name} must be >= 1, got {getattr(self, name)}')
        for name in ('damage_publish_period_s', 'flush_timeout_s', 'sn_slope',
                     'sn_slope_moment'):
            if not getattr(self, name) > 0.0:
                raise ConfigError(f'parameter {name} must be > 0, got {getattr(self, name)}')
        for name in ('live_look_ahead_s', 'damage_budget', 'sample_rate_hz',
                     'sync_tolerance_s'):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f'parameter {name} must be >= 0, got {getattr(self, name)}')

    @property
    def topics(self) -> TopicConfig:
        """Return the topic names as the offline commands see them."""
        return TopicConfig(imu_topics=self.imu_topics, wft_topics=self.wft_topics,
                           output_topics=self.output_topics, damage_topic=self.damage_topic,
                           event_topic=self.event_topic, travel_topic=self.travel_topic,
                           frame_ids=self.frame_ids)


def declare_node_parameters(node) -> NodeParams:
    """
    Declare every parameter on ``node`` and return the validated values.

    Parameters
    ----------
    node : rclpy.node.Node
        The node; overrides come from its ``--ros-args`` (params file, ``-p``).

    Returns
    -------
    NodeParams

    Raises
    ------
    ConfigError
        A value of the wrong type, out of its range, or inconsistent.

    """
    values = {}
    for spec in PARAMETERS:
        if node.has_parameter(spec.name):
            # Declared from its override (automatically_declare_parameters_from_overrides,
            # so that the node can list what it was given): declare it again, properly.
            node.undeclare_parameter(spec.name)
        try:
            param = node.declare_parameter(spec.name, spec.default, spec.descriptor())
        except ParameterException as err:
            hint = ''
            if isinstance(spec.default, float):
                hint = ' (write a float such as 5.0, not 5)'
            raise ConfigError(f'parameter {spec.name}: {err}{hint}') from err
        value = param.value
        values[spec.name] = tuple(value) if isinstance(spec.default, list) else value
    return NodeParams(**values)


@dataclass(frozen=True)
class ModelLayout:
    """
    How the model's outputs map onto the node's topics.

    Attributes
    ----------
    force_rows : tuple of tuple of int
        Per corner, the model output rows of force x, y, z.
    torque_rows : tuple of tuple of int or None
        Per corner, the rows of moments x, y, z, or ``None`` (torque unknown: published as
        ``unknown_torque`` says).
    causal_delay_samples : int
        Look-ahead of the live estimator, ``round(live_look_ahead_s * fs)`` [samples].
    sync_tolerance_ns : int
        Corner stamps at most this far apart are one sample [ns] (``sync_tolerance_s``, or
        half a sample period when it is 0).
    rates, spin : bool
        The model's inputs include the spindle angular rates (Imu angular velocity) / the
        wheel spin accelerations (derived from the JointState ``{corner}_wheel`` velocities
        on ``travel_topic``).
    derived : tuple of str
        The model's last inputs that the node's stream derives from the accelerations (the
        traction/braking and cornering splits; no topic).

    """

    force_rows: Tuple[Tuple[int, int, int], ...]
    torque_rows: Optional[Tuple[Tuple[int, int, int], ...]]
    causal_delay_samples: int
    sync_tolerance_ns: int = 0
    rates: bool = False
    spin: bool = False
    derived: Tuple[str, ...] = ()

    @property
    def inputs(self) -> Tuple[bool, bool]:
        """Return the input groups beyond the accelerations: ``(rates, spin)``."""
        return (self.rates, self.spin)


def model_layout(model, params: NodeParams) -> ModelLayout:
    """
    Check that ``model`` fits the node and return the channel mapping.

    The channel and unit rule is :func:`wheel_force_estimator.core.spindle.spindle_layout`,
    the one ``predict`` and ``evaluate`` apply to bags.

    Raises
    ------
    ModelFileError
        The model does not map the 12 spindle accelerations [m/s^2] to the wheel loads [N],
        its sample rate differs from ``sample_rate_hz``, its look-ahead is shorter than
        ``live_look_ahead_s``, or ``sync_tolerance_s`` exceeds half its sample period.

    """
    where = f'model {params.model_path}'
    layout = spindle_layout(model, where)
    fs = model.fs_hz
    if params.sample_rate_hz and abs(params.sample_rate_hz - fs) > 1e-6 * fs:
        raise ModelFileError(f'{where}: sample rate {fs:g} Hz differs from parameter '
                             f'sample_rate_hz = {params.sample_rate_hz:g} Hz')
    delay = int(round(params.live_look_ahead_s * fs))
    try:    # the one look-ahead rule, shared with predict/evaluate --causal
        check_look_ahead(model, delay)
    except ConfigError as err:
        raise ModelFileError(f'{where}: live_look_ahead_s = {params.live_look_ahead_s:g} s '
                             f'({delay} samples): {err}') from err
    half_period_ns = 0.5e9 / fs
    tolerance_ns = (int(half_period_ns) if params.sync_tolerance_s == 0.0
                    else int(round(params.sync_tolerance_s * 1e9)))
    if tolerance_ns > half_period_ns:
        raise ModelFileError(f'{where}: sync_tolerance_s = {params.sync_tolerance_s:g} s is '
                             f'more than half its sample period ({half_period_ns * 1e-9:g} s '
                             f'at {fs:g} Hz): two samples of one corner could be taken for one')
    return ModelLayout(force_rows=layout.force_rows, torque_rows=layout.torque_rows,
                       causal_delay_samples=delay, sync_tolerance_ns=tolerance_ns,
                       rates=layout.rates, spin=layout.spin, derived=layout.derived)


def unknown_parameters(given: Iterable[str],
                       entities: Iterable[Tuple[str, str]]) -> Tuple[str, ...]:
    """
    Return the names given to the node (params file, ``-p``) that mean nothing to it.

    rclpy ignores them silently; a typo in a params file would otherwise go unnoticed.

    Parameters
    ----------
    given : iterable of str
        Names of the parameter overrides the node was started with.
    entities : iterable of (str, str)
        ``(resolved topic, 'publisher' | 'subscription')`` of the node's publishers and
        subscriptions: ``qos_overrides.<topic>.<kind>.<policy>`` is known for these.

    Returns
    -------
    tuple of str
        Sorted unknown names.

    """
    known = PARAMETER_NAMES | RCLPY_PARAMETER_NAMES
    prefixes = tuple(f'{QOS_OVERRIDES}.{topic}.{kind}.' for topic, kind in entities)
    return tuple(sorted(name for name in given if name not in known
                        and not (name.startswith(prefixes) and name.count('.') >= 3)))
