# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Fleet statistics and the proving-ground correlation, and the ``fleet.csv``/``fleet.json`` text.

Percentiles are taken over the bags that finished (``ok``), per channel, of the damage per
hour (``numpy.percentile``, linear interpolation between order statistics).

Proving-ground correlation: the reference schedule is all ``--reference`` bags driven once;
its pseudo damage per channel is ``D_ref`` (the sum over its bags).  A P-th percentile
customer accumulates ``d_P · T`` in ``T = --target-hours``, so the schedule must be repeated

    repeats_P = d_P · T / D_ref

times to do the same damage on that channel (Miner's rule, linear in cycles; the pseudo S-N
curve's constant cancels, so only the shape ``k`` matters).  ``None`` where the reference
does no damage on a channel.
"""
import csv
import dataclasses
import io
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.fleet.result import BagResult

PERCENTILES = (50, 90, 95, 99)


@dataclasses.dataclass(frozen=True)
class Reference:
    """
    The proving-ground schedule one fleet is compared with.

    Attributes
    ----------
    results : tuple of BagResult
        Its bags (all ``ok``).
    target_hours : float
        Customer usage the schedule must represent [h].

    """

    results: Tuple[BagResult, ...]
    target_hours: float

    def __post_init__(self):
        """Refuse an empty or failed schedule and a non-positive target."""
        if not self.results or not all(r.ok for r in self.results):
            raise ValueError('a reference needs at least one bag and every bag ok')
        if not (np.isfinite(self.target_hours) and self.target_hours > 0):
            raise ValueError(f'target_hours must be finite and > 0, got {self.target_hours!r}')

    @property
    def damage(self) -> Dict[str, float]:
        """Return the pseudo damage of one pass of the schedule per channel."""
        channels = list(self.results[0].damage)
        return {c: float(sum(r.damage[c] for r in self.results)) for c in channels}

    @property
    def duration_s(self) -> float:
        """Return the duration of one pass [s]."""
        return float(sum(r.duration_s for r in self.results))


def percentiles(results: Sequence[BagResult]) -> Optional[Dict[str, Dict[str, float]]]:
    """
    Return ``{'50': {channel: damage per hour}, '90': …}`` over the ``ok`` bags.

    None when no bag finished.
    """
    ok = [r for r in results if r.ok]
    if not ok:
        return None
    channels = list(ok[0].damage_per_hour)
    rates = np.array([[r.damage_per_hour[c] for c in channels] for r in ok])
    values = np.percentile(rates, PERCENTILES, axis=0)
    return {str(p): dict(zip(channels, map(float, row))) for p, row in zip(PERCENTILES, values)}


def repeats_for_target(pct: Dict[str, Dict[str, float]],
                       reference: Reference) -> Dict[str, Dict[str, Optional[float]]]:
    """Return ``repeats_P[channel] = d_P · T / D_ref`` for every percentile P."""
    d_ref = reference.damage
    hours = reference.target_hours
    return {p: {c: (rate * hours / d_ref[c] if d_ref[c] > 0 else None)
                for c, rate in row.items()}
            for p, row in pct.items()}


def fleet_document(results: Sequence[BagResult], reference: Optional[Reference],
                   sn_slope: float, model: str) -> dict:
    """Return the ``fleet.json`` document (DESIGN.md contract)."""
    pct = percentiles(results)
    ref = None
    if reference is not None:
        ref = {'path': [r.path for r in reference.results],
               'target_hours': reference.target_hours,
               'duration_s': reference.duration_s,
               'damage': reference.damage,
               'relative_damage_spectrum': pooled_rds(reference.results),
               'repeats_for_target': (repeats_for_target(pct, reference)
                                      if pct is not None else None)}
    return {'bags': [r.to_dict() for r in results],
            'n_ok': sum(r.ok for r in results),
            'n_failed': sum(not r.ok for r in results),
            'percentiles': pct,
            'relative_damage_spectrum': pooled_rds(results),
            'reference': ref,
            'sn_slope': sn_slope,
            'model': model}


def pooled_rds(results: Sequence[BagResult]) -> Optional[dict]:
    """
    Return the relative damage spectrum of the ``ok`` bags together, per channel.

    Pseudo damage per band summed over the bags (damage adds up), and each channel's
    fractions per band (``fraction``: the band's share of the band sum), which compare a
    fleet with a reference of any length.
    """
    ok = [r for r in results if r.ok]
    if not ok:
        return None
    channels = list(ok[0].rds)
    total = {c: np.sum([r.rds[c] for r in ok], axis=0) for c in channels}
    fraction = {}
    for c, t in total.items():
        s = float(np.sum(t))
        fraction[c] = [float(x) / s if s > 0 else 0.0 for x in t]
    return {'bands_hz': [list(b) for b in ok[0].bands_hz],
            'damage': {c: [float(x) for x in t] for c, t in total.items()},
            'fraction': fraction}


def fleet_csv(results: Sequence[BagResult], channels: Sequence[str]) -> str:
    """Return ``fleet.csv``: one row per bag; failed rows have empty figures."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow(['path', 'bag_id', 'duration_s', 'status', 'error']
                    + [f'damage_{c}' for c in channels]
                    + [f'damage_per_hour_{c}' for c in channels])
    for r in results:
        figures = ([repr(r.damage[c]) for c in channels]
                   + [repr(r.damage_per_hour[c]) for c in channels]) if r.ok else (
            [''] * (2 * len(channels)))
        writer.writerow([r.path, r.bag_id, repr(r.duration_s) if r.ok else '', r.status,
                         r.error or ''] + figures)
    return out.getvalue()
