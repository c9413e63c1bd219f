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


def test_package_xml_dependencies():
    pkg = parse_package(str(ROOT / 'package.xml'))
    execs = {d.name for d in pkg.exec_depends}
    assert {'rclpy', 'sensor_msgs', 'geometry_msgs', 'std_msgs', 'diagnostic_msgs',
            'python3-numpy', 'python3-scipy', 'python3-matplotlib',
            'python3-rosbags-pip'} <= execs
    tests = {d.name for d in pkg.test_depends}
    assert {'ament_copyright', 'ament_flake8', 'ament_pep257', 'python3-pytest'} <= tests


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
