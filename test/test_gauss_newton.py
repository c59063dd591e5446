"""The lean Levenberg–Marquardt search ends where least_squares does, or hands over to it."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from tcomp_core.estimators.gauss_newton import (
    forward_jacobian,
    levenberg_marquardt,
    normal_matrix,
)


def _exponentials(seed: int):
    """Residual of y = a exp(-t / b) + c fitted to noisy data: x = (log a, log b, c)."""
    rng = np.random.default_rng(seed)
    time = np.linspace(0.0, 5.0, 400)
    data = 3.0 * np.exp(-time / 1.3) + 0.4 + rng.normal(0.0, 0.05, time.size)

    def residual(x):
        return np.exp(x[0]) * np.exp(-time / np.exp(x[1])) + x[2] - data

    return residual


def _counted(residual):
    """``residual`` and the list it appends to on every call."""
    calls = []

    def counted(x):
        calls.append(1)
        return residual(x)

    return counted, calls


def test_ends_at_the_minimum_least_squares_finds():
    bounds = (np.array([-5.0, -5.0, -2.0]), np.array([5.0, 5.0, 2.0]))
    for seed in range(5):
        residual = _exponentials(seed)
        start = np.array([np.log(2.5), np.log(1.0), 0.3])
        reference = least_squares(
            residual, start, jac="2-point", bounds=bounds, xtol=1e-12, ftol=1e-12
        )
        found = levenberg_marquardt(residual, start, bounds, xtol=1e-12, ftol=1e-12)
        assert found is not None and found.success
        np.testing.assert_allclose(found.x, reference.x, rtol=1e-8, atol=1e-10)
        assert abs(found.cost - reference.cost) <= 1e-10 * reference.cost
        np.testing.assert_allclose(found.jac, reference.jac, rtol=1e-5, atol=1e-7)
        assert found.nfev >= 1


def test_a_minimum_on_the_edge_is_left_to_least_squares():
    residual = _exponentials(0)
    start = np.array([np.log(2.5), np.log(1.0), 0.0])
    # The offset's bound below its best value (0.4): the minimum lies on the edge.
    bounds = (np.array([-5.0, -5.0, -0.1]), np.array([5.0, 5.0, 0.1]))
    assert levenberg_marquardt(residual, start, bounds, xtol=1e-12, ftol=1e-12) is None


def test_the_forward_jacobian_steps_back_from_the_upper_bound():
    def fun(x):
        return np.array([x[0] ** 2, 3.0 * x[1]])

    x = np.array([1.0, 2.0])
    jacobian = forward_jacobian(fun, x, fun(x), np.array([1.0, 10.0]))
    np.testing.assert_allclose(jacobian, [[2.0, 0.0], [0.0, 3.0]], rtol=1e-6, atol=1e-7)


def test_the_normal_matrix_is_jt_j_for_either_storage_order():
    rng = np.random.default_rng(23)
    jacobian = rng.normal(size=(1000, 3)) * np.array([1.0, 1e-4, 1e3])
    expected = jacobian.T @ jacobian
    for stored in (np.ascontiguousarray(jacobian), np.asfortranarray(jacobian)):
        found = normal_matrix(stored)
        np.testing.assert_allclose(found, expected, rtol=1e-12)
        np.testing.assert_array_equal(found, found.T)


def test_a_search_ends_before_a_trial_the_model_says_would_not_move_it(monkeypatch):
    from tcomp_core.estimators import gauss_newton

    bounds = (np.array([-5.0, -5.0, -2.0]), np.array([5.0, 5.0, 2.0]))
    start = np.array([np.log(2.5), np.log(1.0), 0.3])
    saved = 0
    for seed in range(5):
        counted, calls = _counted(_exponentials(seed))
        found = levenberg_marquardt(counted, start, bounds, xtol=1e-12, ftol=1e-12)
        shortcut = len(calls)
        calls.clear()
        with monkeypatch.context() as patch:
            patch.setattr(gauss_newton, "PREDICTED_SHARE", 0.0)  # every trial taken
            full = levenberg_marquardt(counted, start, bounds, xtol=1e-12, ftol=1e-12)
        assert found is not None and full is not None
        np.testing.assert_allclose(found.x, full.x, rtol=1e-8, atol=1e-10)
        assert shortcut <= len(calls)
        saved += len(calls) - shortcut
    assert saved >= 4  # at least one search skipped its last trial and Jacobian


def test_a_search_told_a_share_of_the_standard_errors_stops_within_it():
    bounds = (np.array([-5.0, -5.0, -2.0]), np.array([5.0, 5.0, 2.0]))
    stop_se = 1e-3
    saved = 0
    for seed in range(8):
        residual = _exponentials(seed)
        full = levenberg_marquardt(
            residual, np.array([1.0, 0.3, 0.4]), bounds, xtol=1e-12, ftol=1e-12
        )
        assert full is not None
        # A warm start: the minimum moved by about a third of a standard error, as a window's
        # does when the node's window slides on.
        sigma2 = 2.0 * full.cost / residual(full.x).size
        covariance = sigma2 * np.linalg.inv(full.jac.T @ full.jac)
        se = np.sqrt(np.diag(covariance))
        warm = full.x + 0.3 * se * np.array([1.0, -1.0, 1.0])
        counted, calls = _counted(residual)
        strict = levenberg_marquardt(counted, warm, bounds, xtol=1e-12, ftol=1e-12)
        strict_calls = len(calls)
        calls.clear()
        found = levenberg_marquardt(counted, warm, bounds, xtol=1e-12, ftol=1e-12, stop_se=stop_se)
        assert strict is not None and found is not None
        # Within the share asked of every standard error, and the Jacobian the end's own.
        assert np.all(np.abs(found.x - strict.x) <= stop_se * se), (found.x - strict.x) / se
        np.testing.assert_allclose(
            found.jac, forward_jacobian(residual, found.x, residual(found.x), bounds[1])
        )
        assert len(calls) <= strict_calls
        saved += strict_calls - len(calls)
    assert saved >= 8 * 4  # a Jacobian and its trial on every search
