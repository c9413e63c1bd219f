# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Helpers shared by the offline subcommands: config files, progress, recordings.

Generic recordings (DAQ exports) are declared with the same three options in ``fit``,
``evaluate`` and ``diagnose``: :func:`add_generic_arguments` registers them and
:func:`generic_request` checks and parses them.  Misuse of the options (incomplete, bags and
generic files mixed, a bad ``--fs``) raises :class:`UsageError`, which ``main`` turns into
exit code 2 like an argparse error.
"""
import argparse
import dataclasses
import math
from pathlib import Path
import sys
from typing import Iterable, Optional, Sequence, Tuple

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator.bagio.topics import FIT_SECTION
from wheel_force_estimator.core.errors import ConfigError
import yaml
_FIT_KEYS = {
    'segment_length': int, 'overlap': float, 'window': str, 'detrend': str,
    'estimator': str, 'regularisation': float, 'f_min_hz': float, 'f_max_hz': float,
    'coherence_floor': float, 'long_segment_length': int, 'crossover_hz': float,
    'long_regularisation': float, 'water_level': float, 'unexcited': str,
}


def add_namespace_argument(parser: argparse.ArgumentParser) -> None:
    """Register ``--namespace NS`` (how relative topic names of ``--config`` resolve)."""
    parser.add_argument(
        '--namespace', default='/', metavar='NS',
        help='namespace the relative topic names (params file, defaults) resolve under, as '
             'for a node started with __ns:=NS; default /')


def topic_config(args: argparse.Namespace):
    """
    Return the resolved topic names of ``args.config`` under ``args.namespace``.

    Raises
    ------
    ConfigError
        Unreadable or invalid params file, or an invalid namespace.

    """
    from wheel_force_estimator.bagio import load_topic_config
    return load_topic_config(args.config, args.namespace)


def default_config_path() -> Optional[Path]:
    """Return the packaged ``config/wheel_force.yaml`` (source tree or ament share dir)."""
    here = Path(__file__).resolve().parents[2] / 'config' / 'wheel_force.yaml'
    if here.is_file():
        return here
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('wheel_force_estimator'))
    except (ImportError, LookupError, ValueError):
        return None
    cfg = share / 'config' / 'wheel_force.yaml'
    return cfg if cfg.is_file() else None


#: Keys of the fit section choosing the model's channels (six components, issue 33).
_CHANNEL_KEYS = ('inputs', 'moments')
#: Input groups a spindle model may declare beyond the 12 accelerations.
INPUT_GROUPS = ('rates', 'spin', 'split', 'cornering')
#: Of those, the groups read from a recording's topics (``split`` and ``cornering`` are
#: derived from the accelerations: core.derived).
READ_GROUPS = ('rates', 'spin')


@dataclasses.dataclass(frozen=True)
class FitChannels:
    """
    The channels ``fit`` gives a spindle model (params file, ``wheel_force_fit`` section).

    ``inputs``: ``"auto"`` (default: the angular rates and the spin where every training
    recording carries them, and the traction/braking and cornering splits, which every
    recording has) or a list among ``rates``, ``spin``, ``split``, ``cornering`` (``[]`` =
    the 12 accelerations only); a
    declared group that a recording lacks is an error naming its topic.  With ``"auto"``
    each output row takes the groups its blocked cross-validation chooses; a list imposes
    them on every row.  ``moments``: ``"auto"`` (fitted when every recording's WFT messages carry a
    torque), ``true`` (required) or ``false``.
    """

    inputs: Optional[Tuple[str, ...]] = None       # None = auto
    moments: Optional[bool] = None                 # None = auto

    def extras(self, available) -> Tuple[str, ...]:
        """Return the reader's extras for recordings that all carry ``available``."""
        groups = [g for g in READ_GROUPS
                  if (g in available if self.inputs is None else g in self.inputs)]
        if self.moments or (self.moments is None and 'moments' in available):
            groups.insert(0, 'moments')
        return tuple(groups)

    @property
    def split(self) -> bool:
        """Say if the model declares the traction/braking inputs (unless a list omits them)."""
        return self.inputs is None or 'split' in self.inputs

    @property
    def cornering(self) -> bool:
        """Say if the model declares the cornering inputs (unless a list omits them)."""
        return self.inputs is None or 'cornering' in self.inputs

    @property
    def derived(self) -> Tuple[str, ...]:
        """Return the inputs derived from the accelerations that the model declares."""
        from wheel_force_estimator.core.spindle import declared_inputs
        return declared_inputs(False, False, self.split, self.cornering)[
            len(INPUT_CHANNELS):]


def fit_channels(path) -> FitChannels:
    """
    Read the ``inputs`` and ``moments`` keys of the params file's fit section.

    Raises
    ------
    ConfigError
        A value of the wrong type or an unknown input group (file and key named).

    """
    if path is None:
        return FitChannels()
    try:
        doc = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f'{path}: cannot read params file: {err}') from err
    section = (doc.get(FIT_SECTION) or {}).get('ros__parameters') or {}
    inputs, moments = section.get('inputs', 'auto'), section.get('moments', 'auto')
    if inputs == 'auto':
        inputs = None
    elif not isinstance(inputs, list) or any(g not in INPUT_GROUPS for g in inputs):
        raise ConfigError(f'{path}: {FIT_SECTION}.inputs must be "auto" or a list among '
                          f'{list(INPUT_GROUPS)} (the 12 accelerations are always inputs), '
                          f'got {inputs!r}')
    else:
        inputs = tuple(inputs)
    if moments == 'auto':
        moments = None
    elif not isinstance(moments, bool):
        raise ConfigError(f'{path}: {FIT_SECTION}.moments must be "auto", true or false, '
                          f'got {moments!r}')
    return FitChannels(inputs, moments)


def _fit_section(path) -> dict:
    """Return the typed values of the params file's ``wheel_force_fit`` section."""
    values = {}
    if path is None:
        return values
    try:
        doc = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f'{path}: cannot read params file: {err}') from err
    section = (doc.get(FIT_SECTION) or {}).get('ros__parameters') or {}
    for key, value in section.items():
        if key in _CHANNEL_KEYS:
            continue  # the model's channels (fit_channels), not a FitConfig setting
        if key not in _FIT_KEYS:
            raise ConfigError(f'{path}: unknown key {FIT_SECTION}.{key} '
                              f'(known: {", ".join(sorted(_FIT_KEYS))})')
        try:
            values[key] = _FIT_KEYS[key](value)
        except (TypeError, ValueError) as err:
            raise ConfigError(f'{path}: {FIT_SECTION}.{key} = {value!r} is not a '
                              f'{_FIT_KEYS[key].__name__}') from err
    return values


def load_fit_config(path=None, **overrides):
    """
    Return the :class:`FitConfig` from the params YAML's ``wheel_force_fit`` section.

    Parameters
    ----------
    path : str or os.PathLike, optional
        Params file; ``None`` uses the built-in defaults.
    **overrides
        Values from the command line (``None`` values are ignored).

    Raises
    ------
    ConfigError
        Unreadable file, unknown key or a value of the wrong type (file and key named).
    UsageError
        A value outside its range (file, key and range named; ``main`` exits 2).

    """
    # What `wheel-force fit` uses when neither the params file nor the command line says
    # otherwise: one home, the fit design shared with the diagnosis.
    from wheel_force_estimator.core.design import PRODUCT_FIT_DEFAULTS
    from wheel_force_estimator.core.pipeline import FitConfig
    values = dict(PRODUCT_FIT_DEFAULTS)
    values.update(_fit_section(path))
    values.update({k: v for k, v in overrides.items() if v is not None})
    if values.get('f_max_hz') == 0.0:
        values['f_max_hz'] = None
    try:
        return FitConfig(**values)
    except ConfigError as err:
        # a value outside its range is a usage error (exit 2), named with its range
        raise UsageError(f'{path or "command line"}: {FIT_SECTION}: {err}') from err


def explicit_fit_keys(path=None, **overrides) -> frozenset:
    """
    Return the fit settings the user chose (params file or command line), not defaults.

    Raises
    ------
    ConfigError
        As :func:`load_fit_config`.

    """
    chosen = set(_fit_section(path))
    chosen.update(k for k, v in overrides.items() if v is not None)
    return frozenset(chosen)


def progress(iterable: Iterable, desc: str, total: Optional[int] = None):
    """Wrap ``iterable`` in a tqdm bar when stderr is a terminal, else return it unchanged."""
    if not sys.stderr.isatty():
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, unit='file', leave=False)


def read_recordings(paths, topics, require_wft: bool, expected_fs_hz: Optional[float] = None,
                    travel: bool = False, extras: Tuple[str, ...] = ()):
    """
    Read every recording (with a progress bar); return a list of ``Recording``.

    ``travel`` also reads the optional suspension travel topic, ``extras`` the six-component
    groups (``bagio.read_recording``).

    Raises
    ------
    BagError
        From the reader, naming the file and topic at fault; also when the recordings do not
        share one sample rate.

    """
    from wheel_force_estimator.bagio import read_recording
    from wheel_force_estimator.core.errors import BagError
    recordings = []
    for path in progress(paths, 'reading', total=len(paths)):
        recordings.append(read_recording(path, topics, require_wft=require_wft,
                                         expected_fs_hz=expected_fs_hz, travel=travel,
                                         extras=tuple(extras)))
    rates = [r.fs_hz for r in recordings]
    if rates and max(rates) > min(rates) * (1 + 1e-3):
        detail = ', '.join(f'{r.path}: {r.fs_hz:g} Hz' for r in recordings)
        raise BagError(f'recordings have different sample rates ({detail}); nothing is '
                       f'resampled — fit them separately')
    return recordings


def nominal_fs_hz(recordings) -> float:
    """Return the common sample rate of already-checked recordings [Hz]."""
    return float(recordings[0].fs_hz)


class UsageError(Exception):
    """Options that do not fit together; ``main`` reports it like argparse (exit code 2)."""


# Paths that are bags for sure (the generic reader decides about everything else).
_BAG_SUFFIXES = ('.bag', '.mcap', '.db3', '.yaml')


def add_generic_arguments(parser: argparse.ArgumentParser) -> None:
    """Register ``--input``, ``--output`` and ``--fs`` (generic recordings) on ``parser``."""
    g = parser.add_argument_group(
        'generic recordings (DAQ exports: .csv/.txt/.tsv, .mat, .npz, .json; one gap-free '
        'segment per file)')
    g.add_argument('--input', action='append', default=[], metavar='NAME:QUANTITY:UNIT',
                   help='input channel, e.g. disp:displacement:m, data[1]:displacement:in '
                        '(repeatable; quantity displacement, velocity or acceleration, the '
                        'same for all inputs)')
    g.add_argument('--output', action='append', default=[], metavar='NAME:force:UNIT',
                   help='force channel, e.g. force:force:N, data[2]:force:kip (repeatable)')
    g.add_argument('--fs', type=float, metavar='HZ', help='sample rate of the generic files')


@dataclasses.dataclass(frozen=True)
class GenericRequest:
    """
    The declared channels and sample rate of one call's generic recordings.

    Attributes
    ----------
    inputs, outputs : tuple of ChannelSpec
        Declared motion and force channels, in model order.
    fs_hz : float
        Sample rate of every file [Hz].

    Raises
    ------
    RecordingError
        An invalid set of channels (see ``daqio.check_specs``) or sample rate.

    """

    inputs: Tuple
    outputs: Tuple
    fs_hz: float

    def __post_init__(self):
        """Validate the channel set and the rate."""
        from wheel_force_estimator.core.errors import RecordingError
        from wheel_force_estimator.daqio import check_specs
        inputs, outputs = check_specs(self.inputs, self.outputs)
        if not (math.isfinite(self.fs_hz) and self.fs_hz > 0.0):
            raise RecordingError(f'sample rate must be a finite number > 0 Hz, '
                                 f'got {self.fs_hz!r}')
        object.__setattr__(self, 'inputs', inputs)
        object.__setattr__(self, 'outputs', outputs)
        object.__setattr__(self, 'fs_hz', float(self.fs_hz))

    @property
    def input_channels(self) -> Tuple[str, ...]:
        """Return the input channel names (spec labels)."""
        return tuple(s.label for s in self.inputs)

    @property
    def output_channels(self) -> Tuple[str, ...]:
        """Return the output channel names (spec labels)."""
        return tuple(s.label for s in self.outputs)

    @property
    def input_quantity(self) -> str:
        """Return the quantity shared by the inputs."""
        return self.inputs[0].quantity

    def read(self, paths: Sequence) -> list:
        """
        Read every file (with a progress bar); return a list of ``DaqRecording``.

        Raises
        ------
        RecordingError
            From the reader, naming the file and channel at fault.

        """
        from wheel_force_estimator.daqio import read_daq
        return [read_daq(path, self.inputs, self.outputs, self.fs_hz)
                for path in progress(paths, 'reading', total=len(paths))]


def generic_request(args: argparse.Namespace, *path_lists: Sequence) -> Optional[GenericRequest]:
    """
    Check the generic-recording options against the recordings of one call.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options (from a parser set up with :func:`add_generic_arguments`).
    *path_lists : sequence of str
        Every list of recordings of the call.

    Returns
    -------
    GenericRequest or None
        The declared channels when ``--input``/``--output``/``--fs`` are given, ``None`` for
        bags.

    Raises
    ------
    UsageError
        Options given only in part, ``--fs`` not a finite rate > 0, a generic file without
        the options, or a bag together with them.
    RecordingError
        A malformed spec or an invalid set of channels (a channel declared twice ...).

    """
    paths = [p for paths in path_lists for p in (paths or ())]
    given = {'--input': bool(args.input), '--output': bool(args.output),
             '--fs': args.fs is not None}
    if not any(given.values()):
        for path in paths:
            if _is_generic(path):
                raise UsageError(f'{path} is a generic recording: declare its channels with '
                                 f'--input, --output and --fs')
        return None
    if not all(given.values()):
        missing = ', '.join(k for k, v in given.items() if not v)
        raise UsageError(f'generic recordings need --input, --output and --fs '
                         f'(missing: {missing})')
    if not (math.isfinite(args.fs) and args.fs > 0.0):
        raise UsageError(f'--fs must be a finite sample rate > 0 Hz, got {args.fs:g}')
    for path in paths:
        if _is_bag(path):
            raise UsageError(f'{path} is a bag: bags and generic recordings (--input, '
                             f'--output, --fs) cannot be mixed in one call')
    from wheel_force_estimator.daqio import parse_spec
    return GenericRequest(tuple(parse_spec(s, 'input') for s in args.input),
                          tuple(parse_spec(s, 'output') for s in args.output), args.fs)


def _is_generic(path) -> bool:
    from wheel_force_estimator.daqio import is_generic_path
    return is_generic_path(path) and not Path(path).is_dir()


def _is_bag(path) -> bool:
    p = Path(path)
    return p.is_dir() or p.suffix.lower() in _BAG_SUFFIXES


def check_bag_model(model, model_path):
    """
    Refuse a model that cannot be applied to the spindle accelerations of a bag.

    The rule is :func:`wheel_force_estimator.core.spindle.spindle_layout`, the one the live
    node applies.

    Returns
    -------
    SpindleLayout
        Where the forces (and moments, if any) are in the model's output.

    Raises
    ------
    ModelFileError
        The model's channels or units do not fit (e.g. a model fitted on generic recordings).

    """
    from wheel_force_estimator.core.spindle import spindle_layout
    return spindle_layout(model, str(model_path))


# --------------------------------------------------------------- --causal options
# ``--causal`` means "what the node publishes": the model's live estimator at the configured
# look-ahead, through the same Predictor the node uses.  Which filter a look-ahead gets is
# decided in one place, core.predict.select_filter; here it is only announced.

def add_causal_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """Register ``--causal``, ``--live-look-ahead-s`` and ``--causal-delay-samples``."""
    parser.add_argument('--causal', action='store_true',
                        help=f'{what} the live (causal) estimate the node publishes: the '
                             "model's live estimator at the configured look-ahead")
    parser.add_argument('--live-look-ahead-s', type=float, metavar='S',
                        help='look-ahead of the live estimate [s] (implies --causal; default: '
                             'live_look_ahead_s of the params file, else 0.05)')
    parser.add_argument('--causal-delay-samples', type=int, metavar='N',
                        help='look-ahead of the live estimate in samples (implies --causal)')


def configured_look_ahead_s(config_path=None, override: Optional[float] = None) -> float:
    """
    Return the live look-ahead [s]: ``override``, else the params file's, else the default.

    Raises
    ------
    ConfigError
        Unreadable params file or a value that is not a number >= 0 (file and key named).

    """
    from wheel_force_estimator.bagio.topics import node_parameters
    from wheel_force_estimator.core.live_estimator import DEFAULT_LIVE_LOOK_AHEAD_S
    value, where = override, '--live-look-ahead-s'
    if value is None and config_path is not None:
        # The node reads the same sections with the same precedence (bagio.topics).
        params, sections = node_parameters(config_path)
        if 'live_look_ahead_s' in params:
            value = params['live_look_ahead_s']
            where = f'{config_path}: {sections}.ros__parameters.live_look_ahead_s'
    if value is None:
        return DEFAULT_LIVE_LOOK_AHEAD_S
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0.0:
        raise ConfigError(f'{where} = {value!r}: expected a look-ahead >= 0 s')
    return float(value)


def causal_delay(args: argparse.Namespace, fs_hz: float) -> Optional[int]:
    """Return the requested look-ahead [samples], or ``None`` for the two-sided filter."""
    from wheel_force_estimator.core.live_estimator import look_ahead_samples
    if args.causal_delay_samples is not None:
        if args.live_look_ahead_s is not None:
            raise UsageError('give --causal-delay-samples or --live-look-ahead-s, not both')
        return args.causal_delay_samples
    if args.causal or args.live_look_ahead_s is not None:
        return look_ahead_samples(
            configured_look_ahead_s(getattr(args, 'config', None), args.live_look_ahead_s),
            fs_hz)
    return None


def announce(model, model_path, delay: Optional[int]) -> Optional[str]:
    """
    Say which filter a look-ahead gets; return the fallback message, if any.

    Raises
    ------
    ConfigError
        A look-ahead the model's live estimators were not fitted for (as the node).

    """
    from wheel_force_estimator.core.live_estimator import find_live
    from wheel_force_estimator.core.predict import select_filter
    _, fallback = select_filter(model, delay)
    if delay is None:
        return None
    ms = 1e3 * delay / model.fs_hz
    if fallback:
        print(f'warning: {model_path}: {fallback}', file=sys.stderr)
    elif delay != model.fir_delay_samples:
        est = find_live(model.live, delay)
        print(f'live estimator: look-ahead {delay} samples ({ms:.1f} ms), '
              f'{est.info.get("method", "?")}, history {est.history_samples / model.fs_hz:.2f} s')
    return fallback
