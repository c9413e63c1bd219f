# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Errors of the fleet run (the CLI reports them on stderr with exit code 1)."""
from wheel_force_estimator.core.errors import WheelForceError


class FleetError(WheelForceError):
    """No bags under a PATH, an unreachable scheduler, failed bags at the end of a run."""
