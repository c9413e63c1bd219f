# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Find the bags of a fleet and say when a bag or a model file has changed.

A bag is a rosbag2 directory (one holding ``metadata.yaml``) or a ROS 1 ``.bag`` file.  A
PATH that is a directory but no bag is searched recursively; a rosbag2 directory is never
searched further (its ``.mcap``/``.db3`` files are part of it).  Directories listed in
``exclude`` (the run's own ``--out``) are skipped, so predicted-force bags written there are
never taken for customer recordings.
"""
import dataclasses
import hashlib
import os
from pathlib import Path
from typing import Iterable, List, Sequence, Tuple

from wheel_force_estimator.fleet.errors import FleetError

_ROS1_SUFFIX = '.bag'
_ROSBAG2_MARKER = 'metadata.yaml'


@dataclasses.dataclass(frozen=True)
class BagRef:
    """
    One bag of the fleet.

    Attributes
    ----------
    path : str
        The bag as found (PATH joined with the part below it).
    bag_id : str
        The bag's name relative to the PATH it was found under (``car_042/run_07``); the
        bag's own name when PATH is the bag.  Unique within a run.

    """

    path: str
    bag_id: str


def is_bag(path: Path) -> bool:
    """Return whether ``path`` is a rosbag2 directory or a ROS 1 bag file."""
    if path.is_dir():
        return (path / _ROSBAG2_MARKER).is_file()
    return path.is_file() and path.suffix == _ROS1_SUFFIX


def _walk(root: Path, excluded: Tuple[Path, ...]) -> Iterable[Path]:
    for dirpath, dirnames, filenames in os.walk(root):
        here = Path(dirpath)
        if here.resolve() in excluded:
            dirnames[:] = []
            continue
        if _ROSBAG2_MARKER in filenames:
            dirnames[:] = []
            yield here
            continue
        dirnames.sort()
        for name in sorted(filenames):
            if name.endswith(_ROS1_SUFFIX):
                yield here / name


def find_bags(paths: Sequence, exclude: Sequence = ()) -> List[BagRef]:
    """
    Return the bags under every PATH, in a stable order.

    Parameters
    ----------
    paths : sequence of str or os.PathLike
        Bags or directories to search recursively.
    exclude : sequence of str or os.PathLike
        Directories never searched (the run's output directory).

    Returns
    -------
    list of BagRef
        Sorted by path; a bag reached through two PATHs is listed once.

    Raises
    ------
    FleetError
        A PATH that does not exist or holds no bag (the PATH is named).

    """
    excluded = tuple(Path(p).resolve() for p in exclude)
    found = {}
    for given in paths:
        root = Path(given)
        if not root.exists():
            raise FleetError(f'{given}: no such file or directory')
        if is_bag(root):
            bags = [(root, root.name)]
        else:
            bags = [(bag, bag.relative_to(root).as_posix()) for bag in _walk(root, excluded)]
        if not bags:
            raise FleetError(f'{given}: no bags found (rosbag2 directories with '
                             f'{_ROSBAG2_MARKER} or ROS 1 {_ROS1_SUFFIX} files, searched '
                             f'recursively)')
        for bag, bag_id in bags:
            found.setdefault(str(bag.resolve()), (str(bag), bag_id))
    ids = [bag_id for _, bag_id in found.values()]
    refs = []
    for path, bag_id in found.values():
        # two PATHs may hold bags of the same relative name: fall back to the full path
        refs.append(BagRef(path, bag_id if ids.count(bag_id) == 1 else path))
    return sorted(refs, key=lambda r: r.path)


def bag_signature(path) -> Tuple[int, int]:
    """
    Return ``(size_bytes, mtime_ns)`` of a bag; for a directory, over every file in it.

    A rosbag2 directory's size is the sum of its files' sizes and its time the newest
    file's, so a bag still being copied or re-recorded gets a new signature.
    """
    path = Path(path)
    if path.is_file():
        st = path.stat()
        return st.st_size, st.st_mtime_ns
    size, mtime_ns = 0, path.stat().st_mtime_ns
    for dirpath, _, filenames in os.walk(path):
        for name in filenames:
            st = (Path(dirpath) / name).stat()
            size += st.st_size
            mtime_ns = max(mtime_ns, st.st_mtime_ns)
    return size, mtime_ns


def file_sha256(path) -> str:
    """Return the SHA-256 (hex) of a file's bytes, e.g. the model's."""
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()
