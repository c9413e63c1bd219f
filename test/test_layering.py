# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The import graph keeps the layers: the library never imports the commands or the node.

Read from the source (every ``import`` statement, including those inside functions), so an
import that only runs on some path is caught too.
"""
import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / 'wheel_force_estimator'
#: Subpackage -> the subpackages it must not import.
FORBIDDEN = {
    'core': {'cli', 'ros', 'bagio', 'daqio', 'sim', 'diagnosis', 'fleet', 'report'},
    'bagio': {'cli', 'ros', 'diagnosis', 'fleet', 'report', 'sim'},
    'daqio': {'cli', 'ros', 'diagnosis', 'fleet', 'report', 'sim'},
    'fleet': {'cli', 'ros'},
    'diagnosis': {'cli', 'ros'},
    'sim': {'cli', 'ros', 'diagnosis', 'fleet'},
    'report': {'cli', 'ros', 'fleet'},
}


def _imports(path):
    """Return every ``wheel_force_estimator`` module that ``path`` imports."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f'{path}: relative import (the package imports absolutely)'
            names.append(node.module)
            if node.module == 'wheel_force_estimator':  # from wheel_force_estimator import cli
                names += [f'{node.module}.{alias.name}' for alias in node.names]
    return [n for n in names if n.startswith('wheel_force_estimator.')]


def _layer(module):
    return module.split('.')[1]


def _violations(subpackage):
    found = []
    for path in sorted((PACKAGE / subpackage).rglob('*.py')):
        for module in _imports(path):
            if _layer(module) in FORBIDDEN[subpackage]:
                found.append(f'{path.relative_to(PACKAGE.parent)} imports {module}')
    return found


@pytest.mark.parametrize('subpackage', sorted(FORBIDDEN))
def test_library_layers_do_not_import_upwards(subpackage):
    assert not _violations(subpackage)


def test_the_check_sees_an_upward_import(tmp_path, monkeypatch):
    # A checker that parsed nothing would pass the test above: plant one violation.
    layer = tmp_path / 'wheel_force_estimator' / 'fleet'
    layer.mkdir(parents=True)
    (layer / 'task.py').write_text('def f():\n    from wheel_force_estimator.cli import x\n')
    monkeypatch.setitem(globals(), 'PACKAGE', tmp_path / 'wheel_force_estimator')
    assert _violations('fleet') == ['wheel_force_estimator/fleet/task.py imports '
                                    'wheel_force_estimator.cli']


def test_no_private_name_is_imported_from_another_module():
    # Names used across modules are public: a leading underscore says "only here".
    found = []
    for path in sorted(PACKAGE.rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.module:
                found += [f'{path.relative_to(PACKAGE.parent)}: {node.module}.{alias.name}'
                          for alias in node.names
                          if alias.name.startswith('_') and not alias.name.startswith('__')]
    assert not found
