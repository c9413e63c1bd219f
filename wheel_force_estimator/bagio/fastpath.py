# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The signal between the bulk storage readers and the generic rosbags fallback."""


class FastPathUnavailable(Exception):
    """The recording cannot be read in bulk here; use the generic rosbags reader."""
