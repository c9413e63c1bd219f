# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
From integrator samples to recorded channels: anti-alias decimation, delay, noise, clipping.

The integrator runs at ``factor`` x the output rate.  :class:`Decimator` low-passes with a
linear-phase (symmetric, Kaiser-windowed) FIR and keeps every ``factor``-th sample, shifted by
the filter's group delay, so the result is zero-phase: output sample ``j`` is the filtered
signal centred on integration sample ``j * factor``.  It streams (chunk by chunk, any chunk
sizes, same result as one call) so a 10 min course never holds the high-rate history.  The
filter state before the first sample is that of a constant signal equal to the first sample
(the car starts in equilibrium).

Sensor models (applied by :mod:`wheel_force_estimator.sim.api`): white Gaussian noise at the
output rate (accelerometer ``accel_noise_mps2``, WFT ``force_noise_n``), the ``time_delay``
effect as a delay line on the WFT channels at the integration rate (before the anti-alias
filter, like a late DAQ channel), and ``sensor_saturation`` as an ADC range clip of the
recorded (noisy) accelerations.
"""
import numpy as np
import scipy.signal

from wheel_force_estimator.core.errors import ConfigError

# half-length of the anti-alias FIR in output samples: 2 * 20 * factor + 1 taps
_HALF_LENGTH_OUT = 20
# pass band edge as a fraction of the output Nyquist frequency
_CUTOFF_FRACTION = 0.9
_KAISER_BETA = 8.0


def anti_alias_taps(factor: int) -> np.ndarray:
    """Return the symmetric low-pass FIR (odd length, unit DC gain) for decimation by factor."""
    n_taps = 2 * _HALF_LENGTH_OUT * factor + 1
    return scipy.signal.firwin(n_taps, _CUTOFF_FRACTION / factor, window=('kaiser', _KAISER_BETA))


class Decimator:
    """Streaming zero-phase FIR decimation of (n_samples, n_channels) chunks by ``factor``."""

    def __init__(self, factor: int, n_channels: int):
        """Create the filter for ``n_channels`` channels; nothing is processed yet."""
        if int(factor) != factor or factor < 1:
            raise ConfigError(f'decimation factor must be a positive integer, got {factor!r}')
        self.factor = int(factor)
        self.taps = anti_alias_taps(self.factor) if self.factor > 1 else np.ones(1)
        self.delay = (self.taps.size - 1) // 2  # group delay [integration samples]
        self.n_channels = n_channels
        self._history = None  # last taps.size - 1 input samples
        self._index = 0  # integration samples consumed

    def process(self, chunk: np.ndarray) -> np.ndarray:
        """
        Filter the next chunk, return the output samples that became complete.

        Returns
        -------
        numpy.ndarray, shape (n_complete, n_channels)

        """
        chunk = np.asarray(chunk, dtype=np.float64)
        if chunk.ndim != 2 or chunk.shape[1] != self.n_channels:
            raise ConfigError(f'decimator expects (n, {self.n_channels}) chunks, got '
                              f'{chunk.shape}')
        n_hist = self.taps.size - 1
        if chunk.shape[0] == 0:
            return np.zeros((0, self.n_channels))
        if self._history is None:
            self._history = np.repeat(chunk[:1], n_hist, axis=0)
        ext = np.concatenate((self._history, chunk), axis=0)
        first = self._index - n_hist  # global index of ext[0]
        self._history = ext[ext.shape[0] - n_hist:]
        self._index += chunk.shape[0]
        # complete outputs: filter output at global m (centred on m - delay) needs ext up to m;
        # keep the m >= delay on the output grid, (m - delay) % factor == 0
        m0 = max(self._index - chunk.shape[0], self.delay)
        m0 += (-(m0 - self.delay)) % self.factor
        if m0 > self._index - 1:
            return np.zeros((0, self.n_channels))
        start = m0 - n_hist - first  # ext index of the oldest sample output m0 needs
        # polyphase: only the kept outputs are computed (n_hist is a multiple of factor)
        y = scipy.signal.upfirdn(self.taps, ext[start:], 1, self.factor, axis=0)
        n_out = (self._index - 1 - m0) // self.factor + 1
        return y[n_hist // self.factor:n_hist // self.factor + n_out]


class DelayLine:
    """Delay (n, n_channels) chunks by a whole number of samples (first sample held before)."""

    def __init__(self, n_samples: int, n_channels: int):
        """Create a delay of ``n_samples`` (>= 0)."""
        self.n_samples = int(n_samples)
        self._buffer = None
        self.n_channels = n_channels

    def process(self, chunk: np.ndarray) -> np.ndarray:
        """Return the chunk delayed by ``n_samples`` (same shape)."""
        if self.n_samples == 0 or chunk.shape[0] == 0:
            return chunk
        if self._buffer is None:
            self._buffer = np.repeat(chunk[:1], self.n_samples, axis=0)
        joined = np.concatenate((self._buffer, chunk), axis=0)
        self._buffer = joined[-self.n_samples:]
        return joined[:chunk.shape[0]]


def add_noise(rng: np.random.Generator, accel_mps2: np.ndarray, force_n: np.ndarray,
              accel_noise_mps2: float, force_noise_n: float):
    """Add white noise in place; draws 24 x n normals whatever the levels (same stream)."""
    noise = rng.standard_normal((accel_mps2.shape[0] + force_n.shape[0], accel_mps2.shape[1]))
    accel_mps2 += accel_noise_mps2 * noise[:accel_mps2.shape[0]]
    force_n += force_noise_n * noise[accel_mps2.shape[0]:]


def saturate(accel_mps2: np.ndarray, limit_mps2: float) -> np.ndarray:
    """Return the accelerations clipped to +-``limit_mps2`` (ADC range)."""
    return np.clip(accel_mps2, -limit_mps2, limit_mps2)
