# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""One gap-free stretch of recorded motion and force, as the diagnosis sees it."""
from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

from wheel_force_estimator.core.errors import DiagnosisError
from wheel_force_estimator.core.physics import QUANTITIES
from wheel_force_estimator.core.validation import freeze_paired_record


@dataclass(frozen=True)
class MotionRecording:
    """
    Synchronous inputs (motion) and outputs (force) of one gap-free segment.

    Attributes
    ----------
    name : str
        Where it came from (file and segment), used in messages and the report.
    fs_hz : float
        Sample rate [Hz].
    inputs : numpy.ndarray, shape (n_inputs, n)
        Recorded motion in SI units of ``input_quantity`` (m, m/s or m/s**2).
    outputs : numpy.ndarray, shape (n_outputs, n)
        Recorded force [N].
    input_channels, output_channels : tuple of str
        Row names.
    input_quantity : str
        ``'acceleration'``, ``'velocity'`` or ``'displacement'``.
    start_s : float
        Time of the first sample [s] (bag stamp or 0), for reported time windows.
    events : tuple of (float, str)
        ``(t_s, name)`` event starts within the recording.

    """

    name: str
    fs_hz: float
    inputs: np.ndarray
    outputs: np.ndarray
    input_channels: Tuple[str, ...]
    output_channels: Tuple[str, ...]
    input_quantity: str = 'acceleration'
    start_s: float = 0.0
    events: Tuple[Tuple[float, str], ...] = ()

    def __post_init__(self):
        freeze_paired_record(self, self.name, QUANTITIES, DiagnosisError)

    @property
    def n_samples(self) -> int:
        """Return the number of samples."""
        return int(self.inputs.shape[1])

    @property
    def duration_s(self) -> float:
        """Return the length of the record [s]."""
        return self.n_samples / self.fs_hz


def check_compatible(recordings: Sequence[MotionRecording], what: str) -> None:
    """
    Refuse recordings that disagree on rate, channels or input quantity.

    Raises
    ------
    DiagnosisError
        Naming the first recording that differs from the first one and how.

    """
    if not recordings:
        raise DiagnosisError(f'no {what} recordings given')
    ref = recordings[0]
    for rec in recordings[1:]:
        if abs(rec.fs_hz - ref.fs_hz) > 1e-6 * ref.fs_hz:
            raise DiagnosisError(f'{what}: {rec.name} is sampled at {rec.fs_hz:g} Hz but '
                                 f'{ref.name} at {ref.fs_hz:g} Hz; nothing is resampled')
        for attr in ('input_channels', 'output_channels', 'input_quantity'):
            if getattr(rec, attr) != getattr(ref, attr):
                raise DiagnosisError(f'{what}: {rec.name} has {attr} {getattr(rec, attr)} but '
                                     f'{ref.name} has {getattr(ref, attr)}')


def from_bag_recording(recording, input_channels, output_channels,
                       travel: bool = False) -> Tuple[MotionRecording, ...]:
    """
    Convert a ``bagio`` recording (with WFT) into one MotionRecording per segment.

    With ``travel`` the inputs are the recorded suspension travel (displacement,
    ``input_channels`` names its four rows) and the outputs the vertical forces named in
    ``output_channels`` (``*_fz``): what the generic path sees of a DAQ export with string
    potentiometers.

    Raises
    ------
    DiagnosisError
        When a segment carries no force (a bag without the WFT topics), or no travel.

    """
    from wheel_force_estimator import OUTPUT_CHANNELS
    rows = [OUTPUT_CHANNELS.index(c) for c in output_channels] if travel else None
    out = []
    t0 = None
    for i, seg in enumerate(recording.segments):
        if seg.force_n is None:
            raise DiagnosisError(f'{recording.path}: segment {i} has no WFT force; the '
                                 f'diagnosis needs recorded forces')
        stamps = np.asarray(seg.stamp_ns, dtype=np.int64)
        t0 = stamps[0] if t0 is None else t0
        start_s = (stamps[0] - t0) * 1e-9
        end_ns = stamps[-1]
        events = tuple(((s - t0) * 1e-9, name) for s, name in recording.events
                       if stamps[0] <= s <= end_ns)
        if travel and seg.travel_m is None:
            raise DiagnosisError(f'{recording.path}: segment {i} has no suspension travel')
        out.append(MotionRecording(
            name=f'{recording.path}#{i}', fs_hz=recording.fs_hz,
            inputs=seg.travel_m if travel else seg.signals(input_channels, recording.fs_hz),
            outputs=seg.force_n[rows] if travel else seg.force_n,
            input_channels=tuple(input_channels), output_channels=tuple(output_channels),
            input_quantity='displacement' if travel else 'acceleration',
            start_s=float(start_s), events=events))
    return tuple(out)
