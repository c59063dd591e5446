"""Closed forms and vectorised paths of the effect chains (issue 15, speed) against scipy."""

import numpy as np
import pytest

from tcomp_core.effects.base import KELVIN
from tcomp_core.effects.chain import SHIFT_HALF_TAPS, _fin_filters, fractional_shift
from tcomp_core.effects.conduction import FIN_TERMS, fin_filter, fin_kappa, fin_length


def _evaluate(zeros_poles, s):
    zeros, poles = zeros_poles
    return np.prod(s[:, None] - zeros, axis=1) / np.prod(s[:, None] - poles, axis=1)


@pytest.mark.parametrize(
    ("fin_ml", "tau", "tau_p"), [(0.5, 0.1, 2.0), (1.8, 0.02, 1.0), (4.0, 0.2, 5.0)]
)
def test_fin_filter_is_the_fin_transfer_function(fin_ml, tau, tau_p):
    # M(s) = 1 - (tau_p - tau) s sech(mL sqrt(1 + tau s)) / (1 + tau_p s) and its inverse.
    s = 2j * np.pi * np.geomspace(1e-3, 10.0, 40) / tau
    exact = 1 - (tau_p - tau) * s / np.cosh(fin_ml * np.sqrt(1 + tau * s)) / (1 + tau_p * s)
    zeros, poles = fin_filter(tau, fin_ml, tau_p, FIN_TERMS)
    error = np.abs(_evaluate((zeros, poles), s) - exact)
    assert np.max(error[np.abs(s) * tau <= 2 * np.pi]) < 5e-3
    assert np.max(error) < 1e-2
    assert np.all(zeros.real < 0)  # minimum phase: M inverts stably


@pytest.mark.parametrize("fin_ml", [0.5, 2.0])
def test_fin_filters_in_discrete_time_invert_each_other_from_a_steady_start(fin_ml):
    rng = np.random.default_rng(3)
    dt = 0.002
    values = 300.0 + np.cumsum(rng.standard_normal(4000))
    forward, inverse = _fin_filters(0.05, fin_ml, 1.5, dt)
    assert np.allclose(inverse(forward(values)), values, rtol=0, atol=1e-8)
    assert np.allclose(forward(np.full(50, 300.0)), 300.0, rtol=0, atol=1e-9)  # steady
    # The bilinear filter follows M(j w) at a tenth of the sample rate.
    tone = np.sin(2 * np.pi * 50.0 * dt * np.arange(4000))
    out = forward(tone)[2000:]
    warped = np.tan(np.pi * 50.0 * dt) / (np.pi * 50.0 * dt)  # bilinear frequency warping
    s = np.array([2j * np.pi * 50.0 * warped])
    expected = _evaluate(fin_filter(0.05, fin_ml, 1.5), s)[0]
    assert np.std(out) * np.sqrt(2) == pytest.approx(abs(expected), rel=2e-3)


def test_fin_kappa_and_length_are_inverse_and_match_the_steady_fin():
    for fin_ml in (0.3, 1.0, 2.5, 6.0):
        kappa = fin_kappa(fin_ml)
        assert fin_length(kappa) == pytest.approx(fin_ml, rel=1e-12)
        # Steady junction of the lumped model, 1/(1 + kappa), is 1 - sech(mL) of the fin.
        assert 1.0 / (1.0 + kappa) == pytest.approx(1.0 - 1.0 / np.cosh(fin_ml), rel=1e-12)
    assert fin_length(0.0) == np.inf and fin_kappa(np.inf) == 0.0


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


@pytest.mark.parametrize("radiating", [False, True])
@pytest.mark.parametrize("film", [None, 1.0, 0.8])
def test_the_compiled_lag_loops_step_as_the_python_recurrence(radiating, film):
    """numba's loops (tcomp_core.effects.recurrence) against the same functions run by Python."""
    from tcomp_core.effects import recurrence

    rng = np.random.default_rng(17)
    n = 3000
    drive = 600.0 + 150.0 * rng.standard_normal(n)
    poles = np.exp(-1e-3 / (0.02 * (1.0 + 0.4 * np.sin(np.arange(n) / 97.0))))
    r, wall4 = (2e-12, 350.0**4) if radiating else (0.0, 0.0)
    expected = np.empty(n + 1)
    if film is None:
        recurrence._lag_steps(drive, poles, 580.0, r, wall4, expected)
        found = recurrence.lag_steps(drive, poles, 580.0, r, wall4)
    else:
        level = (0.6, 850.0, drive + 3.0, 0.5, film)
        recurrence._level_lag_steps(drive, poles, 580.0, r, wall4, *level, expected)
        found = recurrence.level_lag_steps(drive, poles, 580.0, r, wall4, level)
    assert recurrence._kernels()[0] is not recurrence._lag_steps  # compiled, not the fallback
    np.testing.assert_allclose(found, expected, rtol=1e-13, atol=0.0)
    # the recurrence itself, one step written out
    k = n // 2
    pole = poles[k] if film is None else None
    if pole is not None:
        loss = r * ((expected[k] + KELVIN) ** 4 - wall4)
        step = pole * expected[k] + (1.0 - pole) * (drive[k] - loss)
        assert found[k + 1] == pytest.approx(step, rel=1e-14)


def test_the_lag_loops_compile_in_memory_where_no_cache_can_be_written(monkeypatch):
    """numba refuses ``cache=True`` (RuntimeError) where no cache directory is writable."""
    import numba

    from tcomp_core.effects import recurrence

    plain_njit = numba.njit

    def njit(*args, **kwargs):
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function: no locator available")
        return plain_njit(*args, **kwargs)

    monkeypatch.setattr(numba, "njit", njit)
    recurrence._kernels.cache_clear()
    try:
        drive = np.linspace(500.0, 600.0, 50)
        poles = np.full(50, 0.9)
        found = recurrence.lag_steps(drive, poles, 500.0, 0.0, 0.0)
        assert recurrence._kernels()[0] is not recurrence._lag_steps
    finally:
        recurrence._kernels.cache_clear()
    expected = np.empty(51)
    recurrence._lag_steps(drive, poles, 500.0, 0.0, 0.0, expected)
    np.testing.assert_allclose(found, expected, rtol=1e-14)
