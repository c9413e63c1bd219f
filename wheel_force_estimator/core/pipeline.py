# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Fit a model from recorded segments (the ``fit`` command's numeric part).

Each gap-free segment contributes its own Welch windows; the cross-spectra are averaged with
weights equal to the window counts, so joining several recordings never creates a window that
straddles two of them (no join artefact).
"""
import dataclasses
import datetime
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.filtering import fir_from_frf
from wheel_force_estimator.core.frf import estimate_frf
from wheel_force_estimator.core.frf import FrfConfig
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import WelchConfig
from wheel_force_estimator.core.validation import as_signals


@dataclasses.dataclass(frozen=True)
class FitConfig:
    """
    Settings of a model fit.

    Parameters
    ----------
    segment_length : int
        Welch segment length [samples]; also the FIR length.
    overlap : float
        Welch overlap fraction [-].
    window : str
        Welch window name (scipy.signal.get_window).
    detrend : str
        Per-window detrend (``constant``, ``linear``, ``none``).
    estimator : str
        ``h1``, ``h1_tikhonov`` or ``h1_tsvd``.
    regularisation : float
        Relative Tikhonov lambda / TSVD cut-off [-].
    f_min_hz : float
        FRF rolled off to zero below this frequency (drift control) [Hz].  ``0`` keeps the
        quasi-static gain (DC = lowest resolved line), so steady braking/cornering loads pass;
        the static input is removed by the predictor, so gravity never leaks into the force.
    f_max_hz : float or None
        FRF forced to zero above this frequency [Hz]; ``None`` = Nyquist.
    coherence_floor : float
        Output rows of the FRF are faded to zero where the multiple coherence is below this
        value (raised cosine from ``floor`` to ``2 * floor``) [-].  There the estimate is
        noise (e.g. above the road's input band): it predicts nothing useful, and its large
        gain would turn any step or spike in the accelerations into a force burst.  0 = off.

    Raises
    ------
    ConfigError
        On invalid values.

    """

    segment_length: int = 1024
    overlap: float = 0.5
    window: str = 'hann'
    detrend: str = 'constant'
    estimator: str = 'h1_tikhonov'
    regularisation: float = 1e-4
    f_min_hz: float = 0.0
    f_max_hz: Optional[float] = None
    coherence_floor: float = 0.1

    def __post_init__(self):
        """Validate values that the spectral and FRF configs do not check themselves."""
        if not 0.0 <= self.coherence_floor < 0.5:
            raise ConfigError(f'coherence_floor must be in [0, 0.5), got {self.coherence_floor!r}')
        if not np.isfinite(self.f_min_hz) or self.f_min_hz < 0:
            raise ConfigError(f'f_min_hz must be >= 0, got {self.f_min_hz!r}')
        if self.f_max_hz is not None and not self.f_max_hz > self.f_min_hz:
            raise ConfigError(
                f'f_max_hz ({self.f_max_hz!r}) must be > f_min_hz ({self.f_min_hz!r})')

    def welch(self, fs_hz: float) -> WelchConfig:
        """Return the Welch configuration at ``fs_hz``."""
        return WelchConfig(fs_hz=fs_hz, segment_length=self.segment_length,
                           overlap=self.overlap, window=self.window, detrend=self.detrend)

    def frf(self) -> FrfConfig:
        """Return the FRF estimator configuration."""
        return FrfConfig(estimator=self.estimator, regularisation=self.regularisation)


@dataclasses.dataclass(frozen=True)
class TrainingSegment:
    """
    One gap-free stretch of synchronous inputs and outputs.

    Parameters
    ----------
    accel_mps2 : numpy.ndarray, shape (n_inputs, n)
        Specific force [m/s²].
    force_n : numpy.ndarray, shape (n_outputs, n)
        Measured force [N].
    source : str
        Where it came from (file and segment index), for messages and the model's ``fit``.

    """

    accel_mps2: np.ndarray
    force_n: np.ndarray
    source: str


def fit_model(segments: Sequence[TrainingSegment], fs_hz: float, config: FitConfig,
              input_channels: Sequence[str], output_channels: Sequence[str],
              fit_info: Optional[Mapping] = None) -> FrfModel:
    """
    Fit an :class:`FrfModel` from one or more segments.

    Parameters
    ----------
    segments : sequence of TrainingSegment
        Gap-free segments, all at ``fs_hz``.  Segments shorter than one Welch segment are
        refused (never padded).
    fs_hz : float
        Sample rate [Hz].
    config : FitConfig
        Fit settings.
    input_channels, output_channels : sequence of str
        Channel names in array order.
    fit_info : mapping, optional
        Extra provenance stored in the model's ``fit`` metadata (e.g. bag paths).

    Returns
    -------
    FrfModel

    Raises
    ------
    InsufficientDataError
        No segments, or a segment shorter than one Welch segment.
    ShapeError, NonFiniteError
        Bad arrays (the segment source is named).

    """
    if not segments:
        raise InsufficientDataError('no recording segments to fit')
    welch = config.welch(fs_hz)
    spectra = []
    sum_x = np.zeros(len(input_channels))
    sum_y = np.zeros(len(output_channels))
    n_total = 0
    for seg in segments:
        x = as_signals(seg.accel_mps2, f'accelerations of {seg.source}', input_channels)
        y = as_signals(seg.force_n, f'forces of {seg.source}', output_channels)
        spectra.append(cross_spectra(x, y, welch, name=seg.source))
        sum_x += x.sum(axis=1)
        sum_y += y.sum(axis=1)
        n_total += x.shape[1]
    combined = combine_spectra(spectra)
    est = estimate_frf(combined, config.frf())
    f_max = config.f_max_hz
    h = est.h * coherence_weight(est.coherence_multiple, config.coherence_floor)[:, :, None]
    fir = fir_from_frf(est.f_hz, h, fs_hz, f_min_hz=config.f_min_hz, f_max_hz=f_max,
                       keep_dc=config.f_min_hz == 0.0)
    info = {
        'segments': [seg.source for seg in segments],
        'durations_s': [seg.accel_mps2.shape[1] / fs_hz for seg in segments],
        'total_duration_s': n_total / fs_hz,
        'n_windows': int(combined.n_windows),
        'window': config.window, 'segment_length': config.segment_length,
        'overlap': config.overlap, 'detrend': config.detrend,
        'regularisation': config.regularisation,
        'f_min_hz': config.f_min_hz, 'f_max_hz': f_max,
        'coherence_floor': config.coherence_floor,
    }
    info.update(dict(fit_info or {}))
    return FrfModel(
        fs_hz=fs_hz, input_channels=tuple(input_channels),
        output_channels=tuple(output_channels), f_hz=est.f_hz, h=h,
        coherence_ordinary=est.coherence_ordinary, coherence_multiple=est.coherence_multiple,
        cond_sxx=est.cond_sxx, fir_taps=fir.taps, fir_delay_samples=fir.delay_samples,
        static_force_n=sum_y / n_total, static_accel_mps2=sum_x / n_total,
        estimator=config.estimator, fit=info,
        created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'))


def coherence_weight(coherence_multiple: np.ndarray, floor: float) -> np.ndarray:
    """
    Return the per-(frequency, output) weight applied to the FRF rows [-].

    0 below ``floor``, 1 above ``2 * floor``, a raised cosine between; all ones when
    ``floor == 0``.
    """
    coh = np.asarray(coherence_multiple, dtype=np.float64)
    if floor <= 0.0:
        return np.ones_like(coh)
    ramp = np.clip((coh - floor) / floor, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * ramp))


def coherence_summary(model: FrfModel, band_hz: Tuple[float, float] = (0.5, 50.0),
                      threshold: float = 0.5) -> dict:
    """
    Summarise a model's multiple coherence for the ``fit`` command.

    Parameters
    ----------
    model : FrfModel
        The fitted model.
    band_hz : (float, float)
        Band over which the mean multiple coherence is taken [Hz].
    threshold : float
        Coherence below which a band is reported as weak [-].

    Returns
    -------
    dict
        ``mean_coherence`` per output, ``low_bands_hz`` per output (contiguous frequency
        ranges within ``band_hz`` where coherence < threshold), ``worst_cond`` as a list of
        (f_hz, condition number) for the five worst lines.

    """
    f = model.f_hz
    sel = (f >= band_hz[0]) & (f <= band_hz[1])
    mean_coh, low = {}, {}
    for o, name in enumerate(model.output_channels):
        coh = model.coherence_multiple[:, o]
        mean_coh[name] = float(coh[sel].mean()) if sel.any() else float('nan')
        weak = sel & (coh < threshold)
        bands = []
        idx = np.flatnonzero(weak)
        if idx.size:
            splits = np.flatnonzero(np.diff(idx) > 1) + 1
            for run in np.split(idx, splits):
                bands.append((float(f[run[0]]), float(f[run[-1]])))
        low[name] = bands
    order = np.argsort(model.cond_sxx)[::-1][:5]
    worst = [(float(f[i]), float(model.cond_sxx[i])) for i in order]
    return {'mean_coherence': mean_coh, 'low_bands_hz': low, 'worst_cond': worst}
