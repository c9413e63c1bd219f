# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Virtual wheel force transducer: MIMO FRF from spindle accelerations to wheel forces."""

__version__ = '0.1.0'

#: Corners in channel order (DESIGN.md), and the axles they form, left corner first.
CORNERS = ('lf', 'rf', 'lr', 'rr')
AXLES = (('lf', 'rf'), ('lr', 'rr'))
#: Each corner's partner on the same axle.
PARTNER_CORNER = {c: a[1 - a.index(c)] for a in AXLES for c in a}
#: Standard gravity [m/s^2] (ISO 80000-3): what an accelerometer at rest reads on z.
GRAVITY_MPS2 = 9.80665
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
# The traction/braking split (issue 29): the car's low-passed longitudinal specific force,
# derived from the four spindle ax (core.derived), as its positive and negative parts [m/s^2].
SPLIT_CHANNELS = ('traction_ax', 'braking_ax')
# The cornering split (issue 29): the car's low-passed lateral specific force, derived from
# the four spindle ay (core.derived), as its positive (left turn, ISO 8855 y left) and
# negative (right turn) parts [m/s^2].  A tyre's lateral force grows with its load, and the
# load moves to the outer wheels, so each wheel's quasi-static Fy has one slope per turn side.
CORNERING_CHANNELS = ('left_turn_ay', 'right_turn_ay')
