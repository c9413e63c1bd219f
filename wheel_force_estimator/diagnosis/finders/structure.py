# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The inside-the-structure finder: a term whose force reaches the sensor through the structure.

A friction joint or a hardening spring between the measured base and an unmeasured mass does
not add its force to the measured one.  It changes the motion of the mass, and the force at
the sensor follows through the structure's dynamics: for one mode of a base-excited
structure, a force ``n(t)`` in the spring reaches the base as ``n * (1 - H(s) / H(0))``, ``H``
the linear FRF from base acceleration to base force.  A static term (a strength times a
feature) cannot express that (measured on a base-excited 8 Hz mode with friction in the
spring: 16.7 % with the best static friction term, 17.1 % without).  Classical reverse-path
identification (Bendat; Richards & Singh) gives every nonlinear feature a frequency-dependent
coefficient for this reason.

Here the coefficient is a causal FIR spanned by the feature itself and the feature passed
through the causal part of the reference FIR's own row (the structure's response, measured):
two coefficients, not hundreds of taps, and exact for the single mode above (the same
friction: 7.2 %, against 7.1 % with 256 free causal taps).  The feature is the state the
structure's deformation leaves in the predicted load (its rate for friction, its excess for a
hardening), the only trace of an unmeasured mass in a record of base motion and force.

Each basis column is *partialled* against the linear design (the reference's FIR refitted
with the column as its output, the Frisch-Waugh-Lovell step of
:func:`diagnosis.written.backfitted_model`), so a column scores only what the linear model
cannot already explain.  A candidate is judged by the acceptance rule of every other one
(:func:`finders.acceptance.rejection`): its gain on held-out time blocks must reach
``min_gain``, beat ``null_factor`` times the best gain of the same grid with the feature
circularly shifted (:func:`blocks.null_lags`) and lower the cross-validated RMSE by
``min_improvement_pct``.

Only without a simulation or model (the reference is the real-data FIR) and only on channels
the static selection left unexplained: what a static term explains needs no structure
(:func:`find`).
"""
import dataclasses
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

import numpy as np
from scipy import signal

from wheel_force_estimator.core.errors import WheelForceError
from wheel_force_estimator.core.physics import apply_physics
from wheel_force_estimator.core.physics import load_rate
from wheel_force_estimator.core.physics import PhysicsTerm
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.spectra import power_quantile_hz
from wheel_force_estimator.diagnosis.blocks import block_stats
from wheel_force_estimator.diagnosis.blocks import cv_sse
from wheel_force_estimator.diagnosis.blocks import CvData
from wheel_force_estimator.diagnosis.blocks import full_fit
from wheel_force_estimator.diagnosis.blocks import null_lags
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.finders.acceptance import rejection
from wheel_force_estimator.diagnosis.grids import load_state
from wheel_force_estimator.diagnosis.grids import lowpassed_load
from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.result import Finding
from wheel_force_estimator.diagnosis.written import partialled

#: Load-state corners tried, as multiples of the frequency below which 99 % of the load's
#: dynamic power lies: the low-pass only takes out what lies above the band the structure
#: responds in; a corner inside it would shift a friction's switching in phase.
CORNER_FACTORS = (0.5, 1.0, 2.0)
#: Friction regularising rates tried, as fractions of the load-state rate's RMS.
RATE_SCALES = (0.05, 0.2, 0.8)
#: Candidates whose basis is partialled in one fit (bounds the memory of long records).
CANDIDATES_PER_FIT = 4
#: Rounds of :meth:`_Channel.refined` (the fixed point is reached in 2-3, measured).
REFINE_ITERATIONS = 3
#: Energy of the causal response kept when its tail is cut [-].
TAIL_ENERGY = 1e-8


@dataclass(frozen=True)
class _Candidate:
    physics: str
    params: Dict[str, float]
    state_lowpass_hz: float


def _band_top_hz(loads: Sequence[np.ndarray], fs_hz: float) -> float:
    """Frequency below which 99 % of the loads' dynamic power lies [Hz]."""
    n = min(4096, min(x.size for x in loads))
    psd = sum(signal.welch(x - x.mean(), fs_hz, nperseg=n)[1] for x in loads)
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    top = power_quantile_hz(f[1:], psd[1:], 0.99)   # DC left out
    return 0.25 * fs_hz if top is None else top


def _candidates(contexts, fs_hz: float) -> List[_Candidate]:
    top = _band_top_hz([c.load for c in contexts], fs_hz)
    corners = sorted({round(min(k * top, 0.45 * fs_hz), 6) for k in CORNER_FACTORS})
    out = []
    for fc in corners:
        states = [load_state(c, fc) for c in contexts]
        rate_rms = float(np.sqrt(np.mean(np.concatenate([load_rate(s, fs_hz)
                                                         for s in states]) ** 2)))
        if rate_rms > 0.0:
            out.extend(_Candidate('coulomb_friction', {'friction_n': 1.0,
                                                       'rate_scale_n_per_s': k * rate_rms}, fc)
                       for k in RATE_SCALES)
        center = float(np.mean(np.concatenate(states)))
        out.append(_Candidate('cubic_stiffness', {'center_n': center, 'gain': 1.0}, fc))
    return out


def _causal_response(model, o: int, i: int) -> np.ndarray:
    """Causal part of the reference FIR from input ``i`` to output ``o``, tail cut."""
    taps = np.asarray(model.fir_taps[o, i, model.fir_delay_samples:], dtype=np.float64)
    energy = np.cumsum(taps[::-1] ** 2)[::-1]
    if not energy[0] > 0.0:
        return taps[:1]
    keep = int(np.sum(energy > TAIL_ENERGY * energy[0]))
    return taps[:max(keep, 1)]


class _Channel:
    """The records of one output channel: unit forces, their basis, partialled and cut."""

    def __init__(self, prep, reference, design, o: int, channel: str, source: str, config):
        self.prep, self.model, self.o, self.channel = prep, reference.model, o, channel
        self.source, self.config = source, config
        rec0 = prep.recordings[0]
        self.fs_hz = rec0.fs_hz
        self.design = dataclasses.replace(design, live=None)
        self.response = _causal_response(self.model, o, rec0.input_channels.index(source))
        self.data = CvData(pieces(prep, o, channel), config.selection)
        self.base_sse = cv_sse(block_stats(self.data, [[] for _ in self.data.pieces]),
                               self.data.fold, self.data.n_folds)

    def term(self, cand: _Candidate, params=None, taps=()) -> PhysicsTerm:
        rec0 = self.prep.recordings[0]
        return PhysicsTerm(cand.physics, (self.channel,), params or cand.params,
                           sources=(self.source,), input_quantity=rec0.input_quantity,
                           state='load', state_lowpass_hz=cand.state_lowpass_hz,
                           response_taps=taps)

    def _added(self, term: PhysicsTerm, rec, prediction) -> np.ndarray:
        """Return the force ``term`` adds to this channel of ``rec`` (the stage's path)."""
        out = apply_physics([term], rec.fs_hz, rec.input_channels, rec.output_channels,
                            rec.inputs, prediction)
        return out[self.o] - prediction[self.o]

    def units(self, cand: _Candidate) -> List[np.ndarray]:
        """Return the candidate's force at unit strength on every whole record."""
        term = self.term(cand)
        return [self._added(term, rec, pred)
                for rec, pred in zip(self.prep.recordings, self.prep.full_predictions)]

    def basis(self, unit: np.ndarray) -> np.ndarray:
        return np.stack([unit, signal.lfilter(self.response, (1.0,), unit)])

    def _refit(self, recordings):
        """Fit the reference's linear design on ``recordings`` (records too short left out)."""
        segs = [TrainingSegment(r.inputs, r.outputs, f'{r.name} (dynamic basis)')
                for r in recordings if r.n_samples >= self.design.segment_length]
        rec0 = recordings[0]
        return fit_model(segs, self.fs_hz, self.design, rec0.input_channels,
                         rec0.output_channels, input_quantity=rec0.input_quantity)

    def partialled(self, columns: List[np.ndarray]) -> List[np.ndarray]:
        """Return ``columns[k]`` minus what the linear design predicts of them."""
        return partialled(columns, self.prep.recordings, self._refit)

    def sse(self, partialled: List[np.ndarray], rows: Sequence[int]) -> Tuple[float, np.ndarray]:
        """Cross-validated SSE and full-data coefficients of the partialled ``rows``."""
        cols = []
        for i, (part, (a, b)) in enumerate(zip(partialled, self.prep.spans)):
            cols.append([self.data.prepare(i, part[r, a:b]) for r in rows])
        stats = block_stats(self.data, cols)
        return cv_sse(stats, self.data.fold, self.data.n_folds), full_fit(stats)

    def linear_companions(self, corners: Sequence[float]):
        """
        Partial the basis of the *linear* load state and its rate at every corner.

        The reference FIR's own estimation error (resolution bias at a lightly damped mode)
        is linear in the inputs but outside what the FIR design fits, and a nonlinear
        feature of the load carries a linear part that the same design misses alike: on a
        linear 3-input structure a friction feature "explained" 37 % of the residual.
        Fitted beside every candidate, these columns take that linear part, so a candidate
        is credited only with what no linear function of the same state explains.
        """
        columns = [[] for _ in self.prep.recordings]
        for fc in corners:
            for k, pred in enumerate(self.prep.full_predictions):
                state = lowpassed_load(pred[self.o], self.fs_hz, fc)
                rate = load_rate(state, self.fs_hz)
                columns[k].extend([self.basis(state - state.mean()), self.basis(rate)])
        part = self.partialled([np.concatenate(c) for c in columns])
        self._companions = {fc: tuple(range(4 * j, 4 * j + 4)) for j, fc in enumerate(corners)}
        self._companion_part = part
        self._companion_sse = {fc: self.sse(part, rows)[0] for fc, rows in
                               self._companions.items()}

    def gains(self, cands: Sequence[_Candidate], units_per_cand: List[List[np.ndarray]],
              shifts=None):
        """
        Return the held-out gain, two coefficients, SSE and base SSE of every candidate.

        The gain is over the linear companions of the candidate's corner; record ``k``'s
        features are circularly shifted by ``shifts[k]`` samples (None: as recorded).
        """
        out = []
        # A few candidates per fit: the basis of all of them at once, twice over (partialled),
        # held 1.5 GB for 2 x 300 s at 2048 Hz.
        for first in range(0, len(cands), CANDIDATES_PER_FIT):
            chunk = range(first, min(first + CANDIDATES_PER_FIT, len(cands)))
            columns = []
            for k in range(len(self.prep.recordings)):
                shift = 0 if shifts is None else shifts[k]
                columns.append(np.concatenate([self.basis(np.roll(units_per_cand[j][k], shift))
                                               for j in chunk]))
            part = self.partialled(columns)
            for pos, j in enumerate(chunk):
                fc = cands[j].state_lowpass_hz
                sse, coef = self.beside_companions(fc, [p[2 * pos:2 * pos + 2] for p in part])
                base = self._companion_sse[fc]
                out.append((1.0 - sse / base if base > 0.0 else 0.0, coef, sse, base))
        return out

    def beside_companions(self, corner_hz: float, candidate: List[np.ndarray]):
        """
        Return the SSE and the candidate's coefficients, fitted beside the companions.

        ``candidate[k]`` holds the partialled basis (2, n) of record ``k``; the companions are
        the linear columns of the same corner (:meth:`linear_companions`).
        """
        rows = list(self._companions[corner_hz])
        both = [np.concatenate([c[rows], q]) for c, q in zip(self._companion_part, candidate)]
        sse, coef = self.sse(both, range(len(rows) + len(candidate[0])))
        return sse, coef[len(rows):]

    def refined(self, cand: _Candidate, coef, iterations: int = REFINE_ITERATIONS):
        """
        Coefficients at which the term and the FIR refitted around it agree.

        A load-state term reads the load the *written* model predicts, and that model's FIR
        is refitted on the force minus the term, so it predicts less of the friction than the
        plain FIR the candidate was found with.  The coefficients found with the plain load
        are moved to the fixed point: refit the channel's FIR around the term, recompute the
        term's force from the load it now predicts, refit the two coefficients (partialled
        as before); measured on a base-excited mode with friction in the spring: 15.1 % on
        held-out data with the plain-load coefficients, 11.3 % at the fixed point after 3
        rounds (17.5 % without the term).
        """
        recs = self.prep.recordings
        unit_term = self.term(cand)
        for _ in range(iterations):
            term = self.term(cand, taps=tuple(self.taps(coef)))
            # the channel's FIR refitted on the force minus the term
            columns = [rec.outputs[self.o:self.o + 1] - self._added(term, rec, pred)
                       for rec, pred in zip(recs, self.prep.full_predictions)]
            refit = [c - p for c, p in zip(columns, self.partialled(columns))]
            units = []
            for rec, pred, load in zip(recs, self.prep.full_predictions, refit):
                whole = pred.copy()
                whole[self.o] = load[0]
                units.append(self._added(unit_term, rec, whole))
            part = self.partialled([self.basis(u) for u in units])
            coef = self.beside_companions(cand.state_lowpass_hz, part)[1]
        return coef

    def taps(self, coef) -> np.ndarray:
        """Response FIR of coefficients ``(b0, b1)``: ``b0 * delta + b1 * causal FIR``."""
        taps = coef[1] * self.response
        taps[0] += coef[0]
        return taps

    def pct(self, sse: float) -> float:
        ts = self.data.target_ss
        return 100.0 * float(np.sqrt(max(sse, 0.0) / ts)) if ts > 0.0 else 0.0


def find(run, found=()) -> List[Finding]:
    """Return the findings inside the structure (without a simulation or model only)."""
    if run.mode != 'linear':
        return []
    return dynamic_findings(run.prep, run.reference, run.channels, run.sources, run.outcomes,
                            run.config)


def dynamic_findings(prep, reference, channels: Sequence[str], sources: Sequence[str],
                     outcomes, config) -> List[Finding]:
    """
    Find physics inside the structure on the channels the static selection left.

    ``reference`` must be the real-data FIR (``FrfReference`` with its fitted ``design``);
    ``outcomes`` the static selection per channel.  Returns one finding per channel at most.
    """
    design = getattr(reference, 'design', None)
    if design is None or not prep.recordings:
        return []
    cfg = config.selection
    found = []
    for o, ch in enumerate(channels):
        if outcomes[ch].accepted:
            continue
        try:
            chan = _Channel(prep, reference, design, o, ch, sources[o], config)
            if not chan.base_sse > 0.0:
                continue
            cands = _candidates([p.ctx for p in chan.data.pieces], chan.fs_hz)
            if not cands:
                continue
            chan.linear_companions(sorted({c.state_lowpass_hz for c in cands}))
            units = [chan.units(c) for c in cands]
            scores = chan.gains(cands, units)
            best = int(np.argmax([s[0] for s in scores]))
            gain, coef, sse, base = scores[best]
            if rejection(cfg, gain) is not None:
                continue
            # Shifted record by record (a shift of the concatenation could move a record by
            # about its own length, i.e. not at all).
            lags = [null_lags(u, cfg.n_null) for u in units[best]]
            null = max(max(s[0] for s in chan.gains(cands, units, shifts))
                       for shifts in zip(*lags))
        except WheelForceError:
            # A basis the design cannot fit (a record shorter than its segment): no finding.
            continue
        drop = chan.pct(base) - chan.pct(sse)
        if rejection(cfg, gain, null, drop) is not None:
            continue
        try:
            coef = chan.refined(cands[best], coef)
        except WheelForceError:
            pass    # the plain-load coefficients stand
        if np.any(chan.taps(coef)):
            found.append(_finding(chan, cands[best], coef, gain, null, drop))
    return found


def _finding(chan: _Channel, cand: _Candidate, coef, gain: float, null: float,
             drop: float) -> Finding:
    """Return the finding of the best candidate, its response normalised to a unit peak."""
    taps = chan.taps(coef)
    spectrum = np.abs(np.fft.rfft(taps, max(4096, 2 * taps.size)))
    peak = float(spectrum.max())
    peak_hz = float(np.argmax(spectrum) * chan.fs_hz / (2 * (spectrum.size - 1)))
    params = dict(cand.params)
    params[chan.term(cand).kind.strength] = peak
    term = chan.term(cand, params, tuple(taps / peak))
    what = BY_KEY[f'{cand.physics}:load'].inside
    evidence = (f'{chan.channel}: {what} acting inside the structure, reaching the sensor '
                f'through its own response (largest at {peak_hz:.3g} Hz); explains '
                f'{gain:.1%} of the residual on held-out blocks vs {null:.1%} with time-shifted '
                f'features; cross-validated RMSE -{drop:.2f} points')
    shown = dict(params, state_lowpass_hz=cand.state_lowpass_hz, response_peak_hz=peak_hz)
    return Finding(cand.physics, (chan.channel,), shown, float(gain), evidence, (term,),
                   float(null))
