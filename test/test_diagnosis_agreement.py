# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Corners that agree name a weak effect none of them names alone; nulls stay silent."""
from types import SimpleNamespace

import numpy as np
import pytest

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.diagnosis.candidates import BY_KEY
from wheel_force_estimator.diagnosis.candidates import BY_NAME
from wheel_force_estimator.diagnosis.features import ChannelContext
from wheel_force_estimator.diagnosis.finders.agreement import agreed_findings
from wheel_force_estimator.diagnosis.finders.agreement import AgreementConfig
from wheel_force_estimator.diagnosis.finders.agreement import votes
from wheel_force_estimator.diagnosis.prepared import pieces
from wheel_force_estimator.diagnosis.prepared import Prepared
from wheel_force_estimator.diagnosis.run import DiagnosisConfig
from wheel_force_estimator.diagnosis.selection import Selector

FS_HZ = 256.0
CHANNELS = ['lf_fz', 'rf_fz', 'lr_fz', 'rr_fz']
CANDIDATES = [BY_NAME[n] for n in ('cubic_stiffness', 'damper_asymmetry', 'coulomb_friction')]


class _Builder:
    def pooled_finding(self, key, group, shape, coef, gain, null):
        return (key, tuple(group), coef, gain, null)


def _prepared(strength, seed=0, n=int(120 * FS_HZ)):
    """Four corners: band-limited motion, residual = strength * cubic spring + noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    contexts, targets, predictions = [], [], []
    w = 2 * np.pi * np.random.default_rng(99).uniform(1.0, 12.0, 16)  # not periodic
    amp = 0.01 / (w / w.min())
    for _ in CHANNELS:
        arg = np.outer(w, t) + rng.uniform(0.0, 2 * np.pi, 16)[:, np.newaxis]
        disp = amp @ np.sin(arg)
        vel = (amp * w) @ np.cos(arg)
        acc = -(amp * w * w) @ np.sin(arg)
        load = 3000.0 + 2e4 * disp
        ctx = ChannelContext(disp, vel, acc, acc, load, None, FS_HZ)
        term = strength * BY_NAME['cubic_stiffness'].basis(ctx, {})
        noise = rng.normal(0.0, 100.0, n)
        contexts.append(ctx)
        predictions.append(load)
        targets.append(load + term + noise)
    record = SimpleNamespace(name='four corners')       # only its name is read here
    return Prepared((record,), [np.array(targets)], [np.array(predictions)], [contexts], [0.0],
                    [np.array(predictions)], [(0, n)])


def _outcomes(prep, config):
    return {c: Selector(pieces(prep, o, c), config.selection).run(CANDIDATES)
            for o, c in enumerate(CHANNELS)}


def test_a_term_below_the_per_channel_threshold_is_named_when_the_corners_agree():
    config = DiagnosisConfig()
    # A cubic spring that explains about 4 % of each corner's residual: under the 5 % a single
    # channel needs, far above what time-shifted features explain.
    prep = _prepared(strength=9e5)
    outcomes = _outcomes(prep, config)
    per_channel = [outcomes[c].ranking[0].gain for c in CHANNELS]
    assert all(0.02 < g < config.selection.min_gain for g in per_channel), per_channel
    assert not any(outcomes[c].accepted for c in CHANNELS)
    assert votes(outcomes, CHANNELS) == {('z', 'cubic_stiffness'): CHANNELS}
    found = agreed_findings(outcomes, CHANNELS, prep, None, _Builder(), config,
                            AgreementConfig())
    assert len(found) == 1
    key, group, coef, gain, null = found[0]
    assert key == 'cubic_stiffness' and group == tuple(CHANNELS)
    assert abs(coef / 9e5 - 1.0) < 0.15 and gain > config.agreement.min_gain
    # Switched off, or asked for more votes than corners: nothing.
    assert agreed_findings(outcomes, CHANNELS, prep, None, _Builder(), config,
                           AgreementConfig(min_votes=0)) == []
    assert agreed_findings(outcomes, CHANNELS, prep, None, _Builder(), config,
                           AgreementConfig(min_votes=5)) == []


def test_agreeing_noise_is_not_named():
    config = DiagnosisConfig()
    prep = _prepared(strength=0.0, seed=1)
    outcomes = _outcomes(prep, config)
    found = agreed_findings(outcomes, CHANNELS, prep, None, _Builder(), config,
                            AgreementConfig(min_gain=0.001))
    assert found == []


def test_agreement_config_is_validated():
    with pytest.raises(ConfigError):
        AgreementConfig(min_votes=1)
    with pytest.raises(ConfigError):
        AgreementConfig(min_gain=0.0)
    assert BY_KEY['cubic_stiffness'] is BY_NAME['cubic_stiffness']
