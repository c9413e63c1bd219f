# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Test support shared by the test files: fixtures and helpers that do not ship in the package."""
