# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Bags written by real ROS tooling (../shared/data/ros_bags): ROS 1 Imu and rosbag2 talker.

Sources (see ../shared/data/README.md): robot_localization test bags (BSD) and ros2/rosbag2
test resources (Apache-2.0).
"""
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from support.shared_data import dataset
from support.shared_data import SHARED_DATA

from wheel_force_estimator.bagio import read_imu_topic
from wheel_force_estimator.bagio import read_recording
from wheel_force_estimator.bagio import read_string_topic
from wheel_force_estimator.core.errors import BagError

BAGS = SHARED_DATA / 'ros_bags'
TALKERS = ['rosbag2_talker_mcap', 'rosbag2_talker_sqlite3']


@pytest.fixture(autouse=True)
def _bags_present():
    """Fail in CI, skip elsewhere, when ../shared/data/ros_bags is absent."""
    dataset('ros_bags')


@pytest.mark.parametrize('name,count,period_ms,first_stamp', [
    ('robot_localization_test1.bag', 11865, 1000 / 30, 1432235497988949113),
    ('robot_localization_test2.bag', 3061, 1000 / 50, 47580000000),
])
def test_ros1_imu(name, count, period_ms, first_stamp):
    stamp_ns, accel = read_imu_topic(BAGS / name, '/imu/data')
    # counts from the bags' own index; rates from the data README (30 Hz / 50 Hz)
    assert stamp_ns.shape == (count,) and accel.shape == (3, count)
    assert stamp_ns[0] == first_stamp
    assert np.all(np.diff(stamp_ns) > 0)
    # median period within 2 % of the nominal rate: real driver stamps jitter
    assert np.median(np.diff(stamp_ns)) / 1e6 == pytest.approx(period_ms, rel=0.02)
    # ground robots: the specific force magnitude is gravity on average (within 0.3 m/s^2,
    # well above driving accelerations averaged over minutes)
    assert np.median(np.linalg.norm(accel, axis=0)) == pytest.approx(9.81, abs=0.3)


def test_ros1_bag_is_not_a_training_recording():
    with pytest.raises(BagError, match=r'topic /spindle/lf/imu .*not found; topics present: '
                                       r'/fix .*/imu/data \(sensor_msgs/msg/Imu\)'):
        read_recording(BAGS / 'robot_localization_test1.bag')


@pytest.mark.parametrize('name', TALKERS)
def test_rosbag2_talker_strings(name):
    msgs = read_string_topic(BAGS / name, '/topic')
    assert [text for _, text in msgs] == [f'Hello, world! {i}' for i in range(10)]
    assert msgs[0][0] == 1585866235112609068
    assert all(b[0] > a[0] for a, b in zip(msgs, msgs[1:]))


def test_talker_storages_agree():
    mcap, sqlite = (read_string_topic(BAGS / name, '/topic') for name in TALKERS)
    assert mcap == sqlite


@pytest.mark.parametrize('name', TALKERS)
def test_generic_path_reads_every_talker_message(name):
    # The message-by-message (rosbags) path gives the bulk path's 10 messages: a reader that
    # matched connections on QoS and dropped this bag's /topic (metadata.yaml and storage
    # disagree on QoS) would return fewer.
    msgs = read_string_topic(BAGS / name, '/topic', bulk=False)
    assert len(msgs) == 10
    assert msgs == read_string_topic(BAGS / name, '/topic')


def test_generic_path_never_reads_silently_short(monkeypatch):
    # rosbags' AnyReader (the path of ROS 1 bags) can yield fewer messages than the index lists
    # (it matches rosbag2 connections on QoS too): the reader must refuse rather than return
    # 3060 of 3061.
    original = AnyReader.messages

    def drop_last(self, *args, **kwargs):
        return list(original(self, *args, **kwargs))[:-1]

    monkeypatch.setattr(AnyReader, 'messages', drop_last)
    with pytest.raises(BagError, match='/imu/data: the bag index lists 3061 messages but 3060 '
                                       'could be read'):
        read_imu_topic(BAGS / 'robot_localization_test2.bag', '/imu/data')


@pytest.mark.parametrize('name', TALKERS)
def test_talker_is_not_a_training_recording(name):
    with pytest.raises(BagError, match=r'/spindle/lf/imu .*not found; topics present: .*'
                                       r'/topic \(std_msgs/msg/String\)'):
        read_recording(BAGS / name)
