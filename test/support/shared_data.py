# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The real datasets in ``../shared/data/``, read in place (never copied).

In CI (``CI=true``) the folder is part of the checkout's surroundings, so a missing dataset is
a broken setup and its tests fail; elsewhere (a clone without ``../shared``) they skip with the
folder named.
"""
import os
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[3] / 'shared' / 'data'


def in_ci():
    """Return True when the run is a CI run (``CI=true``, as CI services set it)."""
    return os.environ.get('CI', '').strip().lower() in ('true', '1', 'yes')


def dataset(name):
    """
    Return the folder ``../shared/data/<name>``, or fail (CI) or skip (elsewhere) without it.

    Parameters
    ----------
    name : str
        Folder name below ``../shared/data``.

    Returns
    -------
    pathlib.Path
        The dataset folder.

    """
    path = SHARED_DATA / name
    if not path.is_dir():
        message = f'real dataset folder {path} is absent'
        if in_ci():
            pytest.fail(f'{message}: CI=true needs ../shared/data beside the checkout')
        pytest.skip(message)
    return path
