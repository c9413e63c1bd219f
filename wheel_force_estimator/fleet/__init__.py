# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Fleet damage on Dask: many vehicles' bags -> customer percentiles and proving-ground repeats.

- ``discover`` finds the bags under each PATH and signs bags and model files;
- ``task`` is the per-bag work run on a worker (read -> predict -> damage, RMSE with WFT);
- ``result`` the small per-bag result; ``store`` keeps finished ones in ``--out``;
- ``engine`` the Dask cluster and the task loop; ``summary`` percentiles, proving-ground
  repeats and the table text; ``run`` ties them together (``wheel-force fleet``).
"""
from wheel_force_estimator.fleet.result import BagResult
from wheel_force_estimator.fleet.run import DEFAULT_TARGET_HOURS
from wheel_force_estimator.fleet.run import FleetOutcome
from wheel_force_estimator.fleet.run import run_fleet

__all__ = ['BagResult', 'DEFAULT_TARGET_HOURS', 'FleetOutcome', 'run_fleet']
