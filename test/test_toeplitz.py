"""The tridiagonal Toeplitz whitening against a dense Cholesky factor, and its closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import cholesky, solve_triangular

from tcomp_core.estimators.toeplitz import ToeplitzWhitening, powers_minus_one


def _whitening(diagonal: float, off_diagonal: float, size: int) -> ToeplitzWhitening:
    root = float(np.sqrt(diagonal**2 - 4.0 * off_diagonal**2))
    return ToeplitzWhitening.from_bands(diagonal, off_diagonal, root, size)


@pytest.mark.parametrize(
    ("diagonal", "off_diagonal"),
    # The last two: a diagonal Σ, as a search's trial with its poles underflowed gives it (it
    # raised "math domain error" in ml-eiv on campaign draw 2169), and one a rounding away.
    [
        (2.5, -1.0),
        (683_000.0, -341_000.0),
        (3.0, -0.2),
        (2.0000002, -1.0),
        (1.7, 0.0),
        (1.7, -1e-170),
    ],
)
@pytest.mark.parametrize("size", [1, 7, 400])
def test_whitening_equals_the_inverse_cholesky_factor(diagonal, off_diagonal, size):
    sigma = (
        np.diag(np.full(size, diagonal))
        + np.diag(np.full(size - 1, off_diagonal), 1)
        + np.diag(np.full(size - 1, off_diagonal), -1)
    )
    factor = cholesky(sigma, lower=True)
    values = np.random.default_rng(size).standard_normal((3, size))
    expected = solve_triangular(factor, values.T, lower=True).T
    whitening = _whitening(diagonal, off_diagonal, size)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(whitening.apply(values), expected, rtol=1e-9, atol=1e-9 * scale)
    ones = solve_triangular(factor, np.ones(size), lower=True)
    np.testing.assert_allclose(whitening.constant(), ones, rtol=1e-9)
    np.testing.assert_allclose(whitening.constant(), whitening.apply(np.ones(size)), rtol=1e-12)


@pytest.mark.parametrize("log_s", [-1e-7, -0.0024, -0.3, -5.0])
@pytest.mark.parametrize("count", [1, 63, 64, 10_001])
def test_powers_minus_one_equal_expm1(log_s, count):
    expected = np.expm1(np.arange(1.0, count + 1.0) * log_s)
    np.testing.assert_allclose(powers_minus_one(log_s, count), expected, rtol=1e-13, atol=0.0)


def test_a_singular_covariance_is_refused():
    from tcomp_core.errors import EstimationError

    with pytest.raises(EstimationError, match="singular"):
        ToeplitzWhitening.from_bands(-1.0, -0.1, 0.5, 10)
