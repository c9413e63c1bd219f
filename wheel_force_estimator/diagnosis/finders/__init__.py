# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The finders: each names missing physics one way and returns its findings.

Every finder module has one entry, ``find(run, found) -> list of Finding``: ``run`` is the
pipeline's :class:`pipeline.Run` (recordings, reference, prepared pieces, the per-channel
outcomes), ``found`` the findings of the finders before it; a finder that does not apply to
the run's mode returns nothing.  In the order :data:`pipeline.FINDERS` runs them:

- :mod:`.per_channel` - every candidate channel by channel, shared parameters per axis;
- :mod:`.agreement` - pooled over the corners of an axis that agree (a simulation or model);
- :mod:`.structure` - physics inside a structure (no simulation or model);
- :mod:`.structural` - whole-vehicle FRF comparisons: left-right coupling, wrong mass or
  spring rate (a simulation's FRF);
- :mod:`.hardening` - the kind of hardening, pooled over an axis (a simulation);
- :mod:`.motion` - the recorded motion: a clipped sensor, a tyre in the air.

A candidate scored by its held-out gain is accepted by one rule (:mod:`.acceptance`); the
findings combine by the rules of :mod:`.reconcile`.
"""
