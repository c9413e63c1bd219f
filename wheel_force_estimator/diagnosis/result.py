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
    RMSE % per channel of the reference, the best linear model on the real data, the written model.

    With ``data == 'holdout'`` every figure is what ``wheel-force evaluate`` reports for that
    model on the report half of the holdout (:func:`diagnosis.holdout.split_holdout`, named in
    ``report_on``), the ``metric`` field of ``evaluate --json`` (``rmse_hp1_pct`` for
    acceleration inputs, ``rmse_pct`` otherwise: ``highpass_hz`` 1 or 0).  With
    ``'cross_validation'`` (no holdout) every figure is scored the same way on the held-out
    blocks of the training recordings, each model fitted on the other blocks
    (:mod:`diagnosis.crossval`).

    Attributes
    ----------
    before : mapping str -> float
        The simulation's FRF (or ``--model``, or the reference fitted on the real data).
    after : mapping str -> float
        The model ``--out-model`` writes (``model`` says which).
    data : str
        One of :data:`DATA`.
    real_linear : mapping str -> float or None
        The best linear dynamic model fitted on the real training data with the design of
        ``wheel-force fit`` (None when the real records cannot be fitted or hold no
        blocks to judge it on).
    highpass_hz : float
        1.0 when the figures are 1 Hz high-passed, else 0.
    model : str
        Which model is written: ``sim_frf``, ``model``, ``real_linear`` (unchanged reference
        or plain fit), ``sim_frf+physics``, ``model+physics``, ``real_frf+physics``, or
        ``per_channel`` (rows of several, named in ``rows_from``).
    report_on : tuple of str
        What to give ``wheel-force evaluate`` to reproduce the figures: the report files, or
        ``FILE --samples A..B,...`` for a single holdout file.
    gate : mapping str -> float
        Mean RMSE % over the findings' channels of every candidate on the gate half (empty
        when there was no choice).
    notes : tuple of str
        Why a figure is missing.
    gated : tuple of str
        Findings the holdout gate dropped, and why.
    rows_from : mapping str -> str
        With ``model == 'per_channel'``: the candidate each output channel's row (and its
        terms) comes from; empty otherwise.
    figures : mapping str -> mapping str -> float
        Both figures ``evaluate`` reports, whatever ``metric`` is: ``before_unfiltered``,
        ``real_linear_unfiltered``, ``after_unfiltered`` (``rmse_pct``) and ``before_hp1``,
        ``real_linear_hp1``, ``after_hp1`` (``rmse_hp1_pct``), each ``{channel: %}`` on the
        same samples as ``before`` / ``real_linear`` / ``after``; written to the JSON beside
        them.

    """

    before: Mapping[str, float]
    after: Mapping[str, float]
    data: str
    real_linear: Optional[Mapping[str, float]] = None
    highpass_hz: float = 0.0
    model: str = ''
    report_on: Tuple[str, ...] = ()
    gate: Mapping[str, float] = field(default_factory=dict)
    notes: Tuple[str, ...] = ()
    gated: Tuple[str, ...] = ()
    rows_from: Mapping[str, str] = field(default_factory=dict)
    figures: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __post_init__(self):
        if self.data not in DATA:
            raise DiagnosisError(f'fit data must be one of {", ".join(DATA)}, got '
                                 f'{self.data!r}')
        object.__setattr__(self, 'gate', dict(self.gate))
        object.__setattr__(self, 'figures', {k: dict(v) for k, v in self.figures.items()})
        object.__setattr__(self, 'rows_from', dict(self.rows_from))
        object.__setattr__(self, 'report_on', tuple(self.report_on))

    @property
    def metric(self) -> str:
        """Return the ``evaluate --json`` field the figures are."""
        return f'rmse_hp{self.highpass_hz:g}_pct' if self.highpass_hz > 0.0 else 'rmse_pct'

    def to_dict(self) -> Dict:
        """Return the DESIGN.md ``fit`` entry (plus metric, report_on, gate)."""
        out = {'before': {k: _round(v) for k, v in self.before.items()}}
        if self.real_linear is not None:
            out['real_linear'] = {k: _round(v) for k, v in self.real_linear.items()}
        out.update({'after': {k: _round(v) for k, v in self.after.items()},
                    'model': self.model, 'data': self.data, 'metric': self.metric,
                    'report_on': list(self.report_on),
                    'gate': {k: _round(v) for k, v in self.gate.items()}})
        if self.rows_from:
            out['rows_from'] = dict(self.rows_from)
        for key, values in self.figures.items():
            out[key] = {k: _round(v) for k, v in values.items()}
        out['notes'] = list(self.notes)
        return out


#: ``fit.data``: the figures come from the report half of the holdout, from held-out blocks
#: of the training recordings (no holdout), or there are none because the training
#: recordings are too short to hold blocks out (``notes`` says why; the plain fit is written).
DATA = ('holdout', 'cross_validation', 'too_short')


def figure_keys(name: str, figures: Mapping[str, Mapping[str, float]]
                ) -> Dict[str, Dict[str, float]]:
    """Return ``{NAME_unfiltered, NAME_hp1}`` of ``{'rmse_pct', 'rmse_hp1_pct'}`` figures."""
    return {f'{name}_unfiltered': dict(figures['rmse_pct']),
            f'{name}_hp1': dict(figures['rmse_hp1_pct'])}


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
        The model ``--out-model`` writes (``fit.model`` says which); None when no FRF exists.
    baseline : object or None
        The reference predictor (``.predict(recording)``), for reports.
    real_fit : DesignedFit or None
        The run's real-data linear fit (:class:`core.design.DesignedFit`), whose chosen
        design the written model's live estimators follow; None when there is none.

    """

    mismatch: Tuple[ChannelMismatch, ...]
    findings: Tuple[Finding, ...]
    fit: FitComparison
    summary: Tuple[str, ...] = ()
    reference: str = ''
    rejected: Tuple[str, ...] = ()
    model: Optional[object] = None
    baseline: Optional[object] = None
    real_fit: Optional[object] = None

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
                'physics_terms': (list(self.model.physics) if self.model is not None
                                  else [t.to_dict() for t in self.terms])}

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
