# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Allow ``python -m wheel_force_estimator``."""
import sys

from wheel_force_estimator.cli.main import main

sys.exit(main())
