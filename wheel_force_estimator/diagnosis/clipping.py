# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The flat-top test of a clipped sensor: one rule for the motion finding and the model term.

A clip repeats the channel's extreme value exactly.  A sensor that is not clipped reaches its
extreme once (continuous values) or about as often as the values just inside it (quantised
values: the tail thins toward the extreme).  :func:`clip_test` compares the count at the
extreme with a Poisson law whose mean is how often the :data:`NEIGHBOURS` distinct values next
to it repeat, so no fraction of clipped samples is assumed (a clip on far fewer than 0.1 % of
the samples is significant when it is exact).  :mod:`.motion` names ``sensor_saturation`` from
it (Bonferroni over channels and sides); :mod:`.hypotheses` takes the clip level of the
``sensor_saturation`` term from it.
"""
from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy import stats

#: Distinct values next to the extreme whose repeat count is the null mean of a clip test.
NEIGHBOURS = 20
#: False-alarm probability of a clip finding (before the correction over channels and sides).
CLIP_ALPHA = 1e-3
#: Fewest samples at the extreme to call it a clip at all.
MIN_CLIP_SAMPLES = 3


@dataclass(frozen=True)
class Clip:
    """A flat top of one channel: level (signed), samples at it, Poisson p-value."""

    channel: str
    level: float
    count: int
    p_value: float
    null_mean: float


def clip_test(x: np.ndarray, channel: str = '',
              min_samples: int = MIN_CLIP_SAMPLES) -> Optional[Clip]:
    """
    Return the more significant flat top of ``x`` (max or min side), or None.

    The count at the extreme value is compared with a Poisson law whose mean is the mean
    repeat count of the :data:`NEIGHBOURS` distinct values next to it (at least 1).  A clip
    cuts the signal while it is still moving, so the flat top is entered at speed: the median
    of the last full steps before it must be at least half the RMS sample-to-sample step of
    the record (a Gaussian process crosses any level at its typical speed, Rice; a sine
    clipped at 90 % of its amplitude at 0.62 of it).  A smooth turning point (a
    displacement-controlled rig reversing, quantised) dwells longest at its extreme value
    too, but creeps into it.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.size < NEIGHBOURS + min_samples:
        return None
    values, counts = np.unique(x, return_counts=True)
    steps = np.abs(np.diff(x))
    typical = float(np.sqrt(np.mean(steps ** 2)))
    best = None
    for side in (1, -1):
        k = int(counts[-1] if side > 0 else counts[0])
        inner = counts[-1 - NEIGHBOURS:-1] if side > 0 else counts[1:1 + NEIGHBOURS]
        if k < min_samples or inner.size == 0:
            continue
        level = float(values[-1] if side > 0 else values[0])
        at = x == level
        # The full step before the entry (the entry step itself is cut short by the clip).
        entries = np.flatnonzero(at[1:] & ~at[:-1])
        entries = entries[entries >= 1]
        if entries.size == 0 or np.median(steps[entries - 1]) < 0.5 * typical:
            continue
        lam = max(float(np.mean(inner)), 1.0)
        p = float(stats.poisson.sf(k - 1, lam))
        if best is None or p < best.p_value:
            best = Clip(channel, level, k, p, lam)
    return best


def clip_level(x: np.ndarray, alpha: float = CLIP_ALPHA) -> Optional[float]:
    """
    Return the clip magnitude of one sensor record when its flat top is significant, or None.

    Significant = Poisson p-value below ``alpha / 2`` (either side may clip).
    """
    clip = clip_test(x)
    if clip is None or clip.p_value >= alpha / 2.0:
        return None
    return abs(clip.level)
