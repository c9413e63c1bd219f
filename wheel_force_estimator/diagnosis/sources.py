# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Which input drives an output's physics, when several inputs carry no vehicle names.

:func:`features.pairing` picks the input that explains an output best *linearly*; a nonlinear
element may hang on another one (a rig whose reaction force is dominated by actuator A while
a stop or friction acts on actuator B's stroke).  :func:`sources_by_selection` lets the
selection itself choose.
"""
import sys

from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.prepared import prepare
from wheel_force_estimator.diagnosis.selection import Selector


def sources_by_selection(prep, sim_prep, reference, sources, outcomes, config, companions,
                         candidates):
    """
    Return the input that drives each output's physics, chosen by the selection itself.

    For every input other than an output's coherence pick (``sources``) the same selection
    runs with that input's features; an output takes the input whose accepted terms leave
    the lowest cross-validated RMSE (its outcome then replaces the one in ``outcomes``, which
    is updated in place), and keeps the coherence pick when no other input's terms pass the
    selection's tests or none does better.  Cost: one selection per input (``prep`` and
    ``sim_prep``, the :class:`Prepared` real and simulation records of the coherence pick,
    lend their reference predictions).
    """
    real, sim = prep.recordings, (sim_prep.recordings if sim_prep is not None else ())
    rec0 = real[0]
    channels = rec0.output_channels
    n_out = len(channels)
    chosen = list(sources)
    inputs = rec0.input_channels
    if config.progress and sys.stderr.isatty():
        from tqdm import tqdm
        inputs = tqdm(inputs, desc='physics on each input', unit='input', leave=False)
    for inp in inputs:
        todo = [o for o in range(n_out) if sources[o] != inp]
        if not todo:
            continue
        alt = (inp,) * n_out
        alt_prep = prepare(real, reference, alt, (None,) * n_out, config,
                           prep.full_predictions)
        alt_sim = (prepare(sim, reference, alt, (None,) * n_out, config,
                           sim_prep.full_predictions) if sim else None)
        for o in todo:
            ch = channels[o]
            out = Selector(pieces(alt_prep, o, ch), config.selection, companions,
                           pieces(alt_sim, o, ch) if alt_sim else None).run(candidates)
            best = outcomes[ch]
            if out.accepted and out.cv_after_pct < (best.cv_after_pct if best.accepted
                                                    else best.cv_before_pct):
                outcomes[ch] = out
                chosen[o] = inp
    return tuple(chosen)
