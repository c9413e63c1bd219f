# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Blocked cross-validation of linear estimators: the blocks and the one held-out scorer.

Blocks
------
The training segments are cut into contiguous chunks of equal time, dealt to ``n_blocks``
blocks in turn (:func:`block_pieces`; a chunk never straddles a gap).  Never interleaved
samples: neighbouring samples of a road are strongly correlated, so a fold scored
on samples next to the ones it was fitted on would reward over-fitting.  Each block keeps its
own statistics (Welch cross-spectra, correlations), so every fold is a sum of blocks and no
fold refits from raw samples.

Scorer
------
A linear estimator with FRF ``H(f)`` (one row per output) predicts a held-out block with the
error spectrum ``See = Syy - 2 Re(H Sxy) + H Sxx H^H`` (Welch densities of the held-out block,
``Sxy[f, i] = E[conj(X_i) Y]``).  Its integral is the error variance of the prediction, the
numerator of ``evaluate``'s RMSE (mean removed); weighted by the squared magnitude of the
zero-phase 1 Hz high-pass (4th-order Butterworth applied forwards and backwards, as
:func:`.metrics.rmse_hp_pct`) it is the high-passed RMSE's.  Scoring in the frequency domain
costs one batched matrix product per candidate and fold, against a time-domain prediction of
every block per candidate.  The FRF scored is what the model's FIR realises (the candidates
pass their realised responses).
"""
import dataclasses
from typing import List, Optional, Sequence, Tuple

import numpy as np
import scipy.fft
import scipy.signal

from wheel_force_estimator.core.spectra import CrossSpectra

#: Number of blocks the training data is cut into (folds).
N_BLOCKS = 4
#: Contiguous chunks per block, spread over the recording.
CHUNKS_PER_BLOCK = 4
#: High-pass cut-off of the second figure [Hz] (the paper's 1 Hz high-passed RMSE).
HP_CUTOFF_HZ = 1.0


@dataclasses.dataclass(frozen=True)
class Piece:
    """
    A contiguous stretch of one training segment, assigned to one block.

    Attributes
    ----------
    segment : int
        Index of the training segment.
    start, stop : int
        Samples ``start <= n < stop`` of that segment.

    """

    segment: int
    start: int
    stop: int


def block_pieces(lengths: Sequence[int], n_blocks: int,
                 min_piece: int) -> Optional[List[List[Piece]]]:
    """
    Cut segments of ``lengths`` samples into ``n_blocks`` blocks of contiguous chunks.

    The data is cut into ``n_blocks * CHUNKS_PER_BLOCK`` contiguous chunks of about equal
    time (never shorter than ``min_piece``; a chunk never straddles a gap), and chunk ``j``
    goes to block ``j mod n_blocks``.  So every block samples the whole recording (a road
    course is a sequence of different events: with one contiguous block per fold, a fold
    would be scored on an event its training side never saw, measured as a 170 % error on
    a proving-ground quarter), while every chunk is long against the estimators' memory
    (seconds), so a held-out chunk is not predicted from its own samples.

    Parameters
    ----------
    lengths : sequence of int
        Sample counts of the gap-free segments, in recording order.
    n_blocks : int
        Number of blocks (>= 2).
    min_piece : int
        Shortest chunk [samples] (the scoring windows a chunk must hold).

    Returns
    -------
    list of list of Piece or None
        Pieces per block, or ``None`` when the data holds fewer than ``n_blocks`` chunks of
        ``min_piece`` samples (too short to cross-validate).

    """
    total = int(sum(lengths))
    if n_blocks < 2 or min_piece < 1:
        return None
    chunk = max(int(min_piece), total // (n_blocks * CHUNKS_PER_BLOCK))
    pieces = []
    for s, n in enumerate(lengths):
        count = int(n) // chunk
        if count == 0:
            continue                              # a segment shorter than a chunk: unused
        edges = np.linspace(0, int(n), count + 1).round().astype(np.int64)
        pieces.extend(Piece(s, int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]))
    if len(pieces) < n_blocks:
        return None
    return [pieces[k::n_blocks] for k in range(n_blocks)]


def hp_power_weight(f_hz: np.ndarray, fs_hz: float, cutoff_hz: float = HP_CUTOFF_HZ
                    ) -> np.ndarray:
    """Return ``|H(f)|^4`` of the 4th-order Butterworth high-pass (filtfilt applies it twice)."""
    b, a = scipy.signal.butter(4, cutoff_hz, btype='highpass', fs=fs_hz)
    _, resp = scipy.signal.freqz(b, a, worN=np.asarray(f_hz, dtype=np.float64), fs=fs_hz)
    return np.abs(resp) ** 4


@dataclasses.dataclass(frozen=True)
class HeldOutPower:
    """
    Error and target power of candidates on held-out blocks, summed over the folds.

    Attributes
    ----------
    error, target : numpy.ndarray, shape (2, n_out)
        Row 0 unfiltered, row 1 1 Hz high-passed [output unit²].

    """

    error: np.ndarray
    target: np.ndarray

    def rmse_pct(self) -> np.ndarray:
        """Return the held-out RMSE % per figure and output, shape (2, n_out)."""
        return 100.0 * np.sqrt(self.error / np.maximum(self.target, np.finfo(float).tiny))

    def criterion(self) -> np.ndarray:
        """Return the per-output selection criterion: relative MSE, both figures summed."""
        return np.sum(self.error / np.maximum(self.target, np.finfo(float).tiny), axis=0)

    def __add__(self, other: 'HeldOutPower') -> 'HeldOutPower':
        """Sum the powers of two sets of folds."""
        return HeldOutPower(self.error + other.error, self.target + other.target)


def held_out_power(h: np.ndarray, spectra: CrossSpectra, hp_weight: np.ndarray) -> HeldOutPower:
    """
    Return the error and target power of FRF ``h`` on one held-out block.

    Parameters
    ----------
    h : numpy.ndarray, shape (nf, n_out, n_in), complex
        Realised FRF on ``spectra.f_hz`` [output unit / input unit].
    spectra : CrossSpectra
        Welch densities of the held-out block.
    hp_weight : numpy.ndarray, shape (nf,)
        :func:`hp_power_weight` on ``spectra.f_hz``.

    Returns
    -------
    HeldOutPower

    """
    scorer = BlendScorer(spectra, hp_weight)
    scorer.add(0, h)
    return scorer.power(0)


class BlendScorer:
    """
    Held-out power of every blend ``w h_a + (1 - w) h_b`` of a few base responses, one block.

    With ``h = w a + v b`` (``w``, ``v`` real per line) the scorer's terms expand into those
    of the bases: ``Re(h Sxy) = w Re(a Sxy) + v Re(b Sxy)`` and
    ``h Sxx h^H = w² a Sxx a^H + v² b Sxx b^H + 2 w v Re(a Sxx b^H)`` (``Sxx`` Hermitian).
    So each base costs one batched matrix product and each pair one element-wise product,
    and a candidate (a base, or a splice of two at any crossover) costs a weighted sum over
    the lines: the same figure as :func:`held_out_power` of the blended response (tested).

    Parameters
    ----------
    spectra : CrossSpectra
        Welch densities of the held-out block.
    hp_weight : numpy.ndarray, shape (nf,)
        :func:`hp_power_weight` on ``spectra.f_hz``.
    pair_max_hz : float
        Highest line where a blend's weights are both non-zero (a splice's ramp ends at 1.5
        times its crossover): the pair terms are computed up to it only, 0 above (where
        they are multiplied by 0).  Default: every line.

    """

    #: Lines per batched product (temporaries well below glibc's 32 MB mmap threshold, so
    #: they reuse heap pages: a fresh page costs more here than the product that fills it).
    CHUNK_LINES = 1024

    def __init__(self, spectra: CrossSpectra, hp_weight: np.ndarray,
                 pair_max_hz: float = np.inf):
        self._sp = spectra
        self._weights = np.stack([np.ones_like(hp_weight), hp_weight])       # (2, nf)
        self._target = self._weights @ spectra.syy
        self._n_pair = int(np.searchsorted(spectra.f_hz, pair_max_hz, side='right'))
        self._base: dict = {}
        self._pair: dict = {}

    def add(self, key, h: np.ndarray) -> None:
        """Add base ``key`` with realised response ``h`` (nf, n_out, n_in) on the block's grid."""
        sxx, syx = self._sp.sxx, self._sp.syx
        quad = np.empty(h.shape[:2])
        low = np.empty((self._n_pair,) + h.shape[1:], dtype=np.complex128)
        for lo in range(0, h.shape[0], self.CHUNK_LINES):
            hi = min(h.shape[0], lo + self.CHUNK_LINES)
            m = np.matmul(h[lo:hi].conj(), sxx[lo:hi])                # conj(h_oi) Sxx_ij
            quad[lo:hi] = np.einsum('foj,foj->fo', m, h[lo:hi]).real
            if lo < self._n_pair:
                low[lo:min(hi, self._n_pair)] = m[:self._n_pair - lo]
        # Re(h conj(Syx)) from the real and imaginary parts (no conjugated copy of Syx)
        cross = (np.einsum('foi,foi->fo', h.real, syx.real)
                 + np.einsum('foi,foi->fo', h.imag, syx.imag))
        self._base[key] = (h, low, quad, cross)

    def _pair_term(self, a, b) -> np.ndarray:
        if (a, b) not in self._pair:
            term = np.zeros(self._base[a][2].shape)
            n = self._n_pair
            term[:n] = np.einsum('foj,foj->fo', self._base[a][1], self._base[b][0][:n]).real
            self._pair[(a, b)] = term
        return self._pair[(a, b)]

    def power(self, a, b=None, w: Optional[np.ndarray] = None) -> HeldOutPower:
        """
        Return the held-out power of base ``a``, or of ``w a + (1 - w) b``.

        ``w`` is the per-line weight of ``a`` (shape (nf,)); without ``b`` the base alone.
        """
        _, _, quad_a, cross_a = self._base[a]
        if b is None:
            see = self._sp.syy - 2.0 * cross_a + quad_a
        else:
            _, _, quad_b, cross_b = self._base[b]
            wa, wb = w[:, None], 1.0 - w[:, None]
            see = (self._sp.syy - 2.0 * (wa * cross_a + wb * cross_b) + wa * wa * quad_a
                   + wb * wb * quad_b + 2.0 * wa * wb * self._pair_term(a, b))
        return HeldOutPower(self._weights @ np.maximum(see, 0.0), self._target)


def blend_weight(f_hz: np.ndarray, crossover_hz: float) -> np.ndarray:
    """Return 1 below ``crossover_hz``, 0 above ``1.5 crossover_hz``, raised cosine between."""
    if crossover_hz <= 0.0:
        return np.zeros_like(f_hz)
    if not np.isfinite(crossover_hz):
        return np.ones_like(f_hz)
    ramp = np.clip((1.5 * crossover_hz - f_hz) / (0.5 * crossover_hz), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * ramp)


def splice(h_low: np.ndarray, h_high: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Return ``weight * h_low + (1 - weight) * h_high`` (weight per line)."""
    w = weight[:, None, None]
    return w * h_low + (1.0 - w) * h_high


def best_rows(criteria: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Return the index of the best candidate per output and its criterion ((n_cand, n_out))."""
    idx = np.argmin(criteria, axis=0)
    return idx, criteria[idx, np.arange(criteria.shape[1])]
