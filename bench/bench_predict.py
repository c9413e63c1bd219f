# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""
Time force prediction: 12-in / 12-out FIR (1024 taps) over one hour of 512 Hz data.

Prints, from one run:
- batch ``apply_fir`` throughput as a multiple of real time (goal >= 2000x), next to the
  baseline of 144 pair-by-pair ``scipy.signal.oaconvolve`` calls (and ``fftconvolve`` timed on
  one output channel, 12 pairs, extrapolated to 144), with the largest difference between them;
- streaming ``OverlapAddFilter.process`` cost per block (mean and p99 in us) for the block
  lengths the node may use, and the resulting real-time factor;
- the per-frequency 12x12 multiply done by ``matmul`` (used) versus ``einsum``;
- short records, each through a new filter over one model's read-only 8192 taps (what the
  diagnosis does ~400 times per case): the tap spectra shared across filters
  (``overlap_add._SHARED``) against the same calls with that cache emptied before each one.

Usage: ``.venv/bin/python bench/bench_predict.py [--minutes 60] [--blocks 2000]``.
"""
import argparse
import time

from benchutil import best_of
import numpy as np
from scipy import signal
import scipy.fft

from wheel_force_estimator.core import overlap_add
from wheel_force_estimator.core.filtering import fir_from_frf
from wheel_force_estimator.core.filtering import FirFilter
from wheel_force_estimator.core.overlap_add import apply_fir
from wheel_force_estimator.core.overlap_add import OverlapAddFilter

FS_HZ = 512.0
N_CH = 12
N_FFT = 1024


def make_fir(rng, n_fft=N_FFT):
    """Return a 12x12 FIR of ``n_fft`` taps from a smooth random FRF (two resonances/pair)."""
    f_hz = np.arange(n_fft // 2 + 1) * FS_HZ / n_fft
    s = 2j * np.pi * f_hz[:, None, None]
    h = np.zeros((f_hz.size, N_CH, N_CH), complex)
    for f0_hz, zeta in ((1.5, 0.3), (12.0, 0.15)):
        w0 = 2 * np.pi * f0_hz * rng.uniform(0.8, 1.2, (N_CH, N_CH))
        h += rng.standard_normal((N_CH, N_CH)) * w0 ** 2 / (s ** 2 + 2 * zeta * w0 * s + w0 ** 2)
    return fir_from_frf(f_hz, h, FS_HZ)


def pairwise(conv, fir, x, outputs):
    """Time-aligned prediction of ``outputs`` by one ``conv(x_i, taps_oi)`` per pair."""
    n, d = x.shape[1], fir.delay_samples
    y = np.zeros((len(outputs), n))
    for row, o in enumerate(outputs):
        for i in range(fir.n_in):
            y[row] += conv(x[i], fir.taps[o, i])[d:d + n]
    return y


def multiply_us(n_fft, rng):
    """Time the per-frequency (12x12) @ (12,) products at ``n_fft``: matmul vs einsum."""
    nf = n_fft // 2 + 1
    spectrum = rng.standard_normal((nf, N_CH, N_CH)) + 1j * rng.standard_normal((nf, N_CH, N_CH))
    x_f = rng.standard_normal((N_CH, nf)) + 1j * rng.standard_normal((N_CH, nf))
    t_mm, _ = best_of(lambda: np.matmul(spectrum, x_f.T[:, :, np.newaxis]), 50)
    t_es, _ = best_of(lambda: np.einsum('foi,if->of', spectrum, x_f), 50)
    return 1e6 * t_mm, 1e6 * t_es


def main():
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--minutes', type=float, default=60.0, help='record length [min]')
    parser.add_argument('--blocks', type=int, default=2000, help='streaming calls per size')
    args = parser.parse_args()
    rng = np.random.default_rng(2026)
    fir = make_fir(rng)
    n = int(args.minutes * 60.0 * FS_HZ)
    duration_s = n / FS_HZ
    x = rng.standard_normal((N_CH, n))
    print(f'FIR {fir.n_out}x{fir.n_in}x{fir.n_taps} taps (look-ahead {fir.delay_samples}), '
          f'{duration_s / 60:.0f} min at {FS_HZ:g} Hz = {n} samples x {N_CH} channels')

    t_ours, y = best_of(lambda: apply_fir(fir, x), 3)
    t_oa, y_oa = best_of(lambda: pairwise(signal.oaconvolve, fir, x, range(N_CH)), 1)
    t_fft_row, y_fft = best_of(lambda: pairwise(signal.fftconvolve, fir, x, [0]), 1)
    t_fft = t_fft_row * N_CH
    scale = np.abs(y_oa).max()
    diff_oa = np.abs(y - y_oa).max() / scale
    diff_fft = np.abs(y[:1] - y_fft).max() / scale
    print('\nbatch prediction (best wall time)')
    print(f'{"method":48s} {"time s":>8s} {"x real time":>12s} {"max |diff|/max|y|":>18s}')
    print(f'{"apply_fir (OverlapAddFilter, matmul)":48s} {t_ours:8.3f} '
          f'{duration_s / t_ours:12.0f} {"-":>18s}')
    print(f'{"baseline: oaconvolve, 144 pairs":48s} {t_oa:8.3f} {duration_s / t_oa:12.0f} '
          f'{diff_oa:18.1e}')
    print(f'{"baseline: fftconvolve, 12 pairs x 12 (extrap.)":48s} {t_fft:8.3f} '
          f'{duration_s / t_fft:12.0f} {diff_fft:18.1e}')
    print(f'speed-up over oaconvolve: {t_oa / t_ours:.1f}x; goal >= 2000x real time: '
          f'{"met" if duration_s / t_ours >= 2000 else "NOT met"}')

    print(f'\nstreaming OverlapAddFilter.process, {args.blocks} calls per block length')
    print(f'{"block":>6s} {"block ms":>9s} {"mean us":>9s} {"p99 us":>9s} {"x real time":>12s}')
    for m in (1, 64, 128, 256, 512):
        engine = OverlapAddFilter(fir)
        n_calls = min(args.blocks, n // m)
        times = np.empty(n_calls)
        for k in range(n_calls):
            block = x[:, k * m:(k + 1) * m]
            t0 = time.perf_counter()
            engine.process(block)
            times[k] = time.perf_counter() - t0
        times = times[1:]            # the first call builds the cached tap spectrum
        mean_s = times.mean()
        print(f'{m:6d} {1e3 * m / FS_HZ:9.2f} {1e6 * mean_s:9.1f} '
              f'{1e6 * np.percentile(times, 99):9.1f} {m / FS_HZ / mean_s:12.0f}')

    print('\nper-frequency 12x12 multiply, one block (best of 50)')
    print(f'{"n_fft":>6s} {"matmul us":>10s} {"einsum us":>10s}')
    for n_fft in (scipy.fft.next_fast_len(128 + N_FFT - 1, real=True), 8 * N_FFT):
        t_mm, t_es = multiply_us(n_fft, rng)
        print(f'{n_fft:6d} {t_mm:10.0f} {t_es:10.0f}')

    short_records(rng)


def short_records(rng, n_records=20):
    """Print the shared tap-spectrum cache against re-transforming the taps per filter."""
    model_fir = make_fir(rng, 8192)
    records = [rng.standard_normal((N_CH, n)) for n in rng.integers(3000, 60000, n_records)]
    n_s = sum(r.shape[1] for r in records)

    def run(shared):
        out = []
        for x in records:
            if not shared:
                overlap_add._SHARED.clear()
            fir = FirFilter(model_fir.taps, model_fir.delay_samples, FS_HZ)   # a new filter
            out.append(apply_fir(fir, x))
        return out

    run(True)                       # warm: both variants then start from a filled cache
    t_shared, y_shared = best_of(lambda: run(True), 3)
    t_fresh, y_fresh = best_of(lambda: run(False), 3)
    diff = max(np.abs(a - b).max() for a, b in zip(y_shared, y_fresh))
    print(f'\n{n_records} records ({n_s / FS_HZ:.0f} s in all, 3000-60000 samples each), '
          f'a new filter over one {model_fir.n_out}x{model_fir.n_in}x{model_fir.n_taps} '
          f'taps array per record (best of 3)')
    print(f'{"tap spectra":48s} {"time s":>8s} {"ms/record":>10s}')
    print(f'{"shared across filters (used)":48s} {t_shared:8.3f} '
          f'{1e3 * t_shared / n_records:10.1f}')
    print(f'{"baseline: transformed again per filter":48s} {t_fresh:8.3f} '
          f'{1e3 * t_fresh / n_records:10.1f}')
    print(f'speed-up {t_fresh / t_shared:.2f}x, max |difference| {diff:.1e} (expected 0: the '
          f'same spectrum); cache held {overlap_add._SHARED.n_bytes / 2**20:.0f} MiB')


if __name__ == '__main__':
    main()
