# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Plain-text and markdown tables of evaluation results (paper Tables 2 and 3).

Every table is built once as a header plus rows of already formatted cells and rendered by one
of two writers: aligned plain text for the terminal, or a GitHub markdown pipe table for
``report.md`` (``markdown=True``).  Numbers are formatted here, in one place, so the terminal,
the report and the tests agree character for character:

- RMSE in percent with one decimal (``21.3``), as in paper Table 2;
- pseudo damage in scientific notation with three significant digits (``2.78e+17``), as in
  paper Table 3;
- damage ratio prediction / target with two decimals plus Andrew's verdict (``good`` inside
  0.5-2, else ``low`` / ``high``).
"""
import math
from typing import Mapping, Sequence

import numpy as np

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import NonFiniteError
from wheel_force_estimator.core.errors import ShapeError

# Paper rubric: perfect < 25 %, great < 50, good < 75, bad < 100, else not_qualified.  Kept in
# step with core.metrics.rubric (test_report checks the two agree when core.metrics exists).
RUBRIC_NAMES = ('perfect', 'great', 'good', 'bad', 'not_qualified')
RUBRIC_UPPER_PCT = (25.0, 50.0, 75.0, 100.0)
RUBRIC_RANGES = ('0-25 %', '25-50 %', '50-75 %', '75-100 %', '>= 100 %')

# Andrew's criterion quoted by the paper: prediction / target damage within 0.5-2 is 'good'.
DAMAGE_RATIO_GOOD = (0.5, 2.0)


def rubric_index(pct) -> np.ndarray:
    """
    Return the rubric level index (0 = perfect ... 4 = not_qualified) of RMSE values.

    Parameters
    ----------
    pct : array_like
        RMSE in percent, finite and >= 0.

    Returns
    -------
    numpy.ndarray of int, same shape as ``pct``

    """
    # right=False: a value equal to an upper bound belongs to the next (worse) level.
    return np.digitize(np.asarray(pct, dtype=np.float64), RUBRIC_UPPER_PCT, right=False)


def check_values(values, name: str, shape: tuple, dtype=np.float64) -> np.ndarray:
    """
    Return ``values`` as a finite array of exactly ``shape``.

    Parameters
    ----------
    values : array_like
        The numbers to check.
    name : str
        Argument name used in the error messages.
    shape : tuple of int
        Required shape.
    dtype : numpy dtype
        float64 by default; complex128 for FRFs.

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    ShapeError
        Wrong shape.
    NonFiniteError
        NaN or infinity (the first offending index is named).

    """
    arr = np.asarray(values, dtype=dtype)
    if arr.shape != tuple(shape):
        raise ShapeError(f'{name}: expected shape {tuple(shape)}, got {arr.shape}')
    finite = np.isfinite(arr)
    if not finite.all():
        idx = tuple(int(i) for i in np.argwhere(~finite)[0])
        raise NonFiniteError(f'{name}: non-finite value {arr[idx].item()!r} at index {idx}')
    return arr


def check_names(names, name: str) -> tuple:
    """
    Return ``names`` as a non-empty tuple of unique strings.

    Raises
    ------
    ShapeError
        Empty, not strings, or duplicated names.

    """
    if isinstance(names, str):
        raise ShapeError(f'{name}: expected a sequence of names, got the string {names!r}')
    out = tuple(names)
    if not out:
        raise ShapeError(f'{name}: no names given')
    for item in out:
        if not isinstance(item, str) or not item:
            raise ShapeError(f'{name}: every name must be a non-empty string, got {item!r}')
    if len(set(out)) != len(out):
        dup = sorted({n for n in out if out.count(n) > 1})
        raise ShapeError(f'{name}: duplicated names {dup}')
    return out


def render(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool],
           markdown: bool = False) -> str:
    """
    Render formatted cells as an aligned text table or a markdown pipe table.

    Parameters
    ----------
    header : sequence of str
        Column titles.
    rows : sequence of sequence of str
        Already formatted cells, one sequence per row, ``len(header)`` cells each.
    numeric : sequence of bool
        Per column: right-align (numbers) instead of left-align (names).
    markdown : bool
        Markdown pipe table instead of plain text.

    Returns
    -------
    str
        The table, one line per row plus the header rule, no trailing newline.

    """
    widths = [len(h) for h in header]
    for row in rows:
        if len(row) != len(header):
            raise ShapeError(f'table row {list(row)}: {len(row)} cells for {len(header)} columns')
        widths = [max(w, len(c)) for w, c in zip(widths, row)]

    def line(cells):
        padded = [c.rjust(w) if num else c.ljust(w)
                  for c, w, num in zip(cells, widths, numeric)]
        return ('| ' + ' | '.join(padded) + ' |') if markdown else '  '.join(padded).rstrip()

    if markdown:
        rule = '|' + '|'.join(('-' * (w + 1) + ':') if num else (':' + '-' * (w + 1))
                              for w, num in zip(widths, numeric)) + '|'
    else:
        rule = '  '.join('-' * w for w in widths)
    return '\n'.join([line(header), rule] + [line(r) for r in rows])


def _pct(value: float) -> str:
    return f'{value:.1f}'


def _sci(value: float) -> str:
    return f'{value:.2e}'


def _ratio_verdict(ratio: float) -> str:
    low, high = DAMAGE_RATIO_GOOD
    if ratio < low:
        return 'low'
    if ratio > high:
        return 'high'
    return 'good'


def rmse_table(channels: Sequence[str], rmse_pct, rmse_hp_pct, rubric: Sequence[str],
               markdown: bool = False) -> str:
    """
    Per-channel RMSE table with the paper's rubric.

    Parameters
    ----------
    channels : sequence of str
        Output channel names, e.g. ``OUTPUT_CHANNELS``.
    rmse_pct : array_like, shape (n_ch,)
        RMSE of the mean-removed signals in percent of the target RMS.
    rmse_hp_pct : array_like, shape (n_ch,) or None
        RMSE after the 1 Hz high-pass in percent; ``None`` leaves the column out.
    rubric : sequence of str, length n_ch
        Rubric level per channel (one of ``RUBRIC_NAMES``).
    markdown : bool
        Markdown pipe table instead of aligned plain text.

    Returns
    -------
    str

    Raises
    ------
    ShapeError
        A length differs from ``channels``.
    NonFiniteError
        NaN or infinity in the RMSE values.
    ConfigError
        Unknown rubric level.

    """
    names = check_names(channels, 'channels')
    n = len(names)
    rmse = check_values(rmse_pct, 'rmse_pct', (n,))
    hp = None if rmse_hp_pct is None else check_values(rmse_hp_pct, 'rmse_hp_pct', (n,))
    levels = tuple(rubric)
    if len(levels) != n:
        raise ShapeError(f'rubric: expected {n} levels (one per channel), got {len(levels)}')
    for ch, level in zip(names, levels):
        if level not in RUBRIC_NAMES:
            raise ConfigError(f'rubric: unknown level {level!r} for channel {ch}; '
                              f'expected one of {list(RUBRIC_NAMES)}')
    header = ['channel', 'RMSE %'] + ([] if hp is None else ['RMSE HP1 %']) + ['rubric']
    numeric = [False, True] + ([] if hp is None else [True]) + [False]
    rows = []
    for i, ch in enumerate(names):
        row = [ch, _pct(rmse[i])] + ([] if hp is None else [_pct(hp[i])]) + [levels[i]]
        rows.append(row)
    return render(header, rows, numeric, markdown)


def damage_table(channels: Sequence[str], target, prediction, ratio,
                 markdown: bool = False) -> str:
    """
    Pseudo damage of target and prediction per channel (paper Table 3).

    Parameters
    ----------
    channels : sequence of str
        Output channel names.
    target, prediction : array_like, shape (n_ch,)
        Pseudo damage (dimensionless, reference range 1 N at 1 cycle), >= 0.
    ratio : array_like, shape (n_ch,)
        Prediction / target damage, >= 0.  Passed in rather than recomputed so the table shows
        exactly the number the JSON output holds.  Where the target damage is exactly 0 the
        ratio is undefined: NaN or infinity is accepted there and printed as ``n/a``.
    markdown : bool
        Markdown pipe table instead of aligned plain text.

    Returns
    -------
    str

    Raises
    ------
    ShapeError
        A length differs from ``channels``.
    NonFiniteError
        NaN or infinity in the damage, or in a ratio whose target damage is not 0.
    ConfigError
        A negative damage or ratio.

    """
    names = check_names(channels, 'channels')
    n = len(names)
    arrays = {'target': check_values(target, 'target', (n,)),
              'prediction': check_values(prediction, 'prediction', (n,))}
    undefined = arrays['target'] == 0.0
    raw_ratio = np.asarray(ratio, dtype=np.float64)
    if raw_ratio.shape != (n,):
        raise ShapeError(f'ratio: expected shape {(n,)}, got {raw_ratio.shape}')
    arrays['ratio'] = check_values(np.where(undefined, 0.0, raw_ratio), 'ratio', (n,))
    for key, arr in arrays.items():
        if (arr < 0).any():
            i = int(np.argmax(arr < 0))
            raise ConfigError(f'{key}: negative value {arr[i].item()!r} for channel {names[i]}')
    header = ['ch', 'channel', 'target damage', 'prediction damage', 'pred/target',
              'verdict (0.5-2)']
    numeric = [True, False, True, True, True, False]
    rows = []
    for i, ch in enumerate(names):
        r = arrays['ratio'][i]
        rows.append([str(i + 1), ch, _sci(arrays['target'][i]), _sci(arrays['prediction'][i]),
                     'n/a' if undefined[i] else f'{r:.2f}',
                     'n/a' if undefined[i] else _ratio_verdict(r)])
    return render(header, rows, numeric, markdown)


def event_table(events: Sequence[str], channels: Sequence[str], values,
                markdown: bool = False) -> str:
    """
    RMSE (percent) per road event and channel (paper Table 2 layout: events as rows).

    Parameters
    ----------
    events : sequence of str
        Event names, one per row.
    channels : sequence of str
        Channel names, one per column.
    values : array_like, shape (n_events, n_ch)
        RMSE in percent.
    markdown : bool
        Markdown pipe table instead of aligned plain text.

    Returns
    -------
    str

    Raises
    ------
    ShapeError
        ``values`` does not match ``(len(events), len(channels))``.
    NonFiniteError
        NaN or infinity in ``values``.

    """
    ev = check_names(events, 'events')
    names = check_names(channels, 'channels')
    arr = check_values(values, 'values', (len(ev), len(names)))
    header = ['event'] + list(names)
    numeric = [False] + [True] * len(names)
    rows = [[e] + [_pct(v) for v in arr[i]] for i, e in enumerate(ev)]
    return render(header, rows, numeric, markdown)


def rubric_counts_table(counts: Mapping[str, int], markdown: bool = False) -> str:
    """
    How many channel/event results fall in each rubric level, with their share.

    Parameters
    ----------
    counts : mapping of str to int
        Rubric level -> count; missing levels count 0.
    markdown : bool
        Markdown pipe table instead of aligned plain text.

    Returns
    -------
    str
        Rows in rubric order; the share is rounded to whole percent as in paper Table 2
        (``59 (33%)`` there, ``59`` and ``33`` columns here), ``-`` when the total is 0.

    Raises
    ------
    ConfigError
        Unknown level or a negative / non-integer count.

    """
    for key, value in counts.items():
        if key not in RUBRIC_NAMES:
            raise ConfigError(f'counts: unknown rubric level {key!r}; '
                              f'expected one of {list(RUBRIC_NAMES)}')
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise ConfigError(f'counts: {key} must be a non-negative integer, got {value!r}')
    total = sum(int(v) for v in counts.values())
    header = ['rubric', 'RMSE range', 'count', 'share %']
    rows = []
    for level, span in zip(RUBRIC_NAMES, RUBRIC_RANGES):
        count = int(counts.get(level, 0))
        # Round half up so 12.5 % prints 13 like a person would, not banker's 12.
        share = '-' if total == 0 else str(math.floor(100.0 * count / total + 0.5))
        rows.append([level, span, str(count), share])
    return render(header, rows, [False, False, True, True], markdown)
