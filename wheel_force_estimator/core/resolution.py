# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Frequency resolution measured on the data: blocked cross-validation of the Welch segment.

The paper's 1024-sample segment (0.5 Hz at 512 Hz) suits a car, whose modes are well damped.
A lightly damped structure or rig has resonances narrower than that: the windowed H1 estimate
smears them (resolution bias; for a peak it grows with ``(df / B_r)**2``, ``B_r`` the
half-power bandwidth - Bendat & Piersol, *Random Data*, 9.1.4), and the FIR predicts a new run
badly however good the data (measured: a base-excited 8 Hz mode with 5 % damping, 2 % force
noise, 60 s at 512 Hz - 21 % RMSE on a held-out run at 1024 samples, 3 % at 4096).  Longer
segments trade that bias for random error (fewer windows to average) and, on short records,
for data (a segment longer than a record cannot use it).  Which wins depends on the damping,
the noise and the record lengths, none known in advance, so it is measured: each record is cut
into ``n_folds`` contiguous blocks; fold ``k`` fits on every record without its block ``k``
(the pieces before and after, each its own gap-free segment, as ``fit`` joins recordings) and
predicts the whole record, scored on the held-out blocks only.  The inputs around a held-out
block are known, so its prediction is exactly what ``evaluate`` would give there.

The asked-for length is kept unless the best length predicts the held-out blocks better by
more than one standard error of the fold-by-fold difference (the one-standard-error rule of
Hastie, Tibshirani & Friedman, *Elements of Statistical Learning*, 7.10): a different
resolution must earn its place, so a car (measured: 512 and 1024 samples within 0.3 point on
the proving ground) keeps the paper's.  When the folds hold too few Welch windows of the
asked-for length to fit it (a short record), the longest length they can fit takes its place
in that rule: a length the records cannot test gives way to the nearest one they can
(measured on the MR damper's 15 s records: 512 could not be tested, 256 was kept against
128, and the holdout error of the plain fit fell from 93.7 to 83.9 %).
"""
import dataclasses
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.core.metrics import highpass

#: Candidate lengths: the asked-for one times 2**k for these k.
DOUBLINGS = (-2, -1, 0, 1, 2, 3, 4)
#: Shortest segment considered [samples].
MIN_SEGMENT = 64


@dataclasses.dataclass(frozen=True)
class ResolutionChoice:
    """
    Outcome of :func:`choose_segment_length`.

    Attributes
    ----------
    segment_length : int
        Chosen Welch segment [samples].
    asked : int
        The length asked for [samples].
    fold_error_pct : dict of int to tuple of float
        Per candidate length: held-out error of every fold, mean over output channels of
        ``100 * RMS(error) / RMS(target)`` (mean-removed per block) [%].  Lengths that
        cannot be fitted in every fold are absent.

    """

    segment_length: int
    asked: int
    fold_error_pct: Dict[int, Tuple[float, ...]]

    def mean_error_pct(self, length: int) -> float:
        """Return the mean held-out error of one candidate length [%]."""
        return float(np.mean(self.fold_error_pct[length]))

    def note(self, fs_hz: float) -> str:
        """Return a one-line note when the length changed (empty otherwise)."""
        if self.segment_length == self.asked:
            return ''
        against = (f'{self.mean_error_pct(self.asked):.1f} % for {self.asked}'
                   if self.asked in self.fold_error_pct else
                   f'{self.asked}, which the records cannot cross-validate (its folds hold too '
                   f'few Welch windows)')
        return (f'note: the Welch segment was chosen by blocked cross-validation on the '
                f'records: {self.segment_length} samples ({fs_hz / self.segment_length:g} Hz '
                f'resolution) predicted held-out blocks with '
                f'{self.mean_error_pct(self.segment_length):.1f} % RMSE against {against}. '
                f'--segment-length N silences this note.')


def fold_bounds(n_samples: int, n_folds: int, fold: int) -> Tuple[int, int]:
    """Return ``(start, stop)`` of block ``fold`` of a record of ``n_samples`` samples."""
    return n_samples * fold // n_folds, n_samples * (fold + 1) // n_folds


def _fold_error(fit: Callable, records, scored, length: int, fold: int, n_folds: int,
                fs_hz: float, highpass_hz: float) -> Optional[float]:
    """Held-out error of one fold [%], or None when the pieces cannot be fitted."""
    pieces, held = [], []
    for (x, y), target in zip(records, scored):
        a, b = fold_bounds(x.shape[1], n_folds, fold)
        pieces.extend((x[:, lo:hi], y[:, lo:hi]) for lo, hi in ((0, a), (b, x.shape[1]))
                      if hi - lo >= length)
        held.append((x, y, target, a, b))
    if not pieces:
        return None
    try:
        predict = fit(pieces, length)
    except WheelForceError:
        return None  # too few windows or singular at this length: not a candidate
    sse = np.zeros(records[0][1].shape[0])
    sst = np.zeros_like(sse)
    for x, y, target, a, b in held:
        err = predict(x) - y
        if highpass_hz > 0.0:
            err = highpass(err, fs_hz, highpass_hz, 'cross-validation error')
        err = err[:, a:b] - err[:, a:b].mean(axis=1, keepdims=True)
        target = target[:, a:b] - target[:, a:b].mean(axis=1, keepdims=True)
        sse += np.sum(err * err, axis=1)
        sst += np.sum(target * target, axis=1)
    if not np.all(sst > 0.0):
        return None
    return float(np.mean(100.0 * np.sqrt(sse / sst)))


def choose_segment_length(records: Sequence[Tuple[np.ndarray, np.ndarray]], asked: int,
                          fit: Callable, fs_hz: float, highpass_hz: float = 0.0,
                          n_folds: int = 4) -> ResolutionChoice:
    """
    Choose the Welch segment length by blocked cross-validation.

    Parameters
    ----------
    records : sequence of (inputs, outputs)
        Gap-free records: inputs ``(n_inputs, n)``, outputs ``(n_outputs, n)`` [SI units].
    asked : int
        The length asked for [samples]; kept unless another is better by more than one
        standard error.  When the folds cannot fit it (too few Welch windows), the longest
        length they can fit takes its place in that rule.
    fit : callable
        ``fit(pieces, length) -> predict`` with ``pieces`` a list of ``(inputs, outputs)``
        gap-free segments and ``predict(inputs) -> outputs`` the fitted model's prediction
        of a whole record; raises a :class:`WheelForceError` when it cannot fit.
    fs_hz : float
        Sample rate [Hz].
    highpass_hz : float
        High-pass of the scored errors [Hz] (0 = none; 1 Hz for acceleration inputs, as the
        product scores them).
    n_folds : int
        Contiguous blocks per record (>= 2).

    Returns
    -------
    ResolutionChoice

    Raises
    ------
    ConfigError
        ``n_folds < 2`` or ``asked < 1``.

    """
    if n_folds < 2:
        raise ConfigError(f'n_folds must be >= 2, got {n_folds!r}')
    if asked < 1:
        raise ConfigError(f'asked segment length must be >= 1, got {asked!r}')
    records = [(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
               for x, y in records]
    # the targets as scored (high-passed once: they do not depend on the fold or length)
    scored = [highpass(y, fs_hz, highpass_hz, 'cross-validation target') if highpass_hz > 0.0
              else y for _, y in records]
    errors: Dict[int, Tuple[float, ...]] = {}
    lengths = sorted({int(asked * 2.0 ** k) for k in DOUBLINGS})  # k = 0 is asked
    for length in lengths:
        if length < MIN_SEGMENT and length != asked:
            continue
        folds = []
        for fold in range(n_folds):
            e = _fold_error(fit, records, scored, length, fold, n_folds, fs_hz, highpass_hz)
            if e is None:
                break
            folds.append(e)
        if len(folds) == n_folds:
            errors[length] = tuple(folds)
    # The default the others must beat: the asked-for length, or - when the folds hold too
    # few Welch windows of it to be fitted (short records) - the longest length they can fit.
    # A length the records cannot test gives way to the nearest one they can.
    default = asked if asked in errors else max((n for n in errors if n < asked), default=None)
    if default is None:
        return ResolutionChoice(asked, asked, errors)
    best = min(errors, key=lambda n: (np.mean(errors[n]), n))
    diff = np.subtract(errors[best], errors[default])
    se = float(np.std(diff, ddof=1)) / np.sqrt(n_folds)
    chosen = best if float(np.mean(diff)) + se < 0.0 else default
    return ResolutionChoice(chosen, asked, errors)
