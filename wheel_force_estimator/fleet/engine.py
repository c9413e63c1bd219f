# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The Dask engine: a cluster to run on, one task per bag, results as they finish.

Without a scheduler address the run starts a ``LocalCluster`` of worker *processes* (one
thread each: the work is NumPy/SciPy and numba, and a process per core keeps one bag's
memory out of the others').  With ``--scheduler tcp://host:8786`` it joins a cluster the
user runs (``dask scheduler`` and ``dask worker`` on each machine; bags, model and ``--out``
on a filesystem every worker sees).

A worker that dies (segfault, killed for memory) has its task retried elsewhere by Dask; a
task that has killed ``ALLOWED_FAILURES + 1`` = 2 workers is given up (``KilledWorker``) and
its bag marked failed; each worker is sent one bag at a time (``WORKER_SATURATION``), so only
the bag that was running is blamed.  These settings apply to the scheduler this run starts;
an existing cluster's scheduler uses its own ``distributed.scheduler.allowed-failures`` and
``worker-saturation`` (set them to 1 and 1.0 in its Dask config for the same rule).
"""
import contextlib
import os
from typing import Dict, Iterator, Optional, Sequence, Tuple
import uuid
import warnings

from wheel_force_estimator.fleet.discover import BagRef
from wheel_force_estimator.fleet.errors import FleetError
from wheel_force_estimator.fleet.result import BagResult
from wheel_force_estimator.fleet.result import failed
from wheel_force_estimator.fleet.task import FleetSettings
from wheel_force_estimator.fleet.task import process_bag

#: Worker deaths a task may cause and still be retried (Dask's ``allowed-failures``).
ALLOWED_FAILURES = 1
#: Tasks a worker holds per thread (Dask's ``worker-saturation``; its default 1.1 sends a
#: second bag to a 1-thread worker while the first runs).  Every task a dying worker holds
#: counts as a suspect, so with 1.1 an innocent bag queued behind a crashing one is blamed
#: too and can be given up with it; 1.0 blames only the bag that was running.
WORKER_SATURATION = 1.0
#: How long to try to reach an existing scheduler before giving up [s].
CONNECT_TIMEOUT_S = 5.0
#: How long a LocalCluster may take to start its workers [s] (generous: a loaded machine).
START_TIMEOUT_S = 120.0


def default_workers() -> int:
    """Return the number of cores this process may use (the ``--workers`` default)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: Background polling of the cluster this run starts, slowed from Dask's defaults (event-loop
#: health tick 20 ms, worker memory check 100 ms, system monitor 500 ms): an idle 1-worker
#: LocalCluster used 0.95 s of CPU per 20 s with the defaults, 0.50 s with these, on tasks that
#: take ~0.7 s of CPU per 2-minute bag.  The memory limit is still enforced, once a second.
QUIET_POLLING = {'distributed.admin.tick.interval': '500ms',
                 'distributed.worker.memory.monitor-interval': '1s',
                 'distributed.admin.system-monitor.interval': '2s'}


def worker_environ() -> dict:
    """
    Return the environment the LocalCluster's worker processes start with.

    Dask's defaults (``distributed.nanny.pre-spawn-environ``: one BLAS/OpenMP thread per
    worker, which is right here) minus ``MALLOC_TRIM_THRESHOLD_``: that setting turns off
    glibc's adaptive mmap threshold, so every large array a task allocates is a fresh mmap
    and is page-faulted again, which measured 2.6-2.8 s of system time against 0.5-1.6 s
    for five 2-minute bags in one process (``bench/bench_fleet.py`` shows the effect).
    """
    import dask
    environ = dict(dask.config.get('distributed.nanny.pre-spawn-environ', default={}) or {})
    environ.pop('MALLOC_TRIM_THRESHOLD_', None)
    return environ


@contextlib.contextmanager
def dask_client(scheduler: Optional[str] = None, workers: Optional[int] = None):
    """
    Yield a ``distributed.Client`` on an existing or a new local cluster.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``); None starts a LocalCluster.
    workers : int, optional
        Worker processes of the LocalCluster (default :func:`default_workers`).

    Raises
    ------
    FleetError
        The scheduler cannot be reached within ``CONNECT_TIMEOUT_S`` (address named), or
        ``workers`` < 1.

    """
    import dask
    from distributed import Client
    from distributed import LocalCluster

    with dask.config.set({'distributed.scheduler.allowed-failures': ALLOWED_FAILURES,
                          'distributed.scheduler.worker-saturation': WORKER_SATURATION,
                          'distributed.comm.timeouts.connect': f'{CONNECT_TIMEOUT_S}s'}):
        if scheduler:
            try:
                client = Client(scheduler, timeout=f'{CONNECT_TIMEOUT_S}s')
            except (OSError, TimeoutError, ValueError) as err:
                raise FleetError(f'cannot reach the Dask scheduler at {scheduler} within '
                                 f'{CONNECT_TIMEOUT_S:g} s: {err}') from err
            with client:
                yield client
            return
        n = default_workers() if workers is None else int(workers)
        if n < 1:
            raise FleetError(f'--workers must be >= 1, got {n}')
        with dask.config.set({'distributed.comm.timeouts.connect': f'{START_TIMEOUT_S}s',
                              'distributed.nanny.pre-spawn-environ': worker_environ(),
                              **QUIET_POLLING}), \
                warnings.catch_warnings():
            # the scheduler's HTTP endpoint (metrics; no dashboard here) moves to a free port
            # when another cluster holds 8787, which it reports as a warning
            warnings.filterwarnings('ignore', message='Port 8787 is already in use')
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
        with cluster, Client(cluster, timeout=f'{START_TIMEOUT_S}s') as client:
            yield client


def describe_failure(exc: BaseException) -> str:
    """Return the reason shown in a failed row for a task that raised ``exc``."""
    from distributed import KilledWorker
    if isinstance(exc, KilledWorker):
        return (f'the bag killed {ALLOWED_FAILURES + 1} worker processes (a crash or out of '
                f'memory); Dask gave up on it: {exc}')
    return f'{type(exc).__name__}: {exc}'


def run_tasks(client, refs: Sequence[BagRef], settings: FleetSettings,
              function=process_bag) -> Iterator[Tuple[BagRef, BagResult]]:
    """
    Submit one task per bag and yield ``(ref, result)`` in the order they finish.

    A task that raises (a bug, or a bag that killed two workers) yields a failed result
    naming the exception.  When the consumer stops early (an interrupt, an error while
    storing a result) the tasks not yet finished are cancelled.

    Parameters
    ----------
    client : distributed.Client
        The cluster.
    refs : sequence of BagRef
        The bags.
    settings : FleetSettings
        Sent with every task (small).
    function : callable
        ``function(ref, settings) -> BagResult``, run on the workers (:func:`.task.process_bag`).

    Yields
    ------
    (BagRef, BagResult)

    """
    from distributed import as_completed

    run = uuid.uuid4().hex[:8]
    futures: Dict[object, BagRef] = {
        client.submit(function, ref, settings, key=f'fleet-{run}-{i}', retries=0): ref
        for i, ref in enumerate(refs)}
    try:
        for future in as_completed(futures):
            ref = futures[future]
            if future.status == 'finished':
                result = future.result()
            elif future.status == 'error':
                result = failed(ref.path, ref.bag_id, describe_failure(future.exception()))
            else:
                result = failed(ref.path, ref.bag_id,
                                f'task {future.status} by the cluster (scheduler or workers '
                                f'lost)')
            future.release()
            yield ref, result
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)
