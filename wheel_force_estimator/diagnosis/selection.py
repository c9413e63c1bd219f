# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Cross-validated ranking of candidate physics and the significance test that guards it.

The residual of a channel (real force minus reference prediction) is cut into time blocks;
blocks are dealt to ``n_folds`` folds (the same time block of every channel and recording goes
to the same fold).  Inside each block an offset and a linear trend are projected out of the
residual and of every column, so sensor offsets and slow drifts can never pass as physics.  A
candidate's *gain* is the fraction of the residual sum of squares it removes on held-out
folds, with its strength fitted on the other folds.

A candidate is accepted only when its gain beats ``null_factor`` times the best gain the same
candidate (same grid search) reaches when its features are circularly shifted against the
force - an unrelated signal with the same distribution and spectrum, shifted where the feature
is least like itself (:func:`null_lags`: a sine test's feature repeats every period) - and when
it lowers the cross-validated RMSE by a practical amount.  Candidates are added greedily; a
simpler candidate (fewer shape parameters) wins when it is within a small margin of the best.
"""
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.metrics import highpass
from wheel_force_estimator.diagnosis.candidates import Candidate
from wheel_force_estimator.diagnosis.candidates import LINEAR_RATES
from wheel_force_estimator.diagnosis.features import ChannelContext


@dataclass(frozen=True)
class SelectionConfig:
    """
    Cross-validation and acceptance settings.

    Attributes
    ----------
    n_folds : int
        Folds of time blocks.
    block_s : float
        Length of a time block [s] (blocks hold at least ``min_block_samples`` samples).
        Records too short for ``n_folds`` such blocks (rig sine tests of a few seconds) get
        shorter blocks, just enough for ``n_folds`` in all and one per recording, down to
        ``min_block_samples``.
    min_block_samples : int
        Shortest block [samples].
    n_null : int
        Shifted-feature repetitions of the significance test.
    null_factor : float
        Required ratio of the gain to the best shifted-feature gain.
    min_gain : float
        Smallest fraction of the residual a term must explain on held-out data.
    min_improvement_pct : float
        Smallest drop of the cross-validated RMSE [% of the force RMS] a term must bring.
    parsimony_abs, parsimony_rel : float
        A candidate with fewer shape parameters wins when its gain is within
        ``max(parsimony_abs, parsimony_rel * best_gain)`` of the best.
    max_terms : int
        Most terms accepted per channel.
    highpass_hz : float
        Zero-phase high-pass (metrics.highpass) applied to residual and candidate columns
        before fitting, so a band the reference cannot model (quasi-static load transfer
        below ~1 Hz for an FRF) is not mistaken for physics; 0 = none.
    linear_tolerance : float
        Smallest change of a linear rate (``stiffness_error``, ``damping_error``,
        ``mass_error``) that is named, as a fraction of the rate of the same kind the
        reference itself shows (:meth:`Selector.apparent_rates`).  A smaller change is
        parameter drift within tolerance (part-to-part scatter, temperature), not missing
        physics; 0 = name any significant change.  Measured on the proving-ground simulator
        (seeds 0-4, 1 Hz high-passed): with dampers 3 % softer, the 2 of 20 vertical channels
        where the change passes the statistical tests read -2.2 % and -2.5 %; with dampers
        6.25 % softer the four-corner fit reads -106 to -109 N s/m, about -5 % of the
        2100 N s/m average the reference shows.

    """

    n_folds: int = 5
    block_s: float = 2.0
    min_block_samples: int = 64
    n_null: int = 8
    null_factor: float = 2.0
    min_gain: float = 0.05
    min_improvement_pct: float = 0.2
    parsimony_abs: float = 0.01
    parsimony_rel: float = 0.05
    max_terms: int = 3
    highpass_hz: float = 0.0
    linear_tolerance: float = 0.04

    def rejection(self, gain: float, null: Optional[float] = None,
                  drop_pct: Optional[float] = None) -> Optional[str]:
        """
        Return why a candidate is not accepted, or None: the one acceptance rule.

        ``gain`` is the fraction of the residual it explains on held-out blocks, ``null`` the
        best fraction the same candidate explains with time-shifted features, ``drop_pct``
        how much it lowers the cross-validated RMSE [points of %].  A figure not known yet
        (None) is not judged, so a caller may reject on the gain before paying for the null.
        Used by the per-channel selection and by the search inside the structure
        (:mod:`diagnosis.dynamic`).
        """
        if gain < self.min_gain:
            return f'explains {gain:.1%} < {self.min_gain:.0%} of the residual'
        if null is not None and gain <= self.null_factor * max(null, 0.0):
            return (f'explains {gain:.1%}, not {self.null_factor:g}x above the '
                    f'{null:.1%} an unrelated (time-shifted) feature explains')
        if drop_pct is not None and drop_pct < self.min_improvement_pct:
            return (f'lowers the cross-validated RMSE by only {drop_pct:.2f} points '
                    f'(< {self.min_improvement_pct:g})')
        return None

    def __post_init__(self):
        if self.n_folds < 2 or self.n_null < 1 or self.max_terms < 1:
            raise ConfigError('n_folds must be >= 2, n_null and max_terms >= 1')
        if not 0.0 <= self.linear_tolerance < 1.0:
            raise ConfigError(f'linear_tolerance must be in [0, 1), got {self.linear_tolerance}')
        for name in ('block_s', 'null_factor'):
            if not getattr(self, name) > 0.0:
                raise ConfigError(f'{name} must be > 0')


@dataclass(frozen=True)
class NullShift:
    """Circular shift [samples] of every piece's features for one null repetition."""

    data: Tuple[int, ...]
    sim: Optional[Tuple[int, ...]] = None


def null_lags(feature: np.ndarray, n_null: int) -> Tuple[int, ...]:
    """
    Return up to ``n_null`` circular shifts [samples] of ``feature`` for the shifted-feature null.

    The null must be a feature *unrelated* to the force.  A shift where the feature is still
    like itself is not: under periodic excitation (a rig's sine test) a shift by a whole
    period reproduces the feature and a half period its negative, and either explains as much
    as the true feature (measured on the friction-damper sine tests: the fixed quarter-record
    shift explained 26 % of the residual, the aligned backlash 46 %).  So the shifts are the
    lags of the middle half of the record where the least of the feature's energy stays in
    phase, frequency by frequency (a per-frequency measure: the harmonics of a periodic
    feature must each be out of phase, not cancel in a sum), at least ``n / (4 n_null)``
    apart, and only lags keeping at most half in phase (what a signal of random phase keeps on
    average; the best lag is always kept), so a short periodic record may give fewer than
    ``n_null``.  Under broadband excitation every lag keeps about half in phase and the
    choice changes nothing but which unrelated lags are used.  A constant feature keeps
    evenly spread lags.
    """
    x = np.asarray(feature, dtype=np.float64)
    n = x.size
    lo, hi = n // 4, max(3 * n // 4, n // 4 + 1)
    x = x - x.mean()
    power = np.abs(np.fft.rfft(x, n)) ** 2
    if not power.sum() > 0.0:
        return tuple(int(round(f * n)) for f in 0.25 + 0.5 * np.arange(n_null)
                     / max(n_null - 1, 1))
    # Per frequency, a shift by ``lag`` keeps cos^2(2 pi f lag) of the feature's energy in
    # phase; weighted by the squared power that is (1 + rho2(2 lag)) / 2, rho2 the
    # normalised autocorrelation of a signal with power spectrum |X|^4.  Summing per
    # frequency (not |rho| of the whole feature, where harmonics can cancel) keeps every
    # harmonic of a periodic feature out of phase as far as one shift can.
    auto2 = np.fft.irfft(power * power, n)
    rho = auto2[(2 * np.arange(lo, hi)) % n] / auto2[0]
    gap = max(1, n // (4 * n_null))
    chosen: List[int] = []
    for lag in (lo + np.argsort(rho, kind='stable')):
        if chosen and rho[lag - lo] > 0.0:
            # More than half the energy in phase: more like the feature than a signal of
            # random phase (which keeps half on average).  A short periodic record has few
            # unrelated shifts; fewer nulls (repeated by the caller) beat related ones.
            break
        if all(abs(int(lag) - c) >= gap for c in chosen):
            chosen.append(int(lag))
            if len(chosen) == n_null:
                break
    return tuple(sorted(chosen))


@dataclass
class Piece:
    """One output channel of one recording: its features, residual and target force."""

    ctx: ChannelContext
    residual: np.ndarray
    target: np.ndarray
    recording: int
    channel: str


class CvData:
    """Block and fold structure of a set of pieces, with per-block detrending."""

    def __init__(self, pieces: Sequence[Piece], config: SelectionConfig):
        self.pieces = list(pieces)
        self.config = config
        fs = self.pieces[0].ctx.fs_hz
        sizes = {}
        for p in self.pieces:
            sizes.setdefault(p.recording, p.residual.size)
        # Short records: shorter blocks rather than a refusal.  Blocks shorter than the
        # residual's correlation time make the held-out score optimistic for every candidate
        # alike; the shifted-feature null, scored the same way, keeps the test honest.
        length = max(min(int(round(config.block_s * fs)), sum(sizes.values()) // config.n_folds,
                         min(sizes.values())), config.min_block_samples)
        n_blocks = {rec: n // length for rec, n in sizes.items()}
        first_block, total = {}, 0
        for rec, nb in n_blocks.items():
            first_block[rec] = total
            total += nb
        self.starts, folds = [], []
        for p in self.pieces:
            nb = p.residual.size // length
            self.starts.append(np.arange(nb) * length)
            folds.append((first_block[p.recording] + np.arange(nb)) % config.n_folds)
        n_time_blocks = total
        if n_time_blocks < config.n_folds or any(s.size == 0 for s in self.starts):
            raise DiagnosisError(
                f'too little data to cross-validate: {n_time_blocks} time blocks of '
                f'{length / fs:.2f} s ({length} samples), need at least {config.n_folds} and '
                f'one per recording')
        self.fold = np.concatenate(folds)
        self._design = [self._detrend_design(i) for i in range(len(self.pieces))]
        self.residual = [self.prepare(i, p.residual) for i, p in enumerate(self.pieces)]
        self.target_ss = float(sum(np.sum(self.prepare(i, p.target) ** 2)
                                   for i, p in enumerate(self.pieces)))
        self.n_samples = sum(p.residual.size for p in self.pieces)

    def _detrend_design(self, i):
        n = self.pieces[i].residual.size
        starts = self.starts[i]
        idx = np.arange(n)
        block = np.searchsorted(starts, idx, side='right') - 1
        counts = np.diff(np.append(starts, n))
        tau = idx - (starts[block] + 0.5 * (counts[block] - 1))
        tt = np.add.reduceat(tau * tau, starts)
        return block, counts, tau, np.where(tt > 0.0, tt, 1.0)

    def detrend(self, i: int, x: np.ndarray) -> np.ndarray:
        """Remove an offset and a linear trend inside every block of piece ``i``."""
        block, counts, tau, tt = self._design[i]
        starts = self.starts[i]
        mean = np.add.reduceat(x, starts) / counts
        slope = np.add.reduceat(x * tau, starts) / tt
        return x - mean[block] - slope[block] * tau

    def prepare(self, i: int, x: np.ndarray) -> np.ndarray:
        """High-pass (when configured) and detrend a column of piece ``i``."""
        if self.config.highpass_hz > 0.0 and np.any(x):
            x = highpass(x[np.newaxis], self.pieces[i].ctx.fs_hz, self.config.highpass_hz,
                         'diagnosis column')[0]
        return self.detrend(i, x)

    def block_sums(self, i: int, x: np.ndarray) -> np.ndarray:
        """Sum of ``x`` over every block of piece ``i``."""
        return np.add.reduceat(x, self.starts[i])


@dataclass(frozen=True)
class Stats:
    """Per-block normal equations: ``g[b] = D_b'D_b``, ``h[b] = D_b'r_b``, ``s[b] = r_b'r_b``."""

    g: np.ndarray
    h: np.ndarray
    s: np.ndarray


def block_stats(data: CvData, columns: Sequence[Sequence[np.ndarray]],
                offset: Optional[Sequence[np.ndarray]] = None) -> Stats:
    """Return per-block normal equations of detrended columns and residual minus offset."""
    gs, hs, ss = [], [], []
    for i in range(len(data.pieces)):
        r = data.residual[i] if offset is None else data.residual[i] - offset[i]
        cols = list(columns[i])
        p = len(cols)
        nb = data.starts[i].size
        g = np.zeros((nb, p, p))
        h = np.zeros((nb, p))
        for a in range(p):
            h[:, a] = data.block_sums(i, cols[a] * r)
            for b in range(a, p):
                g[:, a, b] = g[:, b, a] = data.block_sums(i, cols[a] * cols[b])
        gs.append(g)
        hs.append(h)
        ss.append(data.block_sums(i, r * r))
    return Stats(np.concatenate(gs), np.concatenate(hs), np.concatenate(ss))


def _solve(g, h):
    """
    Least squares from the normal equations, with a tiny ridge relative to each column.

    Columns are scaled to unit Gram diagonal first: a cubic term of a displacement in metres
    (~1e-6) next to an acceleration companion (~1) would otherwise be ridged away by a ridge
    set from the average diagonal.
    """
    p = h.size
    if p == 0:
        return h
    d = np.sqrt(np.abs(np.diag(g)))
    d = np.where(d > 0.0, d, 1.0)
    gn = g / np.outer(d, d)
    return np.linalg.solve(gn + 1e-10 * np.eye(p), h / d) / d


def cv_sse(stats: Stats, fold: np.ndarray, n_folds: int) -> float:
    """Held-out sum of squared residuals after the fold-wise least-squares fit."""
    if stats.h.shape[1] == 0:
        return float(stats.s.sum())
    total = 0.0
    for k in range(n_folds):
        test = fold == k
        if not test.any():
            continue
        theta = _solve(stats.g[~test].sum(0), stats.h[~test].sum(0))
        total += float(stats.s[test].sum() - 2.0 * np.sum(stats.h[test] @ theta)
                       + np.einsum('bij,i,j->', stats.g[test], theta, theta))
    return total


def full_fit(stats: Stats) -> np.ndarray:
    """Least-squares coefficients on all blocks."""
    return _solve(stats.g.sum(0), stats.h.sum(0))


@dataclass(frozen=True)
class Evaluated:
    """Best shape of one hypothesis at one greedy step."""

    hypothesis: Candidate
    shape: Dict[str, float]
    gain: float


@dataclass(frozen=True)
class Accepted:
    """A term accepted for a channel (or a pooled group of channels)."""

    hypothesis: Candidate
    shape: Dict[str, float]
    gain: float
    null_gains: Tuple[float, ...]
    coefficient: float
    rmse_before_pct: float
    rmse_after_pct: float
    sse_before: float


@dataclass(frozen=True)
class Outcome:
    """Result of the greedy selection for one channel or group."""

    accepted: Tuple[Accepted, ...]
    companions: Dict[str, float]
    ranking: Tuple[Evaluated, ...]
    rejected: Optional[Tuple[Evaluated, Tuple[float, ...], str]]
    cv_before_pct: float
    cv_after_pct: float


class Selector:
    """
    Greedy cross-validated selection over hypotheses for one set of pieces.

    With ``sim_pieces`` (the simulation's own residual against the same reference) every
    candidate is judged by the *contrast*: the held-out error of the real residual when the
    candidate keeps the strength it has in the simulation (H0: real behaves like sim) minus
    the error when its strength is fitted on the real data.  What the linear reference misses
    in the simulation as much as in reality is then not reported as missing physics.
    """

    def __init__(self, pieces: Sequence[Piece], config: SelectionConfig,
                 companions: Sequence[Candidate] = (),
                 sim_pieces: Optional[Sequence[Piece]] = None):
        self.data = CvData(pieces, config)
        self.config = config
        self.companions = tuple(companions)
        self._base_cols = [[self.data.prepare(i, h.basis(p.ctx, {})) for h in self.companions]
                           for i, p in enumerate(self.data.pieces)]
        self._offset = [np.zeros(p.residual.size) for p in self.data.pieces]
        self._rates = None
        self.sim = None
        if sim_pieces:
            self.sim = CvData(sim_pieces, config)
            self._sim_cols = [[self.sim.prepare(i, h.basis(p.ctx, {})) for h in self.companions]
                              for i, p in enumerate(self.sim.pieces)]
            self._sim_offset = [np.zeros(p.residual.size) for p in self.sim.pieces]

    @staticmethod
    def _columns_of(data, hyp, shape, lags=None):
        """Return the prepared columns of every piece, shifted by ``lags[i]`` when given."""
        cols = []
        for i, p in enumerate(data.pieces):
            ctx = p.ctx if lags is None else p.ctx.shifted(lags[i])
            cols.append(data.prepare(i, hyp.basis(ctx, shape)))
        return cols

    def _columns(self, hyp, shape, shift=None):
        return self._columns_of(self.data, hyp, shape, None if shift is None else shift.data)

    def _sse(self, extra_cols=None, extra_offset=None):
        cols = self._base_cols
        if extra_cols is not None:
            cols = [b + [c] for b, c in zip(self._base_cols, extra_cols)]
        offset = self._offset
        if extra_offset is not None:
            offset = [o + c for o, c in zip(self._offset, extra_offset)]
        return cv_sse(block_stats(self.data, cols, offset), self.data.fold,
                      self.config.n_folds)

    def sim_strength(self, hyp, shape, shift=None) -> float:
        """Strength the candidate has in the simulation's residual (0 without a simulation)."""
        if self.sim is None:
            return 0.0
        cols = self._columns_of(self.sim, hyp, shape, None if shift is None else shift.sim)
        if hyp.fixed_coefficient:
            stats = block_stats(self.sim, self._sim_cols, self._sim_offset)
            with_term = block_stats(self.sim, self._sim_cols,
                                    [o + c for o, c in zip(self._sim_offset, cols)])
            return 1.0 if (cv_sse(with_term, self.sim.fold, self.config.n_folds)
                           < cv_sse(stats, self.sim.fold, self.config.n_folds)) else 0.0
        stats = block_stats(self.sim, [b + [c] for b, c in zip(self._sim_cols, cols)],
                            self._sim_offset)
        return float(full_fit(stats)[-1])

    def gain(self, hyp, shape, base_sse, shift=None) -> float:
        """
        Held-out gain of adding one candidate shape (beyond its simulated strength).

        ``shift`` (a :class:`NullShift`) shifts the candidate's features against the force.
        """
        cols = self._columns(hyp, shape, shift)
        if base_sse <= 0.0 or all(not np.any(c) for c in cols):
            return 0.0
        if hyp.fixed_coefficient:
            sse = self._sse(extra_offset=cols)
        else:
            stats = block_stats(self.data, [b + [c] for b, c in zip(self._base_cols, cols)],
                                self._offset)
            if hyp.positive and not full_fit(stats)[-1] > 0.0:
                return 0.0
            sse = cv_sse(stats, self.data.fold, self.config.n_folds)
        reference = base_sse
        if self.sim is not None:
            strength = self.sim_strength(hyp, shape, shift)
            if strength != 0.0:
                # H0 "real behaves like sim": the candidate keeps its simulated strength (or
                # is left out, whichever predicts the real held-out data better).
                reference = min(base_sse, self._sse(extra_offset=[strength * c for c in cols]))
        return (reference - sse) / base_sse

    def best_shape(self, hyp, grid, base_sse, shift=None) -> Tuple[Dict, float]:
        """Grid point with the highest held-out gain."""
        best = ({}, -np.inf)
        for shape in grid:
            g = self.gain(hyp, shape, base_sse, shift)
            if g > best[1]:
                best = (shape, g)
        return best

    def apparent_rates(self) -> Dict[str, float]:
        """
        Stiffness [N/m], damping [N s/m] and mass [kg] the reference itself shows.

        The reference prediction (``ctx.load``) is fitted by least squares on the source's
        displacement, velocity and acceleration, prepared like every candidate column (same
        high-pass and per-block detrending): the rates a quarter-car reading of the
        reference's force would give.  A linear-error candidate's strength divided by the
        rate of its kind is the relative parameter change it stands for.
        """
        if self._rates is None:
            names = list(LINEAR_RATES)
            g = np.zeros((len(names), len(names)))
            h = np.zeros(len(names))
            for i, p in enumerate(self.data.pieces):
                cols = [self.data.prepare(i, getattr(p.ctx, LINEAR_RATES[n][0])) for n in names]
                load = self.data.prepare(i, p.ctx.load)
                g += np.array([[float(np.dot(a, b)) for b in cols] for a in cols])
                h += np.array([float(np.dot(a, load)) for a in cols])
            self._rates = dict(zip(names, (float(v) for v in _solve(g, h))))
        return self._rates

    def _within_tolerance(self, hyp, shape) -> Optional[str]:
        """Reason to reject a linear-rate change inside ``linear_tolerance`` (else None)."""
        tol = self.config.linear_tolerance
        if tol <= 0.0 or hyp.physics not in LINEAR_RATES or hyp.state != 'motion':
            return None
        rate = self.apparent_rates()[hyp.physics]
        cols = [b + [c] for b, c in zip(self._base_cols, self._columns(hyp, shape))]
        coef = float(full_fit(block_stats(self.data, cols, self._offset))[-1])
        if abs(coef) >= tol * abs(rate):
            return None
        _, kind, unit = LINEAR_RATES[hyp.physics]
        return (f'is a {coef:+.4g} {unit} change of the {abs(rate):.4g} {unit} {kind} the '
                f'reference shows ({coef / abs(rate):+.1%}), within the '
                f'+/-{tol:.0%} tolerance of a linear parameter (drift, not missing physics)')

    def _pct(self, sse):
        if self.data.target_ss <= 0.0:
            return 0.0
        return 100.0 * float(np.sqrt(max(sse, 0.0) / self.data.target_ss))

    def run(self, hypotheses: Sequence[Candidate]) -> Outcome:
        """Add candidates greedily while they pass the significance test."""
        cfg = self.config
        contexts = [p.ctx for p in self.data.pieces]
        grids = {h.key: h.grid(contexts) for h in hypotheses}
        candidates = [h for h in hypotheses if grids[h.key]]
        accepted: List[Accepted] = []
        rejected = None
        ranking: Tuple[Evaluated, ...] = ()
        start_sse = self._sse()
        for _ in range(cfg.max_terms):
            base_sse = self._sse()
            if base_sse <= 0.0:
                break
            evaluated = []
            for hyp in candidates:
                shape, g = self.best_shape(hyp, grids[hyp.key], base_sse)
                evaluated.append(Evaluated(hyp, dict(shape), float(g)))
            evaluated.sort(key=lambda e: -e.gain)
            if not ranking:
                ranking = tuple(evaluated)
            if not evaluated:
                break
            # A data-quality effect seen directly in the inputs (flat tops) is tried first: its
            # corrupted features would otherwise be explained away by a wrong linear term.
            first = [e for e in evaluated if e.hypothesis.priority and e.gain > 0.0]
            choice = first[0] if first else self._parsimonious(evaluated)
            hyp = choice.hypothesis
            nulls = self.null_gains(hyp, grids[hyp.key], base_sse, choice.shape)
            after_sse = base_sse * (1.0 - choice.gain)
            drop = self._pct(base_sse) - self._pct(after_sse)
            reason = (cfg.rejection(choice.gain, max(nulls), drop)
                      or self._within_tolerance(hyp, choice.shape))
            if reason is not None:
                rejected = (choice, nulls, reason)
                break
            cols = self._columns(hyp, choice.shape)
            if hyp.fixed_coefficient:
                self._offset = [o + c for o, c in zip(self._offset, cols)]
            else:
                self._base_cols = [b + [c] for b, c in zip(self._base_cols, cols)]
            if self.sim is not None:
                sim_cols = self._columns_of(self.sim, hyp, choice.shape)
                if hyp.fixed_coefficient:
                    self._sim_offset = [o + c for o, c in zip(self._sim_offset, sim_cols)]
                else:
                    self._sim_cols = [b + [c] for b, c in zip(self._sim_cols, sim_cols)]
            accepted.append(Accepted(hyp, choice.shape, choice.gain, nulls, 1.0,
                                     self._pct(base_sse), self._pct(after_sse), base_sse))
            candidates = [h for h in candidates if h.physics != hyp.physics]
        coefs = full_fit(block_stats(self.data, self._base_cols, self._offset))
        n_comp = len(self.companions)
        companions = {h.physics: float(c) for h, c in zip(self.companions, coefs[:n_comp])}
        fitted = iter(coefs[n_comp:])
        final = tuple(a if a.hypothesis.fixed_coefficient else
                      Accepted(a.hypothesis, a.shape, a.gain, a.null_gains, float(next(fitted)),
                               a.rmse_before_pct, a.rmse_after_pct, a.sse_before)
                      for a in accepted)
        return Outcome(final, companions, ranking, rejected, self._pct(start_sse),
                       self._pct(self._sse()))

    def fit_single(self, hyp: Candidate) -> Tuple[Dict[str, float], float, float, float]:
        """Best shape, held-out gain, coefficient and starting SSE of one hypothesis alone."""
        base_sse = self._sse()
        grid = hyp.grid([p.ctx for p in self.data.pieces])
        if not grid or base_sse <= 0.0:
            return {}, 0.0, 0.0, base_sse
        shape, gain = self.best_shape(hyp, grid, base_sse)
        if hyp.fixed_coefficient:
            return dict(shape), float(gain), 1.0, base_sse
        cols = [b + [c] for b, c in zip(self._base_cols, self._columns(hyp, shape))]
        coef = full_fit(block_stats(self.data, cols, self._offset))[-1]
        return dict(shape), float(gain), float(coef), base_sse

    def null_gains(self, hyp: Candidate, grid=None, base_sse=None,
                   shape=None) -> Tuple[float, ...]:
        """
        Best gains of ``hyp`` on features circularly shifted against the force (the null).

        ``n_null`` shifts per piece from the middle half of its record, where the candidate's
        own feature (at ``shape``, the best one on the unshifted data when None) is least
        like itself (:func:`null_lags`); ``grid`` and ``base_sse`` default to the
        hypothesis' grid and the current residual.
        """
        if grid is None:
            grid = hyp.grid([p.ctx for p in self.data.pieces])
        if base_sse is None:
            base_sse = self._sse()
        if not grid or base_sse <= 0.0:
            return (0.0,)
        if shape is None:
            shape = self.best_shape(hyp, grid, base_sse)[0]
        n = self.config.n_null
        data = [null_lags(hyp.basis(p.ctx, shape), n) for p in self.data.pieces]
        sim = (None if self.sim is None else
               [null_lags(hyp.basis(p.ctx, shape), n) for p in self.sim.pieces])
        return tuple(float(self.best_shape(hyp, grid, base_sse, NullShift(
            tuple(lags[k % len(lags)] for lags in data),
            None if sim is None else tuple(lags[k % len(lags)] for lags in sim)))[1])
            for k in range(n))

    def _parsimonious(self, evaluated: Sequence[Evaluated]) -> Evaluated:
        best = evaluated[0]
        margin = max(self.config.parsimony_abs, self.config.parsimony_rel * best.gain)
        close = [e for e in evaluated if e.gain >= best.gain - margin]
        return min(close, key=lambda e: (e.hypothesis.n_shape, -e.gain))
