# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The live (causal) estimate in the offline commands: options, look-ahead, comparison.

``--causal`` means "what the node publishes": the model's live estimator at the configured
look-ahead (``--live-look-ahead-s``, else ``live_look_ahead_s`` of the params file's node
section, else 0.05 s), through the same :class:`~..core.predict.Predictor` the node uses.
``--causal-delay-samples N`` still selects a look-ahead in samples directly.  Which filter a
look-ahead gets is decided in one place, :func:`..core.predict.select_filter`; here it is
only announced (a model without a live estimator: a warning on stderr, like the node's).
"""
import argparse
import dataclasses
from pathlib import Path
import sys
from typing import Callable, List, Optional, Tuple

from wheel_force_estimator.core.errors import ConfigError


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
    from wheel_force_estimator.cli.common import UsageError
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


@dataclasses.dataclass(frozen=True)
class LiveComparison:
    """Offline and live evaluations of the same data, plus the look-ahead sweep."""

    offline: object
    live: object
    look_ahead_samples: int
    live_kind: str
    sweep: Tuple[Tuple[float, str, object], ...]   # (look-ahead [s], kind, Evaluation)


def _kind(model, delay: int) -> str:
    from wheel_force_estimator.core.live_estimator import find_live
    return 'live estimator' if find_live(model.live, delay) is not None else 'cut offline FIR'


def compare(model, evaluate: Callable[[Optional[int]], object], delay: int,
            offline=None) -> LiveComparison:
    """
    Evaluate offline, live at ``delay`` and every stored look-ahead (``evaluate(delay)``).

    A model without live estimators is swept with the cut offline FIR at the standard
    look-aheads it can cut to (and labelled so).
    """
    from wheel_force_estimator.core.live_estimator import look_ahead_samples
    from wheel_force_estimator.core.live_estimator import SWEEP_LOOK_AHEADS_S
    offline = evaluate(None) if offline is None else offline
    if model.live:
        delays = sorted(e.look_ahead_samples for e in model.live)
    else:
        delays = sorted({look_ahead_samples(s, model.fs_hz) for s in SWEEP_LOOK_AHEADS_S}
                        | {delay})
        delays = [d for d in delays if d <= model.fir_delay_samples]
    results = {d: evaluate(d) for d in delays}
    live = results[delay] if delay in results else evaluate(delay)
    sweep = tuple((d / model.fs_hz, _kind(model, d), results[d]) for d in delays)
    return LiveComparison(offline, live, delay, _kind(model, delay), sweep)


def comparison_json(cmp: LiveComparison, fs_hz: float) -> dict:
    """Return the ``live`` and ``look_ahead_sweep`` entries of ``evaluate --json``."""
    from wheel_force_estimator.report.live import direction_means
    ch = cmp.offline.channels
    return {
        'live': {'look_ahead_samples': cmp.look_ahead_samples,
                 'look_ahead_s': cmp.look_ahead_samples / fs_hz, 'estimator': cmp.live_kind,
                 'channels': cmp.live.to_json()['channels']},
        'look_ahead_sweep': [
            {'look_ahead_s': s, 'estimator': kind,
             'rmse_pct_mean': direction_means(ch, ev.rmse_pct),
             'rmse_hp1_pct_mean': direction_means(ch, ev.rmse_hp1_pct)}
            for s, kind, ev in cmp.sweep],
        'offline_rmse_pct_mean': direction_means(ch, cmp.offline.rmse_pct),
    }


def comparison_text(cmp: LiveComparison, fs_hz: float) -> str:
    """Return the terminal side-by-side table and the sweep."""
    from wheel_force_estimator.report.live import comparison_table
    from wheel_force_estimator.report.live import direction_means
    ms = 1e3 * cmp.look_ahead_samples / fs_hz
    lines = [f'offline (two-sided) vs live ({cmp.live_kind}, look-ahead {ms:.1f} ms):',
             comparison_table(cmp.offline, cmp.live, f'live {ms:.0f} ms'), '',
             'mean RMSE % per direction against look-ahead:']
    offline = direction_means(cmp.offline.channels, cmp.offline.rmse_pct)
    lines.append('  offline two-sided: ' + '  '.join(f'{k} {v:.1f}' for k, v in offline.items()))
    for s, kind, ev in cmp.sweep:
        means = direction_means(ev.channels, ev.rmse_pct)
        lines.append(f'  {1e3 * s:6.1f} ms ({kind}): '
                     + '  '.join(f'{k} {v:.1f}' for k, v in means.items()))
    return '\n'.join(lines)


def report_section(out, directory, cmp: LiveComparison, fs_hz: float, data: str) -> None:
    """Append the offline-vs-live section (table + look-ahead plot) to a report."""
    from wheel_force_estimator.report.live import comparison_table
    from wheel_force_estimator.report.live import direction_means
    from wheel_force_estimator.report.live import plot_accuracy_vs_look_ahead
    ms = 1e3 * cmp.look_ahead_samples / fs_hz
    out.heading('Offline vs live', 2)
    out.paragraph(f'{data}. Live = what the node publishes: the {cmp.live_kind} at a '
                  f'look-ahead of {cmp.look_ahead_samples} samples ({ms:.1f} ms); offline = the '
                  f'two-sided FIR of `predict`.')
    out.table(comparison_table(cmp.offline, cmp.live, f'live {ms:.0f} ms', markdown=True))
    ch = cmp.offline.channels
    groups: dict = {}
    for _, _, ev in cmp.sweep:
        for k, v in direction_means(ch, ev.rmse_pct).items():
            groups.setdefault(k, []).append(v)
    kinds = sorted({kind for _, kind, _ in cmp.sweep})
    out.image(plot_accuracy_vs_look_ahead(
        Path(directory) / 'accuracy_vs_look_ahead.png', [s for s, _, _ in cmp.sweep], groups,
        direction_means(ch, cmp.offline.rmse_pct), title=f'{" / ".join(kinds)}: accuracy '
        f'against look-ahead'), 'Mean RMSE % per direction against look-ahead (live) and '
        'the offline two-sided filter (dashed)')


def training_evaluator(model, segments: List, sn_slope: float = 5.0):
    """Return ``evaluate(delay)`` over fit training segments (no stamps: from 0 at fs)."""
    import numpy as np

    from wheel_force_estimator.core.evaluation import EvalSegment
    from wheel_force_estimator.core.evaluation import evaluate_segments
    from wheel_force_estimator.core.predict import predict_forces

    def evaluate(delay):
        evs = [EvalSegment(s.force_n, predict_forces(model, s.accel_mps2, delay),
                           (np.arange(s.force_n.shape[1]) * (1e9 / model.fs_hz)).astype(
                               np.int64), s.source) for s in segments]
        return evaluate_segments(evs, model.fs_hz, model.output_channels, sn_slope)
    return evaluate
