# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The tests' cleaner of Fast DDS shared memory a hard-killed participant left behind."""
import fcntl
import os
import signal
import subprocess
import sys

import pytest
from support.ros_testing import remove_dead_shared_memory

PARTICIPANT = ('import sys, rclpy\n'
               'rclpy.init()\n'
               "node = rclpy.create_node('shm_probe')\n"
               "print('up', flush=True)\n"
               'sys.stdin.read()\n')


def _port(shm_dir, name):
    for file_name in (name, f'{name}_el', f'sem.{name}_mutex'):
        (shm_dir / file_name).write_bytes(b'')


def test_only_ports_and_segments_whose_lock_nobody_holds_are_removed(tmp_path):
    _port(tmp_path, 'fastrtps_port7413')          # its owner died
    _port(tmp_path, 'fastrtps_port7415')          # its owner (this test) holds the lock
    (tmp_path / 'fastrtps_0123456789abcdef').write_bytes(b'')        # a dead segment
    (tmp_path / 'fastrtps_0123456789abcdef_el').write_bytes(b'')
    (tmp_path / 'fastrtps_port7417').write_bytes(b'')                # no lock file: kept
    (tmp_path / 'other_program_el').write_bytes(b'')                 # not Fast DDS: kept
    with open(tmp_path / 'fastrtps_port7415_el', 'ab') as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert remove_dead_shared_memory(tmp_path) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'fastrtps_port7415', 'fastrtps_port7415_el', 'fastrtps_port7417', 'other_program_el',
        'sem.fastrtps_port7415_mutex']


@pytest.mark.ros
def test_a_killed_participants_ports_go_and_a_live_ones_stay(ros_env):
    def start():
        proc = subprocess.Popen([sys.executable, '-c', PARTICIPANT], env=ros_env,
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == 'up'
        return proc

    def owned(proc):
        # a port's or segment's owner keeps its lock file open (other participants map the
        # port to write to it, and may also map a dead one's)
        links = [os.readlink(f'/proc/{proc.pid}/fd/{fd}')
                 for fd in os.listdir(f'/proc/{proc.pid}/fd')]
        return {link[:-3] for link in links
                if link.startswith('/dev/shm/fastrtps_') and link.endswith('_el')}

    live, killed = start(), start()
    try:
        live_own, killed_own = owned(live), owned(killed)
        assert killed_own, 'no shared-memory port'       # LOCALHOST: shared memory in use
        killed.send_signal(signal.SIGKILL)
        killed.wait()
        assert all(os.path.exists(f) for f in killed_own)          # left behind
        assert remove_dead_shared_memory() >= len(killed_own)
        assert not any(os.path.exists(f) or os.path.exists(f + '_el') for f in killed_own)
        assert all(os.path.exists(f) and os.path.exists(f + '_el') for f in live_own)
    finally:
        for proc in (live, killed):
            proc.stdin.close()
            proc.wait(10)
