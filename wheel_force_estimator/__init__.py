# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Virtual wheel force transducer: MIMO FRF from spindle accelerations to wheel forces."""

__version__ = '0.1.0'

CORNERS = ('lf', 'rf', 'lr', 'rr')
INPUT_CHANNELS = tuple(f'{c}_a{ax}' for c in CORNERS for ax in 'xyz')
OUTPUT_CHANNELS = tuple(f'{c}_f{ax}' for c in CORNERS for ax in 'xyz')
# Six components (issue 33): wheel moments after the forces; the extra inputs a model may
# declare after the accelerations (spindle angular rates, then wheel spin rates).
MOMENT_CHANNELS = tuple(f'{c}_m{ax}' for c in CORNERS for ax in 'xyz')
RATE_CHANNELS = tuple(f'{c}_w{ax}' for c in CORNERS for ax in 'xyz')
SPIN_CHANNELS = tuple(f'{c}_spin' for c in CORNERS)
# The spin enters a model as the spin acceleration derived from the recorded spin rate
# (core.derived): the rate's large slow speed changes would leak into every Welch line.
SPIN_ACCEL_CHANNELS = tuple(f'{c}_spin_accel' for c in CORNERS)
