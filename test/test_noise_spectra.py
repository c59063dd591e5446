"""The noise measurement's Welch spectra are scipy's, computed on all segments at once."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from tcomp_core.noise import low_quantile, median, welch_spectra


@pytest.mark.parametrize("size", [1024, 5000, 10_001])
@pytest.mark.parametrize("nperseg", [16, 255, 1024])
@pytest.mark.parametrize("detrend", ["constant", "linear"])
def test_welch_and_csd_equal_scipy(size, nperseg, detrend):
    rng = np.random.default_rng(size + nperseg)
    time = np.arange(size) * 2e-4
    x = 300.0 + 40.0 * time + np.sin(2 * np.pi * 7 * time) + rng.standard_normal(size)
    y = 0.5 * x + rng.standard_normal(size)
    options = {"fs": 5000.0, "nperseg": nperseg, "detrend": detrend}
    freqs, psd = signal.welch(x, **options)
    _, cross = signal.csd(x, y, **options)
    mine_freqs, mine_psd, mine_cross = welch_spectra(x, 2e-4, nperseg, detrend, y)
    np.testing.assert_allclose(mine_freqs, freqs, rtol=1e-12)
    np.testing.assert_allclose(mine_psd, psd, rtol=1e-9, atol=1e-12 * psd.max())
    np.testing.assert_allclose(mine_cross, cross, rtol=1e-9, atol=1e-12 * np.abs(cross).max())
    assert welch_spectra(x, 2e-4, nperseg, detrend)[2] is None


@pytest.mark.parametrize("quantile", [0.0, 0.1, 0.2, 0.5, 0.9, 1.0])
def test_low_quantile_equals_numpy(quantile):
    rng = np.random.default_rng(round(100 * quantile))
    for size in [1, 2, 3, 10, 175, 176, 1000]:
        values = rng.exponential(size=size) * 10.0 ** rng.uniform(-6, 6)
        assert low_quantile(values, quantile) == float(np.quantile(values, quantile))


@pytest.mark.parametrize("overwrite", [False, True])
def test_median_equals_numpy_to_the_last_bit(overwrite):
    rng = np.random.default_rng(17)
    for size in [1, 2, 3, 10, 9998, 9999]:
        values = rng.normal(size=size) * 10.0 ** rng.uniform(-6, 6)
        expected = float(np.median(values))
        kept = values.copy()
        assert median(values, overwrite=overwrite) == expected
        if not overwrite:
            np.testing.assert_array_equal(values, kept)
        else:
            np.testing.assert_array_equal(np.sort(values), np.sort(kept))
