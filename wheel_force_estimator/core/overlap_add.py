# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Apply a MIMO FIR filter by FFT overlap-add (batch and streaming, one engine).

The filter type and its tap convention are in :mod:`wheel_force_estimator.core.filtering`:
output sample ``n`` of a filter with look-ahead ``delay`` uses inputs up to ``n + delay``.

:class:`OverlapAddFilter` is the only filtering engine.  :func:`apply_fir` runs it over a
record and flushes the look-ahead with zeros, so batch and live predictions are the same code.

The one piece of module state is a memo: the tap spectra, shared by every filter over the same
read-only taps array (``_SHARED``).  A spectrum is a pure function of immutable taps and an FFT
length, so the cache changes no result, only how often the taps are transformed; it is bounded
in bytes and drops a spectrum when its taps array is freed (docs/performance.md).
"""
from collections import OrderedDict
import threading
from typing import Optional
import weakref

import numpy as np
import scipy.fft

from wheel_force_estimator.core.errors import ConfigError
from wheel_force_estimator.core.errors import ShapeError
from wheel_force_estimator.core.filtering import as_index
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.filtering import response_on_grid
from wheel_force_estimator.core.validation import as_signals

# Overlap-add segments use FFTs of about 8 filter lengths: for 1024 taps 4x and 8x measured
# equally cheapest per sample, 2x and 16x about 50 % dearer (overlap work vs FFT log-factor).
_FFT_LENGTH_PER_TAP = 8
# Distinct FFT lengths whose tap spectra are kept (streaming calls with varied block lengths).
_MAX_CACHED_SPECTRA = 8
# Tap spectra shared by every filter over the same taps array, at most this many bytes (LRU).
# Each Predictor builds a new filter, so without sharing the diagnosis transformed one model's
# taps again for each of its 423 predictions: 858 transforms of 48 distinct taps arrays, 27 s
# of a 169 s run (measured).
# 256 MiB: 2 spectra of 12x14x8192 taps at a 65536-point FFT, or 15 at 12288.  One damper case
# (bench/diagnose_blind.py, seed 6) at 0 / 128 / 256 / 512 MiB: 170 / 154 / 146 / 133-154 s,
# 2.90 / 3.11 / 3.43 / 4.0-4.2 GB peak RSS, the same rows.
_MAX_SHARED_SPECTRA_BYTES = 256 * 2**20
# Whole segments transformed together in one long call: memory ~ 6 x 12 x batch x n_fft x 8 B
# (75 MB for 2 segments of 65536-point FFTs).  2 already streams the tap spectrum half as often
# as 1; 4 was no faster on 1 h of data and needs 75 MB more (fresh memory is slow on a VM).
_SEGMENTS_PER_BATCH = 2


class _SharedSpectra:
    """
    Tap spectra keyed by taps array and FFT length, shared across filters (LRU in bytes).

    A key is the taps array's ``id`` with a weak reference that must still point at that array,
    so an id reused by a later array never matches; entries go when their taps array is freed.
    Only read-only taps whose memory no numpy object can write are cached
    (:func:`~wheel_force_estimator.core.validation.read_only_array` returns such arrays).
    """

    def __init__(self, max_bytes: int):
        self._max_bytes = int(max_bytes)
        self._entries = OrderedDict()      # (id, n_fft) -> (weakref, spectrum)
        self._bytes = 0
        self._lock = threading.Lock()
        # Weak references whose taps were freed.  The callback only appends (atomic, no lock):
        # it may run from the garbage collector inside any of these methods.
        self._dead = []

    @property
    def n_bytes(self) -> int:
        """Return the bytes of the spectra held."""
        with self._lock:
            self._purge()
            return self._bytes

    def __len__(self) -> int:
        with self._lock:
            self._purge()
            return len(self._entries)

    def clear(self) -> None:
        """Drop every spectrum."""
        with self._lock:
            self._entries.clear()
            self._bytes = 0

    def get(self, taps: np.ndarray, n_fft: int) -> Optional[np.ndarray]:
        """Return the spectrum of ``taps`` at ``n_fft`` if held, else ``None``."""
        key = (id(taps), n_fft)
        with self._lock:
            self._purge()
            entry = self._entries.get(key)
            if entry is None or entry[0]() is not taps:
                return None
            self._entries.move_to_end(key)
            return entry[1]

    def put(self, taps: np.ndarray, n_fft: int, spectrum: np.ndarray) -> None:
        """Hold ``spectrum`` for ``taps`` at ``n_fft``, evicting the least recently used."""
        if spectrum.nbytes > self._max_bytes:
            return
        key = (id(taps), n_fft)
        with self._lock:
            self._purge()
            self._drop(key)
            self._entries[key] = (weakref.ref(taps, self._dead.append), spectrum)
            self._bytes += spectrum.nbytes
            while self._bytes > self._max_bytes:
                self._drop(next(iter(self._entries)))

    def _drop(self, key) -> None:
        entry = self._entries.pop(key, None)
        if entry is not None:
            self._bytes -= entry[1].nbytes

    def _purge(self) -> None:
        """Drop the spectra of freed taps arrays (call with the lock held)."""
        while self._dead:
            ref = self._dead.pop()
            for key in [k for k, v in self._entries.items() if v[0] is ref]:
                self._drop(key)


_SHARED = _SharedSpectra(_MAX_SHARED_SPECTRA_BYTES)


class OverlapAddFilter:
    """
    Streaming FFT overlap-add MIMO FIR filter; the one engine behind batch and live use.

    Each call convolves its block with all taps (FFT, multiply per frequency, inverse FFT), adds
    the tail stored from previous calls, emits as many samples as it received and keeps the new
    tail.  The output equals the direct convolution of the whole stream for any chunking (to
    rounding), so output sample ``j`` of the stream is the estimate for input sample
    ``j - delay_samples``; samples before the first call count as zeros.

    Parameters
    ----------
    fir : FirFilter
        The filter.

    """

    def __init__(self, fir: FirFilter):
        if not isinstance(fir, FirFilter):
            raise ConfigError(f'OverlapAddFilter needs a FirFilter, got {type(fir).__name__}')
        self._fir = fir
        self._taps = np.asarray(fir.taps)
        n_taps = fir.n_taps
        # Long calls are cut into segments whose FFT length is about 8 filter lengths.
        self._segment_len = scipy.fft.next_fast_len(_FFT_LENGTH_PER_TAP * n_taps,
                                                    real=True) - n_taps + 1
        self._spectra = OrderedDict()
        self.reset()

    @property
    def fir(self) -> FirFilter:
        """Return the filter being applied."""
        return self._fir

    @property
    def delay_samples(self) -> int:
        """Return the lag of the output stream behind the input stream [samples]."""
        return self._fir.delay_samples

    @property
    def efficient_block(self) -> int:
        """
        Return the cheapest long block length [samples] for :meth:`process`.

        A whole number of FFT segments (one batch of them): such calls use a single FFT
        length, so one tap spectrum is cached, and no short remainder segment is transformed.
        """
        return _SEGMENTS_PER_BATCH * self._segment_len

    @property
    def n_in(self) -> int:
        """Return the number of input channels."""
        return self._fir.n_in

    @property
    def n_out(self) -> int:
        """Return the number of output channels."""
        return self._fir.n_out

    @property
    def samples_processed(self) -> int:
        """Return the input samples received since construction or the last :meth:`reset`."""
        return self._n_seen

    def reset(self) -> None:
        """Forget the stream: the next call starts from an all-zero history."""
        self._tail = np.zeros((self.n_out, self._fir.n_taps - 1))
        self._n_seen = 0

    def _tap_spectrum(self, n_fft: int) -> np.ndarray:
        """Return rfft of the taps at ``n_fft`` as (nf, n_out, n_in), cached (LRU)."""
        spectrum = self._spectra.get(n_fft)
        if spectrum is None:
            spectrum = _SHARED.get(self._taps, n_fft)
        if spectrum is None:
            spectrum = response_on_grid(self._taps, 0, n_fft)      # line-major, no wrap
            spectrum.flags.writeable = False
            _SHARED.put(self._taps, n_fft, spectrum)
        if n_fft not in self._spectra:
            self._spectra[n_fft] = spectrum
            if len(self._spectra) > _MAX_CACHED_SPECTRA:
                self._spectra.popitem(last=False)
        else:
            self._spectra.move_to_end(n_fft)
        return spectrum

    def _full_segments(self, x: np.ndarray, acc: np.ndarray) -> int:
        """
        Convolve every whole segment of ``x`` into ``acc``; return the samples done.

        Segments are transformed a batch at a time so the tap spectrum (nf x n_out x n_in,
        75 MB for 12x12 channels and 8192 taps) is streamed from memory once per batch
        instead of once per segment, and each frequency's matmul is (o x i) @ (i x batch)
        rather than a matrix-vector product: 2.5x faster on long records (measured, 1 h).
        """
        seg_len = self._segment_len
        n_full = x.shape[1] // seg_len
        if n_full < 2:
            return 0
        n_taps = self._fir.n_taps
        n_fft = scipy.fft.next_fast_len(seg_len + n_taps - 1, real=True)
        n_conv = seg_len + n_taps - 1
        spectrum = self._tap_spectrum(n_fft)                                   # (nf, o, i)
        for first in range(0, n_full, _SEGMENTS_PER_BATCH):
            k = min(_SEGMENTS_PER_BATCH, n_full - first)
            seg = x[:, first * seg_len:(first + k) * seg_len].reshape(self.n_in, k, seg_len)
            x_f = scipy.fft.rfft(seg, n=n_fft, axis=-1)                        # (i, k, nf)
            y_f = np.matmul(spectrum, np.ascontiguousarray(x_f.transpose(2, 0, 1)))
            y = scipy.fft.irfft(np.ascontiguousarray(y_f.transpose(1, 2, 0)), n=n_fft,
                                axis=-1)                                       # (o, k, n_fft)
            for j in range(k):
                at = (first + j) * seg_len
                acc[:, at:at + n_conv] += y[:, j, :n_conv]
        return n_full * seg_len

    def process(self, x_block) -> np.ndarray:
        """
        Filter the next block of the input stream.

        Parameters
        ----------
        x_block : array_like, shape (n_in, m)
            Next ``m >= 0`` input samples [input unit].

        Returns
        -------
        numpy.ndarray, shape (n_out, m), float64
            Next ``m`` output samples [output unit], lagged by ``delay_samples``.

        Raises
        ------
        ShapeError
            ``x_block`` is not 2-D with ``n_in`` channels.
        NonFiniteError
            ``x_block`` holds NaN or infinity (the filter state is left unchanged).

        """
        name = f'filter input block at stream sample {self._n_seen}'
        x = np.asarray(x_block, dtype=np.float64)
        if x.ndim != 2 or x.shape[0] != self.n_in:
            raise ShapeError(f'{name}: expected shape ({self.n_in}, m), got {x.shape}')
        x = as_signals(x, name, min_samples=0)
        m = x.shape[1]
        n_taps = self._fir.n_taps
        acc = np.zeros((self.n_out, m + n_taps - 1))
        acc[:, :n_taps - 1] = self._tail
        start = self._full_segments(x, acc)
        for start in range(start, m, self._segment_len):
            seg = x[:, start:start + self._segment_len]
            n_conv = seg.shape[1] + n_taps - 1
            n_fft = scipy.fft.next_fast_len(n_conv, real=True)
            spectrum = self._tap_spectrum(n_fft)                        # (nf, o, i)
            x_f = scipy.fft.rfft(seg, n=n_fft, axis=-1)                 # (i, nf)
            # Frequency as the batch axis of matmul: 2-3x faster than einsum (measured).
            y_f = np.matmul(spectrum, x_f.T[:, :, np.newaxis])[:, :, 0]  # (nf, o)
            acc[:, start:start + n_conv] += scipy.fft.irfft(y_f.T, n=n_fft, axis=-1)[:, :n_conv]
        self._tail = acc[:, m:].copy()
        self._n_seen += m
        return acc[:, :m]


def apply_fir(fir: FirFilter, x, block_size: Optional[int] = None,
              name: str = 'FIR input') -> np.ndarray:
    """
    Filter a whole record, time-aligned, with the streaming :class:`OverlapAddFilter`.

    The record is fed in blocks and ``delay_samples`` zeros are fed after it to drain the
    look-ahead; the stream lag is then removed, so ``y[:, n]`` is the estimate for ``x[:, n]``.
    The data itself is never padded or altered; the filter simply sees zeros outside the
    record, so the first ``n_taps - 1 - delay_samples`` and the last ``delay_samples`` output
    samples (``n_taps - 1`` in total) are edge transients.

    Parameters
    ----------
    fir : FirFilter
        The filter.
    x : array_like, shape (n_in, n)
        Input record [input unit], ``n >= 1``.
    block_size : int, optional
        Samples per :meth:`OverlapAddFilter.process` call (bounds memory, not the result);
        default 2**16.
    name : str
        What ``x`` is, for error messages.

    Returns
    -------
    numpy.ndarray, shape (n_out, n), float64
        Filtered record [output unit], aligned with ``x``.

    Raises
    ------
    ShapeError
        ``x`` is not 2-D with ``fir.n_in`` channels.
    InsufficientDataError
        ``x`` has no samples.
    NonFiniteError
        ``x`` holds NaN or infinity.
    ConfigError
        ``block_size`` is not a positive integer.

    """
    x = as_signals(x, name)
    if x.shape[0] != fir.n_in:
        raise ShapeError(f'{name}: expected {fir.n_in} channels, got {x.shape[0]}')
    block = 1 << 16 if block_size is None else as_index(block_size, 'block_size')
    if block < 1:
        raise ConfigError(f'block_size must be >= 1, got {block}')
    n = x.shape[1]
    delay = fir.delay_samples
    engine = OverlapAddFilter(fir)
    y = np.empty((fir.n_out, n))
    # Stream output j is the estimate for input j - delay: keep j in [delay, n + delay).
    for start in range(0, n, block):
        out = engine.process(x[:, start:start + block])
        first = max(start, delay)
        if first < start + out.shape[1]:
            y[:, first - delay:start + out.shape[1] - delay] = out[:, first - start:]
    out = engine.process(np.zeros((fir.n_in, delay)))
    first = max(n, delay)
    y[:, first - delay:] = out[:, first - n:]
    return y
