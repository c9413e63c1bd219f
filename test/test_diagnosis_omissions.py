# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""Linear omissions from band gains: known-answer gain errors on a stand-in reference."""
import numpy as np
import pytest
from scipy import signal

from wheel_force_estimator import INPUT_CHANNELS
from wheel_force_estimator import OUTPUT_CHANNELS
from wheel_force_estimator.diagnosis import MotionRecording
from wheel_force_estimator.diagnosis.omissions import band_gains
from wheel_force_estimator.diagnosis.omissions import BODY_HZ
from wheel_force_estimator.diagnosis.omissions import linear_omissions
from wheel_force_estimator.diagnosis.omissions import QUASI_STATIC_HZ

FS = 64.0
N = int(300 * FS)
SKIP = int(15 * FS)


class _Reference:
    """Stand-in reference: the 'prediction' is the recorded input row scaled to newtons."""

    def predict(self, rec):
        return 1000.0 * np.asarray(rec.inputs)


def _law(seed):
    """Broadband inputs (0.05-10 Hz) and the matching linear prediction."""
    rng = np.random.default_rng(seed)
    sos = signal.butter(2, [0.05, 10.0], 'bandpass', fs=FS, output='sos')
    x = signal.sosfilt(sos, rng.standard_normal((12, N)), axis=1)
    return x, 1000.0 * x


def _band(x, band):
    return signal.sosfiltfilt(signal.butter(4, band, 'bandpass', fs=FS, output='sos'), x,
                              axis=-1)


def _rec(name, x, force):
    return MotionRecording(name, FS, x, force, INPUT_CHANNELS, OUTPUT_CHANNELS)


def _pair(extra):
    x, pred = _law(1)
    xs, preds = _law(2)
    return [_rec('real', x, pred + extra(pred))], [_rec('sim', xs, preds)]


def _diagnose(real, sim):
    sources = tuple(c[:2] + '_a' + c[-1] for c in OUTPUT_CHANNELS)
    debug = {}
    found = linear_omissions(real, sim, _Reference(), OUTPUT_CHANNELS, SKIP, 0.0, sources,
                             'acceleration', (0.2, 0.0), debug=debug)
    return found, debug


def test_band_gain_is_the_relative_gain_error():
    real, _ = _pair(lambda p: 0.07 * p)
    g = band_gains(real, _Reference(), QUASI_STATIC_HZ, SKIP, 4.0)
    # An exact 7 % gain error in every band: only filter rounding remains.
    np.testing.assert_allclose(g.gain, 0.07, atol=1e-9)


def test_heavier_car_is_a_mass_error_on_all_channels():
    found, debug = _diagnose(*_pair(lambda p: 0.07 * p))
    assert [f.physics for f in found] == ['mass_error']
    assert set(found[0].channels) == set(OUTPUT_CHANNELS)
    # The sim's own gain is 0 (its law is exact), so the excess is the 7 % put in.
    assert debug['quasi_static']['fx'] == pytest.approx(0.07, abs=1e-6)
    term = found[0].terms[0]
    assert term.state == 'load' and term.parameters['gain'] > 0.0


def test_stiffer_springs_are_a_stiffness_error_on_fz():
    fz = np.array([c.endswith('fz') for c in OUTPUT_CHANNELS])[:, np.newaxis]
    found, debug = _diagnose(*_pair(lambda p: 0.1 * fz * _band(p, BODY_HZ)))
    assert [f.physics for f in found] == ['stiffness_error']
    assert all(c.endswith('fz') for c in found[0].channels)
    # Band edges of the added band-pass and the 4th-order analysis filter differ: ~0.07-0.1.
    assert 0.05 < debug['body_fz'] < 0.11
    assert abs(debug['quasi_static']['fz']) < 0.01


def test_same_law_and_amplitude_dependent_stiffening_are_not_linear_omissions():
    assert _diagnose(*_pair(lambda p: 0.0 * p))[0] == []
    fz = np.array([c.endswith('fz') for c in OUTPUT_CHANNELS])[:, np.newaxis]

    def hardening(p):
        # Extra body-band force only in the roughest stretches (a stop): not linear.
        body = _band(p, BODY_HZ)
        envelope = np.abs(signal.hilbert(body, axis=1))
        return 0.4 * fz * body * (envelope > np.quantile(envelope, 0.9, axis=1, keepdims=True))
    found, debug = _diagnose(*_pair(hardening))
    # Stiffer on average than the acceptance gain (so the linearity rule is what rejects it):
    # its calm half shows about a third of the rough half's gain.
    assert debug['body_fz'] > 0.06
    assert debug['body_calm'] < 0.5 * debug['body_rough']
    assert found == [], debug


def test_known_mass_error_gain_is_read_back_into_the_term():
    from wheel_force_estimator.diagnosis.features import ChannelContext
    from wheel_force_estimator.diagnosis.grids import load_state

    def heavier(pred):
        # A 7 % heavier car as the term models it: 7 % more of the load below 1 Hz.
        return 0.07 * np.array([load_state(ChannelContext(*(row,) * 5, None, FS), 1.0)
                                for row in pred])
    found, _ = _diagnose(*_pair(heavier))
    assert [f.physics for f in found] == ['mass_error']
    gains = {t.parameters['gain'] for t in found[0].terms}
    corners = {t.state_lowpass_hz for t in found[0].terms}
    # Same law and filter as the synthetic error: the corner is found on the grid and the
    # shared least-squares gain is 0.07 up to the centring on the record mean (< 0.5 %).
    assert corners == {1.0} and len(gains) == 1
    assert gains.pop() == pytest.approx(0.07, rel=0.005)
