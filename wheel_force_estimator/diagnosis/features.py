# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Physical states from recorded motion, computed exactly as :class:`PhysicsStage` does.

Displacement, velocity and acceleration come from the recorded quantity through the causal
band-limited integrators / differentiators of :func:`core.physics.feature_filters` (the same
filters the stage applies later, so fitted parameters mean the same thing when applied).
Per output channel the diagnosis also uses the other side of the axle (left-right
difference), the raw recorded level (saturation), the sign of the velocity and the predicted
load (the reference model's total force, static included).
"""
from dataclasses import dataclass
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from wheel_force_estimator import PARTNER_CORNER  # noqa: F401  (re-exported here)
from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.physics import default_source
from wheel_force_estimator.core.physics import FeatureBank


@dataclass(frozen=True)
class FeatureConfig:
    """
    Corners of the feature filters.

    Attributes
    ----------
    highpass_hz : float
        Integration high-pass corner [Hz] (acceleration or velocity inputs).
    lowpass_hz : float
        Differentiation low-pass corner [Hz] (displacement or velocity inputs); 0 picks
        ``fs / 8``.

    """

    highpass_hz: float = 0.2
    lowpass_hz: float = 0.0

    def __post_init__(self):
        if not np.isfinite(self.highpass_hz) or self.highpass_hz <= 0.0:
            raise ConfigError(f'highpass_hz must be > 0, got {self.highpass_hz!r}')
        if not np.isfinite(self.lowpass_hz) or self.lowpass_hz < 0.0:
            raise ConfigError(f'lowpass_hz must be >= 0, got {self.lowpass_hz!r}')

    def resolved(self, fs_hz: float, input_quantity: str) -> Tuple[float, float]:
        """Return ``(highpass_hz, lowpass_hz)`` as stored in the terms for these inputs."""
        hp = self.highpass_hz if input_quantity != 'displacement' else 0.0
        if input_quantity == 'acceleration':
            return hp, 0.0
        return hp, self.lowpass_hz or fs_hz / 8.0


def pairing(output_channels: Sequence[str], input_channels: Sequence[str], recordings=()
            ) -> Tuple[Tuple[str, ...], Tuple[Optional[str], ...]]:
    """
    Source input channel and other-side partner input channel of every output channel.

    Vehicle names pair ``lf_fz`` with ``lf_az`` (partner ``rf_az``; only vertical channels get
    a partner: a roll bar couples vertical motion); a single input drives every output.  Any
    other recording (several inputs, names that say nothing) pairs each output with the input
    that explains the most of it linearly on its own: the largest output-power-weighted mean
    coherence ``sum_f coh_io(f) Pyy(f) / sum_f Pyy(f)`` over ``recordings``, i.e. the fraction
    of the output's dynamic variance that input alone accounts for.  Names and positions are
    not trusted: a rig's channel order is whatever the DAQ export says.

    Raises
    ------
    DiagnosisError
        Several inputs, names that do not pair, and no recordings to measure coherence on.

    """
    inputs = tuple(input_channels)
    sources = _named_sources(output_channels, inputs)
    if sources:
        partners = []
        for s in sources:
            # A roll bar couples the vertical motion of the two sides of an axle only.
            corner, _, axis = s.partition('_')
            other = f'{PARTNER_CORNER.get(corner, "")}_{axis}'
            partners.append(other if other in inputs and axis.endswith('z') else None)
        return sources, tuple(partners)
    if len(inputs) == 1:
        return inputs * len(output_channels), (None,) * len(output_channels)
    if not recordings:
        raise DiagnosisError(
            f'cannot tell which input drives which output: inputs {list(inputs)}, outputs '
            f'{list(output_channels)}, and no recordings to measure their coherence on')
    share = explained_shares(recordings)
    return (tuple(inputs[int(np.argmax(row))] for row in share),
            (None,) * len(output_channels))


def _named_sources(output_channels, inputs) -> Tuple[str, ...]:
    """Vehicle-name sources (``lf_fz`` -> ``lf_az``) when every one is an input, else ()."""
    try:
        sources = tuple(default_source(c) for c in output_channels)
    except ConfigError:
        return ()
    return sources if all(s in inputs for s in sources) else ()


def paired_by_coherence(output_channels: Sequence[str], input_channels: Sequence[str]) -> bool:
    """Return True when :func:`pairing` falls back to coherence (several inputs, no names)."""
    inputs = tuple(input_channels)
    return len(inputs) > 1 and not _named_sources(output_channels, inputs)


def explained_shares(recordings) -> np.ndarray:
    """
    Output-power-weighted mean coherence of every (output, input) pair, shape (n_out, n_in).

    Welch segments of up to 1024 samples per record (shortened for short records), the DC
    line left out; records pooled with weights equal to their output power.
    """
    from scipy import signal
    num = den = 0.0
    for rec in recordings:
        x = np.asarray(rec.inputs, dtype=np.float64)
        y = np.asarray(rec.outputs, dtype=np.float64)
        nperseg = int(min(1024, max(8, x.shape[1] // 4)))
        _, pyy = signal.welch(y, rec.fs_hz, nperseg=nperseg)
        coh = np.stack([np.stack([signal.coherence(x[i], y[o], rec.fs_hz, nperseg=nperseg)[1]
                                  for i in range(x.shape[0])]) for o in range(y.shape[0])])
        num = num + np.sum(coh[:, :, 1:] * pyy[:, None, 1:], axis=2)
        den = den + np.sum(pyy[:, 1:], axis=1)[:, None]
    return num / np.maximum(den, 1e-300)


def motion_features(inputs: np.ndarray, fs_hz: float, input_quantity: str,
                    config: FeatureConfig) -> Dict[str, np.ndarray]:
    """
    Return ``{'displacement'|'velocity'|'acceleration': (n_in, n)}`` for one record.

    The filters start at rest at the record mean (see :func:`settle_samples` for the start-up
    transient that remains).
    """
    hp, lp = config.resolved(fs_hz, input_quantity)
    x = np.asarray(inputs, dtype=np.float64)
    bank = FeatureBank(fs_hz, input_quantity, hp, lp, x.shape[0])
    return bank.process(x, rest=x.mean(axis=1))


def settle_samples(fs_hz: float, input_quantity: str, config: FeatureConfig) -> int:
    """
    Return the samples at the start of a record left out while the feature filters settle.

    The rule of :func:`core.physics.settle_samples` (the physics stage fades its motion
    terms in over the same time) for the filters of these inputs.
    """
    from wheel_force_estimator.core.physics import settle_samples as core_settle
    return core_settle(fs_hz, *config.resolved(fs_hz, input_quantity))


@dataclass(frozen=True)
class ChannelContext:
    """
    Everything a hypothesis may use to explain the residual of one output channel.

    Attributes are 1-D arrays over the record: ``disp`` [m], ``vel`` [m/s], ``acc`` [m/s**2]
    of the source input, ``partner_disp`` (or None), ``level`` (raw recorded input),
    ``load`` (reference total force prediction [N]); ``fs_hz`` the rate; ``n_inputs`` the
    number of input channels of the record (a test over all of them, like the clip test,
    bounds its false alarms over that many).
    """

    disp: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    level: np.ndarray
    load: np.ndarray
    partner_disp: Optional[np.ndarray]
    fs_hz: float
    filters: Tuple[str, float, float] = ('acceleration', 0.2, 0.0)
    n_inputs: int = 1

    def shifted(self, shift: int) -> 'ChannelContext':
        """Return the context circularly shifted in time (a feature unrelated to the force)."""
        def roll(a):
            return None if a is None else np.roll(a, shift)
        return ChannelContext(roll(self.disp), roll(self.vel), roll(self.acc), roll(self.level),
                              roll(self.load), roll(self.partner_disp), self.fs_hz,
                              self.filters, self.n_inputs)


def channel_contexts(inputs: np.ndarray, input_channels: Sequence[str], fs_hz: float,
                     input_quantity: str, prediction_n: np.ndarray,
                     sources: Sequence[str], partners: Sequence[Optional[str]],
                     config: FeatureConfig) -> Tuple[ChannelContext, ...]:
    """Build one :class:`ChannelContext` per output channel of one record."""
    feats = motion_features(inputs, fs_hz, input_quantity, config)
    filters = (input_quantity,) + config.resolved(fs_hz, input_quantity)
    idx = {c: i for i, c in enumerate(input_channels)}
    out = []
    for o, (src, partner) in enumerate(zip(sources, partners)):
        s = idx[src]
        out.append(ChannelContext(
            disp=feats['displacement'][s], vel=feats['velocity'][s],
            acc=feats['acceleration'][s], level=np.asarray(inputs[s], dtype=np.float64),
            load=np.asarray(prediction_n[o], dtype=np.float64),
            partner_disp=None if partner is None else feats['displacement'][idx[partner]],
            fs_hz=fs_hz, filters=filters, n_inputs=len(input_channels)))
    return tuple(out)
