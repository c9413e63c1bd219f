# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Fit a model from recorded segments (the ``fit`` command's numeric part).

Each gap-free segment contributes its own Welch windows; the cross-spectra are averaged with
weights equal to the window counts, so joining several recordings never creates a window that
straddles two of them (no join artefact).

Two resolutions (``long_segment_length > 0``, opt-in): Welch with ``segment_length`` trades
frequency resolution (``fs / segment_length``) against the number of averaged windows.  Below
``crossover_hz`` the loads are quasi-static (braking, cornering, long road waves such as a
twist course at 0.25 Hz) and a 0.5 Hz grid cannot resolve them, while above it the extra
windows of the short segments keep the variance low.  So a second estimate from
``long_segment_length`` windows (with the stronger ``long_regularisation``: at low frequency
the 12 inputs are nearly collinear rigid-body motions) is used below ``crossover_hz``, the
short-segment FIR's own response (its taps zero-padded to the long length, i.e. exactly what
the single-resolution model would do) above ``1.5 * crossover_hz``, with a raised-cosine blend
between.  The model then holds the finer grid and a FIR of ``long_segment_length`` taps.
"""
import dataclasses
import datetime
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.correlations import CorrelationAccumulator
from wheel_force_estimator.core.crossval import blend_weight
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.filtering import fir_from_frf
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import response_on_grid
from wheel_force_estimator.core.frf import bridge_unexcited
from wheel_force_estimator.core.frf import bridged_line_counts
from wheel_force_estimator.core.frf import estimate_frf
from wheel_force_estimator.core.frf import FrfConfig
from wheel_force_estimator.core.frf import FrfEstimate
from wheel_force_estimator.core.live_estimator import LiveDesign
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.normal_equations import design_live
from wheel_force_estimator.core.physics_laws import QUANTITIES
from wheel_force_estimator.core.spectra import combine_spectra
from wheel_force_estimator.core.spectra import cross_spectra
from wheel_force_estimator.core.spectra import CrossSpectra
from wheel_force_estimator.core.spectra import WelchConfig
from wheel_force_estimator.core.validation import as_signals

#: What ``FitConfig.unexcited`` may say (see :func:`.frf.bridge_unexcited`).
UNEXCITED = ('interpolate', 'spring_damper', 'zero')


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
    long_segment_length : int
        0 (default) = one resolution.  Otherwise the Welch segment length of the second,
        low-frequency estimate (> ``segment_length``) and the FIR length [samples]; see the
        module notes.  Segments shorter than it contribute to the short estimate only.
    crossover_hz : float
        Below this frequency the long-segment estimate is used alone; above
        ``1.5 * crossover_hz`` the short one; raised-cosine blend between [Hz].
    long_regularisation : float
        Relative regularisation of the long-segment estimate [-].
    water_level : float
        Frequencies whose mean input power is below this fraction of the strongest
        frequency's are treated as not excited: the FRF there is damped towards zero
        (:mod:`.frf`, water level) [-].  The default 1e-6 (60 dB) is below the noise floor
        of typical 16-24 bit acquisition; on the proving-ground simulator it damps only lines
        above 100 Hz (the weakest is 68 dB down), where the forces hold little: its mean
        holdout RMSE moved 26.18 -> 26.14 %; 0 = off.
    unexcited : str
        What the FRF is between and below the lines the inputs excited, where the water level
        damps it: ``'interpolate'`` (default) bridges them from the excited lines
        (:func:`.frf.bridge_unexcited`: a sine test's response at an untested frequency),
        ``'spring_damper'`` also extends the response to displacement below the lowest
        excited line for velocity and acceleration inputs (it then grows like ``1/f`` or
        ``1/f^2`` towards 0 Hz: opt-in, as it amplifies sensor drift), ``'zero'`` leaves them
        damped.  Lines above an input's band are damped either way.
    live : LiveDesign or None
        Also design the live (causal) estimators (correlations accumulated from the same
        segments while they are in memory); ``None`` = none.

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
    long_segment_length: int = 0
    crossover_hz: float = 2.0
    long_regularisation: float = 5e-2
    water_level: float = 1e-6
    unexcited: str = 'interpolate'
    live: Optional[LiveDesign] = None

    def __post_init__(self):
        """Validate values that the spectral and FRF configs do not check themselves."""
        if isinstance(self.long_segment_length, (bool, np.bool_)) or not isinstance(
                self.long_segment_length, (int, np.integer)):
            raise ConfigError(
                f'long_segment_length must be an integer, got {self.long_segment_length!r}')
        if self.long_segment_length != 0 and self.long_segment_length <= self.segment_length:
            raise ConfigError(
                f'long_segment_length ({self.long_segment_length}) must be 0 (off) or longer '
                f'than segment_length ({self.segment_length})')
        if not (np.isfinite(self.crossover_hz) and self.crossover_hz > 0.0):
            raise ConfigError(f'crossover_hz must be > 0, got {self.crossover_hz!r}')
        if self.long_segment_length and self.f_min_hz > 0.0:
            raise ConfigError('long_segment_length needs f_min_hz == 0 (it exists to resolve '
                              f'the quasi-static band), got f_min_hz={self.f_min_hz!r}')
        try:
            self.long_frf()
        except ConfigError as err:        # named as the user wrote it, not FrfConfig's field
            raise ConfigError(str(err).replace('FrfConfig.regularisation',
                                               'long_regularisation')) from err
        if not 0.0 <= self.coherence_floor < 0.5:
            raise ConfigError(f'coherence_floor must be in [0, 0.5), got {self.coherence_floor!r}')
        if not np.isfinite(self.f_min_hz) or self.f_min_hz < 0:
            raise ConfigError(f'f_min_hz must be >= 0, got {self.f_min_hz!r}')
        if self.live is not None and not isinstance(self.live, LiveDesign):
            raise ConfigError(f'live must be a LiveDesign or None, got {self.live!r}')
        if self.detrend == 'none' and self.water_level > 0.0:
            raise ConfigError(
                'water_level needs detrended Welch windows: with detrend none the sensor '
                'offsets leak into the low lines and no line is a clean reference; set '
                'water_level: 0 or detrend: constant')
        if self.unexcited not in UNEXCITED:
            raise ConfigError(f'unexcited must be one of {list(UNEXCITED)}, got '
                              f'{self.unexcited!r}')
        if self.f_max_hz is not None and not self.f_max_hz > self.f_min_hz:
            raise ConfigError(
                f'f_max_hz ({self.f_max_hz!r}) must be > f_min_hz ({self.f_min_hz!r})')
        # the estimator settings fail here, named, not at the first estimate
        self.frf()
        self.welch(1.0)

    def welch(self, fs_hz: float) -> WelchConfig:
        """Return the Welch configuration at ``fs_hz``."""
        return WelchConfig(fs_hz=fs_hz, segment_length=self.segment_length,
                           overlap=self.overlap, window=self.window, detrend=self.detrend)

    def frf(self) -> FrfConfig:
        """Return the FRF estimator configuration."""
        return FrfConfig(estimator=self.estimator, regularisation=self.regularisation,
                         water_level=self.water_level)

    def long_welch(self, fs_hz: float) -> WelchConfig:
        """Return the Welch configuration of the low-frequency estimate (needs it enabled)."""
        return dataclasses.replace(self.welch(fs_hz), segment_length=self.long_segment_length)

    def long_frf(self) -> FrfConfig:
        """Return the FRF estimator configuration of the low-frequency estimate."""
        return FrfConfig(estimator=self.estimator, regularisation=self.long_regularisation,
                         water_level=self.water_level)


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
              fit_info: Optional[Mapping] = None,
              input_quantity: str = 'acceleration') -> FrfModel:
    """
    Fit an :class:`FrfModel` from one or more segments.

    Parameters
    ----------
    segments : sequence of TrainingSegment
        Gap-free segments, all at ``fs_hz``.  Segments shorter than one Welch segment are
        refused (never padded); those shorter than ``long_segment_length`` feed only the
        short-segment estimate.
    fs_hz : float
        Sample rate [Hz].
    config : FitConfig
        Fit settings.
    input_channels, output_channels : sequence of str
        Channel names in array order.
    fit_info : mapping, optional
        Extra provenance stored in the model's ``fit`` metadata (e.g. bag paths).
    input_quantity : str
        What the inputs are (``'acceleration'``, ``'velocity'``, ``'displacement'``): the
        domain unexcited lines are bridged in (:func:`.frf.bridge_unexcited`).

    Returns
    -------
    FrfModel

    Raises
    ------
    InsufficientDataError
        No segments, a segment shorter than one Welch segment, or (two resolutions) no
        segment as long as ``long_segment_length``.
    ShapeError, NonFiniteError
        Bad arrays (the segment source is named).

    """
    if not segments:
        raise InsufficientDataError('no recording segments to fit')
    if input_quantity not in QUANTITIES:
        raise ConfigError(f'input_quantity must be one of {list(QUANTITIES)}, got '
                          f'{input_quantity!r}')
    order = QUANTITIES.index(input_quantity)     # time derivatives of displacement
    welch = config.welch(fs_hz)
    long_welch = config.long_welch(fs_hz) if config.long_segment_length else None
    spectra, long_spectra = [], []
    sum_x = np.zeros(len(input_channels))
    sum_y = np.zeros(len(output_channels))
    n_total = 0
    corr = None if config.live is None else CorrelationAccumulator(
        len(input_channels), len(output_channels), config.live.max_lag(fs_hz))
    for seg in segments:
        x = as_signals(seg.accel_mps2, f'accelerations of {seg.source}', input_channels)
        y = as_signals(seg.force_n, f'forces of {seg.source}', output_channels)
        spectra.append(cross_spectra(x, y, welch, name=seg.source))
        if long_welch is not None and x.shape[1] >= config.long_segment_length:
            long_spectra.append(cross_spectra(x, y, long_welch, name=seg.source))
        if corr is not None:
            corr.add(x, y)
        sum_x += x.sum(axis=1)
        sum_y += y.sum(axis=1)
        n_total += x.shape[1]
    if long_welch is not None and not long_spectra:
        raise InsufficientDataError(
            f'no segment is as long as long_segment_length = {config.long_segment_length} '
            f'samples ({config.long_segment_length / fs_hz:g} s); longest: '
            f'{max(seg.accel_mps2.shape[1] for seg in segments)} samples; record longer '
            f'runs or set long_segment_length: 0 (single resolution)')
    combined = combine_spectra(spectra)
    long_combined = combine_spectra(long_spectra) if long_welch is not None else None
    est, h, fir, extra = estimate_h1(combined, long_combined, config, fs_hz, order,
                                     input_channels)
    live = () if corr is None else design_live(corr.result(fs_hz), config.live)
    return build_model(segments, fs_hz, config, input_channels, output_channels,
                       (est, h, fir, live, extra, sum_x / n_total, sum_y / n_total), fit_info)


def build_model(segments: Sequence[TrainingSegment], fs_hz: float, config: FitConfig,
                input_channels: Sequence[str], output_channels: Sequence[str], parts,
                fit_info: Optional[Mapping] = None) -> FrfModel:
    """
    Return the :class:`FrfModel` of a fit, with its ``fit`` metadata.

    ``parts`` is ``(est, h, fir, live, extra, static_accel, static_force)``: the indicators
    (:class:`.frf.FrfEstimate`), the FRF, its FIR, the live estimators, the estimate's own
    metadata, and the static input and output.
    """
    est, h, fir, live, extra, static_x, static_y = parts
    info = {
        'segments': [seg.source for seg in segments],
        'durations_s': [seg.accel_mps2.shape[1] / fs_hz for seg in segments],
        'total_duration_s': sum(seg.accel_mps2.shape[1] for seg in segments) / fs_hz,
        'window': config.window, 'segment_length': config.segment_length,
        'overlap': config.overlap, 'detrend': config.detrend,
        'regularisation': config.regularisation, 'water_level': config.water_level,
        'unexcited': config.unexcited,
        'f_min_hz': config.f_min_hz, 'f_max_hz': config.f_max_hz,
        'coherence_floor': config.coherence_floor,
    }
    info.update(extra)
    info.update(dict(fit_info or {}))
    return FrfModel(
        fs_hz=fs_hz, input_channels=tuple(input_channels),
        output_channels=tuple(output_channels), f_hz=est.f_hz, h=h,
        coherence_ordinary=est.coherence_ordinary, coherence_multiple=est.coherence_multiple,
        cond_sxx=stored_condition(est.cond_sxx), fir_taps=fir.taps,
        fir_delay_samples=fir.delay_samples, static_force_n=static_y,
        static_accel_mps2=static_x, estimator=config.estimator, fit=info, live=live,
        created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'))


def estimate_h1(spectra: CrossSpectra, long_spectra: Optional[CrossSpectra], config: FitConfig,
                fs_hz: float, order: int, input_channels: Sequence[str]):
    """
    Return the (dual-resolution) H1 estimate of combined spectra and its FIR.

    Parameters
    ----------
    spectra : CrossSpectra
        Combined short-segment spectra.
    long_spectra : CrossSpectra or None
        Combined long-segment spectra (two resolutions) or ``None``.
    config : FitConfig
        Settings.
    fs_hz : float
        Sample rate [Hz].
    order : int
        Time derivatives of displacement the inputs are (bridging domain).
    input_channels : sequence of str
        Input names (bridged-line counts).

    Returns
    -------
    (FrfEstimate, numpy.ndarray, FirFilter, dict)
        Indicators, the FRF ``h`` on the model grid, its FIR realisation and the ``fit``
        metadata of the estimate (window counts, bridged lines, long-segment settings).

    """
    f_max = config.f_max_hz
    est = estimate_frf(spectra, config.frf())
    h = est.h * coherence_weight(est.coherence_multiple, config.coherence_floor)[:, :, None]
    h, bridged = _bridged(spectra, h, config, order, input_channels)
    fir = fir_from_frf(est.f_hz, h, fs_hz, f_min_hz=config.f_min_hz, f_max_hz=f_max,
                       keep_dc=config.f_min_hz == 0.0)
    extra = {'n_windows': int(spectra.n_windows), 'bridged_lines': bridged}
    if long_spectra is not None:
        long_est = estimate_frf(long_spectra, config.long_frf())
        h_long = long_est.h * coherence_weight(long_est.coherence_multiple,
                                               config.coherence_floor)[:, :, None]
        # counted where the long estimate is used (see splice_estimates)
        h_long, bridged_long = _bridged(long_spectra, h_long, config, order, input_channels,
                                        1.5 * config.crossover_hz)
        est, h = splice_estimates(long_est, h_long, est, fir, config.crossover_hz)
        fir = fir_from_frf(est.f_hz, h, fs_hz, f_max_hz=f_max, keep_dc=True)
        extra.update({'long_segment_length': config.long_segment_length,
                      'n_windows_long': int(long_spectra.n_windows),
                      'bridged_lines_long': bridged_long,
                      'crossover_hz': config.crossover_hz,
                      'long_regularisation': config.long_regularisation})
    return est, h, fir, extra


def stored_condition(cond_sxx: np.ndarray) -> np.ndarray:
    """
    Condition numbers as a model file holds them: capped at ``1 / eps`` (float64).

    An estimate reports ``inf`` where an eigenvalue of the input CSD matrix is exactly 0 (a
    line where an input carries no power at all, e.g. between the lines of a quantised sine
    test).  A model file holds no infinities, and beyond ``1 / eps`` the matrix is singular
    to working precision anyway: the cap keeps that meaning and lets such a recording be
    fitted (it made ``fit`` fail on its own model's validation).
    """
    return np.minimum(cond_sxx, 1.0 / np.finfo(np.float64).eps)


def _fir_response_on_grid(fir: FirFilter, n_fft: int) -> np.ndarray:
    """Return the response (nf, n_out, n_in) of ``fir`` on the ``n_fft`` grid (exact)."""
    return response_on_grid(fir.taps, fir.delay_samples, n_fft)


def _interp_to(f_new: np.ndarray, f_old: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation along axis 0 (real arrays of any trailing shape)."""
    flat = values.reshape(values.shape[0], -1)
    out = np.empty((f_new.size, flat.shape[1]))
    for k in range(flat.shape[1]):
        out[:, k] = np.interp(f_new, f_old, flat[:, k])
    return out.reshape((f_new.size,) + values.shape[1:])


def splice_estimates(long_est: FrfEstimate, h_long: np.ndarray, short_est: FrfEstimate,
                     short_fir: FirFilter, crossover_hz: float) -> Tuple[FrfEstimate, np.ndarray]:
    """
    Join a fine-grid low-frequency estimate and a coarse-grid one (see the module notes).

    Parameters
    ----------
    long_est : FrfEstimate
        Estimate on the fine grid (long Welch segments).
    h_long : numpy.ndarray, shape (nf_long, n_out, n_in)
        FRF to use from it (e.g. ``long_est.h`` with coherence weighting).
    short_est : FrfEstimate
        Estimate on the coarse grid (short segments); its indicators fill the high band.
    short_fir : FirFilter
        FIR realised from the coarse estimate; its exact response on the fine grid is the FRF
        used above the crossover, so the high band behaves as in a single-resolution model.
    crossover_hz : float
        Long estimate alone below it, short alone above ``1.5 * crossover_hz`` [Hz].

    Returns
    -------
    (FrfEstimate, numpy.ndarray)
        Indicators on the fine grid (coherences blended with the same weight, the coarse ones
        interpolated linearly; condition numbers from the dominant estimate, coarse ones from
        the nearest line) and the spliced FRF ``h``.

    """
    f = long_est.f_hz
    n_fft = 2 * (f.size - 1)
    w = blend_weight(f, crossover_hz)                   # 1 below the crossover, 0 above 1.5x
    h_short = _fir_response_on_grid(short_fir, n_fft)
    h = w[:, None, None] * h_long + (1.0 - w[:, None, None]) * h_short

    def blend(fine, coarse):
        wb = w.reshape((-1,) + (1,) * (fine.ndim - 1))
        return wb * fine + (1.0 - wb) * _interp_to(f, short_est.f_hz, coarse)

    # condition numbers may be inf: take the nearer coarse line rather than interpolate
    nearest = np.clip(np.rint(f / short_est.f_hz[1]).astype(int), 0, short_est.f_hz.size - 1)
    short_cond = short_est.cond_sxx[nearest]
    est = FrfEstimate(
        f, h, blend(long_est.coherence_ordinary, short_est.coherence_ordinary),
        blend(long_est.coherence_multiple, short_est.coherence_multiple),
        np.where(w >= 0.5, long_est.cond_sxx, short_cond), long_est.config)
    return est, h


def _bridged(spectra, h, config: FitConfig, order: int, input_channels,
             below_hz: float = np.inf):
    """
    Return ``h`` with its unexcited lines bridged as ``config.unexcited`` says, and the count.

    The count (per input channel, lines below ``below_hz``) is ``{}`` when nothing is bridged
    by configuration (``'zero'``).
    """
    if config.unexcited == 'zero':
        return h, {}
    h = bridge_unexcited(spectra, h, config.water_level, order,
                         config.unexcited == 'spring_damper')
    return h, dict(zip(input_channels, bridged_line_counts(spectra, config.water_level,
                                                           below_hz)))


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
