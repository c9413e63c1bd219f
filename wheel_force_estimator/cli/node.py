# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel-force node [--config YAML] [--model MODEL]``: the live node, like ``wheel_force_node``.

Equivalent to ``ros2 run wheel_force_estimator wheel_force_node --ros-args --params-file YAML
-p model_path:=MODEL``; further ROS arguments may follow ``--ros-args``.
"""
import argparse
from pathlib import Path


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``node``."""
    p = subparsers.add_parser(
        'node', help='run the live virtual WFT node (same as wheel_force_node)',
        description='Subscribe to the four spindle Imu topics and publish virtual wheel '
                    'forces and the running pseudo damage until Ctrl-C.')
    p.add_argument('--config', metavar='YAML',
                   help='ROS 2 params file (default: the packaged config/wheel_force.yaml)')
    p.add_argument('--model', metavar='MODEL', help='model file (.npz); overrides model_path')
    p.add_argument('--ros-args', dest='ros_args', nargs=argparse.REMAINDER, metavar='ARG',
                   help='everything after it goes to ROS, e.g. --ros-args -p block_size:=256')
    return p


def build_ros_args(config, model, extra) -> list:
    """Return the ``rclpy.init`` argument list for the node."""
    args = ['wheel-force node', '--ros-args']
    if config is not None:
        args += ['--params-file', str(config)]
    if model is not None:
        args += ['-p', f'model_path:={model}']
    return args + (['--ros-args', *extra] if extra else [])


def command(args: argparse.Namespace) -> int:
    """Run the node; return its exit code (1 when it refuses to start)."""
    from wheel_force_estimator.cli.common import default_config_path
    from wheel_force_estimator.core.errors import ConfigError

    config = Path(args.config) if args.config else default_config_path()
    if config is not None and not config.is_file():
        raise ConfigError(f'{config}: params file not found')
    from wheel_force_estimator.ros.run import main
    return main(build_ros_args(config, args.model, args.ros_args))
