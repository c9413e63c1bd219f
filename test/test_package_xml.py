# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
package.xml is a valid format-3 manifest with the dependencies the code needs.

catkin_pkg is the parser colcon and rosdep use; it enforces the REP 149 (format 3) rules.
"""
from pathlib import Path

from catkin_pkg.package import parse_package
from lxml import etree

ROOT = Path(__file__).resolve().parents[1]


def test_package_xml_parses_as_format_3():
    warnings = []
    pkg = parse_package(str(ROOT / 'package.xml'), warnings=warnings)
    assert pkg.package_format == 3
    assert pkg.name == 'wheel_force_estimator'
    assert not warnings, warnings
    assert pkg.get_build_type() == 'ament_python'


# Third-party top-level modules the package imports -> their rosdep key in package.xml
# (None: no rosdep key exists; installed by pip, see the README).
RUN_KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'matplotlib': 'python3-matplotlib',
    'yaml': 'python3-yaml', 'tqdm': 'python3-tqdm', 'numba': 'python3-numba', 'rosbags': None,
    'rclpy': 'rclpy', 'rcl_interfaces': 'rcl_interfaces',
    'builtin_interfaces': 'builtin_interfaces', 'sensor_msgs': 'sensor_msgs',
    'geometry_msgs': 'geometry_msgs', 'std_msgs': 'std_msgs',
    'diagnostic_msgs': 'diagnostic_msgs', 'ament_index_python': 'ament_index_python',
    'launch': 'launch', 'launch_ros': 'launch_ros', 'std_srvs': 'std_srvs',
    'lifecycle_msgs': 'lifecycle_msgs',
    # optional speed-ups, imported only when installed
    'isal': None,
    # rosbags' own dependencies (zstd / lz4 chunks, sqlite3 bags), come with it
    'compression': None, 'backports': None, 'zstandard': None, 'lz4': None, 'apsw': None,
    # other engineers' work in progress (fleet command)
    'dask': 'python3-dask', 'distributed': 'python3-distributed',
    # MATLAB v7.3 (HDF5) recordings
    'h5py': 'python3-h5py',
}
TEST_KEYS = {
    'pytest': 'python3-pytest', 'pytest_timeout': 'python3-pytest-timeout',
    'catkin_pkg': 'python3-catkin-pkg', 'lxml': 'etree', 'mcap': None,
    'ament_copyright': 'ament_copyright', 'ament_flake8': 'ament_flake8',
    'ament_pep257': 'ament_pep257', 'rosgraph_msgs': 'rosgraph_msgs',
    # the lifecycle services the tests call (an exec dependency: rclpy.lifecycle needs it)
    'lifecycle_msgs': 'lifecycle_msgs',
}


def _imported_modules(paths):
    """Top-level modules imported anywhere in ``paths`` (import statements, parsed)."""
    import ast
    names = set()
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names


def test_package_xml_dependencies_cover_every_import():
    """A missing run/test dependency (an import with no key) fails here, by name."""
    import sys
    pkg = parse_package(str(ROOT / 'package.xml'))
    execs = {d.name for d in pkg.exec_depends}
    tests = {d.name for d in pkg.test_depends}
    stdlib = set(sys.stdlib_module_names) | {'wheel_force_estimator'}
    code = list((ROOT / 'wheel_force_estimator').rglob('*.py'))
    code += list((ROOT / 'launch').glob('*.py'))
    third_party = _imported_modules(code) - stdlib
    unknown = third_party - set(RUN_KEYS)
    assert not unknown, f'imports without a package.xml mapping: {sorted(unknown)}'
    for module in third_party:
        key = RUN_KEYS[module]
        if key is not None and module not in ('dask', 'distributed'):
            assert key in execs, f'{module}: <exec_depend>{key}</exec_depend> missing'
    test_modules = _imported_modules((ROOT / 'test').rglob('*.py')) - stdlib - third_party
    # the tests' own helper modules (test/*.py, the test/support package) are not dependencies
    test_modules -= {'conftest', 'benchutil', 'support'}
    test_modules -= {p.stem for p in (ROOT / 'test').glob('*.py')}
    test_modules -= {p.name for p in (ROOT / 'test').iterdir() if (p / '__init__.py').is_file()}
    unknown = test_modules - set(TEST_KEYS)
    assert not unknown, f'test imports without a package.xml mapping: {sorted(unknown)}'
    for module in test_modules:
        key = TEST_KEYS[module]
        if key == 'etree':
            key = 'python3-lxml'
        if key is not None:
            # what the package runs with is there for its tests too
            assert key in tests | execs, f'{module}: <test_depend>{key}</test_depend> missing'
    # pytest-timeout is a plugin (a marker, not an import)
    assert 'python3-pytest-timeout' in tests


def test_setup_py_has_the_test_extras_colcon_needs():
    text = (ROOT / 'setup.py').read_text()
    assert "'test': ['pytest', 'pytest-timeout'" in text
    assert "glob('launch/*.launch.py')" in text
    assert (ROOT / 'wheel_force_estimator' / 'py.typed').is_file()
    assert "package_data={package_name: ['py.typed']}" in text


def test_package_xml_is_well_formed_with_schema_reference():
    tree = etree.parse(str(ROOT / 'package.xml'))
    root = tree.getroot()
    assert root.tag == 'package' and root.get('format') == '3'
    pis = list(tree.xpath('/processing-instruction("xml-model")'))
    assert pis and 'package_format3.xsd' in pis[0].text


def test_setup_py_installs_ament_index_marker_and_config():
    text = (ROOT / 'setup.py').read_text()
    assert "'resource/' + package_name" in text
    assert (ROOT / 'resource' / 'wheel_force_estimator').is_file()
    assert (ROOT / 'config' / 'wheel_force.yaml').is_file()
    cfg = (ROOT / 'setup.cfg').read_text()
    assert 'script_dir=$base/lib/wheel_force_estimator' in cfg
    assert 'install_scripts=$base/lib/wheel_force_estimator' in cfg
