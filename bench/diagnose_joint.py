# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
The written model beside one joint least-squares fit of the FIR and the named term.

Issue 30 asks that the diagnosis's written model (real-data FIR + the named terms) be at
least as good as one joint least-squares fit of the FIR together with the named term's
regressor on the same training data.  For real rig data in ``../shared/data`` (friction
damper, MR damper) and simulated rigs (one corner of the synthetic law driven by its
displacement; lightly damped structures with an element inside the loop), each case is
diagnosed as the CLI runs it on generic files (``--holdout``, segment chosen by
cross-validation), then scored on the report half of the holdout as ``evaluate`` scores it
(the diagnosis's metric, and the other figure in brackets):

- ``plain``: the plain ``wheel-force fit`` of the real data (``fit.real_linear``);
- ``joint LS``: the same FIR design and the findings' terms at their selected shapes, the
  FIR and the terms' strengths fitted jointly by least squares in one step
  (Frisch-Waugh-Lovell, ``written.backfitted_model(joint=True, iterations=0)``): the
  baseline the issue names;
- ``written``: the model ``--out-model`` writes (``fit.after``).

Run: ``python bench/diagnose_joint.py`` (~5 min on a 2-core machine).
"""
from pathlib import Path
import sys

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.predict import predict_forces
from wheel_force_estimator.diagnosis import diagnose
from wheel_force_estimator.diagnosis import DiagnosisConfig
from wheel_force_estimator.diagnosis.features import settle_samples
from wheel_force_estimator.diagnosis.holdout import evaluate_figures
from wheel_force_estimator.diagnosis.holdout import METRIC
from wheel_force_estimator.diagnosis.holdout import split_holdout
from wheel_force_estimator.diagnosis.run import real_linear_fit
from wheel_force_estimator.diagnosis.written import backfitted_model

sys.path.insert(0, str(Path(__file__).resolve().parent))
import diagnose_blind as blind  # noqa: E402,I100

OTHER = {'rmse_pct': 'rmse_hp1_pct', 'rmse_hp1_pct': 'rmse_pct'}


def joint_model(result, real, reference, config):
    """
    Return the joint least-squares FIR + terms model of ``result``'s findings, or None.

    ``reference``: the plain fit of ``real`` (:func:`diagnosis.run.real_linear_fit`).
    """
    with_terms = [f for f in result.findings if f.terms]
    if not with_terms:
        return None
    rec0 = real[0]
    skip = settle_samples(rec0.fs_hz, rec0.input_quantity, config.features)
    model, _ = backfitted_model(with_terms, real, reference.model, reference.refit,
                                config.selection.highpass_hz, skip, iterations=0, joint=True)
    return model


def report(title, real, hold, config=None):
    """Diagnose one case and print plain / joint LS / written on the report half."""
    config = config or DiagnosisConfig(choose_resolution=True)
    try:
        result = diagnose(real, None, hold, config)
    except DiagnosisError as err:
        print(f'{title:34s} refused: {err}')
        return None
    metric = METRIC[real[0].input_quantity]
    shown = split_holdout(hold).report_half
    chans = sorted({c for f in result.findings for c in f.channels}) or list(
        real[0].output_channels)

    def mean(figures, fig):
        return float(np.mean([figures[fig][c] for c in chans]))
    plain = real_linear_fit(real, config)
    models = {'plain': plain.model, 'joint LS': joint_model(result, real, plain, config),
              'written': result.model}
    scores = {}
    for name, model in models.items():
        if model is None:
            continue
        figs = evaluate_figures(lambda r, m=model: predict_forces(m, r.inputs), shown.records,
                                shown.masks)
        scores[name] = (mean(figs, metric), mean(figs, OTHER[metric]))
    named = ','.join(f.physics for f in result.findings) or 'none'

    def cell(name):
        if name not in scores:
            return f'{"-":>15s}'
        a, b = scores[name]
        return f'{a:6.2f} ({b:6.2f})'
    print(f'{title:34s} {named:22s} {cell("plain")} {cell("joint LS")} {cell("written")}  '
          f'{result.fit.model}', flush=True)
    return scores


def rig_cases(seeds=(0, 1)):
    """Yield the displacement rigs of ``diagnose_blind`` (2 x 60 s to fit, 2 x 60 s holdout)."""
    for effect in blind.RIG_EFFECTS:
        for seed in seeds:
            real = [blind._rig_record(effect, 10 * seed + k, 'displacement') for k in (1, 2)]
            hold = [blind._rig_record(effect, 10 * seed + k, 'displacement') for k in (3, 4)]
            yield f'rig {effect} seed {seed}', real, hold


def structure_cases():
    """Yield the lightly damped structures with an element inside the loop."""
    fixtures = blind.FIXTURES
    for case in fixtures.STRUCTURES:
        real = [fixtures.structure_recording(case, s) for s in (1, 2)]
        hold = [fixtures.structure_recording(case, 3)]
        yield f'structure: {case}', real, hold


def main():
    """Print the table and the count of cases where the written model is no worse."""
    print('RMSE % on the report half of the holdout, mean over the named channels: the '
          "diagnosis's metric (the other figure)")
    print(f'{"case":34s} {"named":22s} {"plain fit":>15s} {"joint LS":>15s} '
          f'{"written":>15s}  written model')
    rows = []
    cases = list(blind.real_datasets()) + list(rig_cases()) + list(structure_cases())
    for title, real, hold in cases:
        scores = report(title, real, hold)
        if scores and 'joint LS' in scores:
            rows.append(scores)
    within = sum(s['written'][0] <= s['joint LS'][0] + 0.05 for s in rows)
    print(f'named cases with terms: written within 0.05 points of the joint LS fit or better '
          f"(the diagnosis's metric): {within}/{len(rows)}")


if __name__ == '__main__':
    main()
