"""Closed forms and vectorised paths of the effect chains (issue 15, speed) against scipy."""

import numpy as np
import pytest
from scipy import signal

from tcomp_core.effects.chain import (
    SHIFT_HALF_TAPS,
    _steady_filter,
    bilinear_first_order,
    fractional_shift,
)


@pytest.mark.parametrize("seed", range(6))
def test_equals_scipy_bilinear(seed):
    rng = np.random.default_rng(seed)
    numerator = tuple(rng.uniform(0.001, 5.0, 2))
    denominator = tuple(rng.uniform(0.001, 5.0, 2))
    fs = float(rng.uniform(50.0, 50_000.0))
    expected_b, expected_a = signal.bilinear(list(numerator), list(denominator), fs)
    b, a = bilinear_first_order(numerator, denominator, fs)
    assert np.allclose(b, expected_b, rtol=1e-12, atol=1e-15)
    assert np.allclose(a, expected_a, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("seed", range(4))
def test_steady_filter_equals_lfilter_from_lfilter_zi(seed):
    rng = np.random.default_rng(seed)
    b, a = bilinear_first_order(
        tuple(rng.uniform(0.01, 2.0, 2)), tuple(rng.uniform(0.01, 2.0, 2)), 500.0
    )
    values = 20.0 + np.cumsum(rng.standard_normal(300))
    excess = float(rng.normal())
    zi = signal.lfilter_zi(b, a) * values[0] + excess
    expected = signal.lfilter(b, a, values, zi=zi)[0]
    assert np.allclose(_steady_filter(b, a, values, excess), expected, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("shift", [-17.3, -2.5, 0.0, 0.25, 3.75, 40.0])
def test_fractional_shift_equals_the_explicit_stencil_sum(shift):
    rng = np.random.default_rng(3)
    values = np.cumsum(rng.standard_normal(200))
    shifted, weights = fractional_shift(values, shift)
    whole = int(np.floor(shift))
    first_offset = whole - SHIFT_HALF_TAPS + 1
    expected = np.full(values.size, np.nan)
    for k in range(values.size):
        stencil = k + first_offset + np.arange(weights.size)
        if stencil[0] >= 0 and stencil[-1] < values.size:
            expected[k] = float(np.dot(weights, values[stencil]))
    assert np.array_equal(np.isnan(shifted), np.isnan(expected))
    assert np.allclose(shifted, expected, rtol=0, atol=1e-12, equal_nan=True)
