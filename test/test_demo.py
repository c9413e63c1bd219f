# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The demo's fleet severity figure (the demo itself runs as ``make demo``)."""
import pytest

from wheel_force_estimator.demo import severity_ratios


def test_severity_is_damage_per_hour_over_the_reference_rate():
    # Reference: 2 units of damage in 1800 s = 4 per hour; the fleet's P95 does 1 per hour.
    doc = {'reference': {'duration_s': 1800.0, 'damage': {'lf_fz': 2.0, 'lf_fx': 0.0}},
           'percentiles': {'95': {'lf_fz': 1.0, 'lf_fx': 1.0}}}
    ratios = severity_ratios(doc)
    assert ratios['95']['lf_fz'] == pytest.approx(0.25)
    assert ratios['95']['lf_fx'] == float('inf')  # a reference that does no damage there
