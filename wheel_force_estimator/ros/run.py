# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``wheel_force_node`` as a process: rclpy, the signals, the executor and the exit status.

:func:`main` (the ``wheel_force_node`` entry point) makes :class:`~.node.WheelForceNode`,
starts it (``autostart``), spins it with an ``EventsExecutor`` and a finite timeout (without
one it busy-spins and runs nothing) and exits 0 at SIGINT/SIGTERM, after
:meth:`~.node.WheelForceNode.finish` has completed the look-ahead and published every estimate
and the final damage.  SIGINT/SIGTERM only request that stop, checked between executor turns;
a second signal exits at once (status :data:`EXIT_INTERRUPTED`), logging how many estimates
were not published.  Configuration that cannot work (an unreadable params file, a model that
does not load) exits 1 with one line saying why.
"""
import gc
import os
import signal
import threading
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.ros.node import NODE_NAME
from wheel_force_estimator.ros.node import WheelForceNode

#: Longest a shutdown spends taking the input messages DDS already delivered [s]; it stops
#: as soon as the inputs are quiet.  0.5 s lost 841 of 3072 samples per corner of a
#: six-component model replayed at 4x on a slower 2-core machine (2026-12-02: the node took
#: ~1100 samples/s there, the replay sent 2048/s).  With the tail and the acknowledgements a
#: stop stays within the 5 s of ``ros2 launch`` (1.5 + 1 + 2 s).
SHUTDOWN_DRAIN_S = 1.5
#: Exit status after a second SIGINT/SIGTERM (128 + SIGINT, as a shell reports Ctrl-C).
EXIT_INTERRUPTED = 130


def spin(node: Node, timeout_s: float = 0.1, stop: threading.Event = None):
    """
    Spin ``node`` with an EventsExecutor until the context shuts down or ``stop`` is set.

    At ``stop`` the messages DDS already delivered are still taken (up to
    :data:`SHUTDOWN_DRAIN_S`): a Ctrl-C just after a replay must not lose its last samples.
    """
    executor = EventsExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok() and not (stop is not None and stop.is_set()):
            executor.spin_once(timeout_sec=timeout_s)
        deadline = time.monotonic() + SHUTDOWN_DRAIN_S
        idle = 0
        while node.context.ok() and idle < 3 and time.monotonic() < deadline:
            before = node.messages_taken
            executor.spin_once(timeout_sec=0.01)
            idle = idle + 1 if node.messages_taken == before else 0
    finally:
        executor.remove_node(node)
        executor.shutdown()


def main(args=None) -> int:
    """Run the node until SIGINT/SIGTERM; return 0, or 1 when it refuses to start."""
    # SIGINT/SIGTERM only request a stop, checked between executor turns: rclpy's own handler
    # would raise KeyboardInterrupt inside whatever callback is running (a FATAL log line and
    # a half-processed block); this way the last block is finished, published and counted.
    stop = threading.Event()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:         # rclpy's RCLError
        # e.g. an unreadable --params-file: rcl refuses before any node exists.
        rclpy.logging.get_logger(NODE_NAME).fatal(f'refusing to start: {err}')
        return 1
    try:
        node = WheelForceNode()
    except WheelForceError as err:
        rclpy.logging.get_logger(NODE_NAME).fatal(f'refusing to start: {err}')
        rclpy.try_shutdown()
        return 1
    if node.get_parameter('autostart').value:
        # Plain use stays one command: configure and activate now (autostart:=false waits
        # unconfigured for `ros2 lifecycle set`).
        if not node.start():
            rclpy.logging.get_logger(NODE_NAME).fatal(
                f'refusing to start: {node.configure_error}')
            node.destroy_node()
            rclpy.try_shutdown()
            return 1
    # Everything allocated so far (rclpy, numpy, scipy, numba, the model) lives for the whole
    # run: keep it out of the cyclic collector, whose full passes otherwise stall the executor
    # for ~80 ms (measured), long enough to overflow the input queues at a fast replay.
    gc.freeze()

    def on_signal(signum, _frame):
        if not stop.is_set():
            stop.set()
            return
        # Asked twice: leave now, saying what is lost.
        rclpy.logging.get_logger(NODE_NAME).warning(
            f'{signal.Signals(signum).name} again: exiting at once, {node.waiting} estimate(s) '
            f'per corner not published')
        os._exit(EXIT_INTERRUPTED)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    try:
        spin(node, stop=stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node.context.ok():
            node.finish()
        summary = node.summary()
        node.destroy_node()
        rclpy.try_shutdown()
        # rclpy restores the handlers it found at init: keep ours, a second signal must still
        # exit at once, never kill the process half-way through its summary.
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, on_signal)
        # After destroy_node: the context may be gone, so no /rosout publication.
        rclpy.logging.get_logger(NODE_NAME).info(summary)
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
