# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
One full `wheel-force diagnose` through real rosbag2 files in the fast tier.

Its own file (not ``test_cli_offline.py``'s): the diagnosis's real-data fit is the design
search of ``fit``, and beside that file's own fit the two made one worker's critical path of
the fast tier.  The reference is the paper's plain H1 model written by ``save_model`` (the
test is about the report's sample numbers, which any reference shows).
"""
import json

from known_system import known_system
import numpy as np
import pytest

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.bagio import write_recording
from wheel_force_estimator.cli.main import main
from wheel_force_estimator.core.model import save_model
from wheel_force_estimator.core.pipeline import fit_model
from wheel_force_estimator.core.pipeline import FitConfig
from wheel_force_estimator.core.pipeline import TrainingSegment
from wheel_force_estimator.diagnosis.holdout import evaluate_arguments

FS_HZ = 512.0
PERIOD_NS = 1_953_125
T0_NS = 1_750_000_000 * 10**9


def test_diagnose_report_samples_of_a_gapped_bag_with_events_reproduce_in_evaluate(tmp_path):
    # Bug caught: report samples counted per segment (or per record) in fit.report_on while
    # evaluate counts them over the bag, so a holdout bag with a gap reports figures that
    # evaluate --samples cannot reproduce.
    # 40 s of training: the design search's folds are the scoring folds (16 chunks do not
    # fit), so the fast tier pays no input-set cross-validation here (60 s: 103 s, 40 s:
    # 71 s alone on one BLAS thread); the numbers checked do not depend on the model
    x, y = known_system(int(40 * FS_HZ), 1)
    write_recording(tmp_path / 'train', T0_NS + PERIOD_NS * np.arange(x.shape[1]), x, y)
    reference = save_model(fit_model([TrainingSegment(x, y, 'train')], FS_HZ, FitConfig(),
                                     INPUT_CHANNELS, OUTPUT_CHANNELS), tmp_path / 'ref.npz')
    n = int(40 * FS_HZ)
    x, y = known_system(2 * n, 11)
    stamps = T0_NS + PERIOD_NS * np.arange(2 * n, dtype=np.int64)
    stamps[n:] += 10**9                                    # a 1 s gap: two segments
    events = [(int(stamps[0]), 'cobblestone'), (int(stamps[n // 2]), 'braking'),
              (int(stamps[n + 1000]), 'highway')]
    write_recording(tmp_path / 'hold', stamps, x, y, events=events)
    out = tmp_path / 'd.json'
    assert main(['diagnose', '--real', str(tmp_path / 'train'), '--model', str(reference),
                 '--holdout', str(tmp_path / 'hold'), '--json', str(out), '--out-model',
                 str(tmp_path / 'w.npz')]) == 0
    fit = json.loads(out.read_text())['fit']
    (report_on,) = fit['report_on']
    path, _, spec = evaluate_arguments(report_on)
    assert path == str(tmp_path / 'hold')
    # second halves of: event 1 and 2 in segment 0, the stretch before event 3 in segment 1
    # (1000 samples) and event 3, in bag sample numbers
    assert spec == (f'{n // 4}..{n // 2},{3 * n // 4}..{n},{n + 500}..{n + 1000},'
                    f'{n + 1000 + (n - 1000) // 2}..{2 * n}')
    for written, key in ((str(tmp_path / 'w.npz'), 'after'), (str(reference), 'before')):
        assert main(['evaluate', written, path, '--samples', spec, '--json',
                     str(tmp_path / 'e.json')]) == 0
        evaluated = json.loads((tmp_path / 'e.json').read_text())['channels']
        for c, v in fit[key].items():
            assert evaluated[c][fit['metric']] == pytest.approx(v, abs=0.01)
