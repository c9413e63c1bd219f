# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Run a launch file as ``ros2 launch`` would: ``python run_launch.py FILE [name:=value ...]``.

``ros2 launch`` (ros2cli) has no PyPI wheel; this is its core, on the real ``launch``: a
``LaunchService`` including the file with the arguments, stopped by SIGINT (it forwards the
signal to the processes and waits for them, escalating to SIGTERM after 5 s as ``ros2 launch``
does).  ``launch`` / ``launch_ros`` must be importable (``PYTHONPATH``).
"""
import signal
import sys

from launch import LaunchService
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource


def main(argv) -> int:
    """Include ``argv[0]`` with the ``name:=value`` arguments and run it to the end."""
    # A terminal's foreground job has the default Ctrl-C; a test runner started in the
    # background by a non-interactive shell (``cmd &``) hands its children SIGINT *ignored*,
    # and Python then keeps it ignored: launch would never see the Ctrl-C the tests send,
    # and respawn the nodes that did (measured: the launch test timed out that way).
    signal.signal(signal.SIGINT, signal.default_int_handler)
    arguments = [tuple(arg.split(':=', 1)) for arg in argv[1:]]
    service = LaunchService()
    service.include_launch_description(IncludeLaunchDescription(
        PythonLaunchDescriptionSource(argv[0]), launch_arguments=arguments))
    return service.run()


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
