"""The closed-form first-order bilinear transform of the effect chains (issue 15, speed)."""

import numpy as np
import pytest
from scipy import signal

from tcomp_core.effects.chain import bilinear_first_order


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
