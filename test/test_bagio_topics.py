# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Topic configuration from the ROS 2 params file."""
from pathlib import Path

import pytest

from wheel_force_estimator.bagio import load_topic_config
from wheel_force_estimator.bagio import TopicConfig
from wheel_force_estimator.bagio.topics import resolve_name
from wheel_force_estimator.core.errors import ConfigError

REPO_CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'wheel_force.yaml'


def _yaml(tmp_path, body):
    path = tmp_path / 'params.yaml'
    path.write_text('wheel_force_node:\n  ros__parameters:\n' + body)
    return path


def test_defaults_are_design_names():
    from wheel_force_estimator.bagio import topics
    assert topics.DEFAULT_IMU_TOPICS[0] == 'spindle/lf/imu'      # relative: moves with __ns
    assert topics.DEFAULT_DAMAGE_TOPIC == 'virtual_wft/damage'
    cfg = load_topic_config(None)
    assert cfg == TopicConfig()
    assert cfg.imu_topics == ('/spindle/lf/imu', '/spindle/rf/imu', '/spindle/lr/imu',
                              '/spindle/rr/imu')
    assert cfg.wft_topics[3] == '/wft/rr/wrench'
    assert cfg.output_topics[1] == '/virtual_wft/rf/wrench'
    assert cfg.damage_topic == '/virtual_wft/damage'
    assert cfg.event_topic == '/proving_ground/event'
    assert cfg.frame_ids == ('lf_wheel_center', 'rf_wheel_center', 'lr_wheel_center',
                             'rr_wheel_center')


def test_repo_config_file_loads():
    assert load_topic_config(REPO_CONFIG) == TopicConfig()
    assert load_topic_config(REPO_CONFIG, '/car2').imu_topics[3] == '/car2/spindle/rr/imu'


@pytest.mark.parametrize('name, namespace, expected', [
    ('spindle/lf/imu', '/', '/spindle/lf/imu'),
    ('spindle/lf/imu', '/car2', '/car2/spindle/lf/imu'),
    ('spindle/lf/imu', 'car2/', '/car2/spindle/lf/imu'),
    ('spindle/lf/imu', '/fleet/car2', '/fleet/car2/spindle/lf/imu'),
    ('/diagnostics', '/car2', '/diagnostics'),
    ('~/debug', '/car2', '/car2/wheel_force_node/debug'),
    ('~/debug', '/', '/wheel_force_node/debug'),
])
def test_names_resolve_like_ros(name, namespace, expected):
    assert resolve_name(name, namespace) == expected


def test_bad_namespace_is_refused():
    with pytest.raises(ConfigError, match="namespace 'car 2' is not a valid ROS namespace"):
        resolve_name('a', 'car 2')


def test_node_section_overrides_the_wildcard(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('/**:\n  ros__parameters:\n    damage_topic: dmg\n    event_topic: ev\n'
                    'wheel_force_node:\n  ros__parameters:\n    event_topic: /events\n')
    cfg = load_topic_config(path, namespace='/car1')
    assert (cfg.damage_topic, cfg.event_topic) == ('/car1/dmg', '/events')


def test_remapped_topics(tmp_path):
    path = _yaml(tmp_path, '    imu_topics: ["/a/imu", "/b/imu", "/c/imu", "/d/imu"]\n'
                           '    event_topic: "/events"\n    block_size: 64\n')
    cfg = load_topic_config(path)
    assert cfg.imu_topics == ('/a/imu', '/b/imu', '/c/imu', '/d/imu')
    assert cfg.event_topic == '/events' and cfg.wft_topics == TopicConfig().wft_topics


def test_wildcard_section(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('/**:\n  ros__parameters:\n    damage_topic: /dmg\n')
    assert load_topic_config(path).damage_topic == '/dmg'


@pytest.mark.parametrize('body,match', [
    ('    imu_topic: ["/a"]\n', r'params\.yaml: .*ros__parameters\.imu_topic: unknown parameter'),
    ('    wft_topics: ["/a", "/b"]\n', r'params\.yaml: .*wft_topics must be a list of 4'),
    ('    output_topics: ["/a", "/b", "/c", "bad topic"]\n',
     r'params\.yaml: .*output_topics\[3\] \(rr\) must be a valid ROS topic name'),
    ('    event_topic: 3\n', r'params\.yaml: .*event_topic must be a valid ROS topic'),
    ('    frame_ids: ["a", "b", "c", ""]\n', r'params\.yaml: .*frame_ids\[3\]'),
    ('    damage_topic: "/spindle/lf/imu"\n', r'params\.yaml: .*used for two purposes'),
])
def test_invalid_values_name_file_and_key(tmp_path, body, match):
    with pytest.raises(ConfigError, match=match):
        load_topic_config(_yaml(tmp_path, body))


def test_bad_files(tmp_path):
    with pytest.raises(ConfigError, match=r'missing\.yaml: cannot read'):
        load_topic_config(tmp_path / 'missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('a: [1, 2\n')
    with pytest.raises(ConfigError, match=r'bad\.yaml: invalid YAML'):
        load_topic_config(bad)
    other = tmp_path / 'other.yaml'
    other.write_text('some_node:\n  ros__parameters: {}\n')
    with pytest.raises(ConfigError, match=r"other\.yaml: no '/\*\*' or 'wheel_force_node' sec"):
        load_topic_config(other)
    empty = tmp_path / 'empty.yaml'
    empty.write_text('wheel_force_node: {}\n')
    with pytest.raises(ConfigError, match=r'wheel_force_node: missing ros__parameters'):
        load_topic_config(empty)


def test_topic_config_validates_itself():
    with pytest.raises(ConfigError, match=r'imu_topics must be a list of 4'):
        TopicConfig(imu_topics=('/a',))


def test_every_node_parameter_is_accepted(tmp_path):
    """The node's declared parameters must not be reported as typos by the offline tools."""
    params = pytest.importorskip('wheel_force_estimator.ros.params',
                                 reason='rclpy (ROS 2 Jazzy wheels) not importable')
    lines = ''.join(f'    {spec.name}: {spec.default!r}\n' for spec in params.PARAMETERS)
    assert load_topic_config(_yaml(tmp_path, lines.replace("'", '"'))) == TopicConfig()
