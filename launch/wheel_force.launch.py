# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Launch ``wheel_force_node`` for one car.

Arguments: ``model`` (model file, sets ``model_path``), ``namespace`` (e.g. ``/car2``: every
relative topic moves under it), ``params_file`` (default: the installed
``config/wheel_force.yaml``, keyed ``/**`` so it applies under any namespace) and
``use_sim_time`` (``true`` with ``ros2 bag play --clock``).  Two cars in one graph::

    ros2 launch wheel_force_estimator wheel_force.launch.py namespace:=/car1 model:=car1.npz
    ros2 launch wheel_force_estimator wheel_force.launch.py namespace:=/car2 model:=car2.npz
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch.substitutions import PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

PACKAGE = 'wheel_force_estimator'
#: Launch arguments: name -> (default, description).  ``params_file``'s default is the share
#: directory's config (a substitution, filled in below).
ARGUMENTS = {
    'model': ('', 'model file (.npz) written by `wheel-force fit`; sets model_path'),
    'namespace': ('', 'namespace of the node and its relative topics, e.g. /car2'),
    'params_file': (None, 'ROS 2 params file (default: the installed config/wheel_force.yaml)'),
    'use_sim_time': ('false', 'true: ROS time from /clock (ros2 bag play --clock)'),
}
#: Launch arguments that set a node parameter of the same meaning: argument -> parameter.
PARAMETER_ARGUMENTS = {'model': 'model_path', 'use_sim_time': 'use_sim_time'}


def generate_launch_description():
    """Declare the arguments and the node."""
    default_params = PathJoinSubstitution(
        [FindPackageShare(PACKAGE), 'config', 'wheel_force.yaml'])
    declared = [DeclareLaunchArgument(name, default_value=default_params
                                      if default is None else default, description=text)
                for name, (default, text) in ARGUMENTS.items()]
    overrides = {
        'model_path': LaunchConfiguration('model'),
        'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'), value_type=bool),
    }
    node = Node(package=PACKAGE, executable='wheel_force_node', name='wheel_force_node',
                namespace=LaunchConfiguration('namespace'),
                parameters=[LaunchConfiguration('params_file'), overrides],
                output='screen', emulate_tty=True)
    return LaunchDescription(declared + [node])
