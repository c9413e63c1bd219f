# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Node parameters: descriptors, validation, model checks, refusal to start."""
import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.parameter import Parameter
from support.ros_testing import isolated_ros_env
from support.ros_testing import synthetic_model

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.ros.params import model_layout
from wheel_force_estimator.ros.params import MOMENT_CHANNELS
from wheel_force_estimator.ros.params import NodeParams
from wheel_force_estimator.ros.params import PARAMETERS

pytestmark = pytest.mark.ros


def values(**changes):
    base = {s.name: tuple(s.default) if isinstance(s.default, list) else s.default
            for s in PARAMETERS}
    base['model_path'] = 'model.npz'
    base.update(changes)
    return base


def test_shipped_params_file_is_the_code_defaults():
    """One source of defaults: the YAML must say exactly what the code declares."""
    import yaml
    from wheel_force_estimator.core.design import PRODUCT_FIT_DEFAULTS
    from wheel_force_estimator.cli.common import default_config_path
    from wheel_force_estimator.core.pipeline import FitConfig
    doc = yaml.safe_load(default_config_path().read_text())
    assert set(doc) == {'/**', 'wheel_force_fit'}   # applies whatever the node is called
    node = doc['/**']['ros__parameters']
    assert set(node) == {s.name for s in PARAMETERS}
    for spec in PARAMETERS:
        assert '[' in spec.description and spec.description.endswith(']'), spec.name
        assert node[spec.name] == spec.default, spec.name
    fit = doc['wheel_force_fit']['ros__parameters']
    defaults = dataclasses.asdict(FitConfig())
    # The live-estimator design is set by the node section's live_look_ahead_s (one key for
    # the node and `fit`), not by a wheel_force_fit key.
    del defaults['live']
    defaults.update(PRODUCT_FIT_DEFAULTS)
    defaults['f_max_hz'] = defaults['f_max_hz'] or 0.0      # the file writes None as 0
    # settings that would pin `fit`'s design search are not set (one set is imposed)
    searched = {'segment_length', 'estimator', 'regularisation', 'long_regularisation'}
    assert fit == {k: v for k, v in defaults.items() if k not in searched}
    text = default_config_path().read_text()
    for key in searched:
        assert f'# {key}: ' in text, key           # documented, with its default, as a comment


def test_topic_defaults_are_relative_and_shared_with_the_offline_commands():
    from wheel_force_estimator.bagio import topics
    defaults = {s.name: s.default for s in PARAMETERS}
    assert defaults['imu_topics'] == list(topics.DEFAULT_IMU_TOPICS)
    assert defaults['output_topics'] == list(topics.DEFAULT_OUTPUT_TOPICS)
    assert defaults['frame_ids'] == [f'{c}_wheel_center' for c in ('lf', 'rf', 'lr', 'rr')]
    names = (defaults['imu_topics'] + defaults['wft_topics'] + defaults['output_topics']
             + [defaults['damage_topic'], defaults['event_topic'], defaults['travel_topic']])
    assert not any(name.startswith('/') for name in names)
    assert (defaults['block_size'], defaults['live_look_ahead_s']) == (16, 0.05)


@pytest.mark.parametrize('changes, match', [
    ({'model_path': ''}, 'model_path is empty'),
    ({'imu_topics': ('/a', '/b', '/c')}, 'imu_topics must be a list of 4'),
    ({'output_topics': ('/a', '/b', '/c', 'not a topic')}, 'output_topics\\[3\\]'),
    ({'output_topics': ('spindle/lf/imu', '/b', '/c', '/d')}, 'two purposes'),
    ({'unknown_torque': 'none'}, 'unknown_torque must be one of zero, nan'),
    ({'imu_frame_ids': ('a', 'b')}, 'imu_frame_ids must be'),
    ({'input_reliability': 'sometimes'}, 'input_reliability must be one of'),
    ({'block_size': 512, 'output_qos_depth': 1024}, 'output_qos_depth = 1024 must hold'),
    ({'block_size': 0}, 'block_size must be >= 1'),
    ({'flush_timeout_s': 0.0}, 'flush_timeout_s must be > 0'),
])
def test_node_params_refuse_bad_values(changes, match):
    with pytest.raises(ConfigError, match=match):
        NodeParams(**values(**changes))


def test_node_params_normalise_imu_frame_ids():
    assert NodeParams(**values()).imu_frame_ids == ('',) * 4
    frames = ('a', '', 'c', 'd')
    assert NodeParams(**values(imu_frame_ids=frames)).imu_frame_ids == frames


def test_model_layout_maps_channels_and_checks_rate_and_delay():
    params = NodeParams(**values(live_look_ahead_s=0.05))
    layout = model_layout(synthetic_model(delay_samples=48), params)
    assert layout.force_rows[1] == (3, 4, 5) and layout.torque_rows is None
    assert layout.causal_delay_samples == round(0.05 * 512)
    with_moments = synthetic_model(output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS)
    assert model_layout(with_moments, params).torque_rows[3] == (21, 22, 23)


@pytest.mark.parametrize('kwargs, changes, match', [
    ({'input_channels': INPUT_CHANNELS[:11] + ('rr_gz',)}, {}, 'model inputs'),
    ({'input_channels': tuple(reversed(INPUT_CHANNELS))}, {}, 'in that order'),
    ({'output_channels': OUTPUT_CHANNELS[:11] + ('rr_mx',)}, {}, 'model outputs'),
    ({'output_channels': OUTPUT_CHANNELS + ('lf_mx',)}, {}, 'all of'),
    ({'fs_hz': 1000.0}, {'sample_rate_hz': 512.0}, 'sample rate 1000 Hz differs'),
    ({'delay_samples': 10}, {'live_look_ahead_s': 0.25}, r"within \[0, 10\] \(the model's"),
])
def test_model_layout_refuses_models_that_do_not_fit(kwargs, changes, match):
    with pytest.raises(ModelFileError, match=match):
        model_layout(synthetic_model(**kwargs), NodeParams(**values(**changes)))


def test_cli_and_node_apply_one_compatibility_rule(tmp_path):
    """check_bag_model (predict/evaluate) and model_layout (node) accept/refuse alike."""
    from wheel_force_estimator.cli.common import check_bag_model
    params = NodeParams(**values(live_look_ahead_s=0.0))
    candidates = {
        'canonical': synthetic_model(),
        'moments': synthetic_model(output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS),
        # issue 33: the node runs spin models too (it refused them while predict took them)
        'rates and spin': synthetic_model(
            input_channels=INPUT_CHANNELS + RATE_CHANNELS + SPIN_ACCEL_CHANNELS,
            output_channels=OUTPUT_CHANNELS + MOMENT_CHANNELS),
        'reordered': synthetic_model(input_channels=tuple(reversed(INPUT_CHANNELS))),
        'some moments': synthetic_model(output_channels=OUTPUT_CHANNELS + ('lf_mx',)),
        'generic': synthetic_model(input_channels=tuple(f'x{i}' for i in range(12))),
        'displacement': dataclasses.replace(synthetic_model(),
                                            units={'input': 'm', 'output': 'N'}),
    }
    verdicts = {}
    for name, model in candidates.items():
        outcomes = []
        for check in (lambda m: check_bag_model(m, 'm.npz'), lambda m: model_layout(m, params)):
            try:
                check(model)
                outcomes.append(True)
            except ModelFileError:
                outcomes.append(False)
        assert outcomes[0] == outcomes[1], name
        verdicts[name] = outcomes[0]
    assert verdicts == {'canonical': True, 'moments': True, 'rates and spin': True,
                        'reordered': False,
                        'some moments': False, 'generic': False, 'displacement': False}


@pytest.fixture
def ros_context(monkeypatch):
    for key, value in isolated_ros_env().items():
        monkeypatch.setenv(key, value)
    context = Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture(scope='module')
def model_file(tmp_path_factory):
    return save_model(synthetic_model(delay_samples=48),
                      tmp_path_factory.mktemp('model') / 'model.npz')


def make_node(context, model_path, **params):
    from wheel_force_estimator.ros.node import WheelForceNode
    overrides = [Parameter('model_path', value=str(model_path)),
                 Parameter('live_look_ahead_s', value=48 / 512)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    node = WheelForceNode(context=context, parameter_overrides=overrides)
    if node.trigger_configure() != TransitionCallbackReturn.SUCCESS:
        node.destroy_node()
        raise node.configure_error
    return node


def test_node_declares_descriptors_and_only_budget_is_live(ros_context, model_file):
    node = make_node(ros_context, model_file)
    try:
        desc = node.describe_parameter('block_size')
        assert desc.read_only and '[samples]' in desc.description
        assert (desc.integer_range[0].from_value, desc.integer_range[0].to_value) == (1, 8192)
        assert '[s]' in node.describe_parameter('live_look_ahead_s').description
        assert node.set_parameters([Parameter('damage_budget', value=1e15)])[0].successful
        assert node.get_parameter('damage_budget').value == 1e15
        result = node.set_parameters([Parameter('block_size', value=64)])[0]
        assert not result.successful and 'read-only' in result.reason
        assert node.get_parameter('block_size').value == 16
    finally:
        node.destroy_node()


@pytest.mark.parametrize('params, error, match', [
    ({'block_size': 0}, ConfigError, 'block_size.*out of range'),
    ({'sn_slope': 5}, ConfigError, 'sn_slope.*write a float'),
    ({'input_reliability': 'fast'}, ConfigError, 'input_reliability'),
    ({'sample_rate_hz': 1000.0}, ModelFileError, 'sample rate 512 Hz differs'),
])
def test_node_refuses_bad_parameters(ros_context, model_file, params, error, match):
    with pytest.raises(error, match=match):
        make_node(ros_context, model_file, **params)


def test_node_refuses_model_with_other_channels_or_missing(ros_context, tmp_path):
    other = save_model(synthetic_model(input_channels=tuple(f'ch{i}' for i in range(12))),
                       tmp_path / 'other.npz')
    with pytest.raises(ModelFileError, match='model inputs'):
        make_node(ros_context, other)
    with pytest.raises(ModelFileError, match='not found'):
        make_node(ros_context, tmp_path / 'missing.npz')


def test_node_configures_a_spin_model_and_reload_refuses_other_input_groups(
        ros_context, model_file, tmp_path):
    # issue 33: a spin model configures (it was refused) and its node subscribes to the
    # JointState topic once active; a reload to a model with other input groups is refused
    # and the old model keeps running (bug caught: the aligner and subscriptions of the
    # running model fed to the new one, a ShapeError in a callback)
    from std_srvs.srv import Trigger
    spin = save_model(synthetic_model(delay_samples=48,
                                      input_channels=INPUT_CHANNELS + SPIN_ACCEL_CHANNELS),
                      tmp_path / 'spin.npz')
    node = make_node(ros_context, spin)
    try:
        node.trigger_activate()
        subscribed = {name for name, _ in node.get_subscriber_names_and_types_by_node(
            node.get_name(), node.get_namespace())}
        assert '/suspension/joint_states' in subscribed
        assert node._stream.delay_samples == 49          # one more sample for the spin
    finally:
        node.destroy_node()
    node = make_node(ros_context, model_file)
    try:
        node.set_parameters([Parameter('model_path', value=str(spin))])
        response = node._on_reload_model(Trigger.Request(), Trigger.Response())
        assert not response.success and 'wheel spin: True' in response.message
        assert 'reconfigure' in response.message and node._model.input_channels == INPUT_CHANNELS
    finally:
        node.destroy_node()


def test_cli_refusal_is_one_clear_line_and_exit_1(tmp_path, model_file):
    env = isolated_ros_env()
    missing = tmp_path / 'missing.npz'
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator', 'node', '--model',
                           str(missing)], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert 'refusing to start' in lines[0] and str(missing) in lines[0]
    assert 'Traceback' not in proc.stderr
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator', 'node', '--config',
                           str(tmp_path / 'none.yaml')], env=env, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 1 and 'none.yaml: params file not found' in proc.stderr
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator.ros.run', '--ros-args',
                           '--params-file', str(tmp_path / 'none.yaml')],
                          env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and 'refusing to start' in proc.stderr
    assert 'Traceback' not in proc.stderr
    proc = subprocess.run([sys.executable, '-m', 'wheel_force_estimator.ros.run', '--ros-args',
                           '-p', f'model_path:={model_file}', '-p', 'block_size:=0'],
                          env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert 'block_size' in proc.stderr and 'out of range' in proc.stderr


def test_dataclass_is_frozen():
    params = NodeParams(**values())
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.block_size = 3


def test_model_layout_refuses_a_model_fitted_on_other_input_units():
    model = synthetic_model()
    params = NodeParams(**values(live_look_ahead_s=0.05))
    assert model_layout(model, params).force_rows[0] == (0, 1, 2)
    displacement = dataclasses.replace(model, units={'input': 'm', 'output': 'N'})
    with pytest.raises(ModelFileError, match="units .*'input': 'm'.* is needed"):
        model_layout(displacement, params)


def test_random_bytes_model_file_is_a_model_file_error(tmp_path):
    from wheel_force_estimator.core.model import load_model
    junk = tmp_path / 'junk.npz'
    junk.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(ModelFileError, match=r'junk\.npz: not a \.npz model file') as info:
        load_model(junk)
    assert 'pickle' not in str(info.value)


def test_unknown_parameters_are_named(ros_context, model_file):
    # Bug caught: a typo in a params file silently ignored, or a valid QoS override taken for
    # a typo.
    node = make_node(ros_context, model_file, **{
        'blok_size': 3, 'qos_overrides./spindle/lf/imu.subscription.depth': 300,
        'qos_overrides./spindle/lf/imuu.subscription.depth': 300})
    try:
        assert node.unknown_parameters == (
            'blok_size', 'qos_overrides./spindle/lf/imuu.subscription.depth')
    finally:
        node.destroy_node()


def test_qos_overrides_take_effect_on_subscriptions_and_publishers(ros_context, model_file):
    # Bug caught: qos_overrides.* declared but not applied, or the deprecated parameters
    # winning over them.  Read back from the DDS graph, as another node sees them.
    from rclpy.qos import DurabilityPolicy
    from rclpy.qos import ReliabilityPolicy
    node = make_node(ros_context, model_file, **{
        'input_reliability': 'best_effort',
        'qos_overrides./spindle/rf/imu.subscription.reliability': 'reliable',
        'qos_overrides./virtual_wft/damage.publisher.durability': 'transient_local',
        'qos_overrides./virtual_wft/lr/wrench.publisher.depth': 4096})
    try:
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        subs = {topic: info.qos_profile.reliability for topic in
                ('/spindle/lf/imu', '/spindle/rf/imu')
                for info in node.get_subscriptions_info_by_topic(topic)}
        assert subs == {'/spindle/lf/imu': ReliabilityPolicy.BEST_EFFORT,
                        '/spindle/rf/imu': ReliabilityPolicy.RELIABLE}
        damage, = node.get_publishers_info_by_topic('/virtual_wft/damage')
        assert damage.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert node.get_parameter(
            'qos_overrides./virtual_wft/lr/wrench.publisher.depth').value == 4096
        assert node.unknown_parameters == ()
    finally:
        node.destroy_node()
