# Copyright 2026 wheel_force_estimator contributors
# SPDX-License-Identifier: Apache-2.0
"""The tap-spectrum cache shared by overlap-add filters: identity, LRU bound, freed taps."""
import gc

import numpy as np

from wheel_force_estimator.core.overlap_add import _SharedSpectra
from wheel_force_estimator.core.validation import read_only_array


def _frozen(rng, shape=(2, 2, 8)):
    taps = rng.standard_normal(shape)
    taps.flags.writeable = False
    return taps


def test_a_spectrum_is_served_only_for_the_same_array_object():
    rng = np.random.default_rng(1)
    cache = _SharedSpectra(max_bytes=2**20)
    taps = _frozen(rng)
    spectrum = np.ones((5, 2, 2), complex)
    cache.put(taps, 8, spectrum)
    assert cache.get(taps, 8) is spectrum
    assert cache.get(taps, 16) is None
    assert cache.get(taps.copy(), 8) is None          # equal values, another array
    assert cache.n_bytes == spectrum.nbytes and len(cache) == 1


def test_least_recently_used_spectra_go_first_within_the_byte_bound():
    rng = np.random.default_rng(2)
    one = np.ones((5, 2, 2), complex)                  # 320 bytes each
    cache = _SharedSpectra(max_bytes=2 * one.nbytes)
    a, b, c = _frozen(rng), _frozen(rng), _frozen(rng)
    cache.put(a, 8, one.copy())
    cache.put(b, 8, one.copy())
    assert cache.get(a, 8) is not None                 # a is now the most recent
    cache.put(c, 8, one.copy())
    assert cache.get(b, 8) is None
    assert cache.get(a, 8) is not None and cache.get(c, 8) is not None
    assert cache.n_bytes == 2 * one.nbytes
    cache.put(a, 4, np.ones((100, 2, 2), complex))     # larger than the bound: not held
    assert cache.get(a, 4) is None and len(cache) == 2


def test_spectra_of_a_freed_taps_array_are_dropped():
    rng = np.random.default_rng(3)
    cache = _SharedSpectra(max_bytes=2**20)
    taps, kept = _frozen(rng), _frozen(rng)
    cache.put(taps, 8, np.ones((5, 2, 2), complex))
    cache.put(taps, 16, np.ones((9, 2, 2), complex))
    cache.put(kept, 8, np.ones((5, 2, 2), complex))
    del taps
    gc.collect()
    assert len(cache) == 1 and cache.get(kept, 8) is not None
    assert cache.n_bytes == np.ones((5, 2, 2), complex).nbytes


def test_read_only_array_shares_only_arrays_nothing_can_write():
    rng = np.random.default_rng(4)
    frozen = _frozen(rng)
    assert read_only_array(frozen, np.float64) is frozen
    view = frozen[1:]                                  # read-only view of a read-only base
    assert read_only_array(view, np.float64) is view
    strided = frozen[:, :, ::2]                        # copied to C order, like any other
    assert read_only_array(strided, np.float64) is not strided
    assert read_only_array(strided, np.float64).flags.c_contiguous
    writable = rng.standard_normal((2, 2, 8))
    ro_view = writable.view()
    ro_view.flags.writeable = False                    # its base can still be written
    for value in (writable, ro_view, frozen.astype(np.float32), frozen.tolist()):
        out = read_only_array(value, np.float64)
        assert out is not value and not out.flags.writeable
        np.testing.assert_array_equal(out, np.asarray(value, np.float64))
    out = read_only_array(ro_view, np.float64)
    writable[:] = 0.0
    assert np.abs(out).max() > 0
