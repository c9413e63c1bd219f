# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Linear omissions (wrong sprung mass, wrong spring rate) found from band-wise gain changes.

A wrong parameter of a linear car changes the acceleration-to-force FRF, not its linearity, so
no per-corner nonlinear feature can show it; and the spindle IMU does not see the body motion
the spring and the sprung mass act through.  The simulation's FRF applied to the real
accelerations shows it as a *gain error* whose band tells the parameter (quarter car, force
``F = M s^2 (c s + k) / (M s^2 + c s + k) z``):

- sprung mass: ``dF/dM`` is the force through the body transmissibility, so every quasi-static
  load (braking ``Fx``, cornering ``Fy``, load transfer ``Fz``) is off by the same fraction
  below the body mode, on all three axes;
- spring rate: ``dF/dk`` peaks around the body mode and vanishes quasi-statically, on ``Fz``
  only (longitudinal and lateral loads do not go through the spring);
- damping: a quadrature change above the body mode (left to the per-corner ``damping_error``
  candidate, which sees it directly in the wheel velocity).

The gain of a band is the least-squares factor of the residual on the reference prediction,
both band-passed (zero phase), measured on the real recordings minus the same measurement on
the simulation's own recordings.  A spring-rate error is also told from hardening (cubic
spring, stops: the FRF of the real data looks stiffer too) by *linearity*: its gain is the
same in calm and rough time blocks, while a hardening's gain grows with the amplitude.

Each omission becomes a finding with a load-driven term (``gain * (F_lin - F0)`` on the
prediction low-passed at a fitted corner, :func:`core.physics.load_linear_force`), fitted by
least squares on the residual in the metric's band.
"""
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from scipy import signal

from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.grids import load_state
from wheel_force_estimator.diagnosis.result import Finding

#: Quasi-static band [Hz] (below the body mode, above the integrators' settling).
QUASI_STATIC_HZ = (0.1, 0.8)
#: Body-mode band [Hz] where a spring-rate error shows most.
BODY_HZ = (1.6, 3.2)
#: Corners [Hz] tried for the low-passed load state of the term.
STATE_LOWPASS_HZ = (0.5, 1.0, 2.0, 4.0)
AXES = ('fx', 'fy', 'fz')


@dataclass(frozen=True)
class OmissionConfig:
    """
    Acceptance rules of the linear-omission findings.

    Attributes
    ----------
    mass_gain : float
        Smallest quasi-static gain excess (real minus sim) required on *every* axis (mean of
        the corners).  Measured on 120 s proving-ground pairs: 0.01-0.04 between two nominal
        runs (seeds 0, 1), 0.08-0.11 for a 7 % heavier car.
    stiffness_gain : float
        Smallest mean body-band ``Fz`` gain excess: -0.01..0.01 between nominal runs, 0.02-0.04
        for a stop, 0.10 for springs 15 % stiffer.
    linearity : float
        The gain in the calmer half of the time blocks must be at least this fraction of the
        gain in the rougher half (a hardening spring gives ~0 in calm blocks).
    block_s : float
        Time block for the linearity split [s].

    """

    mass_gain: float = 0.05
    stiffness_gain: float = 0.06
    linearity: float = 0.5
    block_s: float = 4.0


def _bandpass(x: np.ndarray, fs_hz: float, band: Tuple[float, float]) -> np.ndarray:
    sos = signal.butter(4, band, 'bandpass', fs=fs_hz, output='sos')
    return signal.sosfiltfilt(sos, x, axis=-1)


@dataclass
class _Gains:
    """Per channel: pooled band gain, and block-wise cross / energy sums for the split."""

    gain: np.ndarray
    cross: List[np.ndarray]
    energy: List[np.ndarray]


def band_gains(recordings, reference, band, skip: int, block_s: float) -> _Gains:
    """Return the band gain of residual on prediction per output channel."""
    cross, energy = None, None
    for rec in recordings:
        pred = reference.predict(rec)
        fs = rec.fs_hz
        p = _bandpass(pred, fs, band)[:, skip:]
        r = _bandpass(np.asarray(rec.outputs) - pred, fs, band)[:, skip:]
        length = max(int(round(block_s * fs)), 1)
        nb = p.shape[1] // length
        if nb == 0:
            continue
        shape = (p.shape[0], nb, length)
        pc = p[:, :nb * length].reshape(shape)
        rc = r[:, :nb * length].reshape(shape)
        c, e = np.sum(pc * rc, axis=2), np.sum(pc * pc, axis=2)
        cross = c if cross is None else np.concatenate([cross, c], axis=1)
        energy = e if energy is None else np.concatenate([energy, e], axis=1)
    gain = cross.sum(axis=1) / np.maximum(energy.sum(axis=1), 1e-300)
    return _Gains(gain, list(cross), list(energy))


def _split_gains(g: _Gains, o: int) -> Tuple[float, float]:
    """Return the gain over the calmer and the rougher half of the blocks of channel ``o``."""
    order = np.argsort(g.energy[o])
    half = order.size // 2
    lo, hi = order[:half], order[half:]
    c, e = g.cross[o], g.energy[o]
    return (float(c[lo].sum() / max(e[lo].sum(), 1e-300)),
            float(c[hi].sum() / max(e[hi].sum(), 1e-300)))


def _fit_term(physics, recordings, reference, channels, group, skip, hp, sources, quantity,
              feature_filters):
    """Shared least-squares load-driven term: (terms, explained fraction, gain, corner)."""
    idx = [channels.index(c) for c in group]
    preds, resid = [], []
    for rec in recordings:
        pred = reference.predict(rec)
        preds.append(pred[idx])
        r = np.asarray(rec.outputs)[idx] - pred[idx]
        resid.append(highpass(r, rec.fs_hz, hp, 'omission residual')[:, skip:] if hp > 0.0
                     else r[:, skip:])
    fs = recordings[0].fs_hz
    best = None
    for fc in STATE_LOWPASS_HZ:
        cols, centers = [], []
        for pred in preds:
            states = []
            for row in pred:
                ctx = ChannelContext(row, row, row, row, row, None, fs)
                states.append(load_state(ctx, fc))
            states = np.array(states)
            centers.append(states.mean(axis=1))
            cols.append(states)
        center = np.mean(centers, axis=0)
        num = den = ss = 0.0
        for states, r in zip(cols, resid):
            b = states - center[:, np.newaxis]
            b = highpass(b, fs, hp, 'omission basis')[:, skip:] if hp > 0.0 else b[:, skip:]
            num += float(np.sum(b * r))
            den += float(np.sum(b * b))
            ss += float(np.sum(r * r))
        gain = num / den if den > 0.0 else 0.0
        explained = gain * num / ss if ss > 0.0 else 0.0
        if best is None or explained > best[1]:
            best = (fc, explained, gain, center)
    fc, explained, gain, center = best
    terms = tuple(PhysicsTerm(physics, (c,), {'center_n': float(center[k]), 'gain': gain},
                              sources=(sources[channels.index(c)],), input_quantity=quantity,
                              highpass_hz=feature_filters[0], lowpass_hz=feature_filters[1],
                              state='load', state_lowpass_hz=fc)
                  for k, c in enumerate(group))
    return terms, explained, gain, fc


def linear_omissions(real, sim, reference, channels: Sequence[str], skip: int, hp: float,
                     sources, quantity, feature_filters,
                     config: Optional[OmissionConfig] = None, debug: Optional[Dict] = None
                     ) -> List[Finding]:
    """
    Name a wrong sprung mass or spring rate from band gains of the sim FRF on real data.

    Parameters
    ----------
    real, sim : sequence of MotionRecording
        Real and simulated recordings (the reference was fitted on ``sim``).
    reference : FrfReference
        The simulation's FRF.
    channels : sequence of str
        Output channels (vehicle names ``lf_fx`` ... are needed; otherwise nothing is named).
    skip : int
        Samples left out at the start of each record (filter settling).
    hp : float
        High-pass of the metric [Hz] (the term is fitted in that band).
    sources : sequence of str
        Input channel of each output channel (for the terms).
    quantity : str
        Input quantity.
    feature_filters : tuple of float
        ``(highpass_hz, lowpass_hz)`` stored in the terms.
    config : OmissionConfig, optional
        Acceptance rules.
    debug : dict, optional
        Filled with the measured gains (for benchmarks).

    Returns
    -------
    list of Finding

    """
    config = config or OmissionConfig()
    channels = list(channels)
    by_axis = {a: [c for c in channels if c.endswith('_' + a)] for a in AXES}
    if any(len(v) == 0 for v in by_axis.values()):
        return []
    qs = [band_gains(recs, reference, QUASI_STATIC_HZ, skip, config.block_s)
          for recs in (real, sim)]
    excess_q = qs[0].gain - qs[1].gain
    axis_q = {a: float(np.mean([excess_q[channels.index(c)] for c in by_axis[a]]))
              for a in AXES}
    body = [band_gains(recs, reference, BODY_HZ, skip, config.block_s) for recs in (real, sim)]
    excess_b = body[0].gain - body[1].gain
    fz = by_axis['fz']
    fz_b = float(np.mean([excess_b[channels.index(c)] for c in fz]))
    splits = [_split_gains(body[0], channels.index(c)) for c in fz]
    calm = float(np.mean([s[0] for s in splits]))
    rough = float(np.mean([s[1] for s in splits]))
    if debug is not None:
        debug.update(quasi_static=axis_q, body_fz=fz_b, body_calm=calm, body_rough=rough)
    args = (real, reference, channels)
    rest = (skip, hp, sources, quantity, feature_filters)
    if min(axis_q.values()) >= config.mass_gain:
        return [_mass_finding(axis_q, [c for a in AXES for c in by_axis[a]], args, rest)]
    if fz_b >= config.stiffness_gain and rough > 0.0 and calm >= config.linearity * rough:
        return [_stiffness_finding(fz, fz_b, calm, rough, args, rest)]
    return []


def _mass_finding(axis_q: Dict[str, float], group: List[str], args: tuple,
                  rest: tuple) -> Finding:
    """Return the ``mass_error`` finding on ``group``, its term fitted (``_fit_term``'s args)."""
    terms, explained, gain, fc = _fit_term('mass_error', *args, group, *rest)
    fraction = float(np.mean(list(axis_q.values())))
    evidence = (f'mass_error on all channels: every quasi-static load ({QUASI_STATIC_HZ[0]:g}'
                f'-{QUASI_STATIC_HZ[1]:g} Hz) is larger than the simulation predicts by '
                + ', '.join(f'{a.upper()} {100 * v:+.1f} %' for a, v in axis_q.items())
                + f' (a sprung mass about {100 * fraction:+.0f} % off: braking, cornering '
                f'and load transfer all scale with it); modelled as {100 * gain:+.1f} % of '
                f'the predicted load below {fc:g} Hz')
    return Finding('mass_error', tuple(group), {'mass_fraction': fraction},
                   max(explained, 0.0), evidence, terms, 0.0)


def _stiffness_finding(fz: List[str], fz_b: float, calm: float, rough: float, args: tuple,
                       rest: tuple) -> Finding:
    """Return the ``stiffness_error`` finding on the Fz channels ``fz``, its term fitted."""
    terms, explained, gain, fc = _fit_term('stiffness_error', *args, fz, *rest)
    evidence = (f'stiffness_error on {", ".join(fz)}: around the body mode '
                f'({BODY_HZ[0]:g}-{BODY_HZ[1]:g} Hz) the vertical forces are '
                f'{100 * fz_b:+.1f} % larger than the simulation predicts, as much in calm '
                f'({100 * calm:+.1f} %) as in rough ({100 * rough:+.1f} %) stretches (linear, '
                f'unlike a hardening), while quasi-static loads agree: a spring rate is off; '
                f'modelled as {100 * gain:+.1f} % of the predicted load low-passed at '
                f'{fc:g} Hz (spring part of the suspension force)')
    return Finding('stiffness_error', tuple(fz), {'stiffness_fraction': fz_b},
                   max(explained, 0.0), evidence, terms, 0.0)
