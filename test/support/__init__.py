# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Fixtures the tests and the benchmarks share (``bench/benchutil.test_support``)."""
