# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Recordings in and out: rosbag2 (mcap, sqlite3) and ROS 1 bags via rosbags, never rclpy.

``read_recording`` aligns the four Imu and four WrenchStamped topics on ``header.stamp`` and
splits them at gaps into :class:`Segment` s; ``write_recording`` writes rosbag2 version 8 with
the Jazzy message types.  Topic names come from the node's params file
(``load_topic_config``).
"""
from wheel_force_estimator.bagio.align import Gap
from wheel_force_estimator.bagio.align import Segment
from wheel_force_estimator.bagio.reader import available_extras
from wheel_force_estimator.bagio.reader import read_imu_topic
from wheel_force_estimator.bagio.reader import read_recording
from wheel_force_estimator.bagio.reader import read_string_topic
from wheel_force_estimator.bagio.reader import read_wrench_topics
from wheel_force_estimator.bagio.reader import Recording
from wheel_force_estimator.bagio.topics import load_topic_config
from wheel_force_estimator.bagio.topics import TopicConfig
from wheel_force_estimator.bagio.writer import write_forces
from wheel_force_estimator.bagio.writer import write_recording

__all__ = [
    'Gap', 'Recording', 'Segment', 'TopicConfig', 'available_extras', 'load_topic_config',
    'read_imu_topic', 'read_recording', 'read_string_topic', 'read_wrench_topics',
    'write_forces', 'write_recording',
]
