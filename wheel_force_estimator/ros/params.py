# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Parameters of ``wheel_force_node``: declarations, validation and the model check.

Every key of the ``wheel_force_node`` section of ``config/wheel_force.yaml`` is declared with a
``ParameterDescriptor`` whose description states the unit, with a numeric range where one
exists, read-only unless a live change makes sense (only ``damage_budget`` may change while
running: it affects the diagnostics level, nothing else).  All values are then checked together
in :class:`NodeParams`; any problem raises :class:`ConfigError` naming the parameter, and the
node refuses to start with that one message.
"""
from dataclasses import dataclass
from typing import Any, Optional, Tuple

from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterException

from wheel_force_estimator import CORNERS
from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio.topics import TopicConfig
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError

RELIABILITIES = ('best_effort', 'reliable')
#: Extra output channels a model may carry (moments), published as the wrench torque.
MOMENT_CHANNELS = tuple(f'{c}_m{ax}' for c in CORNERS for ax in 'xyz')
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
    _Spec('model_path', '', 'model file (.npz) written by `wheel-force fit` [path]',
          constraints='required; channels and sample rate must match the node'),
    _Spec('imu_topics', [f'/spindle/{c}/imu' for c in CORNERS],
          'sensor_msgs/Imu input topics [topic names]', constraints=_FOUR),
    _Spec('wft_topics', [f'/wft/{c}/wrench' for c in CORNERS],
          'measured wheel force topics (offline commands; not used live) [topic names]',
          constraints=_FOUR),
    _Spec('output_topics', [f'/virtual_wft/{c}/wrench' for c in CORNERS],
          'geometry_msgs/WrenchStamped output topics [topic names]', constraints=_FOUR),
    _Spec('damage_topic', '/virtual_wft/damage',
          'diagnostic_msgs/DiagnosticArray running pseudo damage topic [topic name]'),
    _Spec('event_topic', '/proving_ground/event',
          'std_msgs/String proving-ground event topic (shown in diagnostics) [topic name]'),
    _Spec('frame_ids', [f'{c}_wheel' for c in CORNERS],
          'header.frame_id of the output wrenches [frame ids]', constraints=_FOUR),
    _Spec('imu_frame_ids', [''],
          'accepted Imu header.frame_id per corner; other frames are dropped [frame ids]',
          constraints='[""] accepts any; otherwise ' + _FOUR + ' ("" = any)'),
    _Spec('block_size', 128, 'samples per overlap-add block [samples]', int_range=(1, 8192)),
    _Spec('causal_delay_s', 0.25, 'FIR look-ahead kept by the live filter [s]',
          float_range=(0.0, 60.0),
          constraints="at most the model's look-ahead (fir_delay_samples / fs)"),
    _Spec('sn_slope', 5.0, 'Basquin exponent k of the pseudo damage [-]',
          float_range=(0.5, 50.0)),
    _Spec('damage_publish_period_s', 1.0, 'period of the damage diagnostics [s]',
          float_range=(0.01, 3600.0)),
    _Spec('damage_budget', 0.0,
          'pseudo damage per channel that raises ERROR (WARN from 80 %); 0 = off [N^k]',
          read_only=False, float_range=(0.0, _MAX_FLOAT)),
    _Spec('stale_timeout_samples', 64,
          'a corner silent (or lagging) this long is reported stale [sample periods]',
          int_range=(1, 10_000_000)),
    _Spec('input_qos_depth', 200, 'history depth of the Imu subscriptions [messages]',
          int_range=(1, 100_000)),
    _Spec('input_reliability', 'best_effort', 'reliability of the Imu subscriptions [-]',
          constraints='best_effort | reliable'),
    _Spec('output_qos_depth', 1024,
          'history depth of the reliable wrench publishers [messages]',
          int_range=(1, 1_000_000), constraints='>= 4 * block_size'),
    _Spec('flush_timeout_s', 0.5,
          'no input for this long: estimates in flight are completed (end of stream) [s]',
          float_range=(0.001, 3600.0)),
    _Spec('sample_rate_hz', 0.0,
          "expected input sample rate; 0 = the model's; else must equal the model's [Hz]",
          float_range=(0.0, 1.0e6)),
)


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
    output_topics: Tuple[str, ...]
    damage_topic: str
    event_topic: str
    frame_ids: Tuple[str, ...]
    imu_frame_ids: Tuple[str, ...]
    block_size: int
    causal_delay_s: float
    sn_slope: float
    damage_publish_period_s: float
    damage_budget: float
    stale_timeout_samples: int
    input_qos_depth: int
    input_reliability: str
    output_qos_depth: int
    flush_timeout_s: float
    sample_rate_hz: float

    def __post_init__(self):
        """Check what descriptors cannot express; normalise ``imu_frame_ids`` to 4 entries."""
        if not self.model_path:
            raise ConfigError('parameter model_path is empty: set it to a model file '
                              '(-p model_path:=MODEL.npz or --model MODEL.npz)')
        try:
            TopicConfig(imu_topics=tuple(self.imu_topics), wft_topics=tuple(self.wft_topics),
                        output_topics=tuple(self.output_topics),
                        damage_topic=self.damage_topic, event_topic=self.event_topic,
                        frame_ids=tuple(self.frame_ids))
        except ConfigError as err:
            raise ConfigError(f'parameters: {err}'.replace('TopicConfig: ', '')) from err
        frames = tuple(self.imu_frame_ids)
        if frames == ('',):
            frames = ('',) * len(CORNERS)
        if len(frames) != len(CORNERS):
            raise ConfigError(f'parameter imu_frame_ids must be [""] (accept any) or a list of '
                              f'{len(CORNERS)} frame ids (lf, rf, lr, rr), got {list(frames)}')
        object.__setattr__(self, 'imu_frame_ids', frames)
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
        for name in ('damage_publish_period_s', 'flush_timeout_s', 'sn_slope'):
            if not getattr(self, name) > 0.0:
                raise ConfigError(f'parameter {name} must be > 0, got {getattr(self, name)}')
        for name in ('causal_delay_s', 'damage_budget', 'sample_rate_hz'):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f'parameter {name} must be >= 0, got {getattr(self, name)}')

    @property
    def topics(self) -> TopicConfig:
        """Return the topic names as the offline commands see them."""
        return TopicConfig(imu_topics=self.imu_topics, wft_topics=self.wft_topics,
                           output_topics=self.output_topics, damage_topic=self.damage_topic,
                           event_topic=self.event_topic, frame_ids=self.frame_ids)


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
    How the model's channels map onto the node's topics.

    Attributes
    ----------
    input_order : tuple of int
        ``input_order[k]`` is the aligned row (corner-major lf_ax ... rr_az) feeding model
        input ``k``.
    force_rows : tuple of tuple of int
        Per corner, the model output rows of force x, y, z.
    torque_rows : tuple of tuple of int or None
        Per corner, the rows of moments x, y, z, or ``None`` (torque published as 0).
    causal_delay_samples : int
        FIR look-ahead in samples.

    """

    input_order: Tuple[int, ...]
    force_rows: Tuple[Tuple[int, int, int], ...]
    torque_rows: Optional[Tuple[Tuple[int, int, int], ...]]
    causal_delay_samples: int


def model_layout(model, params: NodeParams) -> ModelLayout:
    """
    Check that ``model`` fits the node and return the channel mapping.

    Raises
    ------
    ModelFileError
        The model's channels are not the 12 spindle accelerations / 12 (or 24) wheel loads,
        its units are not m/s^2 in and N out, its sample rate differs from
        ``sample_rate_hz``, or its look-ahead is shorter than ``causal_delay_s``.

    """
    where = f'model {params.model_path}'
    if sorted(model.input_channels) != sorted(INPUT_CHANNELS):
        raise ModelFileError(
            f'{where}: input channels {list(model.input_channels)} are not the 12 spindle '
            f'accelerations {list(INPUT_CHANNELS)} the node subscribes to')
    outputs = list(model.output_channels)
    missing = [c for c in OUTPUT_CHANNELS if c not in outputs]
    unknown = [c for c in outputs if c not in OUTPUT_CHANNELS + MOMENT_CHANNELS]
    if missing or unknown:
        raise ModelFileError(
            f'{where}: output channels {outputs} do not fit the node (missing '
            f'{missing or "none"}, unknown {unknown or "none"})')
    units = dict(model.units)
    if units.get('input') != 'm/s^2' or units.get('output') != 'N':
        # Imu messages carry m/s^2; a model fitted on displacement or velocity inputs (a
        # generic DAQ fit) would turn them into forces off by orders of magnitude.
        raise ModelFileError(
            f'{where}: units {units} - the node feeds sensor_msgs/Imu linear accelerations '
            f"[m/s^2] and publishes forces [N]; it needs a model with units input 'm/s^2', "
            f"output 'N'")
    moments = [c for c in outputs if c in MOMENT_CHANNELS]
    if moments and len(moments) != len(MOMENT_CHANNELS):
        raise ModelFileError(f'{where}: has moments {moments} but not all of '
                             f'{list(MOMENT_CHANNELS)}')
    fs = model.fs_hz
    if params.sample_rate_hz and abs(params.sample_rate_hz - fs) > 1e-6 * fs:
        raise ModelFileError(f'{where}: sample rate {fs:g} Hz differs from parameter '
                             f'sample_rate_hz = {params.sample_rate_hz:g} Hz')
    delay = int(round(params.causal_delay_s * fs))
    if delay > model.fir_delay_samples:
        raise ModelFileError(
            f'{where}: causal_delay_s = {params.causal_delay_s:g} s ({delay} samples) exceeds '
            f"the model's look-ahead of {model.fir_delay_samples} samples "
            f'({model.fir_delay_samples / fs:g} s)')
    index = {name: k for k, name in enumerate(outputs)}
    force_rows = tuple(tuple(index[f'{c}_f{ax}'] for ax in 'xyz') for c in CORNERS)
    torque_rows = tuple(tuple(index[f'{c}_m{ax}'] for ax in 'xyz') for c in CORNERS) \
        if moments else None
    return ModelLayout(
        input_order=tuple(INPUT_CHANNELS.index(name) for name in model.input_channels),
        force_rows=force_rows, torque_rows=torque_rows, causal_delay_samples=delay)
