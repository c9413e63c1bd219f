# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
``run_fleet``: find the bags, skip the finished ones, run the rest on Dask, write the tables.

Order of work: the model is checked once (a model that is not a spindle-acceleration to
wheel-force model is refused before any cluster starts); every PATH must hold a bag; bags with
a stored result for the same path, size, mtime and settings are taken from ``--out``; the
others become one task each.  Each finished bag's result is stored the moment it arrives, so
an interrupted run loses only the bags in flight.  ``fleet.csv`` and ``fleet.json`` are
written (atomically) only when every bag has a row; an interrupted run writes neither.
"""
import dataclasses
import json
from pathlib import Path
from typing import Callable, Optional, Sequence, Tuple

from wheel_force_estimator.fleet.discover import BagRef
from wheel_force_estimator.fleet.discover import file_sha256
from wheel_force_estimator.fleet.discover import find_bags
from wheel_force_estimator.fleet.engine import dask_client
from wheel_force_estimator.fleet.engine import run_tasks
from wheel_force_estimator.fleet.result import BagResult
from wheel_force_estimator.fleet.store import atomic_write_text
from wheel_force_estimator.fleet.store import ResultStore
from wheel_force_estimator.fleet.summary import fleet_csv
from wheel_force_estimator.fleet.summary import fleet_document
from wheel_force_estimator.fleet.summary import Reference
from wheel_force_estimator.fleet.task import FleetSettings
from wheel_force_estimator.fleet.task import FORCES_DIR
from wheel_force_estimator.fleet.task import process_bag

#: Default customer usage the reference schedule must represent [h]: a 240 000 km vehicle
#: life at a 40 km/h average speed.  Set ``--target-hours`` to your own durability target.
DEFAULT_TARGET_HOURS = 6000.0
CSV_NAME = 'fleet.csv'
JSON_NAME = 'fleet.json'
REFERENCE_ID = 'reference'


@dataclasses.dataclass(frozen=True)
class FleetOutcome:
    """
    What a finished run produced.

    Attributes
    ----------
    results : tuple of BagResult
        One per fleet bag, sorted by path.
    reference_results : tuple of BagResult
        One per ``--reference`` bag.
    reference : Reference or None
        The reference schedule when every reference bag is ok.
    document : dict
        The ``fleet.json`` content.
    n_cached, n_computed : int
        Bags taken from ``--out`` / processed in this run (fleet and reference).
    csv_path, json_path : pathlib.Path
        The written tables.

    """

    results: Tuple[BagResult, ...]
    reference_results: Tuple[BagResult, ...]
    reference: Optional[Reference]
    document: dict
    n_cached: int
    n_computed: int
    csv_path: Path
    json_path: Path

    @property
    def failed(self) -> Tuple[BagResult, ...]:
        """Return the failed rows (fleet and reference)."""
        return tuple(r for r in self.results + self.reference_results if not r.ok)


def run_fleet(model_path, paths: Sequence, out_dir, *, reference_paths: Sequence = (),
              scheduler: Optional[str] = None, workers: Optional[int] = None,
              write_forces: bool = False, config_path=None, sn_slope: float = 5.0,
              target_hours: float = DEFAULT_TARGET_HOURS,
              on_result: Optional[Callable[[BagResult, int, int], None]] = None,
              task=process_bag, sn_slope_moment: Optional[float] = None) -> FleetOutcome:
    """
    Process every bag under ``paths`` and write ``fleet.csv`` and ``fleet.json``.

    Parameters
    ----------
    model_path : str or os.PathLike
        Model file (.npz), on a filesystem the workers share.
    paths : sequence of str or os.PathLike
        Bags, or directories searched recursively.
    out_dir : str or os.PathLike
        Output directory (tables, stored results, ``forces/``).
    reference_paths : sequence, optional
        Bags of the proving-ground schedule (driven once).
    scheduler : str, optional
        Address of a running Dask scheduler; None starts a LocalCluster.
    workers : int, optional
        LocalCluster worker processes (default: the usable cores).
    write_forces : bool
        Write each bag's predicted forces to ``out_dir/forces/<bag id>`` as ``predict`` does.
    config_path : str or os.PathLike, optional
        Params file (topic names).
    sn_slope : float
        Basquin exponent ``k``.
    target_hours : float
        Customer usage the reference schedule must represent [h].
    on_result : callable, optional
        Called as ``on_result(result, n_done, n_total)`` after each bag (cached ones too).
    task : callable
        The per-bag function run on the workers (default :func:`.task.process_bag`).
    sn_slope_moment : float, optional
        Basquin exponent of the wheel moments (default ``sn_slope``).

    Returns
    -------
    FleetOutcome

    Raises
    ------
    ModelFileError
        The model cannot be loaded or is not a spindle-acceleration model.
    FleetError
        A PATH without bags, an unreachable scheduler.

    """
    from wheel_force_estimator.core.model import load_model
    from wheel_force_estimator.core.spindle import spindle_layout

    model = load_model(model_path)
    spindle_layout(model, str(model_path))
    out = Path(out_dir)
    exclude = [out]
    references = [BagRef(r.path, f'{REFERENCE_ID}/{r.bag_id}')
                  for r in (find_bags(reference_paths, exclude) if reference_paths else [])]
    reference_set = {str(Path(r.path).resolve()) for r in references}
    fleet = [r for r in find_bags(paths, exclude)
             if str(Path(r.path).resolve()) not in reference_set]
    settings = FleetSettings(
        model_path=str(Path(model_path).resolve()), model_sha256=file_sha256(model_path),
        sn_slope=float(sn_slope),
        config_path=None if config_path is None else str(Path(config_path).resolve()),
        forces_dir=str((out / FORCES_DIR).resolve()) if write_forces else None,
        sn_slope_moment=None if sn_slope_moment is None else float(sn_slope_moment))
    store = ResultStore(out, settings.key())
    everything = fleet + references
    keys = {r.path: store.key(r) for r in everything}
    done = {}
    for ref in everything:
        cached = store.get(keys[ref.path])
        if cached is not None and cached.forces is not None and not Path(cached.forces).is_dir():
            cached = None  # its forces bag was deleted since: write it again
        if cached is not None:
            # the same bag named the way this run names it (./fleet vs fleet)
            cached = dataclasses.replace(cached, path=ref.path)
            done[ref.path] = cached
            if on_result is not None:
                on_result(cached, len(done), len(everything))
    n_cached = len(done)
    pending = [r for r in everything if r.path not in done]
    if pending:
        with dask_client(scheduler, workers) as client:
            for ref, result in run_tasks(client, pending, settings, task):
                store.put(keys[ref.path], result)
                done[ref.path] = result
                if on_result is not None:
                    on_result(result, len(done), len(everything))
    results = tuple(done[r.path] for r in fleet)
    ref_results = tuple(done[r.path] for r in references)
    reference = (Reference(ref_results, float(target_hours))
                 if ref_results and all(r.ok for r in ref_results) else None)
    document = fleet_document(results, reference, float(sn_slope), str(model_path))
    document['target_hours'] = float(target_hours)
    if ref_results and reference is None:
        document['reference_error'] = '; '.join(f'{r.path}: {r.error}' for r in ref_results
                                                if not r.ok)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = atomic_write_text(out / CSV_NAME, fleet_csv(results, model.output_channels))
    json_path = atomic_write_text(out / JSON_NAME, json.dumps(document, indent=1))
    return FleetOutcome(results, ref_results, reference, document, n_cached,
                        len(pending), csv_path, json_path)
