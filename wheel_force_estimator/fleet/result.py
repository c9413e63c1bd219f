# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The small result one fleet task returns for one bag (no arrays, a few hundred numbers).

It travels from a worker to the client through the Dask scheduler, is stored in ``--out`` so
a rerun can skip the bag, and becomes one row of ``fleet.csv`` / ``fleet.json``.
"""
import dataclasses
from typing import Dict, Mapping, Optional, Tuple

STATUS_OK = 'ok'
STATUS_FAILED = 'failed'
SECONDS_PER_HOUR = 3600.0


@dataclasses.dataclass(frozen=True)
class BagResult:
    """
    Figures of one bag, or why there are none.

    Attributes
    ----------
    path, bag_id : str
        The bag (see :class:`.discover.BagRef`).
    status : {'ok', 'failed'}
        ``failed`` with ``error`` set when the bag could not be processed.
    error : str or None
        Why the bag failed (file, topic or channel named by the reader).
    duration_s : float
        Samples used / sample rate [s] (gaps excluded).
    damage : dict of str to float
        Pseudo damage of the predicted force per output channel, N**k: what ``evaluate``
        reports as ``damage_prediction`` for this bag and model.
    damage_per_hour : dict of str to float
        ``damage / duration_s * 3600`` [N**k / h].
    rds : dict of str to tuple of float
        Relative damage spectrum of the predicted force per channel (pseudo damage per band
        of ``bands_hz``), N**k.
    bands_hz : tuple of (float, float)
        Bands of ``rds`` [Hz].
    events : tuple of str
        Road event names recorded in the bag, in order of first occurrence.
    rmse_pct, rmse_hp1_pct : dict of str to float, or None
        RMSE % against the bag's WFT topics (unfiltered, 1 Hz high-passed) when it has them.
    forces : str or None
        Predicted-force bag written by ``--write-forces``.

    """

    path: str
    bag_id: str
    status: str
    error: Optional[str] = None
    duration_s: float = 0.0
    damage: Mapping[str, float] = dataclasses.field(default_factory=dict)
    damage_per_hour: Mapping[str, float] = dataclasses.field(default_factory=dict)
    rds: Mapping[str, Tuple[float, ...]] = dataclasses.field(default_factory=dict)
    bands_hz: Tuple[Tuple[float, float], ...] = ()
    events: Tuple[str, ...] = ()
    rmse_pct: Optional[Mapping[str, float]] = None
    rmse_hp1_pct: Optional[Mapping[str, float]] = None
    forces: Optional[str] = None

    def __post_init__(self):
        """Check the status and that a failed result says why."""
        if self.status not in (STATUS_OK, STATUS_FAILED):
            raise ValueError(f'status must be {STATUS_OK!r} or {STATUS_FAILED!r}, '
                             f'got {self.status!r}')
        if (self.status == STATUS_FAILED) != (self.error is not None):
            raise ValueError('a failed result needs an error, an ok result none')

    @property
    def ok(self) -> bool:
        """Return whether the bag was processed."""
        return self.status == STATUS_OK

    def to_dict(self) -> dict:
        """Return the JSON row (``fleet.json`` ``bags`` entry)."""
        return {
            'path': self.path, 'bag_id': self.bag_id, 'status': self.status,
            'error': self.error, 'duration_s': self.duration_s,
            'damage': dict(self.damage), 'damage_per_hour': dict(self.damage_per_hour),
            'relative_damage_spectrum': {k: list(v) for k, v in self.rds.items()},
            'bands_hz': [list(b) for b in self.bands_hz],
            'events': list(self.events),
            'rmse_pct': None if self.rmse_pct is None else dict(self.rmse_pct),
            'rmse_hp1_pct': None if self.rmse_hp1_pct is None else dict(self.rmse_hp1_pct),
            'forces': self.forces,
        }

    @classmethod
    def from_dict(cls, row: dict) -> 'BagResult':
        """
        Return the result stored by :meth:`to_dict`.

        Raises
        ------
        KeyError, TypeError, ValueError
            A row that is not a stored result.

        """
        def floats(d: Optional[dict]) -> Optional[Dict[str, float]]:
            return None if d is None else {str(k): float(v) for k, v in d.items()}
        return cls(
            path=str(row['path']), bag_id=str(row['bag_id']), status=str(row['status']),
            error=row['error'], duration_s=float(row['duration_s']),
            damage=floats(row['damage']), damage_per_hour=floats(row['damage_per_hour']),
            rds={str(k): tuple(float(x) for x in v)
                 for k, v in row['relative_damage_spectrum'].items()},
            bands_hz=tuple((float(lo), float(hi)) for lo, hi in row['bands_hz']),
            events=tuple(str(e) for e in row['events']),
            rmse_pct=floats(row['rmse_pct']), rmse_hp1_pct=floats(row['rmse_hp1_pct']),
            forces=row['forces'])


def failed(path: str, bag_id: str, error: str) -> BagResult:
    """Return the row of a bag that could not be processed."""
    return BagResult(path=path, bag_id=bag_id, status=STATUS_FAILED, error=error)
