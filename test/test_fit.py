"""The free-run prediction of tc2 from tc1 (Eq. 8) and its fit error, against a slow reference."""

from __future__ import annotations

import numpy as np
import pytest

from tcomp_core.fit import fit_error_percent, rms_about_mean, simulate_tc2_from_tc1


def _difference_equation(tc1: np.ndarray, initial_tc2: float, a1: float, a2: float) -> np.ndarray:
    """Eq. (8) sample by sample: tc2[k] = a2 tc2[k-1] + (1-a2)/(1-a1) (tc1[k] - a1 tc1[k-1])."""
    gain = (1.0 - a2) / (1.0 - a1)
    out = [initial_tc2]
    for k in range(1, tc1.size):
        out.append(a2 * out[-1] + gain * (tc1[k] - a1 * tc1[k - 1]))
    return np.array(out)


@pytest.mark.parametrize("size", [1, 2, 500])
def test_prediction_equals_the_difference_equation(size):
    rng = np.random.default_rng(5)
    tc1 = 300.0 + 20.0 * rng.standard_normal(size)
    predicted = simulate_tc2_from_tc1(tc1, 301.5, 0.9, 0.98)
    np.testing.assert_allclose(predicted, _difference_equation(tc1, 301.5, 0.9, 0.98), atol=1e-9)


def test_fit_error_restarts_from_the_measurement_after_a_gap():
    rng = np.random.default_rng(6)
    tc1 = 300.0 + 20.0 * rng.standard_normal(400)
    a1, a2 = 0.9, 0.98
    # tc2 follows Eq. (8) on each side of a gap at 250, with a jump across it.
    tc2 = np.concatenate(
        (
            _difference_equation(tc1[:250], 300.0, a1, a2),
            _difference_equation(tc1[250:], 340.0, a1, a2),
        )
    )
    assert fit_error_percent(tc1, tc2, a1, a2, np.array([250])) < 1e-9
    assert fit_error_percent(tc1, tc2, a1, a2) > 1.0  # run across the gap, the jump decays


def test_rms_about_mean_is_numpy_std():
    rng = np.random.default_rng(4)
    block = rng.normal(300.0, 7.0, (5000, 2))
    for values in (block[:, 1], block[:, 0], rng.normal(size=3), np.full(10, 2.5)):
        assert rms_about_mean(values) == pytest.approx(float(np.std(values)), rel=1e-12, abs=0)
