# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the tests and the benchmarks (not part of the installed package)."""
