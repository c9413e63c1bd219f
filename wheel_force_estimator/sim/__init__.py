# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Proving-ground simulator: the instrumented car that produces training and test recordings.

``simulate`` returns the 12 spindle accelerations and 12 WFT forces of a full-vehicle model
(body heave / pitch / roll, four corners with vertical, fore-aft and lateral hub compliance,
transient tyres, driver) on proving-ground events; ``simulate_pair`` writes the nominal car
(``sim/``), the car with physics effects (``real/``) and a hold-out run as rosbag2.  Modules:
``vehicle`` (parameters, YAML), ``roads`` (ISO 8608, obstacles), ``courses`` (events, driver
plan), ``dynamics`` (equations of motion, numba RK4), ``sensors`` (decimation, noise),
``effects`` (switchable physics), ``api``.
"""
from wheel_force_estimator.sim.api import SimResult
from wheel_force_estimator.sim.api import simulate
from wheel_force_estimator.sim.api import simulate_pair
from wheel_force_estimator.sim.courses import COURSES
from wheel_force_estimator.sim.courses import EventSpec
from wheel_force_estimator.sim.effects import EFFECT_DEFAULTS
from wheel_force_estimator.sim.effects import EFFECT_NAMES
from wheel_force_estimator.sim.vehicle import load_vehicle
from wheel_force_estimator.sim.vehicle import quarter_car
from wheel_force_estimator.sim.vehicle import VehicleParams

__all__ = [
    'COURSES', 'EFFECT_DEFAULTS', 'EFFECT_NAMES', 'EventSpec', 'SimResult', 'VehicleParams',
    'load_vehicle', 'quarter_car', 'simulate', 'simulate_pair',
]
