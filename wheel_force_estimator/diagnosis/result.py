# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""What a diagnosis found, as frozen dataclasses with the DESIGN.md JSON form."""
from dataclasses import dataclass
from dataclasses import field
import json
import math
from pathlib import Path
from typing import Dict, Mapping, Optional, Tuple

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.core.physics import VOCABULARY


def _round(x: float, digits: int = 4) -> float:
    if x == 0.0 or not math.isfinite(x):
        return float(x)
    return float(f'{x:.{digits}g}')


@dataclass(frozen=True)
class ChannelMismatch:
    """Where one output channel's residual lives: bands, time windows, operating regime."""

    channel: str
    rmse_pct: float
    bands_hz: Tuple[Tuple[float, float], ...] = ()
    time_windows_s: Tuple[Tuple[float, float], ...] = ()
    regime: str = 'uniform'

    def to_dict(self) -> Dict:
        """Return the DESIGN.md ``mismatch`` entry."""
        return {'channel': self.channel, 'rmse_pct': _round(self.rmse_pct),
                'bands_hz': [[_round(a), _round(b)] for a, b in self.bands_hz],
                'time_windows_s': [[round(a, 3), round(b, 3)] for a, b in self.time_windows_s],
                'regime': self.regime}


@dataclass(frozen=True)
class Finding:
    """
    One named physics effect the simulation / model leaves out.

    Attributes
    ----------
    physics : str
        Vocabulary name.
    channels : tuple of str
        Output channels it acts on (shared parameters).
    parameters : mapping str -> float
        Fitted parameters (SI units in the names).
    explained_fraction : float
        Fraction of the residual sum of squares it removes on held-out data.
    evidence : str
        Plain-language account: what, where, how strong, against which null.
    terms : tuple of PhysicsTerm
        Terms added to the augmented model (the effect plus any linear companions refitted
        with it).
    null_fraction : float
        Best fraction the same candidate explains with time-shifted features.
    rmse_after_pct : mapping str -> float
        Holdout RMSE % of its channels with this and all earlier findings applied (empty
        without holdout data).
    time_windows_s : tuple of (float, float)
        Where the effect acts in the real recordings (motion findings, :mod:`motion`);
        written to the JSON only when not empty.

    """

    physics: str
    channels: Tuple[str, ...]
    parameters: Mapping[str, float]
    explained_fraction: float
    evidence: str
    terms: Tuple[PhysicsTerm, ...] = ()
    null_fraction: float = 0.0
    rmse_after_pct: Mapping[str, float] = field(default_factory=dict)
    time_windows_s: Tuple[Tuple[float, float], ...] = ()

    def __post_init__(self):
        if self.physics not in VOCABULARY:
            raise DiagnosisError(f'finding names unknown physics {self.physics!r}')
        object.__setattr__(self, 'rmse_after_pct', dict(self.rmse_after_pct))
        object.__setattr__(self, 'channels', tuple(self.channels))
        object.__setattr__(self, 'parameters', dict(self.parameters))
        object.__setattr__(self, 'terms', tuple(self.terms))
        object.__setattr__(self, 'time_windows_s',
                           tuple((float(a), float(b)) for a, b in self.time_windows_s))

    def to_dict(self) -> Dict:
        """Return the DESIGN.md ``findings`` entry."""
        out = {'physics': self.physics, 'channels': list(self.channels),
               'parameters': {k: _round(v, 6) for k, v in self.parameters.items()},
               'explained_fraction': _round(self.explained_fraction, 3),
               'null_fraction': _round(self.null_fraction, 3),
               'rmse_after_pct': {k: _round(v) for k, v in self.rmse_after_pct.items()},
               'evidence': self.evidence}
        if self.time_windows_s:
            out['time_windows_s'] = [[round(a, 3), round(b, 3)] for a, b in self.time_windows_s]
        return out


@dataclass(frozen=True)
class FitComparison:
    """
    RMSE % per channel of the reference (before) and the augmented model (after).

    ``highpass_hz`` > 0: both signals high-passed first (``rmse_hp`` of the paper).
    ``linear_real``: the best linear model fitted on the real recordings themselves;
    ``augmented_real``: that model and the named physics terms fitted jointly (backfitting:
    strengths refitted, shapes kept) - what the named physics add to the best linear fit.
    With ``data == 'holdout'`` every figure is measured on the half of the holdout blocks the
    holdout gate never saw (:func:`diagnosis.holdout.alternate_blocks`).
    """

    before: Mapping[str, float]
    after: Mapping[str, float]
    data: str
    linear_real: Optional[Mapping[str, float]] = None
    highpass_hz: float = 0.0
    augmented_real: Optional[Mapping[str, float]] = None

    def __post_init__(self):
        if self.data not in ('holdout', 'cross_validation'):
            raise DiagnosisError(f'fit data must be holdout or cross_validation, got '
                                 f'{self.data!r}')

    def to_dict(self) -> Dict:
        """Return the DESIGN.md ``fit`` entry (plus ``linear_real`` / ``augmented_real``)."""
        out = {'before': {k: _round(v) for k, v in self.before.items()},
               'after': {k: _round(v) for k, v in self.after.items()},
               'data': self.data,
               'metric': (f'rmse_hp{self.highpass_hz:g}_pct' if self.highpass_hz > 0.0
                          else 'rmse_pct')}
        if self.linear_real is not None:
            out['linear_real'] = {k: _round(v) for k, v in self.linear_real.items()}
        if self.augmented_real is not None:
            out['augmented_real'] = {k: _round(v) for k, v in self.augmented_real.items()}
        return out


@dataclass(frozen=True)
class DiagnosisResult:
    """
    Everything ``wheel-force diagnose`` reports.

    Attributes
    ----------
    mismatch : tuple of ChannelMismatch
        Channels, worst first.
    findings : tuple of Finding
        Accepted effects (empty when nothing beyond noise).
    fit : FitComparison
        Before/after RMSE % per channel.
    summary : tuple of str
        Plain-language lines, one per finding (or why there is none).
    reference : str
        What produced the "before" prediction (``sim FRF``, ``model``, ``linear fit``).
    rejected : tuple of str
        Why the best remaining candidates were not accepted, per channel.
    model : FrfModel or None
        The augmented model (reference FRF + physics terms) when the reference is an FRF.
    baseline : object or None
        The reference predictor (``.predict(recording)``), for reports.

    """

    mismatch: Tuple[ChannelMismatch, ...]
    findings: Tuple[Finding, ...]
    fit: FitComparison
    summary: Tuple[str, ...] = ()
    reference: str = ''
    rejected: Tuple[str, ...] = ()
    model: Optional[object] = None
    baseline: Optional[object] = None

    @property
    def terms(self) -> Tuple[PhysicsTerm, ...]:
        """All physics terms of the augmented model, in finding order."""
        return tuple(t for f in self.findings for t in f.terms)

    def to_json(self) -> Dict:
        """Return the DESIGN.md ``diagnose --json`` document (plus summary/reference)."""
        return {'mismatch': [m.to_dict() for m in self.mismatch],
                'findings': [f.to_dict() for f in self.findings],
                'fit': self.fit.to_dict(),
                'summary': list(self.summary),
                'reference': self.reference,
                'rejected': list(self.rejected),
                'physics_terms': [t.to_dict() for t in self.terms]}

    def write_json(self, path) -> Path:
        """
        Write :meth:`to_json` to ``path`` (indented); return the path.

        Raises
        ------
        DiagnosisError
            When the file cannot be written.

        """
        path = Path(path)
        try:
            path.write_text(json.dumps(self.to_json(), indent=2) + '\n')
        except OSError as err:
            raise DiagnosisError(f'{path}: cannot write diagnosis JSON: {err}') from err
        return path
