# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
One model from the output rows of several: each force channel from the model that predicts it best.

Every output row of a MIMO FRF is its own least-squares problem (the H1 estimate of row ``o``
is ``S_yo,x S_xx^-1``; the FIR of row ``o`` touches no other output), so a model whose rows
come from different fits of the same inputs predicts every channel exactly as the model the
row came from.  Prediction runs the FIR taps only, so rows of shorter filters are embedded in
the longest one with their lag zero aligned (the added taps are zeros: the same filter).  The
FRF estimate and coherences of such a row are interpolated onto the longest filter's
frequency lines (they are descriptions of the fit, not used to predict).  Rows of a model
with fewer inputs (the 12 accelerations, where another model adds the traction/braking split
after them) are embedded the same way: their inputs must be the first of the widest model's,
and the added inputs get zero taps (:func:`widened`).  The static operating point is the one
subtlety: a model subtracts its own mean input ``static_accel_mps2``
before the filter, so a row taken from another model gets its static force corrected by the
row's DC gain times the difference of the two operating points, which keeps its prediction of
a constant input unchanged.
"""
from dataclasses import replace
from typing import Mapping, Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import ConfigError


def _interp(f_to, f_from, values):
    """Linear interpolation along axis 0 (complex-safe) onto ``f_to``."""
    flat = values.reshape(values.shape[0], -1)
    cols = [np.interp(f_to, f_from, flat[:, j].real) for j in range(flat.shape[1])]
    if np.iscomplexobj(values):
        cols = [c + 1j * np.interp(f_to, f_from, flat[:, j].imag) for j, c in enumerate(cols)]
    return np.stack(cols, axis=1).reshape((f_to.size,) + values.shape[1:])


#: Fields that describe each output row on the frequency lines (axis 0 lines, axis 1 outputs).
_PER_ROW = ('h', 'coherence_ordinary', 'coherence_multiple')


def _longest(models):
    return max(models, key=lambda m: m.fir_taps.shape[2])


def _widest(models):
    return max(models, key=lambda m: len(m.input_channels))


def _units_in(model, frame) -> dict:
    """Return ``model.units`` with ``frame``'s per-channel units of the inputs it lacks."""
    units = dict(model.units)
    n_in = len(model.input_channels)
    if 'input_channels' in units and 'input_channels' in frame.units:
        units['input_channels'] = (list(units['input_channels'])
                                   + list(frame.units['input_channels'])[n_in:])
    return units


def widened(model, frame):
    """
    Return ``model`` taking the inputs of ``frame``: zero taps on the inputs it lacks.

    ``model``'s inputs must be the first of ``frame``'s (:func:`compatible`).  The added
    inputs' operating point is ``frame``'s, their FRF and ordinary coherence zero; the
    prediction is ``model``'s for any values of them.  Live estimators are dropped (they take
    ``model``'s inputs).
    """
    n_in, n_frame = len(model.input_channels), len(frame.input_channels)
    if n_in == n_frame:
        return model

    def pad(values):
        out = np.zeros(values.shape[:-1] + (n_frame,), dtype=values.dtype)
        out[..., :n_in] = values
        return out
    taps = np.asarray(model.fir_taps)
    wide_taps = np.zeros((taps.shape[0], n_frame, taps.shape[2]), dtype=taps.dtype)
    wide_taps[:, :n_in] = taps
    static = np.concatenate([np.asarray(model.static_accel_mps2, dtype=np.float64),
                             np.asarray(frame.static_accel_mps2, dtype=np.float64)[n_in:]])
    return replace(model, input_channels=tuple(frame.input_channels),
                   h=pad(np.asarray(model.h)),
                   coherence_ordinary=pad(np.asarray(model.coherence_ordinary)),
                   fir_taps=wide_taps, static_accel_mps2=static,
                   units=_units_in(model, frame), live=())


def compatible(models: Sequence) -> Tuple[bool, str]:
    """Return ``(True, '')`` when rows of ``models`` can be combined, else False and why."""
    first = models[0]
    frame = tuple(_widest(models).input_channels)
    base = _longest(models)
    lead, tail = base.fir_delay_samples, base.fir_taps.shape[2] - base.fir_delay_samples
    for m in models[1:]:
        if m.fs_hz != first.fs_hz:
            return False, f'sample rates {first.fs_hz:g} and {m.fs_hz:g} Hz'
        if m.output_channels != first.output_channels:
            return False, 'different output channels'
    for m in models:
        if tuple(m.input_channels) != frame[:len(m.input_channels)]:
            return False, (f'inputs {list(m.input_channels)} are not the first of '
                           f'{list(frame)}')
    wide = _widest(models)
    for m in models:
        # a model of fewer inputs declares none for those it lacks: they are the widest's
        if _units_in(m, wide) != dict(wide.units):
            return False, 'different units'
    for m in models:
        if m.fir_delay_samples > lead or m.fir_taps.shape[2] - m.fir_delay_samples > tail:
            return False, (f'a FIR of {m.fir_taps.shape[2]} taps with lag zero at '
                           f'{m.fir_delay_samples} does not fit in the longest one '
                           f'({base.fir_taps.shape[2]} taps, lag zero at {lead})')
    return True, ''


def compose_rows(models: Sequence, source: Sequence[int], physics: Sequence[Mapping],
                 fit: Mapping) -> object:
    """
    Return a model whose output row ``o`` is row ``o`` of ``models[source[o]]``.

    Parameters
    ----------
    models : sequence of FrfModel
        Models of the same outputs, whose inputs are the first of the widest one's
        (:func:`compatible`).
    source : sequence of int
        Per output channel, the index of the model its row comes from.
    physics : sequence of mapping
        Physics terms of the result (``PhysicsTerm.to_dict()`` form).
    fit : mapping
        The result's ``fit`` metadata.

    Returns
    -------
    FrfModel
        The widest model's inputs; the longest filter's realisation, frequency lines,
        operating point and input condition numbers; no live estimators (``fit`` designs
        them for one FIR).

    Raises
    ------
    ConfigError
        Incompatible models or a bad ``source``.

    """
    ok, why = compatible(models)
    if not ok:
        raise ConfigError(f'cannot combine model rows: {why}')
    src = np.asarray(source, dtype=np.int64)
    no = len(models[0].output_channels)
    if src.shape != (no,) or src.min() < 0 or src.max() >= len(models):
        raise ConfigError(f'row sources must be {no} indices below {len(models)}, got '
                          f'{list(source)}')
    frame = _widest(models)
    models = [widened(m, frame) for m in models]
    base = _longest(models)
    f_hz = np.asarray(base.f_hz)
    # the frequency descriptions of each row (FRF estimate, coherences), per output on axis 1
    described = {name: np.array(getattr(base, name)) for name in _PER_ROW}
    taps = np.array(base.fir_taps)
    static_force = np.array(base.static_force_n, dtype=np.float64)
    for o, k in enumerate(src.tolist()):
        m = models[k]
        if m is base:
            continue
        same_lines = m.f_hz.shape == f_hz.shape and np.array_equal(m.f_hz, f_hz)
        for name, values in described.items():
            row = getattr(m, name)[:, o]
            values[:, o] = row if same_lines else _interp(f_hz, m.f_hz, row)
        at = base.fir_delay_samples - m.fir_delay_samples
        taps[o] = 0.0
        taps[o, :, at:at + m.fir_taps.shape[2]] = m.fir_taps[o]
        # the row's response to a constant input stays what it was in its own model
        dc_gain = m.fir_taps[o].sum(axis=1)
        static_force[o] = m.static_force_n[o] + float(
            dc_gain @ (np.asarray(base.static_accel_mps2) - np.asarray(m.static_accel_mps2)))
    return replace(base, **described, fir_taps=taps, static_force_n=static_force,
                   physics=tuple(dict(p) for p in physics), fit=dict(fit), live=())
