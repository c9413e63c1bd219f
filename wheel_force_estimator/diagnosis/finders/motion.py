# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The motion finder: physics that changes the motion, not the map (clipped sensor, tyre in air).

A clipped accelerometer and a tyre that leaves the ground hardly change the
acceleration-to-force map a linear model fits, so the residual ranking cannot see them; the
recordings themselves differ.  This module compares the real and the simulated motion on the
same course, with two statistical rules that need no threshold fitted to our simulator:

``sensor_saturation``
    A clip repeats the channel's extreme value exactly.  A sensor that is not clipped reaches
    its extreme once (continuous values) or about as often as the values just inside it
    (quantised values: the tail thins toward the extreme).  The count at the extreme is
    tested against a Poisson law whose mean is how often the distinct values next to the
    extreme repeat (:mod:`.clipping`); the level is the extreme itself, found from the data.
    The simulation on the same course shows the peaks the sensor lost (how often it goes
    beyond the level) and must not clip at that level itself.
``tire_lift_off``
    A wheel force transducer reads the tyre force minus the inertia of the mass outboard of
    it: ``Fz = F_tyre - m_o * az`` (``az`` specific force).  In free flight the tyre force is
    zero, so the hub force is exactly proportional to the spindle's specific force through the
    origin, and a tyre that cannot pull keeps ``T = Fz + m_o az >= 0``: the real data lie
    above a supporting line of slope ``m_o``.  Each recording's line is the lowest ratio
    ``Fz / -az`` (az below -1 g); a bilateral simulated contact puts the tyre in tension
    below the real line where the real one never goes below the simulated line.  The
    exchangeable counts (simulated tension runs below the real line vs real runs below the
    simulated line) are compared with a one-sided binomial test pooled over the corners, and
    the real record must show free-flight spans (``|T| <= 10 %`` of the static load for at
    least :data:`FLIGHT_MIN_S`) that locate the lift-off in time and corner.

Both findings carry no model term: the clip removes input information a map cannot restore
(a term fitted on few clipped peaks does not carry over), and in flight the hub force is the
outboard inertia, which the linear map already predicts.  The written model is then the best
linear one the holdout prefers (documented in the README).
"""
from dataclasses import dataclass
import math
from typing import List, Optional, Sequence, Tuple

import numpy as np
from scipy import stats

from wheel_force_estimator import CORNERS
from wheel_force_estimator import GRAVITY_MPS2
from wheel_force_estimator.core.sample_ranges import runs
from wheel_force_estimator.diagnosis.clipping import CLIP_ALPHA
from wheel_force_estimator.diagnosis.clipping import clip_bound
from wheel_force_estimator.diagnosis.clipping import clip_test
from wheel_force_estimator.diagnosis.clipping import MIN_CLIP_SAMPLES
from wheel_force_estimator.diagnosis.result import Finding

#: Shortest free flight [s]: a quarter period of a 50 Hz wheel-hop mode, far above any car's.
FLIGHT_MIN_S = 0.005
#: Tyre force band counted as free flight, as a fraction of the static tyre load.
FLIGHT_BAND = 0.1


@dataclass(frozen=True)
class MotionConfig:
    """
    Rules of the motion comparison.

    Attributes
    ----------
    alpha : float
        False-alarm probability of each finding: the clip test is Bonferroni-corrected over
        channels and sides, the lift-off test is one pooled test.
    min_clip_samples : int
        Fewest samples at the extreme to call it a clip at all.
    merge_s : float
        Spans closer than this are reported as one time window [s].
    max_windows : int
        Time windows listed per finding.

    """

    alpha: float = CLIP_ALPHA
    min_clip_samples: int = MIN_CLIP_SAMPLES
    merge_s: float = 0.2
    max_windows: int = 12


def _windows(spans_s: List[Tuple[float, float]], merge_s: float, limit: int):
    out: List[List[float]] = []
    for a, b in sorted(spans_s):
        if out and a - out[-1][1] <= merge_s:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return tuple((round(a, 3), round(b, 3)) for a, b in out[:limit])


def _rows(recs, attr, row):
    """Return one channel of every record, a list (records are never joined)."""
    return [np.asarray(getattr(r, attr))[row] for r in recs]


def _concat(recs, attr, row):
    return np.concatenate(_rows(recs, attr, row))


def _clips(real: Sequence, sim: Sequence, bound: float, config: MotionConfig) -> list:
    """Return the real inputs' clips below ``bound`` the simulation does not share."""
    clips = []
    for i, name in enumerate(real[0].input_channels):
        clip = clip_test(_rows(real, 'inputs', i), name, config.min_clip_samples)
        if clip is None or clip.p_value >= bound:
            continue
        if sim:
            own = clip_test(_rows(sim, 'inputs', i), name, config.min_clip_samples)
            if own is not None and own.p_value < bound and own.level == clip.level:
                continue  # the simulation models the same sensor range
        clips.append(clip)
    return clips


def _clipped_spans(real: Sequence, clips: Sequence) -> Tuple[list, int]:
    """Return the time spans [s] with any input at its clip level, and that sample count."""
    inputs = real[0].input_channels
    spans, at_any = [], 0
    for rec in real:
        mask = np.zeros(rec.n_samples, bool)
        for c in clips:
            mask |= np.asarray(rec.inputs)[inputs.index(c.channel)] == c.level
        at_any += int(mask.sum())
        spans += [(rec.start_s + a / rec.fs_hz, rec.start_s + b / rec.fs_hz)
                  for a, b in runs(mask)]
    return spans, at_any


def saturation_finding(real: Sequence, sim: Sequence, sources: Sequence[str],
                       config: MotionConfig) -> Optional[Finding]:
    """
    Name ``sensor_saturation`` when real input channels show flat tops the simulation lacks.

    Parameters
    ----------
    real, sim : sequence of MotionRecording
        Real and simulated recordings (``sim`` may be empty: no contrast).
    sources : sequence of str
        Input channel paired with each output channel (the finding's channels are the
        outputs of clipped inputs; all outputs when none is paired).
    config : MotionConfig
        Significance level and reporting rules.

    Returns
    -------
    Finding or None

    """
    rec0 = real[0]
    inputs = rec0.input_channels
    bound = clip_bound(len(inputs), config.alpha)
    clips = _clips(real, sim, bound, config)
    if not clips:
        return None
    n_real = sum(r.n_samples for r in real)
    spans, at_any = _clipped_spans(real, clips)
    windows = _windows(spans, config.merge_s, config.max_windows)
    limit = min(abs(c.level) for c in clips)
    beyond = ''
    if sim:
        parts = []
        for c in clips:
            x = _concat(sim, 'inputs', inputs.index(c.channel))
            parts.append(f'{c.channel} {100 * np.mean(np.sign(c.level) * x > abs(c.level)):.2f} %')
        beyond = ('; the simulation on the same course goes beyond those levels without a flat '
                  'top (' + ', '.join(parts) + ' of its samples): the real sensor lost them')
    detail = ', '.join(f'{c.channel} at {c.level:+.4g} ({c.count} samples, a neighbour value '
                       f'repeats {c.null_mean:.2g} times, Poisson p = {c.p_value:.1e})'
                       for c in clips)
    clipped = {c.channel for c in clips}
    channels = tuple(o for o, s in zip(rec0.output_channels, sources) if s in clipped) \
        or tuple(rec0.output_channels)
    evidence = (f'sensor_saturation: flat tops at one extreme level, {detail}; p below '
                f'{bound:.1e} (false-alarm rate {config.alpha:g} over {2 * len(inputs)} '
                f'channel sides){beyond}; {100 * at_any / n_real:.3f} % of the samples clipped, '
                f'in {len(spans)} spans, first at '
                + ', '.join(f'{a:.2f}-{b:.2f} s' for a, b in windows[:4])
                + '. No model term: a map cannot restore the lost peaks; the best linear model '
                'is kept (fit the model on unclipped data or use a larger sensor range)')
    return Finding('sensor_saturation', channels,
                   {'limit': limit, 'clipped_fraction': at_any / n_real,
                    'n_spans': float(len(spans))}, 0.0, evidence, (), 0.0, {}, windows)


def _corner_rows(rec0, corner):
    fz, az = f'{corner}_fz', f'{corner}_az'
    if fz in rec0.output_channels and az in rec0.input_channels:
        return rec0.output_channels.index(fz), rec0.input_channels.index(az)
    return None


def supporting_mass(fz: np.ndarray, az: np.ndarray) -> Optional[float]:
    """
    Slope of the line ``Fz = -m az`` the record's points stay above (az below -1 g), or None.

    The third-lowest ratio ``Fz / -az``: two stray samples cannot set it.
    """
    cand = az < -GRAVITY_MPS2
    if np.count_nonzero(cand) < 3:
        return None
    r = np.partition(fz[cand] / -az[cand], 2)[2]
    return float(r)


def _flights(real, o: int, i: int, m_real: float, band: float) -> list:
    """Spans ``(start_s, end_s, samples)`` where the tyre force stays within ``band``."""
    spans = []
    for rec in real:
        t = np.asarray(rec.outputs)[o] + m_real * np.asarray(rec.inputs)[i]
        need = max(int(math.ceil(FLIGHT_MIN_S * rec.fs_hz)), 2)
        for a, b in runs(np.abs(t) <= band):
            if b - a >= need:
                spans.append((rec.start_s + a / rec.fs_hz, rec.start_s + b / rec.fs_hz, b - a))
    return spans


def _corner(real, sim, o: int, i: int):
    """
    Return ``(m_real, static, n_sim_below, n_real_below, flights)`` of one corner, or None.

    None when either record has no supporting line or the real static load is not positive.
    """
    fz_r, az_r = _concat(real, 'outputs', o), _concat(real, 'inputs', i)
    fz_s, az_s = _concat(sim, 'outputs', o), _concat(sim, 'inputs', i)
    m_real, m_sim = supporting_mass(fz_r, az_r), supporting_mass(fz_s, az_s)
    if m_real is None or m_sim is None or m_real <= 0.0:
        return None
    static = float(np.median(fz_r + m_real * az_r))
    if static <= 0.0:
        return None
    band = FLIGHT_BAND * static
    # Exchangeable counts: each record's runs below the other record's supporting line.
    n_sim_below = len(runs(fz_s + m_real * az_s < -band))
    n_real_below = len(runs(fz_r + max(m_sim, 0.0) * az_r < -band))
    return m_real, static, n_sim_below, n_real_below, _flights(real, o, i, m_real, band)


def lift_off_finding(real: Sequence, sim: Sequence, config: MotionConfig) -> Optional[Finding]:
    """
    Name ``tire_lift_off`` when the real tyres fly where the simulated ones pull the road.

    Needs vehicle channel names (``{corner}_fz`` outputs and ``{corner}_az`` acceleration
    inputs) and simulated recordings of the same course; otherwise None.

    Parameters
    ----------
    real : sequence of MotionRecording
        Real recordings (WFT ``Fz`` and spindle ``az`` of each corner).
    sim : sequence of MotionRecording
        Simulated recordings of the same course.
    config : MotionConfig
        Significance level and reporting rules.

    Returns
    -------
    Finding or None
        None when no corner flew where the simulated tyre pulled, or the pooled binomial test
        is not significant at ``config.alpha``.

    """
    rec0 = real[0]
    if not sim or rec0.input_quantity != 'acceleration':
        return None
    pooled_sim = pooled_real = 0
    corners = []
    for corner in CORNERS:
        rows = _corner_rows(rec0, corner)
        found = None if rows is None else _corner(real, sim, *rows)
        if found is None:
            continue
        m_real, static, n_sim_below, n_real_below, spans = found
        pooled_sim += n_sim_below
        pooled_real += n_real_below
        if spans and n_sim_below > n_real_below:
            corners.append((corner, m_real, static, n_sim_below, n_real_below, spans))
    total = pooled_sim + pooled_real
    if not corners or total == 0:
        return None
    n_real = sum(r.n_samples for r in real)
    n_sim = sum(r.n_samples for r in sim)
    p = float(stats.binom.sf(pooled_sim - 1, total, n_sim / (n_sim + n_real)))
    if p >= config.alpha:
        return None
    return _lift_off(corners, pooled_sim, pooled_real, p, n_real, config)


def _lift_off(corners, pooled_sim: int, pooled_real: int, p: float, n_real: int,
              config: MotionConfig) -> Finding:
    """Return the lift-off finding of the corners that flew."""
    flown = sum(s[2] for c in corners for s in c[5])
    windows = _windows([s[:2] for c in corners for s in c[5]], config.merge_s,
                       config.max_windows)
    per_corner = '; '.join(
        f'{c}: outboard mass {m:.1f} kg, {len(sp)} flights, first '
        + ', '.join(f'{a:.2f}-{b:.2f} s' for a, b, _ in sp[:3])
        + f' (simulated tyre in tension {ns} times below this line, real {nr} times below the '
        f'simulated one)' for c, m, _, ns, nr, sp in corners)
    evidence = (f'tire_lift_off: the hub force follows the outboard inertia alone '
                f'(Fz = -m_o az, tyre force within {100 * FLIGHT_BAND:.0f} % of the static '
                f'load) for spans of at least {1e3 * FLIGHT_MIN_S:g} ms, and the real tyre '
                f'never pulls while the simulated one does ({pooled_sim} tension runs vs '
                f'{pooled_real}, binomial p = {p:.1e} < {config.alpha:g}): {per_corner}. No '
                f'model term: in flight the hub force is the outboard inertia the linear map '
                f'already predicts; the simulation needs a unilateral tyre contact')
    return Finding('tire_lift_off', tuple(f'{c[0]}_fz' for c in corners),
                   {'outboard_mass_kg': float(np.mean([c[1] for c in corners])),
                    'flight_fraction': float(flown / n_real),
                    'n_flights': float(sum(len(c[5]) for c in corners))},
                   0.0, evidence, (), 0.0, {}, windows)


def motion_findings(real: Sequence, sim: Sequence, sources: Sequence[str],
                    config: Optional[MotionConfig] = None) -> List[Finding]:
    """
    Return the motion findings (``sensor_saturation``, ``tire_lift_off``) of a diagnosis.

    Parameters
    ----------
    real : sequence of MotionRecording
        Real recordings.
    sim : sequence of MotionRecording
        Simulated recordings of the same course (empty with ``--model`` / generic data: the
        clip test still runs, the lift-off test needs the contrast).
    sources : sequence of str
        Input channel paired with each output channel.
    config : MotionConfig, optional
        Significance level and reporting rules (defaults when None).

    Returns
    -------
    list of Finding
        Without model terms, each with the time windows where it acts.

    """
    config = config or MotionConfig()
    real, sim = tuple(real), tuple(sim or ())
    found = [saturation_finding(real, sim, sources, config), lift_off_finding(real, sim, config)]
    return [f for f in found if f is not None]


def find(run, found=()) -> List[Finding]:
    """Return the run's motion findings (``found`` unused: they read the recordings only)."""
    return motion_findings(run.real, run.sim, run.sources, run.config.motion)
