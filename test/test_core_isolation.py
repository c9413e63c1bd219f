# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The numeric core imports in a process where rclpy (and friends) cannot be imported."""
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = r"""
import importlib, pkgutil, sys

class Block:
    BLOCKED = ('rclpy', 'matplotlib', 'rosbags', 'sensor_msgs', 'geometry_msgs')
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in self.BLOCKED:
            raise ImportError(f'blocked: {name}')
        return None

sys.meta_path.insert(0, Block())
import wheel_force_estimator.core as core
names = [m.name for m in pkgutil.iter_modules(core.__path__)]
for name in names:
    importlib.import_module(f'wheel_force_estimator.core.{name}')
leaked = [m for m in sys.modules if m.split('.')[0] in Block.BLOCKED]
assert not leaked, leaked
print(len(names))
"""


def test_core_imports_without_ros_or_matplotlib():
    proc = subprocess.run([sys.executable, '-c', SCRIPT], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    # at least errors, validation, model, predict, pipeline, evaluation and the helpers' modules
    assert int(proc.stdout.strip().splitlines()[-1]) >= 6
