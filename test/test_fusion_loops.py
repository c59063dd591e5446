"""The Kalman filters' compiled loops (tcomp_core.fusion.loops) against the computations
they replace: scipy's Riccati solver, the forward pass's filters, the causal filter's
covariance recursion as numpy computes it, and the same loops run by Python."""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
import pytest
import scipy.linalg
from sim_records import make_pair

from tcomp_core.fusion import causal, fitting, kalman, loops

#: log10 offsets of each model's hyper-parameters around its reference scale (fitting.py's
#: search coordinates), from far below to far above what records give.
SPREAD = (-8.0, -2.0, 3.0)


@functools.cache
def fitting_of(kind: str, noise_percent: float = 1.0) -> fitting._Fitting:
    pair = make_pair(kind, duration=4.0, noise_percent=noise_percent, seed=5)
    return fitting._prepare(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, None, None)


def models(fit: fitting._Fitting):
    """Every kind of signal model over a spread of its hyper-parameters."""
    for order, variance, cutoff, level in itertools.product(
        fitting.BAND_LIMITED_ORDERS, SPREAD, (-2.9, -1.0, -0.05), SPREAD
    ):
        yield fitting._band_limited_model(fit, [variance, cutoff, level - 4.0], order)
    for drive, level in itertools.product(SPREAD, SPREAD):
        yield fitting._periodic_model(fit, [drive, level - 4.0])
    for kind, scale in itertools.product(("random-walk", "integrated-random-walk"), SPREAD):
        yield fitting._random_walk_model(fit, kind, [scale])
    yield fitting._fit_autoregressive(fit)


def riccati_residual(space, predicted):
    """|F (P − K S Kᵀ) Fᵀ + Q − P| relative to |P| (max norms)."""
    f, h = space.transition, space.observation
    innovation = h @ predicted @ h.T + space.noise
    filtered = predicted - predicted @ h.T @ np.linalg.solve(innovation, h @ predicted)
    residual = f @ filtered @ f.T + space.covariance - predicted
    return np.max(np.abs(residual)) / np.max(np.abs(predicted))


@pytest.mark.parametrize("kind", ["multisine", "ramp"])
def test_doubling_solves_the_riccati_equation_as_scipy_does_or_hands_it_over(kind):
    doubled = compared = 0
    for model in models(fitting_of(kind)):
        space = model.state_space()
        found = loops.riccati_by_doubling(
            space.transition, space.observation, space.covariance, space.noise
        )
        if found is None:
            continue
        doubled += 1
        assert riccati_residual(space, found) <= loops.DOUBLING_RESIDUAL
        try:
            expected = scipy.linalg.solve_discrete_are(
                space.transition.T, space.observation.T, space.covariance, space.noise
            )
        except (np.linalg.LinAlgError, ValueError):
            continue  # scipy's QZ gives up where doubling solves it: the residual says so
        # Two solutions agree only as far as the equation pins P down: a residual r allows an
        # error up to about cond(P) r (a band-limited model with P's entries from 1e-12 to 6e4,
        # cond 3e14, gave scipy a residual of 3e-13 and the doubling 6e-16, 6e-6 apart).
        if riccati_residual(space, expected) * np.linalg.cond(expected) < 1e-7:
            compared += 1
            scale = np.max(np.abs(expected))
            assert np.max(np.abs(found - expected)) <= 1e-6 * scale, (model, found, expected)
    assert doubled >= 50  # the doubling is the rule, scipy the exception
    assert compared >= 20, compared  # 49 and 54 of 97


def test_a_badly_scaled_riccati_equation_is_handed_to_scipy():
    """A noise-free record floors σ near 1e-5 °C against a drive near 1e6 °C²: the doubling
    settles on a matrix that solves nothing (residual ~1), and scipy's balanced QZ solves it."""
    fit = fitting_of("ramp", noise_percent=0.0)
    space = fitting._periodic_model(fit, [3.0, -4.0]).state_space()
    assert np.max(space.noise) < 1e-8 and np.max(space.covariance) > 1e5
    assert (
        loops.riccati_by_doubling(
            space.transition, space.observation, space.covariance, space.noise
        )
        is None
    )
    gains = kalman.steady_state(space)
    assert riccati_residual(space, gains.predicted) < 1e-10


@pytest.mark.parametrize("kind", ["multisine", "sinusoid", "ramp", "exhaust"])
def test_the_modal_likelihood_is_the_forward_pass_likelihood(kind):
    fit = fitting_of(kind)
    compared = 0
    for model in models(fit):
        space = model.state_space()
        try:
            gains = kalman.steady_state(space)
        except (np.linalg.LinAlgError, ValueError):
            continue
        modal = kalman._modal_log_likelihood(space, gains, fit.y)
        if modal is None:
            continue
        passed = kalman.forward_pass(space, gains, fit.y, None, states=False).log_likelihood
        if not math.isfinite(passed):
            continue
        compared += 1
        # The same sums in another order; on the worst models (likelihoods of -1e4 to -1e7
        # nats, far from any fit) the initial state's projection cancels to ~1e-7 of them,
        # still far below the fit's tolerance of 0.05 nats (fitting._polish).
        assert modal == pytest.approx(passed, rel=1e-6), model
    assert compared >= 50


@pytest.mark.parametrize("kind", ["multisine", "exhaust"])
def test_the_likelihood_reuses_the_closed_loops_modes_to_the_bit(kind):
    # The stability check's eigen-decomposition is handed to the modal likelihood, and V⁻¹ on
    # to the initial state's equations, instead of being computed again: the same value.
    fit = fitting_of(kind)
    rng = np.random.default_rng(5)
    compared = 0
    for model in models(fit):
        space = model.state_space()
        try:
            gains, modes = kalman._steady_state(space, modes=True)
        except (np.linalg.LinAlgError, ValueError):
            continue
        np.testing.assert_array_equal(gains.gain, kalman.steady_state(space).gain)
        if modes is None:
            continue
        reused = kalman._modal_log_likelihood(space, gains, fit.y, modes)
        assert reused == kalman._modal_log_likelihood(space, gains, fit.y), model
        eigenvalues, vectors = modes
        condition = float(np.linalg.cond(vectors))
        if reused is None or condition > kalman.MAX_EIGENVECTOR_CONDITION:
            continue
        whitened = rng.standard_normal(fit.y.shape)
        given = (eigenvalues, vectors, condition, np.linalg.inv(vectors))
        for mine, theirs in zip(
            kalman._initial_state_equations(gains, whitened, given),
            kalman._initial_state_equations(gains, whitened),
            strict=True,
        ):
            assert mine.tobytes() == theirs.tobytes(), model
        compared += 1
    assert compared >= 20


def test_the_symmetric_pseudo_inverse_is_numpys_to_the_bit():
    rng = np.random.default_rng(11)
    for trial in range(600):
        n = int(rng.integers(1, 12))
        factor = rng.standard_normal((n, max(1, n - trial % 3))) * 10.0 ** rng.uniform(-6, 6)
        matrix = factor @ factor.T  # full rank, or short of it by one or two
        if trial % 5 == 0:
            matrix -= rng.uniform(0.0, 2.0) * np.abs(matrix).max() * np.eye(n)  # indefinite
        expected = np.linalg.pinv(matrix, rcond=1e-13, hermitian=True)
        assert kalman._pinv_symmetric(matrix, 1e-13).tobytes() == expected.tobytes(), matrix


def test_the_compiled_loops_compute_what_python_computes():
    """numba's kernels against the same functions run by Python, on a band-limited model."""
    fit = fitting_of("multisine")
    space = fitting._band_limited_model(fit, [0.0, -1.0, -10.0], 4).state_space()
    coupling = space.observation.T @ np.linalg.solve(space.noise, space.observation)
    arguments = (
        np.ascontiguousarray(space.transition.T),
        coupling,
        space.covariance,
        loops.DOUBLING_TOLERANCE,
        loops.DOUBLING_STEPS,
    )
    compiled_doubling, compiled_modes, compiled_sums, _ = loops._kernels()
    assert compiled_doubling is not loops._doubling  # numba is installed: these are compiled
    expected, steps = loops._doubling(*arguments)
    found, found_steps = compiled_doubling(*arguments)
    assert found_steps == steps > 0
    np.testing.assert_allclose(found, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))

    gains = kalman.steady_state(space)
    eigenvalues, vectors = np.linalg.eig(gains.closed_loop)
    inverse = np.linalg.inv(vectors)
    drive = inverse @ (space.transition @ gains.gain)
    read = vectors[-2:].astype(np.complex128)
    poles = eigenvalues.astype(np.complex128)
    y = np.ascontiguousarray(fit.y[:, :500])
    whitened = {}
    for name, function in (("python", loops._modal_innovations), ("numba", compiled_modes)):
        whitened[name] = np.empty(y.shape)
        function(poles, drive.astype(np.complex128), read, y, 2.0, 0.5, 1.5, whitened[name])
    np.testing.assert_allclose(whitened["numba"], whitened["python"], rtol=1e-12, atol=1e-12)

    reach = np.array([500, 3, 0, 250][: poles.size] + [500] * max(0, poles.size - 4))
    sums = {}
    for name, function in (("python", loops._discounted), ("numba", compiled_sums)):
        sums[name] = np.empty((2, poles.size), dtype=np.complex128)
        function(whitened["python"], poles, reach, sums[name])
    np.testing.assert_allclose(sums["numba"], sums["python"], rtol=1e-12, atol=1e-12)
    # The sums themselves, as numpy writes them.
    for i, pole in enumerate(poles):
        expected_sum = whitened["python"][:, : reach[i]] @ pole ** np.arange(reach[i])
        np.testing.assert_allclose(sums["python"][:, i], expected_sum, rtol=1e-10, atol=1e-10)


def numpy_schedule(space, target, tolerance, max_steps):
    """The time-varying Kalman recursion as matrix products (the causal filter's former code)."""
    f, noise, covariance, c = space.transition, space.noise, space.covariance, space.output
    predicted = np.diag(space.prior_std**2)
    identity = np.eye(f.shape[0])
    rows = {"gains": [], "std": [], "inverse": [], "log_det": [], "var": [c @ predicted @ c]}
    for _ in range(max_steps):
        innovation = predicted[-2:, -2:] + noise
        inverse = np.linalg.inv(innovation)
        gain = predicted[:, -2:] @ inverse
        update = identity.copy()
        update[:, -2:] -= gain
        filtered = update @ predicted @ update.T + gain @ noise @ gain.T
        predicted = f @ filtered @ f.T + covariance
        predicted = 0.5 * (predicted + predicted.T)
        rows["gains"].append(gain)
        rows["std"].append(math.sqrt(max(c @ filtered @ c, 0.0)))
        rows["inverse"].append(inverse)
        rows["log_det"].append(np.linalg.slogdet(innovation)[1])
        rows["var"].append(c @ predicted @ c)
        if np.abs(gain - target).max() <= tolerance:
            break
    return tuple(np.array(rows[name]) for name in ("gains", "std", "inverse", "log_det", "var"))


@pytest.mark.parametrize("kind", ["multisine", "sinusoid"])
def test_the_causal_filters_start_is_the_kalman_recursion(kind, monkeypatch):
    """Every kind of model: the same steps to convergence, the same gains and variances, as
    the causal filter builds its start (ExactSchedule, at most 300 steps here)."""
    monkeypatch.setattr(causal, "MAX_EXACT_SAMPLES", 300)
    fit = fitting_of(kind)
    compared = 0
    for model in itertools.islice(models(fit), 0, None, 4):
        space = model.state_space()
        try:
            target = kalman.steady_state(space).gain
        except (np.linalg.LinAlgError, ValueError):
            continue
        tolerance = causal.GAIN_TOLERANCE * np.max(np.abs(target))
        expected = numpy_schedule(space, target, tolerance, 300)
        schedule = causal.ExactSchedule.of(space, target)
        found = (
            schedule.gains,
            schedule.std,
            schedule.inverse,
            schedule.log_det,
            schedule.predicted_var,
        )
        assert found[0].shape[0] == expected[0].shape[0], model
        # The recursion amplifies rounding: over 300 steps of these models, numpy's own results
        # move by up to 1e-7 of their largest entry when the prior moves by 2e-16.
        for got, want in zip(found, expected, strict=True):
            assert np.max(np.abs(got - want)) <= 1e-6 * np.max(np.abs(want)), model
        compared += 1
    assert compared >= 10


def test_the_gain_solve_is_scipys_positive_definite_solve_to_the_bit():
    """The filter gain's 2×2 solve calls LAPACK's posv itself: scipy's result, its errors."""
    rng = np.random.default_rng(5)
    for columns in (3, 5, 11, 35):
        factor = rng.standard_normal((2, 2))
        matrix = factor @ factor.T + rng.uniform(1e-8, 1.0) * np.eye(2)
        rhs = rng.standard_normal((2, columns))
        expected = scipy.linalg.solve(matrix, rhs, assume_a="pos")
        assert np.array_equal(kalman._solve_positive(matrix, rhs), expected)
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        kalman._solve_positive(np.array([[1.0, 2.0], [2.0, 1.0]]), np.ones((2, 3)))
    with pytest.raises(ValueError, match="infs or NaNs"):
        kalman._solve_positive(np.array([[1.0, 0.0], [0.0, np.nan]]), np.ones((2, 3)))
