# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Where the residual of one channel lives: frequency bands, time windows, operating regime.

- Bands: lines where the residual ASD is a large part of the target ASD (the reference cannot
  follow the real force there) and the residual carries power, merged into ranges.
- Time windows: stretches where the rolling residual RMS stands well above its median (events).
- Regime: the residual RMS conditioned on a physical state (large compression, fast rebound,
  velocity reversals, low load, ...) relative to its overall RMS.
"""
from typing import List, Sequence, Tuple

import numpy as np
from scipy import signal

from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.core.metrics import rmse_pct
from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.result import ChannelMismatch

#: Residual RMS ratio (state bin / overall) needed to call a regime.
REGIME_RATIO = 1.5


def _segment_runs(mask: np.ndarray, max_gap: int = 1) -> List[Tuple[int, int]]:
    """Index ranges ``[start, stop)`` of True runs, joining runs separated by <= max_gap."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > max_gap + 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks], [idx[-1]]]) + 1
    return list(zip(starts.tolist(), stops.tolist()))


def residual_bands(targets: Sequence[np.ndarray], residuals: Sequence[np.ndarray],
                   fs_hz: float, max_bands: int = 3) -> Tuple[Tuple[float, float], ...]:
    """Frequency ranges [Hz] where the residual dominates, most residual power first."""
    n_min = min(r.size for r in residuals)
    nperseg = int(min(2 ** int(np.log2(max(n_min, 16))), 2 ** int(np.log2(4 * fs_hz))))
    p_res, p_tgt, weight = 0.0, 0.0, 0
    for t, r in zip(targets, residuals):
        f, pr = signal.welch(r, fs_hz, nperseg=nperseg)
        _, pt = signal.welch(t, fs_hz, nperseg=nperseg)
        p_res, p_tgt, weight = p_res + r.size * pr, p_tgt + r.size * pt, weight + r.size
    p_res, p_tgt = p_res / weight, p_tgt / weight
    if not np.any(p_res > 0.0):
        return ()
    ratio = p_res / np.maximum(p_tgt, 1e-300)
    live = p_res >= 0.01 * p_res.max()
    flagged = live & (ratio >= max(0.1, 3.0 * float(np.median(ratio[live]))))
    runs = _segment_runs(flagged)
    runs.sort(key=lambda ab: -float(p_res[ab[0]:ab[1]].sum()))
    df = f[1] - f[0]
    return tuple((float(max(f[a] - 0.5 * df, 0.0)), float(f[b - 1] + 0.5 * df))
                 for a, b in runs[:max_bands])


def residual_windows(residuals: Sequence[np.ndarray], starts_s: Sequence[float], fs_hz: float,
                     window_s: float = 0.25, max_windows: int = 5
                     ) -> Tuple[Tuple[float, float], ...]:
    """
    Time windows [s] where the rolling residual RMS exceeds 3x its median, worst first.

    Returns nothing when more than 30 % of the time is flagged: the mismatch is then not an
    event but everywhere.
    """
    w = max(int(round(window_s * fs_hz)), 4)
    found, flagged_total, n_total = [], 0, 0
    rolls = []
    for r in residuals:
        if r.size < w:
            rolls.append(None)
            continue
        rolls.append(np.sqrt(np.convolve(r * r, np.ones(w) / w, mode='same')))
    valid = [x for x in rolls if x is not None]
    if not valid:
        return ()
    level = 3.0 * float(np.median(np.concatenate(valid)))
    for roll, start in zip(rolls, starts_s):
        if roll is None:
            continue
        mask = roll > level
        flagged_total += int(mask.sum())
        n_total += roll.size
        for a, b in _segment_runs(mask, max_gap=w):
            found.append((float(roll[a:b].max()), start + a / fs_hz, start + b / fs_hz))
    if not found or n_total == 0 or flagged_total > 0.3 * n_total:
        return ()
    found.sort(key=lambda x: -x[0])
    return tuple((a, b) for _, a, b in found[:max_windows])


def regime_ratios(residuals: Sequence[np.ndarray],
                  contexts: Sequence[ChannelContext]) -> List[Tuple[str, float]]:
    """Residual RMS in each state bin divided by the overall residual RMS, largest first."""
    r = np.concatenate(residuals)
    r = r - r.mean()
    overall = float(np.sqrt(np.mean(r * r)))
    if overall <= 0.0:
        return []
    disp = np.concatenate([c.disp for c in contexts])
    vel = np.concatenate([c.vel for c in contexts])
    acc = np.concatenate([c.acc for c in contexts])
    load = np.concatenate([c.load for c in contexts])
    speed = np.abs(vel)

    def q(x, p):
        return float(np.quantile(x, p))
    masks = {
        'large compression': disp >= q(disp, 0.95),
        'large extension': disp <= q(disp, 0.05),
        'fast compression': vel >= q(vel, 0.95),
        'fast rebound': vel <= q(vel, 0.05),
        'velocity reversals': speed <= q(speed, 0.10),
        'large acceleration': np.abs(acc) >= q(np.abs(acc), 0.95),
        'low load': load <= q(load, 0.05),
        'high load': load >= q(load, 0.95),
    }
    out = []
    for label, mask in masks.items():
        if mask.sum() >= 8:
            out.append((label, float(np.sqrt(np.mean(r[mask] ** 2))) / overall))
    out.sort(key=lambda x: -x[1])
    return out


def regime(residuals: Sequence[np.ndarray], contexts: Sequence[ChannelContext]) -> str:
    """Name of the state where the residual concentrates, or ``'uniform'``."""
    ratios = regime_ratios(residuals, contexts)
    if not ratios or ratios[0][1] < REGIME_RATIO:
        return 'uniform'
    return ratios[0][0]


def locate_channel(channel: str, targets: Sequence[np.ndarray],
                   predictions: Sequence[np.ndarray], contexts: Sequence[ChannelContext],
                   starts_s: Sequence[float], fs_hz: float,
                   highpass_hz: float = 0.0) -> ChannelMismatch:
    """Describe the mismatch of one channel over several records (optionally high-passed)."""
    if highpass_hz > 0.0:
        targets = [highpass(t[np.newaxis], fs_hz, highpass_hz, channel)[0] for t in targets]
        predictions = [highpass(p[np.newaxis], fs_hz, highpass_hz, channel)[0]
                       for p in predictions]
    t = np.concatenate(targets)
    p = np.concatenate(predictions)
    pct = float(rmse_pct(t[np.newaxis], p[np.newaxis], (channel,))[0])
    residuals = [a - b for a, b in zip(targets, predictions)]
    return ChannelMismatch(channel=channel, rmse_pct=pct,
                           bands_hz=residual_bands(targets, residuals, fs_hz),
                           time_windows_s=residual_windows(residuals, starts_s, fs_hz),
                           regime=regime(residuals, contexts))
