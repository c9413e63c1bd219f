# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Licence header check (ament_copyright has no PyPI wheel, so this is our own)."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEADER = ('# Copyright 2026 wheel_force_estimator contributors',
          '# SPDX-License-Identifier: Apache-2.0')


def _python_files():
    for top in ('wheel_force_estimator', 'test', 'bench'):
        yield from sorted((ROOT / top).rglob('*.py'))
    yield ROOT / 'setup.py'


def test_every_python_file_has_the_licence_header():
    missing = []
    for path in _python_files():
        lines = path.read_text(encoding='utf-8').splitlines()
        if tuple(lines[:2]) != HEADER:
            missing.append(str(path.relative_to(ROOT)))
    assert not missing, 'files without the licence header:\n' + '\n'.join(missing)


def test_licence_file_matches_package_xml():
    text = (ROOT / 'LICENSE').read_text()
    assert 'Apache License' in text and 'Version 2.0' in text
    assert '<license>Apache-2.0</license>' in (ROOT / 'package.xml').read_text()
