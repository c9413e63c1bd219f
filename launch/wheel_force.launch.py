# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Launch ``wheel_force_node`` for one car.

Arguments: ``model`` (model file, sets ``model_path``), ``namespace`` (e.g. ``/car2``: every
relative topic moves under it), ``params_file`` (default: the installed
``config/wheel_force.yaml``, keyed ``/**`` so it applies under any namespace),
``use_sim_time`` (``true`` with ``ros2 bag play --clock``), ``autostart`` (``false``: the
lifecycle node waits unconfigured for ``ros2 lifecycle set``), ``log_level`` and ``respawn``
(restart the node if it dies).  An argument that sets a node parameter overrides the params
file **only when given**: ``params_file:=car.yaml`` alone runs the model named in
``car.yaml``.  Two cars in one graph::

    ros2 launch wheel_force_estimator wheel_force.launch.py namespace:=/car1 model:=car1.npz
    ros2 launch wheel_force_estimator wheel_force.launch.py namespace:=/car2 model:=car2.npz
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.actions import OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch.substitutions import PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

PACKAGE = 'wheel_force_estimator'
#: Launch arguments: name -> (default, description).  ``params_file``'s default is the share
#: directory's config (a substitution, filled in below).
ARGUMENTS = {
    'model': ('', 'model file (.npz) written by `wheel-force fit`; sets model_path '
                  '(default: model_path of the params file)'),
    'namespace': ('', 'namespace of the node and its relative topics, e.g. /car2'),
    'params_file': (None, 'ROS 2 params file (default: the installed config/wheel_force.yaml)'),
    'use_sim_time': ('', 'true: ROS time from /clock (ros2 bag play --clock); default: the '
                         'value in the params file, else false'),
    'autostart': ('', 'true: configure and activate at start; false: wait unconfigured for '
                      'ros2 lifecycle set; default: the value in the params file, else true'),
    'log_level': ('info', 'log level of the node: debug, info, warn, error or fatal'),
    'respawn': ('false', 'true: start the node again if it dies (1 s later)'),
}
#: Launch arguments that set a node parameter of the same meaning: argument -> parameter.
#: Each is passed only when given (not empty), so the params file decides otherwise.
PARAMETER_ARGUMENTS = {'model': 'model_path', 'use_sim_time': 'use_sim_time',
                       'autostart': 'autostart'}
_BOOLEAN_PARAMETERS = ('use_sim_time', 'autostart')
#: Wait before a respawn [s].
RESPAWN_DELAY_S = 1.0


def node_parameters(context):
    """
    Return the node's ``parameters``: the params file, then the arguments that were given.

    Parameters
    ----------
    context : launch.LaunchContext
        Holds the launch arguments.

    Returns
    -------
    list
        ``[params_file, {parameter: value}]``.

    Raises
    ------
    ValueError
        A boolean argument that is neither true nor false.

    """
    overrides = {}
    for argument, parameter in PARAMETER_ARGUMENTS.items():
        value = LaunchConfiguration(argument).perform(context).strip()
        if not value:
            continue
        if parameter in _BOOLEAN_PARAMETERS:
            if value.lower() not in ('true', 'false'):
                raise ValueError(f'launch argument {argument}:={value}: expected true or false')
            overrides[parameter] = value.lower() == 'true'
        else:
            overrides[parameter] = value
    return [LaunchConfiguration('params_file').perform(context), overrides]


def _node(context):
    respawn = LaunchConfiguration('respawn').perform(context).strip().lower()
    if respawn not in ('true', 'false'):
        raise ValueError(f'launch argument respawn:={respawn}: expected true or false')
    return [Node(package=PACKAGE, executable='wheel_force_node', name='wheel_force_node',
                 namespace=LaunchConfiguration('namespace'),
                 parameters=node_parameters(context),
                 ros_arguments=['--log-level', LaunchConfiguration('log_level')],
                 respawn=respawn == 'true', respawn_delay=RESPAWN_DELAY_S,
                 output='screen', emulate_tty=True)]


def generate_launch_description():
    """Declare the arguments and the node."""
    default_params = PathJoinSubstitution(
        [FindPackageShare(PACKAGE), 'config', 'wheel_force.yaml'])
    declared = [DeclareLaunchArgument(name, default_value=default_params
                                      if default is None else default, description=text)
                for name, (default, text) in ARGUMENTS.items()]
    return LaunchDescription(declared + [OpaqueFunction(function=_node)])
