# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The batch commands keep freed memory for reuse: a second large array faults no page in."""
import json
import subprocess
import sys

import pytest

#: Bytes of the array filled twice: above glibc's largest mmap threshold (32 MiB), so by
#: default it is a fresh mapping each time.
SIZE = 64 * 2**20
#: Fewest page faults that fill a fresh mapping of SIZE: one per 2 MiB (the largest page
#: transparent huge pages give on x86-64; 4 KiB pages fault 16384 times).
FRESH_FAULTS = SIZE // 2**21
#: Faults of other small allocations allowed during the fill (none measured).
SLACK = 8

CHILD = f"""
import json, resource, sys
import numpy as np
from wheel_force_estimator.cli.heap import keep_freed_memory
from wheel_force_estimator.cli.main import main
argv = json.loads(sys.argv[1])
if argv == ['keep']:
    assert keep_freed_memory()
elif argv:
    assert main(argv) == 1        # fails on the missing file, after the allocator is set

def faults_of_one_fill():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = np.ones({SIZE} // 8)
    del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

faults_of_one_fill()
print(faults_of_one_fill())
"""


def second_fill_faults(argv) -> int:
    """Return the minor page faults of the second fill of a freed 64 MiB array in a child."""
    out = subprocess.run([sys.executable, '-c', CHILD, json.dumps(argv)], check=True,
                         capture_output=True, text=True)
    return int(out.stdout.split()[-1])


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='glibc mallopt')
def test_freed_memory_is_reused_by_the_next_array_of_its_size():
    assert second_fill_faults(['keep']) <= SLACK
    assert second_fill_faults([]) >= FRESH_FAULTS        # the default maps it afresh


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='glibc mallopt')
def test_batch_commands_keep_freed_memory_and_replay_gives_it_back():
    missing = ['/nonexistent/model.npz', '/nonexistent/bag']
    assert second_fill_faults(['predict', *missing, '-o', '/nonexistent/out']) <= SLACK
    assert second_fill_faults(['evaluate', *missing]) <= SLACK
    # replay is a long-lived ROS process: it keeps glibc's default, which gives memory back
    assert second_fill_faults(['replay', missing[1]]) >= FRESH_FAULTS
