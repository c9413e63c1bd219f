# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Compose the ``fit`` and ``evaluate`` reports from the plot and table functions.

Any channel count works.  Each output is paired with one input for the "same-axis" curves
(ordinary coherence, FRF magnitude under the ASD): by vehicle names (``lf_fx`` <-
``lf_ax``), else input ``k`` for output ``k`` when the counts agree, else the single input;
without such a pairing those curves are left out.  Vehicle models get the per-axis FRF
diagonal plot, other models the FRF of every input-output pair.  Units come from the model.
"""
from pathlib import Path
from typing import List, Optional

import numpy as np

from wheel_force_estimator import MOMENT_CHANNELS
from wheel_force_estimator import RATE_CHANNELS
from wheel_force_estimator import SPIN_ACCEL_CHANNELS
from wheel_force_estimator.report import tables
from wheel_force_estimator.report.evaluation_plots import plot_damage_ratio
from wheel_force_estimator.report.evaluation_plots import plot_relative_damage_spectrum
from wheel_force_estimator.report.evaluation_plots import plot_rmse_colormap
from wheel_force_estimator.report.evaluation_plots import plot_time_overlay
from wheel_force_estimator.report.figures import channel_unit
from wheel_force_estimator.report.figures import ratio_unit
from wheel_force_estimator.report.markdown import ReportWriter
from wheel_force_estimator.report.spectral_plots import plot_asd
from wheel_force_estimator.report.spectral_plots import plot_coherence
from wheel_force_estimator.report.spectral_plots import plot_condition_number
from wheel_force_estimator.report.spectral_plots import plot_frf_diagonal
from wheel_force_estimator.report.spectral_plots import plot_frf_matrix
from wheel_force_estimator.report.spectral_plots import same_axis_pairs


def evaluation_text(evaluation) -> str:
    """Return the terminal summary of an evaluation (RMSE table, rubric counts, damage)."""
    from wheel_force_estimator.core.metrics import rubric
    names = evaluation.channels
    lines = ['RMSE % per channel (unfiltered / 1 Hz high-passed):',
             tables.rmse_table(names, evaluation.rmse_pct, evaluation.rmse_hp1_pct,
                               [rubric(float(v)) for v in evaluation.rmse_pct]),
             'rubric counts: ' + ', '.join(f'{k} {v}'
                                           for k, v in evaluation.rubric_counts().items()),
             '',
             f'pseudo damage (rainflow, Basquin k = {evaluation.sn_slope:g}, Miner):',
             tables.damage_table(names, evaluation.damage_target, evaluation.damage_prediction,
                                 evaluation.damage_ratio)]
    if evaluation.events:
        events = sorted(evaluation.events)
        values = np.array([evaluation.events[e]['rmse_pct'] for e in events])
        lines += ['', 'RMSE % per road event:', tables.event_table(events, names, values)]
    return '\n'.join(lines)


def paired_inputs(input_channels, output_channels) -> Optional[List[int]]:
    """Return the input index paired with each output (see the module notes), or None."""
    n_in, n_out = len(input_channels), len(output_channels)
    pairs = same_axis_pairs(tuple(input_channels), tuple(output_channels))
    if len(pairs) == n_out:
        return [i for _, i in pairs]
    if n_in == n_out:
        return list(range(n_out))
    if n_in == 1:
        return [0] * n_out
    return None


def output_units(model) -> List[str]:
    """Return the unit of each output: from vehicle names (N, N·m), else the model's."""
    fallback = str(model.units.get('output', 'N'))
    return [channel_unit(c) if channel_unit(c) != '-' else fallback for c in model.output_channels]


#: Mean multiple coherence (0.5-50 Hz) below which a moment is reported as not identifiable
#: from the inputs the recordings have: less than half its power is linearly explained.
IDENTIFIABLE_COHERENCE = 0.5


def moment_input_lines(model, summary) -> List[str]:
    """
    Say which inputs a six-component model's moments were given, and which they cannot explain.

    With more than one input set searched, the set each moment's row chose is listed too.

    A moment whose mean multiple coherence (0.5-50 Hz) is below
    :data:`IDENTIFIABLE_COHERENCE` is named as not identifiable from these inputs (``My``
    needs the wheel spin rate or drive/brake torque information).  Empty without moments.
    """
    moments = [c for c in model.output_channels if c in MOMENT_CHANNELS]
    if not moments:
        return []
    groups = ['12 accelerations']
    if any(c in RATE_CHANNELS for c in model.input_channels):
        groups.append('12 angular rates')
    if any(c in SPIN_ACCEL_CHANNELS for c in model.input_channels):
        groups.append('4 spin accelerations (from the spin rates)')
    lines = [f'moments fitted from: {", ".join(groups)}']
    design = model.fit.get('design') or {}
    if len(design.get('input_sets') or ()) > 1:
        # each row's own set, chosen by cross-validation (the groups above are the offer)
        chosen: dict = {}
        for name in moments:
            row = design['rows'].get(name) or {}
            chosen.setdefault(row.get('inputs', '?'), []).append(name)
        lines.append('  input set chosen per moment (held-out blocks): ' + '; '.join(
            f'{k}: {", ".join(v)}' for k, v in chosen.items()))
    header = len(lines)
    for name in moments:
        coh = summary['mean_coherence'][name]
        if coh < IDENTIFIABLE_COHERENCE:
            need = (' (My needs the wheel spin rate or drive/brake torque information)'
                    if name.endswith('_my') else '')
            lines.append(f'  {name}: NOT identifiable from these inputs: mean multiple '
                         f'coherence {coh:.2f} < {IDENTIFIABLE_COHERENCE}{need}')
    if len(lines) == header:
        lines.append(f'  every moment has a mean multiple coherence >= {IDENTIFIABLE_COHERENCE}')
    return lines


def write_fit_report(directory, model, summary, extra=None) -> Path:
    """
    Write the fit report (coherence, FRF, condition number); return report.md.

    ``extra(writer, directory)``, when given, appends more sections (the live comparison).
    """
    out = ReportWriter(directory)
    d = Path(directory)
    paired = paired_inputs(model.input_channels, model.output_channels)
    diag = None if paired is None else np.stack(
        [model.coherence_ordinary[:, o, i] for o, i in enumerate(paired)], axis=1)
    out.heading('FRF fit', 1)
    out.paragraph(
        f'{len(model.fit.get("segments", []))} segment(s), '
        f'{model.fit.get("total_duration_s", 0):.1f} s at {model.fs_hz:g} Hz; '
        f'{len(model.input_channels)} input(s) [{model.units.get("input", "m/s^2")}] -> '
        f'{len(model.output_channels)} output(s) [{model.units.get("output", "N")}]; '
        f'estimator `{model.estimator}`, segment length {model.fit.get("segment_length")}, '
        f'{model.fit.get("n_windows")} windows averaged.')
    out.heading('Coherence', 2)
    out.image(plot_coherence(d / 'coherence.png', model.f_hz, model.coherence_multiple,
                             diag, model.output_channels),
              'Multiple coherence per output and ordinary coherence of the paired input')
    rows = '\n'.join(f'| {n} | {summary["mean_coherence"][n]:.3f} | '
                     + (', '.join(f'{a:.1f}-{b:.1f}' for a, b in summary['low_bands_hz'][n])
                        or '-') + ' |'
                     for n in model.output_channels)
    out.table('| output | mean multiple coherence 0.5-50 Hz | bands < 0.5 [Hz] |\n'
              '|---|---|---|\n' + rows)
    moments = moment_input_lines(model, summary)
    if moments:
        out.heading('Moments: inputs and identifiability', 2)
        out.paragraph('\n'.join(f'- {line.strip()}' for line in moments))
    if same_axis_pairs(model.input_channels, model.output_channels):
        out.heading('FRF diagonal', 2)
        out.image(plot_frf_diagonal(d / 'frf_diagonal.png', model.f_hz, model.h,
                                    model.input_channels, model.output_channels),
                  'Same-axis FRF per corner: magnitude and phase')
    else:
        out.heading('FRF', 2)
        out.image(plot_frf_matrix(d / 'frf.png', model.f_hz, model.h, model.input_channels,
                                  model.output_channels,
                                  input_unit=model.units.get('input', 'm/s^2'),
                                  output_unit=model.units.get('output', 'N')),
                  'FRF of every input-output pair: magnitude and phase')
    out.heading('Conditioning', 2)
    out.image(plot_condition_number(d / 'condition_number.png', model.f_hz,
                                    model.cond_sxx),
              'Condition number of the input cross-spectral matrix')
    _design_section(out, d, model)
    if extra is not None:
        extra(out, d)
    return out.write()


def _design_section(out: ReportWriter, d: Path, model) -> None:
    """Write how the design was chosen: each output's choice, every candidate, a plot."""
    from wheel_force_estimator.core.search import other_set_folds
    from wheel_force_estimator.report.design_plots import design_tables
    from wheel_force_estimator.report.design_plots import plot_design_scores
    design = model.fit.get('design') or {}
    out.heading('Design', 2)
    if design.get('method') != 'blocked_cross_validation':
        out.paragraph(design.get('reason') or 'The design was not cross-validated.')
        return
    imposed = ', '.join(f'`{k}`' for k in design['imposed']) or 'none'
    out.paragraph(
        f'Chosen per output by blocked cross-validation: {design["n_blocks"]} blocks of '
        f'contiguous chunks ({", ".join(f"{b:.0f}" for b in design["blocks_s"])} s), each '
        f'held out in turn and scored on its Welch spectra '
        f'({design["scoring_segment_length"]}-sample segments). Settings imposed by the '
        f'params file or the command line (kept, not searched): {imposed}.')
    folds = other_set_folds(design)
    if folds:
        out.paragraph(
            f'The input set of each output was chosen on folds of shorter chunks, so that '
            f'every block samples the whole record: {folds["n_blocks"]} blocks '
            f'({", ".join(f"{b:.0f}" for b in folds["blocks_s"])} s) scored on '
            f'{folds["scoring_segment_length"]}-sample segments; the per-set figures are '
            f'theirs (docs/fit_design.md, "Input sets").')
    groups = design.get('input_set_groups') or []
    if groups and len(design.get('input_sets') or ()) > 1:
        names = '; '.join(', '.join(f'`{n}`' for n in g) for g in groups)
        out.paragraph('The four corners of a component chose their input set together, on '
                      f'their held-out criteria summed ({names}).')
    choice, table = design_tables(design, model.output_channels)
    out.table(choice)
    out.image(plot_design_scores(d / 'design_scores.png', design, model.output_channels),
              'Held-out RMSE of every candidate per output; the chosen one in red')
    out.table(table)


def write_evaluation_report(directory, model, evaluation, segments, extra=None) -> Path:
    """
    Write the evaluation report (paper Figures 6-13, Tables 2-3); return report.md.

    ``extra(writer, directory)``, when given, appends more sections (the live comparison).
    """
    from wheel_force_estimator.core.metrics import rubric
    out = ReportWriter(directory)
    d = Path(directory)
    ch = evaluation.channels
    out.heading('Virtual WFT evaluation', 1)
    out.paragraph(f'{len(segments)} segment(s) at {evaluation.fs_hz:g} Hz. RMSE % = RMS '
                  f'error / RMS target on mean-removed signals; rubric: perfect < 25, great '
                  f'25-50, good 50-75, bad 75-100, not qualified > 100.')
    out.heading('RMSE', 2)
    out.table(tables.rmse_table(ch, evaluation.rmse_pct, evaluation.rmse_hp1_pct,
                                [rubric(float(v)) for v in evaluation.rmse_pct],
                                markdown=True))
    out.table(tables.rubric_counts_table(evaluation.rubric_counts(), markdown=True))
    if evaluation.events:
        events = sorted(evaluation.events)
        values = np.array([evaluation.events[e]['rmse_pct'] for e in events])
        out.heading('RMSE per road event', 2)
        out.image(plot_rmse_colormap(d / 'rmse_events.png', events, ch, values),
                  'RMSE % per event and channel (paper Table 2 / Figure 9)')
    out.heading('Pseudo damage', 2)
    out.table(tables.damage_table(ch, evaluation.damage_target, evaluation.damage_prediction,
                                  evaluation.damage_ratio, markdown=True))
    ratio = evaluation.damage_ratio
    finite = np.isfinite(ratio)  # a target without cycles has no ratio (n/a in the table)
    if finite.any():
        out.image(plot_damage_ratio(d / 'damage_ratio.png',
                                    [c for c, ok in zip(ch, finite) if ok], ratio[finite]),
                  'Prediction/target pseudo damage (0.5-2 is good)')
    out.image(plot_relative_damage_spectrum(
        d / 'relative_damage_spectrum.png', ch, evaluation.bands_hz, evaluation.rds_target,
        evaluation.rds_prediction), 'Relative damage spectrum (paper Figure 13)')
    out.heading('Spectra', 2)
    units = output_units(model)
    paired = paired_inputs(model.input_channels, ch)
    mag = None if paired is None else np.stack(
        [np.interp(evaluation.f_hz, model.f_hz, np.abs(model.h[:, o, i]))
         for o, i in enumerate(paired)])
    vehicle = all(channel_unit(c) != '-' for c in ch)  # units per channel from the names
    gain = None if vehicle else ratio_unit(model.units.get('output', 'N'),
                                           model.units.get('input', 'm/s^2'))
    out.image(plot_asd(d / 'asd.png', evaluation.f_hz, evaluation.asd_target,
                       evaluation.asd_prediction, evaluation.asd_error, ch,
                       frf_mag=mag, units=units, frf_unit=gain),
              'ASD of target, prediction and error with the paired FRF (Figures 10-12)'
              if mag is not None else 'ASD of target, prediction and error (Figures 10-12)')
    out.image(plot_coherence(d / 'coherence.png', model.f_hz, model.coherence_multiple,
                             None, model.output_channels),
              'Model multiple coherence (Figure 6)')
    out.heading('Time histories', 2)
    longest = max(segments, key=lambda s: s.target_n.shape[1])
    t_s = (longest.stamp_ns - longest.stamp_ns[0]) * 1e-9
    out.image(plot_time_overlay(d / 'time_history.png', t_s, longest.target_n,
                                longest.prediction_n, ch, title=longest.source, units=units),
              f'Target vs prediction, {longest.source}')
    mid = t_s[-1] / 2
    if mid > 5.0:  # a shorter record is readable whole
        out.image(plot_time_overlay(d / 'time_history_zoom.png', t_s, longest.target_n,
                                    longest.prediction_n, ch, window_s=(mid, mid + 5.0),
                                    title=f'{longest.source} (5 s zoom)', units=units),
                  'Zoom on 5 s')
    if extra is not None:
        extra(out, d)
    return out.write()
