# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Generic recordings in: DAQ exports (CSV, MAT, NPZ, JSON) with declared channel roles.

The counterpart of ``bagio`` for files without ROS topics: every channel is declared as
``NAME:QUANTITY:UNIT`` (:func:`parse_spec`), and :func:`read_daq` returns one
:class:`DaqRecording` (one gap-free segment, SI units) per file.  numpy / scipy only: no
rclpy, no rosbags, no matplotlib.  Errors are :class:`~..core.errors.RecordingError`.
"""
from wheel_force_estimator.daqio.channels import ChannelSpec
from wheel_force_estimator.daqio.channels import check_specs
from wheel_force_estimator.daqio.channels import INPUT_QUANTITIES
from wheel_force_estimator.daqio.channels import parse_spec
from wheel_force_estimator.daqio.channels import quantity_of_unit
from wheel_force_estimator.daqio.channels import SI_UNITS
from wheel_force_estimator.daqio.channels import UNITS
from wheel_force_estimator.daqio.reader import DaqRecording
from wheel_force_estimator.daqio.reader import is_generic_path
from wheel_force_estimator.daqio.reader import read_daq
from wheel_force_estimator.daqio.reader import SUFFIXES

__all__ = [
    'ChannelSpec', 'DaqRecording', 'INPUT_QUANTITIES', 'SI_UNITS', 'SUFFIXES', 'UNITS',
    'check_specs', 'is_generic_path', 'parse_spec', 'quantity_of_unit', 'read_daq',
]
