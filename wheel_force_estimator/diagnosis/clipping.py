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
it (Bonferroni over channels and sides); :mod:`.grids` takes the clip level of the
``sensor_saturation`` term from it.
"""
from dataclasses import dataclass
from typing import List, Optional

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


def _records(x) -> List[np.ndarray]:
    """Return ``x`` as a list of 1-D records (one array, or a list/tuple of them)."""
    if isinstance(x, (list, tuple)):
        return [np.asarray(r, dtype=np.float64).ravel() for r in x]
    return [np.asarray(x, dtype=np.float64).ravel()]


def clip_test(x, channel: str = '', min_samples: int = MIN_CLIP_SAMPLES) -> Optional[Clip]:
    """
    Return the more significant flat top of ``x`` (max or min side), or None.

    ``x`` is one record or a list of records of one channel (never joined: the last sample
    of one and the first of the next are not a step).  The count at the extreme value is
    compared with a Poisson law whose mean is the mean repeat count of the
    :data:`NEIGHBOURS` distinct values next to it (at least 1).  A clip cuts the signal while
    it is still moving, so the flat top is entered at speed: the median of the last full
    steps before it must be at least half the RMS sample-to-sample step of the records (a
    Gaussian process crosses any level at its typical speed, Rice; a sine clipped at 90 % of
    its amplitude at 0.62 of it).  A smooth turning point (a displacement-controlled rig
    reversing, quantised) dwells longest at its extreme value too, but creeps into it.  Only
    runs entered within a record count: a run that starts with the record (a rig at rest at
    its start position before the test, measured on the MR damper's runs 4.2 and 4.3: 1.45
    and 5.8 s at their extreme displacement) shows no entry, so nothing tells it from a rest.
    """
    records = _records(x)
    joined = np.concatenate(records) if records else np.zeros(0)
    if joined.size < NEIGHBOURS + min_samples:
        return None
    values, counts = np.unique(joined, return_counts=True)
    steps = [np.abs(np.diff(r)) for r in records]
    all_steps = np.concatenate(steps)
    if all_steps.size == 0:
        return None
    typical = float(np.sqrt(np.mean(all_steps ** 2)))
    best = None
    for side in (1, -1):
        inner = counts[-1 - NEIGHBOURS:-1] if side > 0 else counts[1:1 + NEIGHBOURS]
        if inner.size == 0:
            continue
        level = float(values[-1] if side > 0 else values[0])
        k, before = 0, []
        for r, st in zip(records, steps):
            at = r == level
            # runs entered within the record: at[e + 1] and not at[e]
            entries = np.flatnonzero(at[1:] & ~at[:-1])
            # samples at the level, less a run the record starts with (no entry seen)
            lead = r.size if at.all() else int(np.argmin(at))
            k += int(at.sum()) - lead
            # the full step before the entry (the entry step itself is cut short by the clip)
            before.extend(st[entries[entries >= 1] - 1])
        if k < min_samples or not before or np.median(before) < 0.5 * typical:
            continue
        lam = max(float(np.mean(inner)), 1.0)
        p = float(stats.poisson.sf(k - 1, lam))
        if best is None or p < best.p_value:
            best = Clip(channel, level, k, p, lam)
    return best


def clip_bound(n_inputs: int, alpha: float = CLIP_ALPHA) -> float:
    """
    Return the p-value below which a flat top is a clip: ``alpha / (2 n_inputs)``.

    Either side of every one of the ``n_inputs`` sensors of a recording may clip, and all are
    tested, so the false-alarm rate of the recording stays ``alpha`` (Bonferroni).  The one
    rule of the clip finding (:mod:`diagnosis.finders.motion`) and of the clip term's candidate
    (:mod:`diagnosis.grids`): a clip significant for one is significant for the other.
    """
    return alpha / (2.0 * n_inputs)


def clip_level(x, n_inputs: int, alpha: float = CLIP_ALPHA) -> Optional[float]:
    """
    Return the clip magnitude of one sensor's records when its flat top is significant, or None.

    Significant = Poisson p-value below :func:`clip_bound` of the recording's ``n_inputs``.
    """
    clip = clip_test(x)
    if clip is None or clip.p_value >= clip_bound(n_inputs, alpha):
        return None
    return abs(clip.level)
