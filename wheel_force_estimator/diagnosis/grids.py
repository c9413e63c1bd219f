# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The shapes each candidate tries: small grids scaled to the pooled training features.

A grid function takes the :class:`ChannelContext` of every training piece and returns the
shapes to try (gap, exponent, velocity scale, delay, load-state corner); an empty list means
the candidate does not apply to these records.  :mod:`diagnosis.candidates` binds one grid to
each candidate; the load state and the fractional shift here are the ones the written terms
compute (:class:`core.physics.PhysicsStage`).
"""
import numpy as np
from scipy import signal

from wheel_force_estimator.core import physics as ph
from wheel_force_estimator.core.filter_design import butter_ba
from wheel_force_estimator.diagnosis.clipping import clip_level
from wheel_force_estimator.diagnosis.features import ChannelContext


def pooled(contexts, attr):
    return np.concatenate([getattr(c, attr) for c in contexts])


def one(contexts):
    return [{}]


def stop_grid(sign):
    def grid(contexts):
        d = sign * pooled(contexts, 'disp')
        gaps = np.quantile(d, [0.6, 0.8, 0.9, 0.95, 0.98, 0.99, 0.995])
        gaps = sorted({float(g) for g in gaps if g >= 0.0})
        return [{'gap_m': g, 'exponent': p} for g in gaps for p in (1.0, 2.0, 3.0)]
    return grid


#: Corners of the load-state low-pass tried [Hz]: high enough to keep stop impacts in phase.
LOAD_LOWPASS_HZ = (2.5, 5.0, 10.0)


def load_state(ctx: ChannelContext, lowpass_hz: float) -> np.ndarray:
    """Predicted load low-passed like :class:`PhysicsStage` does for ``state='load'``."""
    return lowpassed_load(ctx.load, ctx.fs_hz, lowpass_hz)


def lowpassed_load(load_n: np.ndarray, fs_hz: float, lowpass_hz: float) -> np.ndarray:
    """Return ``load_n`` low-passed like the stage's load state (started at its first value)."""
    b, a = butter_ba(1, float(lowpass_hz), 'lowpass', float(fs_hz))
    return signal.lfilter(b, a, load_n, zi=signal.lfilter_zi(b, a) * load_n[0])[0]


def load_stop_grid(sign):
    def grid(contexts):
        out = []
        for fc in LOAD_LOWPASS_HZ:
            state = np.concatenate([load_state(c, fc) for c in contexts])
            qs = (0.8, 0.9, 0.95, 0.98, 0.99, 0.995)
            for q in qs:
                thr = float(np.quantile(state, q if sign > 0 else 1.0 - q))
                out.extend({'threshold_n': thr, 'exponent': p, 'state_lowpass_hz': fc}
                           for p in (1.0, 2.0))
        return out
    return grid


def load_cubic_grid(contexts):
    out = []
    for fc in LOAD_LOWPASS_HZ:
        state = np.concatenate([load_state(c, fc) for c in contexts])
        out.append({'center_n': float(np.mean(state)), 'state_lowpass_hz': fc})
    return out


def load_backlash_grid(contexts):
    out = []
    for fc in LOAD_LOWPASS_HZ:
        state = np.concatenate([load_state(c, fc) for c in contexts])
        sd = float(np.std(state))
        if sd > 0.0:
            out.extend({'center_n': float(np.mean(state)), 'threshold_n': f * sd,
                        'state_lowpass_hz': fc} for f in (0.05, 0.1, 0.2, 0.4))
    return out


def backlash_grid(contexts):
    sd = float(np.std(pooled(contexts, 'disp')))
    if sd <= 0.0:
        return []
    return [{'gap_m': f * sd, 'hysteretic': h} for h in (0.0, 1.0)
            for f in (0.05, 0.1, 0.2, 0.4, 0.7)]


def coulomb_grid(contexts):
    sd = float(np.std(pooled(contexts, 'vel')))
    return [] if sd <= 0.0 else [{'velocity_scale_mps': f * sd}
                                 for f in (0.003, 0.01, 0.03, 0.1, 0.3)]


def lift_off_grid(contexts):
    # Only a preloaded contact can lift off: the load must stay well above zero on average
    # (a normal force), not swing around it (a tangential force such as Fx or Fy).
    load = pooled(contexts, 'load')
    mean = float(np.mean(load))
    if mean <= 2.0 * float(np.std(load)) or float(load.min()) > 0.2 * mean:
        return []
    return [{'threshold_n': f * mean} for f in (0.0, 0.05, 0.15)]


def arb_grid(contexts):
    return [{}] if all(c.partner_disp is not None for c in contexts) else []


#: Delays tried [samples]: fine near zero (fractional, linear interpolation as in the stage).
DELAYS_SAMPLES = (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0,
                  24.0, 32.0)


def delay_grid(contexts):
    fs = contexts[0].fs_hz
    steps = [d for d in DELAYS_SAMPLES if d <= 0.1 * fs]
    return [{'delay_samples': s * d} for d in steps for s in (1.0, -1.0)]


def shift_signal(x: np.ndarray, delay_samples: float) -> np.ndarray:
    """
    ``y[n] = x[n - d]`` by linear interpolation, edge values held (d < 0 looks ahead).

    For d >= 0 this is what :class:`PhysicsStage` computes for a time_delay term.
    """
    n = np.arange(x.size, dtype=np.float64)
    return np.interp(n - delay_samples, n, x)


def saturation_grid(contexts):
    # The clip test of the motion comparison, on the source's whole recorded level (a flat
    # top is judged against the values next to it over all of the record).
    level = clip_level([c.level for c in contexts], contexts[0].n_inputs)
    if level is None:
        return []
    order = ph.QUANTITIES.index(contexts[0].filters[0])
    return [{'limit': level, 'integration': float(k)} for k in range(order + 1)]


def load_linear_grid(contexts):
    return [{'center_n': float(np.mean(np.concatenate([load_state(c, fc) for c in contexts]))),
             'state_lowpass_hz': fc} for fc in (1.0, 2.0, 4.0)]
