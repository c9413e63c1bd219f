# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live (causal) estimator: a MIMO least-squares FIR designed for a stated look-ahead.

Why this method
---------------
The offline FIR is the two-sided inverse of the FRF; cutting its acausal part to a short
look-ahead throws away what the cut taps did, and nothing else makes up for it.  The causal
Wiener filter instead asks which causal filter (inputs up to ``n + D``, ``D`` the look-ahead)
minimises the mean square error, so the history takes over what the future cannot supply.
Of the ways to get it:

- spectral factorisation of the 12x12 input spectrum (causal Wiener) needs a stable MIMO
  spectral factor of a nearly singular matrix at low frequency (collinear rigid-body
  motion): fragile, and it does not bound the filter length;
- a Kalman observer needs an identified state-space model (order selection, stability), a
  second estimation problem with its own failure modes;
- the least-squares FIR with look-ahead solves linear normal equations (Wiener-Hopf) built
  from the correlation functions of the training data: one Cholesky solve, a filter length
  chosen up front, and the same data ``fit`` already holds in memory.

So the estimator is the least-squares FIR.  Its history must be long (the quasi-static
loads of braking and cornering live in seconds of history: measured z RMSE 22 % with 0.5 s,
12.7 % with 2 s), but a full-rate FIR of seconds has 12 x 1000s of unknowns per output.  The
impulse response far in the past is smooth, so the taps are **multi-rate**: one tap per
sample from ``-D`` to ``fine_s``, then piecewise-constant blocks whose width grows
geometrically (``blocks_per_octave`` per doubling of the lag) up to ``history_s``.  About
310 unknowns per input at the defaults for a car (48 blocks per octave), solved exactly; the
piecewise-constant blocks also give a cheap recursive realisation (a running sum,
:mod:`.causal_filter`).

The coarse blocks must stay narrow far into the past: the rear wheels meet the road the
front wheels met a wheelbase earlier (0.1-2 s at road speeds), with its wheel-hop content.
Measured (2026-11-29, all 14 inputs, 10 min of the course at seed 1, held-out seed 2, 50 ms,
`Fz` mean of the corners, unfiltered / 1 Hz high-passed): 32 blocks per octave at ridge 1e-4
(the default before) 8.4 / 7.5 % on the compact car, 9.9 / 11.3 % on a pickup, 10.6 / 11.1 %
on the van; 48 blocks per octave at ridge 1e-5 6.1 / 5.2, 7.3 / 7.6 and 7.8 / 7.4 %; 64
blocks 5.4 / 4.0, 6.3 / 5.5 and 6.6 / 5.4 % (x and y equal within 0.3 point).  The finest
basis the cost bound allows (:data:`MAX_PAST_UNKNOWNS`) is the default, and the ridge, chosen
by ``fit``'s cross-validation, sets how much of it the data can carry.  48, not 64: every
factorisation of ``fit``'s search costs (n / n32)³ of the 32-block one's, 1.9x at 48 and
3.1x at 64, and at 64 a 60 s bag's `fit` took 49 s against 14 s (48: 32 s) and the fast test
tier 7 minutes against its 5.

The correlations the design starts from are :mod:`.correlations`; the normal equations of
the basis and their factorisation, :mod:`.normal_equations`.

Defaults (``LiveDesign``), chosen on held-out simulated data (5 min training, 2.5 min
held-out, other seed; mean RMSE % x / y / z at 50 ms; offline two-sided 29.0 / 20.6 / 10.7):
32 blocks per octave 29.3 / 13.7 / 8.2, 16 per octave 29.5 / 13.9 / 12.2 (Fz needs the
resolution); ridge 1e-3 instead of 1e-4 (the FRF's own default) 29.6 / 13.8 / 10.8; history
2 s 30.6 / 14.4 / 9.5, 8 s 28.6 / 13.5 / 8.0 (30 % dearer fit), so 4 s.
"""
import dataclasses
import functools
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ModelFileError
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.validation import read_only_array

# The look-ahead the node and `predict --causal` use when nothing else is configured [s]
# (DESIGN.md `live_look_ahead_s`): 26 samples at 512 Hz.
DEFAULT_LIVE_LOOK_AHEAD_S = 0.05
# Look-aheads `fit` also designs, so reports can show accuracy against look-ahead [s].
SWEEP_LOOK_AHEADS_S = (0.0, 0.025, 0.05, 0.1, 0.25)
METHOD = 'multirate_ls_fir'
#: Coarse-tap resolutions of the default basis, finest first [blocks per octave].
BLOCKS_PER_OCTAVE_CHOICES = (48, 32)
#: Past unknowns (all inputs) the default basis may reach: the finest of
#: :data:`BLOCKS_PER_OCTAVE_CHOICES` within it, else the coarsest.  A cost bound, not a tuned
#: accuracy figure: the Cholesky factor of ``n`` unknowns is ``8 n²`` bytes and ``n³ / 3``
#: flops, and ``fit`` factorises a few per fold.  With the 0.25 s offline look-ahead a car's
#: 12-18 inputs at 512 Hz reach 5300-7900 unknowns (0.2-0.5 GB per factor) at 48 blocks per
#: octave; 20 inputs and more get 32.  Counted per input set of the search
#: (:func:`.candidates.set_design`), not over the model's inputs.
MAX_PAST_UNKNOWNS = 6144


def look_ahead_samples(look_ahead_s: float, fs_hz: float) -> int:
    """Return the look-ahead in samples for ``look_ahead_s`` at ``fs_hz`` (rounded)."""
    return int(round(float(look_ahead_s) * float(fs_hz)))


@dataclasses.dataclass(frozen=True)
class LiveDesign:
    """
    How the live estimators are designed at fit time.

    Parameters
    ----------
    look_aheads_s : tuple of float
        Look-aheads to design, each >= 0 [s]; the first one is the configured one.
    history_s : float
        Longest past lag used [s], > 0.
    fine_s : float
        Past lags up to this are one tap per sample [s], >= 0.
    blocks_per_octave : int or None
        Resolution of the coarse taps beyond ``fine_s``: blocks per doubling of the lag, >= 1.
        None (the default): the finest the cost bound allows for the inputs at hand
        (:meth:`for_inputs`).
    regularisation : float
        Ridge per unit tap relative to each input's power [-], >= 0.

    Raises
    ------
    ConfigError
        On invalid values.

    """

    look_aheads_s: Tuple[float, ...] = (DEFAULT_LIVE_LOOK_AHEAD_S,)
    history_s: float = 4.0
    fine_s: float = 0.125
    blocks_per_octave: Optional[int] = None
    regularisation: float = 1e-4

    def __post_init__(self):
        """Validate the values."""
        try:
            looks = tuple(float(v) for v in self.look_aheads_s)
        except (TypeError, ValueError) as err:
            raise ConfigError(f'live look-aheads must be numbers, got '
                              f'{self.look_aheads_s!r}') from err
        if not looks or not all(np.isfinite(v) and v >= 0.0 for v in looks):
            raise ConfigError(f'live look-aheads must be finite and >= 0 s, got {looks!r}')
        object.__setattr__(self, 'look_aheads_s', looks)
        for name in ('history_s', 'fine_s', 'regularisation'):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ConfigError(f'live {name} must be finite and >= 0, got {value!r}')
        if self.history_s <= 0.0:
            raise ConfigError(f'live history_s must be > 0, got {self.history_s!r}')
        bpo = self.blocks_per_octave
        if bpo is not None and (isinstance(bpo, bool) or not isinstance(
                bpo, (int, np.integer)) or bpo < 1):
            raise ConfigError(f'live blocks_per_octave must be an integer >= 1, '
                              f'got {self.blocks_per_octave!r}')

    def for_inputs(self, n_in: int, fs_hz: float) -> 'LiveDesign':
        """
        Return the design with its coarse resolution fixed for ``n_in`` inputs at ``fs_hz``.

        A resolution already set is kept.  Otherwise the finest of
        :data:`BLOCKS_PER_OCTAVE_CHOICES` whose past lags over all ``n_in`` inputs stay within
        :data:`MAX_PAST_UNKNOWNS`, else the coarsest.  ``fit`` resolves it per input set, with
        the set's input count (:func:`.candidates.set_design`): the sets of one fit may have
        two bases, and the model's estimator takes the union of their edges
        (:func:`on_common_edges`).
        """
        if self.blocks_per_octave is not None:
            return self
        fine = int(round(self.fine_s * fs_hz))
        history = max(1, int(round(self.history_s * fs_hz)))
        for bpo in BLOCKS_PER_OCTAVE_CHOICES:
            if n_in * (lag_edges(0, fine, history, bpo).size - 1) <= MAX_PAST_UNKNOWNS:
                break
        return dataclasses.replace(self, blocks_per_octave=bpo)

    def max_lag(self, fs_hz: float) -> int:
        """Return the longest correlation lag the design needs at ``fs_hz`` [samples]."""
        longest = max(look_ahead_samples(v, fs_hz) for v in self.look_aheads_s)
        return longest + max(1, int(round(self.history_s * fs_hz))) + 2


@dataclasses.dataclass(frozen=True)
class CausalEstimator:
    """
    A fitted live estimator (immutable; arrays read-only).

    Output sample ``n`` is ``sum_k fine_taps[:, :, k] x(n + D - k)`` (tap ``k`` is lag
    ``k - D``, so the fine part covers lags ``-D .. n_fine - D - 1``) plus, for every coarse
    block ``p``, ``coarse_taps[:, :, p]`` times the sum of ``x(n - l)`` over lags
    ``coarse_edges[p] <= l < coarse_edges[p + 1]``.

    Parameters
    ----------
    look_ahead_samples : int
        ``D`` [samples], >= 0.
    fine_taps : numpy.ndarray, shape (n_out, n_in, n_fine)
        Full-rate taps [output unit / input unit], ``n_fine > D``.
    coarse_edges : numpy.ndarray, shape (n_coarse + 1,), int
        Lag block boundaries [samples], increasing, starting at ``n_fine - D``
        (``n_coarse = 0``: one edge, no coarse part).
    coarse_taps : numpy.ndarray, shape (n_out, n_in, n_coarse)
        Tap value of each coarse block [output unit / input unit].
    info : dict
        How it was designed (method, history, regularisation, look-ahead in s).

    Raises
    ------
    ModelFileError
        A field with the wrong type, shape or values (the field is named).

    """

    look_ahead_samples: int
    fine_taps: np.ndarray
    coarse_edges: np.ndarray
    coarse_taps: np.ndarray
    info: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        """Validate shapes and values; store read-only copies."""
        d = self.look_ahead_samples
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 0:
            raise ModelFileError(f'live estimator look_ahead_samples: expected an int >= 0, '
                                 f'got {d!r}')
        object.__setattr__(self, 'look_ahead_samples', int(d))
        fine = _read_only(self.fine_taps, np.float64, 'fine_taps', d)
        if fine.ndim != 3 or fine.shape[2] <= d:
            raise ModelFileError(f'live estimator (look-ahead {d}) fine_taps: expected '
                                 f'(n_out, n_in, > {d}), got {fine.shape}')
        edges = _read_only(self.coarse_edges, np.int64, 'coarse_edges', d)
        coarse = _read_only(self.coarse_taps, np.float64, 'coarse_taps', d)
        n_fine = fine.shape[2]
        if (edges.ndim != 1 or edges.size < 1 or edges[0] != n_fine - d
                or np.any(np.diff(edges) <= 0)):
            raise ModelFileError(f'live estimator (look-ahead {d}) coarse_edges: expected '
                                 f'increasing lags from {n_fine - d}, got {edges.tolist()[:5]}')
        if coarse.shape != fine.shape[:2] + (edges.size - 1,):
            raise ModelFileError(f'live estimator (look-ahead {d}) coarse_taps: expected shape '
                                 f'{fine.shape[:2] + (edges.size - 1,)}, got {coarse.shape}')
        if not isinstance(self.info, Mapping):
            raise ModelFileError(f'live estimator (look-ahead {d}) info: expected an object')
        object.__setattr__(self, 'fine_taps', fine)
        object.__setattr__(self, 'coarse_edges', edges)
        object.__setattr__(self, 'coarse_taps', coarse)
        object.__setattr__(self, 'info', dict(self.info))

    @property
    def n_out(self) -> int:
        """Return the number of outputs."""
        return int(self.fine_taps.shape[0])

    @property
    def n_in(self) -> int:
        """Return the number of inputs."""
        return int(self.fine_taps.shape[1])

    @property
    def history_samples(self) -> int:
        """Return the longest past lag used [samples]."""
        return int(self.coarse_edges[-1]) - 1

    def fir(self, fs_hz: float) -> FirFilter:
        """Return the same filter as one full-rate FIR (lag zero at tap ``D``)."""
        d = self.look_ahead_samples
        taps = np.zeros((self.n_out, self.n_in, d + self.history_samples + 1))
        taps[:, :, :self.fine_taps.shape[2]] = self.fine_taps
        for p in range(self.coarse_taps.shape[2]):
            lo, hi = self.coarse_edges[p] + d, self.coarse_edges[p + 1] + d
            taps[:, :, lo:hi] = self.coarse_taps[:, :, p:p + 1]
        return FirFilter(taps, d, fs_hz)


def _read_only(value, dtype, name: str, d: int) -> np.ndarray:
    try:
        arr = read_only_array(value, dtype)
    except (TypeError, ValueError) as err:
        raise ModelFileError(f'live estimator (look-ahead {d}) {name}: not convertible '
                             f'to {np.dtype(dtype).name}') from err
    if arr.dtype.kind == 'f' and not np.all(np.isfinite(arr)):
        raise ModelFileError(f'live estimator (look-ahead {d}) {name}: NaN or infinity')
    return arr


# -- basis ------------------------------------------------------------------------------------

def lag_edges(look_ahead: int, fine: int, history: int, blocks_per_octave: int) -> np.ndarray:
    """
    Return the lag block boundaries of the multi-rate basis [samples].

    One block per lag from ``-look_ahead`` to ``fine - 1``, then blocks whose edges grow by
    ``2 ** (1 / blocks_per_octave)`` (at least one sample) up to lag ``history``.  Block
    ``p`` covers lags ``edges[p] <= l < edges[p + 1]``.
    """
    fine = max(1, min(fine, history + 1))
    edges = list(range(-look_ahead, fine + 1))
    ratio = 2.0 ** (1.0 / blocks_per_octave)
    while edges[-1] < history + 1:
        edges.append(min(history + 1, max(edges[-1] + 1, int(round(edges[-1] * ratio)))))
    return np.asarray(edges, dtype=np.int64)


def on_common_edges(estimators: Sequence[CausalEstimator]) -> List[CausalEstimator]:
    """
    Return ``estimators`` on one basis: the longest fine part, then the union of coarse edges.

    The one-sample blocks a basis begins its coarse part with are full-rate taps (a finer
    basis has more of them), so a shorter fine part is extended with its blocks' taps up to
    the longest one, and every block of the union lies inside one block of each estimator,
    whose tap it takes: every estimator stays the same filter (:meth:`CausalEstimator.fir`
    unchanged).  The estimators share their look-ahead and history (ValueError otherwise).
    """
    first = estimators[0]
    d = first.look_ahead_samples
    if any(e.look_ahead_samples != d or e.coarse_edges[-1] != first.coarse_edges[-1]
           for e in estimators):
        raise ValueError('live estimators of different look-aheads or histories have no '
                         'common basis')
    n_fine = max(e.fine_taps.shape[2] for e in estimators)
    edges = functools.reduce(np.union1d, [e.coarse_edges for e in estimators])
    edges = edges[edges >= n_fine - d]            # the longest fine part's first edge is in
    out = []
    for e in estimators:
        if e.fine_taps.shape[2] == n_fine and e.coarse_edges.size == edges.size:
            out.append(e)
            continue
        # the lags that become full-rate taps, and each union block, in the estimator's blocks
        moved = np.arange(e.fine_taps.shape[2] - d, n_fine - d)
        into = np.searchsorted(e.coarse_edges, moved, side='right') - 1
        inside = np.searchsorted(e.coarse_edges, edges[:-1], side='right') - 1
        out.append(dataclasses.replace(
            e, fine_taps=np.concatenate([e.fine_taps, e.coarse_taps[:, :, into]], axis=2),
            coarse_edges=edges, coarse_taps=e.coarse_taps[:, :, inside]))
    return out


# -- model file section -----------------------------------------------------------------------

def _keys(d: int) -> Tuple[str, str, str]:
    return (f'live{d}_fine_taps', f'live{d}_coarse_edges', f'live{d}_coarse_taps')


def live_arrays(estimators: Sequence[CausalEstimator]) -> Dict[str, np.ndarray]:
    """Return the model-file arrays of ``estimators`` (keys carry the look-ahead)."""
    arrays = {}
    for est in estimators:
        fine, edges, coarse = _keys(est.look_ahead_samples)
        arrays.update({fine: est.fine_taps, edges: est.coarse_edges, coarse: est.coarse_taps})
    return arrays


def live_meta(estimators: Sequence[CausalEstimator]) -> list:
    """Return the ``meta.live_estimators`` list of ``estimators``."""
    return [dict(est.info, look_ahead_samples=est.look_ahead_samples) for est in estimators]


def live_from_contents(meta: Mapping, contents: Mapping[str, np.ndarray]
                       ) -> Tuple[CausalEstimator, ...]:
    """
    Parse the live estimators of a model file (none for schema 1).

    Raises
    ------
    ModelFileError
        A malformed ``meta.live_estimators`` entry or a missing / malformed array (named).

    """
    entries = meta.get('live_estimators', [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise ModelFileError("model field 'meta.live_estimators': expected a list of objects")
    out = []
    for entry in entries:
        d = entry.get('look_ahead_samples')
        if isinstance(d, bool) or not isinstance(d, int) or d < 0:
            raise ModelFileError(f"model field 'meta.live_estimators': look_ahead_samples "
                                 f'must be an int >= 0, got {d!r}')
        arrays = []
        for key in _keys(d):
            if key not in contents:
                raise ModelFileError(f'model field {key!r} is missing (live estimator with '
                                     f'look-ahead {d} samples)')
            arrays.append(contents[key])
        if arrays[1].dtype.kind not in 'iu':
            raise ModelFileError(f'model field {_keys(d)[1]!r}: expected integers')
        info = {k: v for k, v in entry.items() if k != 'look_ahead_samples'}
        out.append(CausalEstimator(d, arrays[0], arrays[1], arrays[2], info))
    return tuple(out)


def check_live(estimators, n_out: int, n_in: int) -> Tuple[CausalEstimator, ...]:
    """
    Validate a model's live estimators against its channel counts.

    Raises
    ------
    ModelFileError
        Not estimators, wrong channel counts or a look-ahead present twice.

    """
    if isinstance(estimators, CausalEstimator) or not all(
            isinstance(e, CausalEstimator) for e in estimators):
        raise ModelFileError("model field 'live': expected a sequence of CausalEstimator")
    looks = [e.look_ahead_samples for e in estimators]
    if len(set(looks)) != len(looks):
        raise ModelFileError(f"model field 'live': look-aheads {looks} repeat")
    for e in estimators:
        if (e.n_out, e.n_in) != (n_out, n_in):
            raise ModelFileError(
                f"model field 'live': estimator with look-ahead {e.look_ahead_samples} has "
                f'{e.n_out} outputs x {e.n_in} inputs, the model {n_out} x {n_in}')
    return tuple(estimators)


def find_live(estimators: Sequence[CausalEstimator], look_ahead: int
              ) -> Optional[CausalEstimator]:
    """Return the estimator for ``look_ahead`` samples, or ``None``."""
    return next((e for e in estimators if e.look_ahead_samples == look_ahead), None)
