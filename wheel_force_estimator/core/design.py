# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The product's fit design: what ``wheel-force fit`` makes from recordings, in one place.

``wheel-force fit`` and the diagnosis's "best linear model fitted on the real data" (its
``real_linear`` figure, the reference of a diagnosis without ``--sim``/``--model``, the real-data
FRF of the written model) call :func:`fit_design`, so the two can never drift apart:

- segments shorter than one Welch segment are left out (and listed), none usable is refused;
- the two-resolution fit (:data:`PRODUCT_FIT_DEFAULTS`) unless the settings say otherwise;
- short records (rig and DAQ exports, often a few seconds): when no record holds the long
  segment and the caller allows it (generic recordings, long segment not chosen by the user),
  the fit falls back to one resolution and says so in ``note``; nothing is padded;
- very short records: when the Welch segments of all records number no more than the inputs,
  the H1 estimate reproduces every window exactly (the input cross-spectral matrix has rank
  <= the number of windows), so its coherence is 1 by construction (only the Tikhonov term
  keeps it below) and says nothing about noise or nonlinearity; when the caller allows it
  (generic recordings, segment length not chosen by the user) the segment is halved until
  there are more windows than inputs, and ``note`` says so;
- generic records whose segment length was not chosen: the Welch segment is chosen by
  blocked cross-validation (:mod:`core.resolution`) and ``note`` says so when it changes;
- the model's ``units`` name the declared input quantity.
"""
import dataclasses
import sys
from typing import Iterable, Mapping, Optional, Sequence, Tuple


from wheel_force_estimator.core.crossval import N_BLOCKS
from wheel_force_estimator.core.errors import InsufficientDataError
from wheel_force_estimator.core.model import FrfModel
from wheel_force_estimator.core.physics_laws import QUANTITIES
from wheel_force_estimator.core.pipeline import build_model
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.core.resolution import choose_segment_length
from wheel_force_estimator.core.search import fit_chosen
from wheel_force_estimator.core.search import INPUTS_KEY
from wheel_force_estimator.core.search import MIN_SCORING_SEGMENT
from wheel_force_estimator.core.search import search
from wheel_force_estimator.core.spindle import CHANNEL_UNITS
from wheel_force_estimator.core.spindle import input_sets
from wheel_force_estimator.core.validation import as_signals


#: What ``wheel-force fit`` uses when neither the params file nor the command line says
#: otherwise (the library's ``FitConfig()`` keeps the single-resolution paper method): the
#: two-resolution fit measured better on held-out simulated data on every Fz and most Fx/Fy
#: channels (bench/bench_accuracy.py, README).  Every other default (``long_regularisation``
#: 5e-2 included, the value those measurements used) is ``FitConfig``'s own.
PRODUCT_FIT_DEFAULTS = {'long_segment_length': 8192, 'crossover_hz': 2.0}

#: Unit written to a model's ``units['input']`` per input quantity (SI).
INPUT_UNITS = {'acceleration': 'm/s^2', 'velocity': 'm/s', 'displacement': 'm'}


def product_fit_config() -> FitConfig:
    """Return the :class:`FitConfig` ``wheel-force fit`` uses without a params file."""
    return FitConfig(**PRODUCT_FIT_DEFAULTS)


@dataclasses.dataclass(frozen=True)
class DesignedFit:
    """
    A model fitted with the product's design and how it was made.

    Attributes
    ----------
    model : FrfModel
        The fitted model (``units`` set).
    config : FitConfig
        The settings actually used (after a short-record fallback).
    used : tuple of TrainingSegment
        Segments that entered the fit.
    skipped : tuple of str
        Segments left out (too short for one Welch segment), with their lengths.
    note : str
        Why the settings differ from the ones asked for (empty when they do not).
    warning : str
        Why the design was not cross-validated (records too short, named), for stderr and
        the report; empty when it was (or was not asked for).
    chosen : ChosenDesign or None
        The design the cross-validation chose (None when it did not run), so other records
        can be fitted with it (:meth:`refit`).

    """

    model: FrfModel
    config: FitConfig
    used: Tuple[TrainingSegment, ...]
    skipped: Tuple[str, ...]
    note: str
    warning: str = ''
    chosen: Optional['ChosenDesign'] = None

    def refit(self, segments: Sequence[TrainingSegment],
              fit_info: Optional[Mapping] = None) -> FrfModel:
        """
        Fit ``segments`` with this fit's design: its settings and, when chosen, its rows.

        The design is not searched again: the rows the cross-validation chose on the whole
        data (input set, H1 variant, FIR ridge, crossover per output) are fitted on the
        segments given, as :func:`fit_design` fits them on the whole data.  For a caller that fits
        pieces of the same recordings many times (the diagnosis's held-out blocks and its
        joint fits of the FIR with physics terms), so every piece gets the design ``fit``
        writes without a search per piece.  The refitted model carries no live estimators
        (a caller that writes it designs them, as the diagnosis does).

        Raises
        ------
        InsufficientDataError
            A segment shorter than one Welch segment of the design, or none usable.

        """
        model = self.model
        used = [s for s in segments if s.accel_mps2.shape[1] >= self.config.segment_length]
        if not used:
            raise InsufficientDataError(
                f'no piece holds one Welch segment of {self.config.segment_length} samples')
        # pieces too short for the long segment, or holding no more of its windows than
        # inputs, fall back to one resolution as fit_design does (an H1 estimate from that
        # few windows fits them exactly).  The chosen rows are kept: the fallback changes
        # only their H1 part (one resolution), never the least-squares rows and crossovers
        # (before, a fallback refitted the plain H1 instead: the diagnosis's held-out blocks
        # of 2-minute records judged that, 20 % unfiltered on Fz, where the written plain fit
        # scored 12 % on a new recording, so the simulation's rows won the blocks)
        config, _ = _short_record_fallback(self.config, used, model.fs_hz)
        config, _ = _few_long_windows_fallback(
            config, used, model.fs_hz, _guarded_inputs(
                model.input_channels, self.chosen is not None
                and len(self.chosen.choice.space.input_sets) > 1))
        info = dict(fit_info or {})
        if self.chosen is None:
            out = fit_model(used, model.fs_hz, dataclasses.replace(config, live=None),
                            model.input_channels, model.output_channels, fit_info=info,
                            input_quantity=self.input_quantity)
        else:
            out = self.chosen.fit(used, model.fs_hz, config, model.input_channels,
                                  model.output_channels, info, live_estimators=False)
        return dataclasses.replace(out, units=model.units)

    @property
    def input_quantity(self) -> str:
        """Return the input quantity of the fitted model (from its ``units``)."""
        unit = self.model.units.get('input', 'm/s^2')
        return {v: k for k, v in INPUT_UNITS.items()}[unit]


@dataclasses.dataclass(frozen=True)
class ChosenDesign:
    """
    What a search chose, to fit other data with it (:meth:`DesignedFit.refit`).

    Attributes
    ----------
    choice : Choice
        Per output the chosen candidate, and the live ridges.
    welch : dict
        The Welch configurations of the search.
    lags : int
        Correlation lags of the least-squares FIRs.
    order : int
        Input quantity index (``QUANTITIES``).

    """

    choice: object
    welch: dict
    lags: int
    order: int

    def fit(self, used, fs_hz: float, config: FitConfig, input_channels, output_channels,
            fit_info, live_estimators: bool = True) -> FrfModel:
        """Fit the chosen rows on ``used`` (:func:`core.search.fit_chosen`)."""
        est, h, fir, live, extra, static_x, static_y = fit_chosen(
            used, self.choice, self.welch, self.lags, fs_hz, config, self.order,
            input_channels, live_estimators)
        extra = dict(extra, design=self.choice.record(output_channels, input_channels))
        return build_model(used, fs_hz, config, input_channels, output_channels,
                           (est, h, fir, live, extra, static_x, static_y), fit_info)


def _short_record_fallback(config: FitConfig, segments, fs_hz: float) -> Tuple[FitConfig, str]:
    """Return the config with one resolution when no record holds the long segment, a note."""
    long = config.long_segment_length
    if not long:
        return config, ''
    longest = max(s.accel_mps2.shape[1] for s in segments)
    if longest >= long:
        return config, ''
    note = (f'note: no record holds the {long}-sample long segment of the default '
            f'two-resolution fit ({long / fs_hz:g} s at {fs_hz:g} Hz; longest: {longest} '
            f'samples); fitted with one resolution (segment {config.segment_length}). '
            f'--long-segment-length 0 silences this note.')
    return dataclasses.replace(config, long_segment_length=0), note


def _few_long_windows_fallback(config: FitConfig, segments, fs_hz: float,
                               n_inputs: int) -> Tuple[FitConfig, str]:
    """
    Return the config with one resolution when too few long windows exist, and a note.

    Too few: the records hold no more windows of the long segment than there are inputs.
    H1 from that few windows reproduces them exactly below the crossover (coherence 1 by
    construction, only the regularisation keeps it finite), the rule
    :func:`_few_windows_fallback` applies to the short segment.  Measured: the MR damper's
    115 s run beside two 15 s runs holds one 8192-sample window (the plain fit scored 162 %
    on a held-out run with it, 71 % without); a 1-minute simulated car holds 6 for 12 inputs
    (held-out 1 Hz high-passed RMSE 32.9 % with it, 29.4 % without).
    """
    long = config.long_segment_length
    if not long:
        return config, ''
    lengths = [s.accel_mps2.shape[1] for s in segments if s.accel_mps2.shape[1] >= long]
    if not lengths:
        return config, ''
    windows = _window_count(dataclasses.replace(config, long_segment_length=0), long, fs_hz,
                            lengths)
    if windows > n_inputs:
        return config, ''
    note = (f'note: the records hold {windows} window(s) of the {long}-sample long segment of '
            f'the default two-resolution fit for {n_inputs} input(s): an H1 estimate from no '
            f'more windows than inputs fits them exactly (coherence 1 by construction); fitted '
            f'with one resolution (segment {config.segment_length}). --long-segment-length 0 '
            f'silences this note.')
    return dataclasses.replace(config, long_segment_length=0), note


def _guarded_inputs(input_channels, sets_searched: bool) -> int:
    """
    Return the inputs the few-long-windows fallback counts.

    All of them, unless each output row chooses among nested input sets by blocked
    cross-validation (:func:`.spindle.input_sets`): then the smallest set's.  That set is
    every row's baseline; a bigger set fitted from too few windows shows it in its held-out
    score and is not chosen.  Counting every set's inputs switched every row to one
    resolution as soon as one optional group was offered (measured 2026-11-28: with the
    traction/braking split's 2 inputs, 2-minute records' y and z rows got 0.2-3 points worse,
    although they chose the accelerations alone; bench/bench_split.py).
    """
    if sets_searched:
        return len(input_sets(input_channels)[0][1])
    return len(input_channels)


#: Shortest Welch segment the few-windows fallback goes down to [samples].
MIN_FALLBACK_SEGMENT = 64


def _window_count(config: FitConfig, length: int, fs_hz: float, record_lengths) -> int:
    """Return the Welch windows of ``length`` samples the records hold together."""
    welch = dataclasses.replace(config, segment_length=length).welch(fs_hz)
    return sum(welch.n_windows(n) for n in record_lengths)


def _few_windows_fallback(config: FitConfig, segments, fs_hz: float,
                          n_inputs: int) -> Tuple[FitConfig, str]:
    """Return the config with a segment short enough for more windows than inputs, and a note."""
    def windows(length):
        return _window_count(config, length, fs_hz, [s.accel_mps2.shape[1] for s in segments])
    length = config.segment_length
    if windows(length) > n_inputs:
        return config, ''
    while length // 2 >= MIN_FALLBACK_SEGMENT and windows(length) <= n_inputs:
        length //= 2
    if windows(length) <= n_inputs:
        return config, ''
    note = (f'note: the records hold {windows(config.segment_length)} Welch window(s) of '
            f'{config.segment_length} samples for {n_inputs} input(s): an H1 estimate from no '
            f'more windows than inputs fits them exactly (coherence 1 by construction); fitted '
            f'with segment {length} ({windows(length)} windows, '
            f'{fs_hz / length:g} Hz resolution). --segment-length N silences this note.')
    return dataclasses.replace(config, segment_length=length), note


def _cross_validated(config: FitConfig, segments, fs_hz: float, input_channels,
                     output_channels, input_quantity: str) -> Tuple[FitConfig, str]:
    """Return the config with the segment :func:`choose_segment_length` picks, and a note."""
    from wheel_force_estimator.core.predict import predict_forces

    def at(length, record_lengths):
        # one resolution when the long segment is not longer or no record holds it (as the
        # short-record fallback fits); no live estimator: the folds score the offline FIR
        # alone, and a live design is a factorisation per fold and length (28 of them, 23 s
        # of a 49-s fit of 2 minutes at 2048 Hz, one input)
        long = config.long_segment_length
        if long and (length >= long or all(n < long for n in record_lengths)):
            long = 0
        return dataclasses.replace(config, segment_length=length, long_segment_length=long,
                                   live=None)

    def fit(pieces, length):
        cfg = at(length, [x.shape[1] for x, _ in pieces])
        if _window_count(cfg, length, fs_hz, [x.shape[1] for x, _ in pieces]) <= len(
                input_channels):
            # H1 from no more windows than inputs reproduces them exactly: not a candidate
            raise InsufficientDataError(f'{length}: too few Welch windows')
        model = fit_model([TrainingSegment(x, y, 'fold') for x, y in pieces], fs_hz, cfg,
                          input_channels, output_channels, input_quantity=input_quantity)
        return lambda x: predict_forces(model, x)
    choice = choose_segment_length([(s.accel_mps2, s.force_n) for s in segments],
                                   config.segment_length, fit, fs_hz,
                                   1.0 if input_quantity == 'acceleration' else 0.0)
    length = choice.segment_length
    if length == config.segment_length:
        return config, ''
    # The long segment is dropped only when the chosen one reaches it; one the records cannot
    # hold stays, so that fit refuses it (a long segment left in the config was asked for:
    # the short-record fallback has already dropped the default one).
    long = config.long_segment_length if config.long_segment_length > length else 0
    return (dataclasses.replace(config, segment_length=length, long_segment_length=long),
            choice.note(fs_hz))


def fit_design(segments: Sequence[TrainingSegment], fs_hz: float, config: FitConfig,
               input_channels: Sequence[str], output_channels: Sequence[str],
               input_quantity: str = 'acceleration', fit_info: Optional[Mapping] = None,
               short_record_fallback: bool = False,
               segment_fallback: bool = False,
               choose_resolution: bool = False,
               long_window_fallback: Optional[bool] = None,
               cross_validate: bool = True,
               imposed: Iterable[str] = (),
               show_progress: bool = True) -> DesignedFit:
    """
    Fit a model as ``wheel-force fit`` does.

    Parameters
    ----------
    segments : sequence of TrainingSegment
        Gap-free segments (inputs in SI units of ``input_quantity``, forces [N]).
    fs_hz : float
        Sample rate [Hz].
    config : FitConfig
        Settings asked for (:func:`product_fit_config` for the defaults).
    input_channels, output_channels : sequence of str
        Channel names.
    input_quantity : str
        ``'acceleration'``, ``'velocity'`` or ``'displacement'`` (written to ``units``).
    fit_info : mapping, optional
        Provenance stored in the model's ``fit`` metadata.
    short_record_fallback : bool
        Allow the one-resolution fallback for records shorter than the long segment
        (generic recordings whose long segment the user did not choose).
    segment_fallback : bool
        Allow a shorter Welch segment when the records hold no more windows than inputs
        (generic recordings whose segment length the user did not choose).
    choose_resolution : bool
        Choose the Welch segment (the asked-for length times a power of two) by blocked
        cross-validation on the segments (:mod:`core.resolution`; generic recordings whose
        segment length the user did not choose).  Segments shorter than the chosen length
        are then left out and listed, as shorter than the asked-for one always are.
    long_window_fallback : bool, optional
        Allow the one-resolution fallback when the records hold no more windows of the long
        segment than inputs (bags and generic recordings whose long segment the user did not
        choose); None = as ``short_record_fallback``.
    cross_validate : bool
        Choose each output's design by blocked cross-validation
        (:func:`cross_validated_fit`); records too short for it are fitted with ``config``
        alone, and ``note`` says so naming them.
    imposed : iterable of str
        Fit settings the user chose (params file or command line): the search keeps them.
    show_progress : bool
        The search's progress bars on a terminal (:func:`progress`); False for a library
        caller that prints nothing by default (the diagnosis).

    Returns
    -------
    DesignedFit

    Raises
    ------
    InsufficientDataError
        No segment holds one Welch segment (the longest ones named), or (without the
        fallback) none holds the long segment.

    """
    imposed = frozenset(imposed)
    used, skipped = [], []
    for seg in segments:
        n = seg.accel_mps2.shape[1]
        if n >= config.segment_length:
            used.append(seg)
        else:
            skipped.append(f'{seg.source}: {n} samples < segment length '
                           f'{config.segment_length}')
    if not used:
        detail = '; '.join(skipped[:3]) + (' ...' if len(skipped) > 3 else '')
        raise InsufficientDataError(
            f'no recording holds one Welch segment of {config.segment_length} samples '
            f'({config.segment_length / fs_hz:g} s at {fs_hz:g} Hz): {detail}; for a coarser '
            f'frequency grid set a shorter segment N (N <= the record length): `fit '
            f'--segment-length N`, or `segment_length: N` under `wheel_force_fit` in the '
            f'--config params file (fit, diagnose)')
    notes = []
    if short_record_fallback:
        config, note = _short_record_fallback(config, used, fs_hz)
        notes.append(note)
    if short_record_fallback if long_window_fallback is None else long_window_fallback:
        config, note = _few_long_windows_fallback(
            config, used, fs_hz, _guarded_inputs(
                input_channels, cross_validate and INPUTS_KEY not in imposed))
        notes.append(note)
    if segment_fallback and not config.long_segment_length:
        config, note = _few_windows_fallback(config, used, fs_hz, len(input_channels))
        notes.append(note)
    if choose_resolution:
        config, note = _cross_validated(config, used, fs_hz, input_channels, output_channels,
                                        input_quantity)
        notes.append(note)
        short = [s for s in used if s.accel_mps2.shape[1] < config.segment_length]
        skipped.extend(f'{s.source}: {s.accel_mps2.shape[1]} samples < segment length '
                       f'{config.segment_length}' for s in short)
        used = [s for s in used if s.accel_mps2.shape[1] >= config.segment_length]
    model, warning, chosen = None, '', None
    if cross_validate:
        model, chosen = _cross_validated_model(used, fs_hz, config, input_channels,
                                               output_channels, input_quantity, fit_info,
                                               frozenset(imposed), show_progress)
        if model is None:
            warning = _too_short_note(used, fs_hz, config)
    note = '\n'.join(n for n in notes if n)
    if model is None:
        model = fit_model(used, fs_hz, config, input_channels, output_channels,
                          fit_info=fit_info, input_quantity=input_quantity)
    model = dataclasses.replace(model, units=model_units(input_channels, output_channels,
                                                         input_quantity))
    if warning:
        model = dataclasses.replace(model, fit=dict(model.fit, design={
            'method': 'defaults', 'reason': warning}))
    return DesignedFit(model, config, tuple(used), tuple(skipped), note, warning, chosen)


def model_units(input_channels, output_channels, input_quantity: str) -> dict:
    """
    Return a model's ``units``: one per side, plus one per channel for spindle channels.

    Spindle models (every channel a package channel: accelerations, angular rates, spin,
    forces, moments) list each channel's unit (schema 3), so a model with rates or moments
    says so channel by channel; generic models keep one unit per side.
    """
    units = {'input': INPUT_UNITS[input_quantity], 'output': 'N'}
    names = tuple(input_channels) + tuple(output_channels)
    if all(n in CHANNEL_UNITS for n in names):
        units['input_channels'] = [CHANNEL_UNITS[n] for n in input_channels]
        units['output_channels'] = [CHANNEL_UNITS[n] for n in output_channels]
    return units


def _too_short_note(used, fs_hz: float, config: FitConfig) -> str:
    """Say which recordings were too short to cross-validate and what was fitted instead."""
    total = sum(s.accel_mps2.shape[1] for s in used)
    names = ', '.join(f'{s.source} ({s.accel_mps2.shape[1] / fs_hz:.1f} s)' for s in used[:4])
    more = f' and {len(used) - 4} more' if len(used) > 4 else ''
    return (f'note: {names}{more}: {total / fs_hz:.1f} s in all is too short to '
            f'cross-validate the design ({N_BLOCKS} blocks of two '
            f'{max(MIN_SCORING_SEGMENT, config.segment_length)}-sample windows each at '
            f'least); fitted with the documented defaults (H1, segment '
            f'{config.segment_length}, long segment {config.long_segment_length or "off"}).')


def _cross_validated_model(used, fs_hz, config, input_channels, output_channels,
                           input_quantity, fit_info, imposed, show_progress=True):
    """Return the cross-validated model and its design (``None``: records too short)."""
    for seg in used:
        as_signals(seg.accel_mps2, f'accelerations of {seg.source}', input_channels)
        as_signals(seg.force_n, f'forces of {seg.source}', output_channels)
    order = QUANTITIES.index(input_quantity)
    searched = search(used, fs_hz, config, input_channels, order, imposed,
                      progress if show_progress else _silent, output_channels)
    if searched is None:
        return None, None
    chosen = ChosenDesign(*searched, order)
    return chosen.fit(used, fs_hz, config, input_channels, output_channels, fit_info), chosen


def _silent(iterable, desc: str):
    return iterable


def progress(iterable, desc: str):
    """Wrap ``iterable`` in a tqdm bar when stderr is a terminal (long fits)."""
    if not sys.stderr.isatty():
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, leave=False)
