# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Judge a prediction like a durability engineer (the ``evaluate`` command's numeric part).

Conventions for several recordings / gap-separated segments (documented in docs/design.md):

- RMSE %: segments are concatenated and the global means removed; the 1 Hz high-passed variant
  filters each segment on its own (zero phase) before concatenating, so no filter runs across
  a join.
- Pseudo damage and the relative damage spectrum are summed over segments (each segment is
  rainflow-counted on its own, residue as half cycles): a join is not a load reversal.
- ASD: Welch per segment, averaged with weights equal to the segment lengths.
- Events: event ``i`` spans from its start stamp to the next event's start (the last one to
  the end of the recording); all spans with the same name are pooled.
- Sample ranges (``evaluate --samples``, :func:`select_samples`): each segment is predicted
  whole, then the listed samples are cut out and judged as gap-free segments of their own,
  exactly as the per-event figures judge an event's span.
"""
import dataclasses
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.fatigue import damage_bands_hz
from wheel_force_estimator.core.fatigue import pseudo_damage
from wheel_force_estimator.core.fatigue import relative_damage_spectrum
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.core.metrics import rubric
from wheel_force_estimator.core.metrics import RUBRIC_LEVELS
from wheel_force_estimator.core.sample_ranges import per_segment
from wheel_force_estimator.core.spectra import auto_spectral_density
from wheel_force_estimator.core.spectra import WelchConfig


@dataclasses.dataclass(frozen=True)
class EvalSegment:
    """
    Target and prediction of one gap-free segment.

    Parameters
    ----------
    target_n, prediction_n : numpy.ndarray, shape (n_outputs, n)
        Measured and predicted force [N].
    stamp_ns : numpy.ndarray, shape (n,)
        Sample stamps [ns] (for event windows).
    source : str
        Recording and segment, for messages.

    """

    target_n: np.ndarray
    prediction_n: np.ndarray
    stamp_ns: np.ndarray
    source: str


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """All figures of one evaluation (arrays indexed by output channel)."""

    channels: Tuple[str, ...]
    fs_hz: float
    sn_slope: float
    rmse_pct: np.ndarray
    rmse_hp1_pct: np.ndarray
    damage_target: np.ndarray
    damage_prediction: np.ndarray
    bands_hz: Tuple[Tuple[float, float], ...]
    rds_target: np.ndarray
    rds_prediction: np.ndarray
    f_hz: np.ndarray
    asd_target: np.ndarray
    asd_prediction: np.ndarray
    asd_error: np.ndarray
    events: Dict[str, Dict[str, np.ndarray]]
    sn_slope_moment: Optional[float] = None

    @property
    def damage_ratio(self) -> np.ndarray:
        """Prediction/target pseudo damage per channel (inf where the target has none)."""
        with np.errstate(divide='ignore', invalid='ignore'):
            return np.where(self.damage_target > 0,
                            self.damage_prediction / np.where(self.damage_target > 0,
                                                              self.damage_target, 1.0),
                            np.inf)

    def rubric_counts(self) -> Dict[str, int]:
        """Count of channels per rubric level (overall, unfiltered RMSE)."""
        counts = dict.fromkeys(RUBRIC_LEVELS, 0)
        for value in self.rmse_pct:
            counts[rubric(float(value))] += 1
        return counts

    def to_json(self) -> dict:
        """Return the DESIGN.md ``evaluate --json`` document."""
        ratio = self.damage_ratio
        channels = {}
        for i, name in enumerate(self.channels):
            channels[name] = {
                'rmse_pct': float(self.rmse_pct[i]),
                'rmse_hp1_pct': float(self.rmse_hp1_pct[i]),
                'rubric': rubric(float(self.rmse_pct[i])),
                'damage_target': float(self.damage_target[i]),
                'damage_prediction': float(self.damage_prediction[i]),
                'damage_ratio': float(ratio[i]) if np.isfinite(ratio[i]) else None,
            }
        events = {}
        for event, figures in self.events.items():
            events[event] = {
                name: {'rmse_pct': float(figures['rmse_pct'][i]),
                       'rmse_hp1_pct': float(figures['rmse_hp1_pct'][i]),
                       'rubric': rubric(float(figures['rmse_pct'][i])),
                       'duration_s': float(figures['duration_s'])}
                for i, name in enumerate(self.channels)}
        return {
            'channels': channels,
            'events': events,
            'rubric_counts': self.rubric_counts(),
            'relative_damage_spectrum': {
                'bands_hz': [list(b) for b in self.bands_hz],
                'target': {n: self.rds_target[i].tolist() for i, n in enumerate(self.channels)},
                'prediction': {n: self.rds_prediction[i].tolist()
                               for i, n in enumerate(self.channels)},
            },
            'sn_slope': self.sn_slope,
            'sample_rate_hz': self.fs_hz,
            **({} if self.sn_slope_moment is None else {'sn_slope_moment': self.sn_slope_moment}),
        }


def select_samples(segments: Sequence[EvalSegment],
                   ranges: Sequence[Tuple[int, int]]) -> List[EvalSegment]:
    """
    Return the pieces of ``segments`` that ``ranges`` select, each a segment of its own.

    Parameters
    ----------
    segments : sequence of EvalSegment
        One recording's gap-free segments, in order, each predicted whole (so a piece keeps
        the prediction the whole record gives it: no FIR or settling edge at its start).
    ranges : sequence of (int, int)
        Half-open sample ranges over the segments' samples counted in order
        (:mod:`core.sample_ranges`); a range across a gap is cut there.

    Raises
    ------
    ValueError
        A range ends after the last sample.

    """
    pieces = per_segment(ranges, [len(s.stamp_ns) for s in segments])
    return [EvalSegment(segments[i].target_n[:, a:b], segments[i].prediction_n[:, a:b],
                        segments[i].stamp_ns[a:b], f'{segments[i].source}[{a}..{b}]')
            for i, a, b in pieces]


#: Segments shorter than this are left out of the 1 Hz high-passed RMSE [samples].
HP_MIN_SAMPLES = 64


def rmse_figures(targets: List[np.ndarray], preds: List[np.ndarray], fs_hz: float,
                 channels: Sequence[str],
                 hp_min_samples: int = HP_MIN_SAMPLES) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return ``(rmse_pct, rmse_hp1_pct)`` per channel over gap-free segments, as ``evaluate``.

    The one home of the figures :func:`evaluate_segments` reports (the diagnosis scores its
    models with it without paying for damage and spectra it does not report).

    Parameters
    ----------
    targets, preds : list of numpy.ndarray, shape (n_channels, n_i)
        Target and prediction per segment [N].
    fs_hz : float
        Sample rate [Hz].
    channels : sequence of str
        Channel names (error messages).
    hp_min_samples : int
        Segments shorter than this are left out of the high-passed figure only.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray), each shape (n_channels,)
        Unfiltered and 1 Hz high-passed relative RMSE [%] (NaN when no segment is long
        enough for the high-pass).

    """
    t = np.concatenate(targets, axis=1)
    p = np.concatenate(preds, axis=1)
    raw = rmse_pct(t, p, channels=channels)
    # zero-phase high-pass per segment; segments too short for filtfilt's edge handling are
    # left out of the high-passed figure only (counted in the unfiltered one)
    keep = [i for i, x in enumerate(targets) if x.shape[1] >= hp_min_samples]
    if not keep:
        hp = np.full(len(channels), np.nan)
    else:
        th = np.concatenate([highpass(targets[i], fs_hz) for i in keep], axis=1)
        ph = np.concatenate([highpass(preds[i], fs_hz) for i in keep], axis=1)
        hp = rmse_pct(th, ph, channels=channels)
    return raw, hp


def damage_figures(signals: Sequence[np.ndarray], fs_hz: float, sn_slope: float,
                   bands_hz: Sequence[Tuple[float, float]]) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the pseudo damage and relative damage spectrum of gap-separated segments.

    Each segment is rainflow-counted (and band-filtered) on its own and the results are
    summed: a join between segments is not a load reversal.  ``evaluate`` (target and
    prediction) and ``fleet`` (prediction) both use this one rule.

    Parameters
    ----------
    signals : sequence of numpy.ndarray, shape (n_channels, n_i)
        Load histories of the segments, e.g. force_n.
    fs_hz : float
        Sample rate [Hz].
    sn_slope : float or numpy.ndarray, shape (n_channels,)
        Basquin exponent ``k`` [-], one for all channels or one per channel (moments have
        their own, ``sn_slope_moment``).
    bands_hz : sequence of (lo_hz, hi_hz)
        Bands of the relative damage spectrum [Hz].

    Returns
    -------
    damage : numpy.ndarray, shape (n_channels,)
        Pseudo damage, (unit of the signals)**k.
    rds : numpy.ndarray, shape (n_channels, n_bands)
        Pseudo damage per band.

    """
    slopes = np.broadcast_to(np.asarray(sn_slope, np.float64),
                             (np.asarray(signals[0]).shape[0],))
    damage, rds = 0.0, 0.0
    for k in np.unique(slopes):  # each Basquin exponent on its rows (forces, moments)
        rows = np.flatnonzero(slopes == k)
        part_d = sum(pseudo_damage(np.asarray(x)[rows], k) for x in signals)
        part_r = sum(relative_damage_spectrum(np.asarray(x)[rows], fs_hz, k, bands_hz=bands_hz)
                     for x in signals)
        if np.ndim(damage) == 0:
            damage = np.zeros(slopes.size)
            rds = np.zeros((slopes.size,) + np.shape(part_r)[1:])
        damage[rows], rds[rows] = part_d, part_r
    return np.asarray(damage), np.asarray(rds)


def channel_sn_slopes(channels: Sequence[str], sn_slope: float,
                      sn_slope_moment: Optional[float] = None) -> np.ndarray:
    """
    Return the Basquin exponent of every channel: ``sn_slope_moment`` for the wheel moments.

    Bending (forces) and torsion (moments) have S-N curves of their own; the one rule that
    ``evaluate``, ``fleet`` and the node share.
    """
    moment = sn_slope if sn_slope_moment is None else sn_slope_moment
    return np.array([float(moment) if c in MOMENT_CHANNELS else float(sn_slope)
                     for c in channels])


def evaluate_segments(segments: Sequence[EvalSegment], fs_hz: float, channels: Sequence[str],
                      sn_slope: float = 5.0,
                      events: Sequence[Tuple[int, str]] = (),
                      asd_segment_length: int = 1024,
                      end_stamp_ns: Optional[int] = None,
                      sn_slope_moment: Optional[float] = None) -> Evaluation:
    """
    Compute RMSE %, pseudo damage, relative damage spectrum, ASD and per-event RMSE.

    Parameters
    ----------
    segments : sequence of EvalSegment
        Target and prediction per gap-free segment.
    fs_hz : float
        Sample rate [Hz].
    channels : sequence of str
        Output channel names.
    sn_slope : float
        Basquin exponent ``k`` of the pseudo S-N curve [-].
    events : sequence of (int, str)
        Event start stamps [ns] and names, sorted by stamp.
    asd_segment_length : int
        Welch segment length of the ASD [samples] (shortened to the shortest segment).
    end_stamp_ns : int, optional
        End of the last event (default: last sample stamp).
    sn_slope_moment : float, optional
        Basquin exponent of the moment channels (``MOMENT_CHANNELS``); default ``sn_slope``.

    Returns
    -------
    Evaluation

    Raises
    ------
    InsufficientDataError
        No segments.

    """
    if not segments:
        raise InsufficientDataError('nothing to evaluate: no segments')
    targets = [np.asarray(s.target_n, dtype=np.float64) for s in segments]
    preds = [np.asarray(s.prediction_n, dtype=np.float64) for s in segments]
    raw, hp = rmse_figures(targets, preds, fs_hz, channels)
    bands = tuple(tuple(b) for b in damage_bands_hz(fs_hz))
    slopes = channel_sn_slopes(channels, sn_slope, sn_slope_moment)
    dmg_t, rds_t = damage_figures(targets, fs_hz, slopes, bands)
    dmg_p, rds_p = damage_figures(preds, fs_hz, slopes, bands)
    nperseg = int(min(asd_segment_length, min(t.shape[1] for t in targets)))
    cfg = WelchConfig(fs_hz=fs_hz, segment_length=nperseg)
    weights = np.array([t.shape[1] for t in targets], dtype=np.float64)
    weights /= weights.sum()
    asd_t = asd_p = asd_e = 0.0
    f_hz = None
    for w, t, p in zip(weights, targets, preds):
        f_hz, a_t = auto_spectral_density(t, cfg)
        _, a_p = auto_spectral_density(p, cfg)
        _, a_e = auto_spectral_density(p - t, cfg)
        asd_t, asd_p, asd_e = asd_t + w * a_t, asd_p + w * a_p, asd_e + w * a_e
    per_event = _event_figures(segments, targets, preds, fs_hz, channels, events, end_stamp_ns)
    return Evaluation(
        channels=tuple(channels), fs_hz=float(fs_hz), sn_slope=float(sn_slope),
        rmse_pct=raw, rmse_hp1_pct=hp, damage_target=dmg_t,
        damage_prediction=dmg_p, bands_hz=bands, rds_target=rds_t,
        rds_prediction=rds_p, f_hz=f_hz, asd_target=asd_t,
        asd_prediction=asd_p, asd_error=asd_e, events=per_event,
        sn_slope_moment=(float(sn_slope_moment) if sn_slope_moment is not None
                         and any(c in MOMENT_CHANNELS for c in channels) else None))


def _event_figures(segments, targets, preds, fs_hz, channels, events, end_stamp_ns):
    if not events:
        return {}
    starts = np.array([int(s) for s, _ in events], dtype=np.int64)
    names = [n for _, n in events]
    last = max(int(s.stamp_ns[-1]) for s in segments if len(s.stamp_ns))
    ends = np.append(starts[1:], (end_stamp_ns if end_stamp_ns is not None else last) + 1)
    pooled: Dict[str, Tuple[list, list]] = {}
    for seg, t, p in zip(segments, targets, preds):
        stamps = np.asarray(seg.stamp_ns, dtype=np.int64)
        for start, end, name in zip(starts, ends, names):
            lo, hi = np.searchsorted(stamps, [start, end])
            if hi - lo >= 2:
                pooled.setdefault(name, ([], []))
                pooled[name][0].append(t[:, lo:hi])
                pooled[name][1].append(p[:, lo:hi])
    out = {}
    for name, (ts, ps) in pooled.items():
        raw, hp = rmse_figures(ts, ps, fs_hz, channels)
        out[name] = {'rmse_pct': raw, 'rmse_hp1_pct': hp,
                     'duration_s': sum(x.shape[1] for x in ts) / fs_hz}
    return out
