# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
launch/wheel_force.launch.py with the real ``launch`` / ``launch_ros``.

On a ROS 2 install they come from apt; here (no PyPI wheels) from the Jazzy sources in
``../shared/vendor/ros2_launch_jazzy`` (README there), put on ``sys.path`` by a fixture only
when ``launch_ros`` is not importable.  The package is found through a throwaway install
prefix (``share/`` with the params file, ``lib/wheel_force_estimator/wheel_force_node``), as
``colcon build`` would lay it out.
"""
import ast
import importlib.util
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'wheel_force.launch.py'
CONFIG = ROOT / 'config' / 'wheel_force.yaml'
VENDOR = ROOT.parent / 'shared' / 'vendor' / 'ros2_launch_jazzy'
RUN_LAUNCH = Path(__file__).resolve().parent / 'support' / 'run_launch.py'
PACKAGE = 'wheel_force_estimator'


def _tables():
    tree = ast.parse(LAUNCH_FILE.read_text())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            name = getattr(node.targets[0], 'id', None)
            if name in ('ARGUMENTS', 'PARAMETER_ARGUMENTS', 'PACKAGE'):
                out[name] = ast.literal_eval(node.value)
    return out


def test_launch_arguments_are_the_contract_and_map_to_declared_parameters():
    params = pytest.importorskip('wheel_force_estimator.ros.params',
                                 reason='rclpy (ROS 2 Jazzy wheels) not importable')
    tables = _tables()
    assert tables['PACKAGE'] == PACKAGE
    assert set(tables['ARGUMENTS']) == {'model', 'namespace', 'params_file', 'use_sim_time',
                                        'autostart', 'log_level', 'respawn'}
    mapped = tables['PARAMETER_ARGUMENTS']
    assert set(mapped) <= set(tables['ARGUMENTS'])
    assert set(mapped.values()) <= params.PARAMETER_NAMES, mapped
    assert mapped['model'] == 'model_path'
    # an argument that sets a parameter must default to "not given"
    assert all(tables['ARGUMENTS'][arg][0] == '' for arg in mapped)
    # the file is installed with the package (setup.py data_files)
    assert "glob('launch/*.launch.py')" in (ROOT / 'setup.py').read_text()


@pytest.fixture
def launch_path(monkeypatch):
    """Make ``launch`` / ``launch_ros`` importable; return the PYTHONPATH entries it took."""
    spec = importlib.util.find_spec('launch_ros')
    if spec is not None and not str(spec.origin).startswith(str(VENDOR)):
        return []                               # a real ROS 2 install
    if not VENDOR.is_dir():
        pytest.skip(f'no launch_ros installed and no vendored sources at {VENDOR}')
    entries = [str(VENDOR), str(VENDOR / 'stubs')]
    for entry in reversed(entries):
        monkeypatch.syspath_prepend(entry)
    return entries


@pytest.fixture
def prefix(tmp_path, monkeypatch):
    """Return an install prefix holding the package as colcon would; on AMENT_PREFIX_PATH."""
    root = tmp_path / 'install'
    index = root / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / PACKAGE).write_text('')
    config = root / 'share' / PACKAGE / 'config'
    config.mkdir(parents=True)
    (config / 'wheel_force.yaml').write_text(CONFIG.read_text())
    lib = root / 'lib' / PACKAGE
    lib.mkdir(parents=True)
    exe = lib / 'wheel_force_node'
    exe.write_text(f'#!{sys.executable}\nimport sys\n'
                   f'from wheel_force_estimator.ros.run import main\nsys.exit(main())\n')
    exe.chmod(0o755)
    monkeypatch.setenv('AMENT_PREFIX_PATH', os.pathsep.join(
        [str(root)] + [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                       if p]))
    return root


def _load_launch_module():
    spec = importlib.util.spec_from_file_location('wheel_force_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def node_gets(arguments):
    """
    Return (parameters, command line) the node would get from ``ros2 launch ... arguments``.

    The description is built and its arguments declared with the real launch; the node's
    ``parameters`` are evaluated by launch_ros, then merged as rcl merges them (the params
    file's ``/**`` section, then the overrides in order).
    """
    from launch import LaunchContext
    from launch.actions import DeclareLaunchArgument
    from launch.actions import OpaqueFunction
    from launch.utilities import perform_substitutions
    from launch_ros.utilities import evaluate_parameters
    from launch_ros.utilities import normalize_parameters
    module = _load_launch_module()
    description = module.generate_launch_description()
    context = LaunchContext()
    context.launch_configurations.update(arguments)
    for entity in description.entities:
        if isinstance(entity, DeclareLaunchArgument):
            entity.execute(context)             # fills in the defaults of what is not given
    opaque, = [e for e in description.entities if isinstance(e, OpaqueFunction)]
    node, = opaque.execute(context)
    merged = {}
    for item in evaluate_parameters(context, normalize_parameters(
            module.node_parameters(context))):
        if isinstance(item, dict):
            merged.update(item)
        else:
            doc = yaml.safe_load(Path(item).read_text())
            merged.update(doc['/**']['ros__parameters'])
    # What launch_ros fills in when it runs the node (name and namespace remaps).
    context.extend_locals({'ros_specific_arguments': {'name': '__node:=wheel_force_node',
                                                      'ns': '__ns:=/'}})
    cmd = [perform_substitutions(context, part) for part in node.cmd]
    return merged, cmd


def test_params_file_alone_names_the_model(launch_path, prefix, tmp_path):
    # Bug caught (issue 31): model:= always overriding model_path, with '' when not given.
    car = tmp_path / 'car.yaml'
    car.write_text(CONFIG.read_text().replace('model_path: ""', 'model_path: "/cars/car.npz"'))
    params, cmd = node_gets({'params_file': str(car)})
    assert params['model_path'] == '/cars/car.npz'
    assert params['autostart'] is True and 'use_sim_time' not in params
    at = cmd.index('--log-level')
    assert cmd[at + 1] == 'info'


def test_model_and_flag_arguments_override_the_params_file_when_given(
        launch_path, prefix, tmp_path):
    car = tmp_path / 'car.yaml'
    car.write_text(CONFIG.read_text().replace('model_path: ""', 'model_path: "/cars/car.npz"')
                   .replace('autostart: true', 'autostart: false'))
    params, cmd = node_gets({'params_file': str(car), 'model': '/cars/other.npz',
                             'use_sim_time': 'true', 'log_level': 'debug'})
    assert params['model_path'] == '/cars/other.npz'
    assert params['use_sim_time'] is True
    assert params['autostart'] is False                 # not given: the file's value
    at = cmd.index('--log-level')
    assert cmd[at + 1] == 'debug'
    # the installed params file is the default
    params, _ = node_gets({'model': '/cars/m.npz'})
    assert params['model_path'] == '/cars/m.npz' and params['autostart'] is True


def test_bad_boolean_argument_is_refused(launch_path, prefix):
    with pytest.raises(ValueError, match='respawn:=maybe'):
        node_gets({'respawn': 'maybe'})


def _children(pid):
    path = Path(f'/proc/{pid}/task/{pid}/children')
    return [int(p) for p in path.read_text().split()] if path.exists() else []


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(180)
def test_two_cars_from_the_shipped_launch_file(launch_path, prefix, ros_env, tmp_path):
    # Two `ros2 launch` of the shipped file, one naming the model by argument, one in its
    # params file.  Bugs caught: colliding /diagnostics names between the cars (issue 31), a
    # params file's model lost, respawn or log_level not reaching the node, a stop that
    # launch has to escalate.
    from diagnostic_msgs.msg import DiagnosticArray
    from support.ros_testing import SpinningParticipant
    from support.ros_testing import synthetic_model
    from support.ros_testing import wait_until
    from support.ros_testing import remove_dead_shared_memory

    from wheel_force_estimator.core.model import save_model
    from wheel_force_estimator.ros.diagnostics import status_values
    model = save_model(synthetic_model(delay_samples=48), tmp_path / 'car.npz')
    car2 = tmp_path / 'car2.yaml'
    car2.write_text(CONFIG.read_text().replace('model_path: ""', f'model_path: "{model}"'))
    env = dict(ros_env, AMENT_PREFIX_PATH=os.environ['AMENT_PREFIX_PATH'])
    env['PYTHONPATH'] = os.pathsep.join(launch_path + [env.get('PYTHONPATH', '')])
    runs = {
        '/car1': ['namespace:=/car1', f'model:={model}', 'respawn:=true'],
        '/car2': ['namespace:=/car2', f'params_file:={car2}', 'log_level:=debug'],
    }
    logs = {ns: tmp_path / f'{ns[1:]}.log' for ns in runs}
    procs = {}

    class Monitor(SpinningParticipant):
        def __init__(self):
            super().__init__('robot_monitor')
            self.health = []
            self.sub = self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                                     self.health.append, 100)
            self.start()

    monitor = Monitor()
    try:
        for ns, args in runs.items():
            with open(logs[ns], 'w') as out:
                procs[ns] = subprocess.Popen(
                    [sys.executable, str(RUN_LAUNCH), str(LAUNCH_FILE), *args],
                    env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)

        def names():
            return {s.name for m in list(monitor.health) for s in m.status}
        expected = {f'{ns}/wheel_force_node{suffix}' for ns in runs
                    for suffix in ('', ': lf', ': rf', ': lr', ': rr')}
        assert wait_until(lambda: expected <= names(), 60.0), (
            names(), {ns: log.read_text()[-2000:] for ns, log in logs.items()})
        models = {status_values(s)['model'] for m in list(monitor.health) for s in m.status
                  if s.name in ('/car1/wheel_force_node', '/car2/wheel_force_node')}
        assert models == {str(model)}
        assert '[DEBUG]' in logs['/car2'].read_text()
        assert '[DEBUG]' not in logs['/car1'].read_text()

        # respawn: car1's node killed, launch starts it again
        node_pid, = _children(procs['/car1'].pid)
        os.kill(node_pid, signal.SIGKILL)
        assert wait_until(lambda: _children(procs['/car1'].pid) not in ([], [node_pid]), 30.0)
        seen = len(monitor.health)
        assert wait_until(lambda: any(s.name == '/car1/wheel_force_node'
                                      for m in monitor.health[seen:] for s in m.status), 60.0)

        # Ctrl-C in each terminal (the whole process group, as a terminal sends it): every
        # node stops on its own, before launch would escalate to SIGTERM (5 s).
        started = time.monotonic()
        for proc in procs.values():
            os.killpg(proc.pid, signal.SIGINT)
        codes = [proc.wait(30) for proc in procs.values()]
        elapsed = time.monotonic() - started
    finally:
        monitor.close()
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        # car1's first node was killed with SIGKILL: its shared-memory ports stay behind.
        remove_dead_shared_memory()
    assert codes == [0, 0], {ns: log.read_text()[-2000:] for ns, log in logs.items()}
    assert elapsed < 5.0, {ns: log.read_text()[-3000:] for ns, log in logs.items()}
    for log in logs.values():
        text = log.read_text()
        assert 'SIGTERM' not in text and 'counters per corner' in text
