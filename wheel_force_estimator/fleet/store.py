# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Results kept in ``--out`` so that a rerun skips finished bags, and atomic file writes.

Each finished bag's result is one small JSON file ``results/<key>.json``, where the key is a
hash of the bag's absolute path, size and modification time (:func:`.discover.bag_signature`)
and of the run's settings (model file hash, Basquin exponent, params file text,
``--write-forces``).  A changed bag, model or setting therefore gets a new key and is
processed again; only ``ok`` results are kept, so a failed bag is retried on the next run.
Every file is written to a temporary name in the same directory and renamed
(``os.replace``), so a crash leaves the old file or the new one, never a part.
"""
import hashlib
import json
import os
from pathlib import Path
import tempfile
from typing import Optional

from wheel_force_estimator.fleet.discover import bag_signature
from wheel_force_estimator.fleet.discover import BagRef
from wheel_force_estimator.fleet.result import BagResult

RESULTS_DIR = 'results'


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file and a rename; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.tmp', dir=path.parent)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8', newline='') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise
    return path


class ResultStore:
    """
    The finished bags of ``--out`` for one model and setting.

    Parameters
    ----------
    out_dir : str or os.PathLike
        The run's output directory.
    settings_key : dict
        What the results depend on besides the bag (:meth:`.task.FleetSettings.key`).

    """

    def __init__(self, out_dir, settings_key: dict):
        self._dir = Path(out_dir) / RESULTS_DIR
        self._settings = json.dumps(settings_key, sort_keys=True)

    def key(self, ref: BagRef) -> str:
        """Return the store key of a bag (changes with its path, size, mtime and settings)."""
        size, mtime_ns = bag_signature(ref.path)
        text = json.dumps([str(Path(ref.path).resolve()), ref.bag_id, size, mtime_ns,
                           self._settings])
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def get(self, key: str) -> Optional[BagResult]:
        """Return the stored result for ``key``, or None (missing or unreadable)."""
        try:
            return BagResult.from_dict(json.loads((self._dir / f'{key}.json').read_text()))
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError):
            return None  # a damaged entry is recomputed, never trusted

    def put(self, key: str, result: BagResult) -> None:
        """Store an ``ok`` result atomically (failed ones are not kept: a rerun retries)."""
        if result.ok:
            atomic_write_text(self._dir / f'{key}.json', json.dumps(result.to_dict()))
