"""Steady-state Kalman filter: Riccati solution, forward pass and innovation likelihood.

For a time-invariant model the Kalman gain converges to a constant, found once from the
discrete algebraic Riccati equation; the filter is then a linear recursion
(:func:`~tcomp_core.fusion.recursion.linear_recursion`). Offline, the unknown initial state is
estimated by generalised least squares from the innovations (a diffuse prior).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .loops import discounted_sums, modal_innovations, riccati_by_doubling
from .recursion import (
    MAX_EIGENVECTOR_CONDITION,
    MODAL_CONDITION,
    decay_horizon,
    driven_states,
    matrix_powers,
)
from .signal_model import FusionModel, StateSpace

__all__ = [
    "ForwardPass",
    "SteadyState",
    "forward_pass",
    "innovation_log_likelihood",
    "steady_state",
]


@dataclass(frozen=True)
class SteadyState:
    """Steady-state Kalman quantities of a :class:`StateSpace`.

    Attributes
    ----------
    predicted : ndarray, shape (n, n)
        Covariance of the one-step prediction (solution of the Riccati equation).
    filtered : ndarray, shape (n, n)
        Covariance after the measurement update.
    gain : ndarray, shape (n, 2)
        ``x_{k|k} = x_{k|k-1} + gain (y_k - H x_{k|k-1})``.
    innovation : ndarray, shape (2, 2)
        Innovation covariance, °C².
    closed_loop : ndarray, shape (n, n)
        ``F (I - gain H)``, the matrix of the prediction recursion.
    """

    predicted: NDArray[np.float64]
    filtered: NDArray[np.float64]
    gain: NDArray[np.float64]
    innovation: NDArray[np.float64]
    closed_loop: NDArray[np.float64]


def steady_state(model: StateSpace) -> SteadyState:
    """Solve the discrete algebraic Riccati equation for the steady-state Kalman filter.

    By doubling (:func:`~tcomp_core.fusion.loops.riccati_by_doubling`, a few dozen
    microseconds); where that does not converge to a filter whose closed loop decays, by scipy's
    ``solve_discrete_are`` (a QZ decomposition, ten times slower), which raises if there is no
    stabilising solution.

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        If the Riccati equation has no stabilising solution (scipy's errors).
    """
    return _steady_state(model, modes=False)[0]


#: The closed loop's eigenvalues and eigenvectors (``np.linalg.eig``'s result).
_Modes = tuple[NDArray[np.complex128], NDArray[np.complex128]]


def _steady_state(model: StateSpace, modes: bool) -> tuple[SteadyState, _Modes | None]:
    """:func:`steady_state`, and with ``modes`` the closed loop's eigen-decomposition.

    The doubled solution is taken when its closed loop decays; the likelihood needs that
    loop's eigenvectors as well (:func:`_modal_log_likelihood`), so with ``modes`` the check
    reads the eigenvalues of ``np.linalg.eig`` and hands the decomposition on (None where
    scipy's solver gave the gains) instead of a second decomposition of the same matrix.
    """
    f, h = model.transition, model.observation
    doubled = riccati_by_doubling(f, h, model.covariance, model.noise)
    if doubled is not None:
        gains = _gains(model, doubled)
        if modes:
            eigenvalues, vectors = np.linalg.eig(gains.closed_loop)
            if np.max(np.abs(eigenvalues)) < 1.0:
                return gains, (eigenvalues, vectors)
        elif np.max(np.abs(np.linalg.eigvals(gains.closed_loop))) < 1.0:
            return gains, None
    predicted = np.asarray(
        scipy.linalg.solve_discrete_are(f.T, h.T, model.covariance, model.noise), dtype=np.float64
    )
    return _gains(model, 0.5 * (predicted + predicted.T)), None


def _gains(model: StateSpace, predicted: NDArray[np.float64]) -> SteadyState:
    """The filter's gain, covariances and closed loop from the prediction covariance (n, n)."""
    f, h = model.transition, model.observation
    innovation = h @ predicted @ h.T + model.noise
    gain = _solve_positive(innovation, h @ predicted).T
    filtered = predicted - gain @ innovation @ gain.T
    closed_loop = f @ (np.eye(f.shape[0]) - gain @ h)
    return SteadyState(predicted, 0.5 * (filtered + filtered.T), gain, innovation, closed_loop)


def _solve_positive(matrix: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.linalg.solve(matrix, rhs, assume_a="pos")``: LAPACK's ``posv`` called directly.

    The same routine and the same result to the bit, without scipy's checks around it: they
    took 19 µs of a likelihood evaluation's ~900, the call alone takes 1 µs, and a fit
    evaluates the likelihood hundreds of times. Unlike scipy's ``solve`` it does not warn of
    an ill-conditioned matrix.

    Raises
    ------
    ValueError
        If either array holds a NaN or an infinity (as scipy's check raises).
    numpy.linalg.LinAlgError
        If ``matrix`` is not positive definite.
    """
    if not (np.all(np.isfinite(matrix)) and np.all(np.isfinite(rhs))):
        raise ValueError("array must not contain infs or NaNs")
    _, solution, info = scipy.linalg.lapack.dposv(matrix, rhs)
    if info > 0:
        raise np.linalg.LinAlgError("the innovation covariance is not positive definite")
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of LAPACK's dposv")
    return np.asarray(solution, dtype=np.float64)


@dataclass(frozen=True)
class ForwardPass:
    """Steady-state filter run over a record (arrays component first).

    Attributes
    ----------
    predicted : ndarray, shape (n, N+1)
        x_{k|k-1}, k = 0..N, from the given initial state (zero when it was estimated).
    innovations : ndarray, shape (2, N)
        Innovations of ``predicted``.
    log_likelihood : float
        Nats.
    initial : ndarray, shape (n,) or None
        GLS estimate of x_0 when it was estimated: add ``A^k x_0`` to ``predicted``.
    initial_covariance : ndarray, shape (n, n) or None
        Covariance of that estimate.
    """

    predicted: NDArray[np.float64]
    innovations: NDArray[np.float64]
    log_likelihood: float
    initial: NDArray[np.float64] | None = None
    initial_covariance: NDArray[np.float64] | None = None


def _cholesky(covariance: NDArray[np.float64]) -> tuple[float, float, float]:
    """L[0, 0], L[1, 0], L[1, 1] of ``covariance = L Lᵀ`` (2×2)."""
    l00 = math.sqrt(covariance[0, 0])
    l10 = covariance[1, 0] / l00
    return l00, l10, math.sqrt(covariance[1, 1] - l10**2)


def _whiten(values: NDArray[np.float64], covariance: NDArray[np.float64]) -> NDArray:
    """``L⁻¹ values`` for ``covariance = L Lᵀ`` (2×2), values of shape (2, ...)."""
    l00, l10, l11 = _cholesky(covariance)
    first = values[0] / l00
    return np.stack((first, (values[1] - l10 * first) / l11))


def _gaussian_log_likelihood(sum_of_squares: float, count: int, covariance: NDArray) -> float:
    """Log-likelihood (nats) of ``count`` Gaussian innovations of covariance (2, 2).

    From the sum of squares of the whitened innovations.
    """
    _, logdet = np.linalg.slogdet(covariance)
    return -0.5 * (count * (logdet + 2.0 * math.log(2.0 * math.pi)) + sum_of_squares)


#: The closed loop's eigenvalues, eigenvectors, their condition number and their inverse.
_Eigen = tuple[NDArray[np.complex128], NDArray[np.complex128], float, NDArray[np.complexfloating]]


def _profile_log_likelihood(
    gains: SteadyState,
    whitened: NDArray[np.float64],
    sum_of_squares: float,
    eigen: _Eigen | None = None,
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Log-likelihood with the initial state at its GLS estimate, the estimate and its covariance.

    ``whitened`` (2, N) are the innovations from a zero initial state, whitened; ``eigen`` the
    closed loop's eigenvalues, eigenvectors, their condition number and their inverse when the
    caller has them.
    """
    normal, projection = _initial_state_equations(gains, whitened, eigen)
    covariance = _pinv_symmetric(normal, 1e-13)
    estimate = covariance @ projection
    # Σ|w - D x̂|² = Σ|w|² - pᵀ x̂ at the least-squares x̂ (p = Dᵀ w).
    log_likelihood = _gaussian_log_likelihood(sum_of_squares, whitened.shape[1], gains.innovation)
    return log_likelihood + 0.5 * float(projection @ estimate), estimate, covariance


def _pinv_symmetric(matrix: NDArray[np.float64], rcond: float) -> NDArray[np.float64]:
    """``np.linalg.pinv(matrix, rcond, hermitian=True)`` of a real symmetric (n, n) matrix.

    numpy's own steps (``eigh``, the eigenvalues by decreasing magnitude, their signs moved
    into the right factor, those below ``rcond`` times the largest dropped) in its order, so
    the result is the same to the bit, without the checks and the stacking around them: they
    took most of the call's ~60 µs, once per likelihood evaluation.
    """
    values, vectors = np.linalg.eigh(matrix)
    signs = np.copysign(1.0, values)
    values = np.abs(values)
    order = np.argsort(values)[::-1]
    signs, values, vectors = signs[order], values[order], vectors[:, order]
    right = np.transpose(vectors * signs[None, :])
    large = values > rcond * np.max(values)
    values = np.divide(1, values, where=large, out=values)
    values[~large] = 0
    return np.matmul(np.transpose(right), np.multiply(values[:, None], np.transpose(vectors)))


def forward_pass(
    model: StateSpace,
    gains: SteadyState,
    y: NDArray[np.float64],
    initial: NDArray | None,
    states: bool = True,
) -> ForwardPass:
    """Steady-state Kalman filter over y (2, N); estimates x_0 by GLS when ``initial`` is None.

    With a fixed gain the innovations are affine in the initial state x_0,
    ``e_k = e⁰_k - H A^k x_0`` (A the closed-loop matrix); minimising their whitened sum of
    squares over x_0 maximises the likelihood under a diffuse prior on x_0. Without
    ``states`` only what the innovations need is formed: ``predicted`` then holds the sensors'
    two components for k = 0..N-1, shape (2, N) (the likelihood's case).
    """
    n = model.transition.shape[0]
    count = y.shape[1]
    start = np.zeros(n) if initial is None else initial
    drive = model.transition @ gains.gain
    # The innovations end at x_(N-1): x_N, among the states only, is one more step.
    runs = driven_states(gains.closed_loop, drive, y[:, :-1], start)
    sensors = np.concatenate((start[-2:, None], runs(slice(-2, None), count - 1)), axis=1)
    innovations = y - sensors
    predicted = sensors
    if states:
        before = np.concatenate((start[:, None], runs(slice(None), count - 1)), axis=1)
        last = gains.closed_loop @ before[:, -1] + drive @ y[:, -1]
        predicted = np.concatenate((before, last[:, None]), axis=1)
    whitened = _whiten(innovations, gains.innovation)
    sum_of_squares = float(np.sum(whitened**2))
    if initial is not None:
        log_likelihood = _gaussian_log_likelihood(sum_of_squares, count, gains.innovation)
        return ForwardPass(predicted, innovations, log_likelihood)
    log_likelihood, estimate, covariance = _profile_log_likelihood(gains, whitened, sum_of_squares)
    return ForwardPass(predicted, innovations, log_likelihood, estimate, covariance)


def _initial_state_equations(
    gains: SteadyState,
    whitened: NDArray[np.float64],
    eigen: _Eigen | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normal equations ``DᵀD x_0 = Dᵀ w`` of the initial state, D_k = L⁻¹ H A^k.

    With ``A = V Λ V⁻¹``, ``D_k = Σ_i a_i λ_i^k b_iᵀ`` (a_i = L⁻¹ H V e_i, b_i the i-th row
    of V⁻¹), so ``DᵀD`` is a sum of geometric series and ``Dᵀw`` needs ``Σ_k λ̄_i^k w_k``
    (:func:`~tcomp_core.fusion.loops.discounted_sums`): O(N n) work without forming D. Falls
    back to forming D when V is ill conditioned. ``eigen`` is (Λ, V, cond V, V⁻¹) of the closed
    loop when the caller has it.

    Returns
    -------
    normal : ndarray, shape (n, n)
    projection : ndarray, shape (n,)
    """
    count = whitened.shape[1]
    rows = None
    if eigen is None:
        eigenvalues, vectors = np.linalg.eig(gains.closed_loop)
        condition = float(np.linalg.cond(vectors))
    else:
        eigenvalues, vectors, condition, rows = eigen
    if condition > MAX_EIGENVECTOR_CONDITION:
        length = decay_horizon(gains.closed_loop, count)
        powers = matrix_powers(gains.closed_loop, length, slice(-2, None))  # (2, L, n)
        design = _whiten(powers, gains.innovation)
        normal = np.einsum("rki,rkj->ij", design, design)
        return normal, np.einsum("rki,rk->i", design, whitened[:, :length])
    if rows is None:
        rows = np.linalg.inv(vectors)
    columns = _whiten(vectors[-2:], gains.innovation)  # a_i as columns, (2, n)
    ratio = eigenvalues.conj()[:, None] * eigenvalues[None, :]
    near_one = np.abs(1.0 - ratio) < 1e-12
    series = np.where(near_one, count, (1.0 - ratio**count) / np.where(near_one, 1.0, 1.0 - ratio))
    inner = (columns.conj().T @ columns) * series
    normal = (rows.conj().T @ inner @ rows).real
    transforms = discounted_sums(whitened, eigenvalues.conj())  # Σ_k λ̄_i^k w_k, (2, n)
    projection = (rows.conj().T @ np.sum(columns.conj() * transforms, axis=0)).real
    return 0.5 * (normal + normal.T), projection


def innovation_log_likelihood(model: FusionModel, y: NDArray[np.float64]) -> float:
    """Profile log-likelihood of the innovations, nats (−inf where the Riccati equation fails)."""
    space = model.state_space()
    try:
        gains, modes = _steady_state(space, modes=True)
        value = _modal_log_likelihood(space, gains, y, modes)
        if value is None:
            value = forward_pass(space, gains, y, None, states=False).log_likelihood
    except (np.linalg.LinAlgError, ValueError):
        return -math.inf
    return value if math.isfinite(value) else -math.inf


def _modal_log_likelihood(
    space: StateSpace, gains: SteadyState, y: NDArray[np.float64], modes: _Modes | None = None
) -> float | None:
    """:func:`forward_pass`'s log-likelihood (x_0 estimated) run in the closed loop's eigenbasis.

    One compiled pass over the samples (:func:`~tcomp_core.fusion.loops.modal_innovations`)
    instead of a filter call per mode; the same sums in another order. None where the
    eigenvectors are too ill conditioned for the modes (:data:`~.recursion.MODAL_CONDITION`):
    :func:`forward_pass` then runs in the Schur basis. ``modes`` is the closed loop's
    eigen-decomposition when the caller has it.
    """
    eigenvalues, vectors = np.linalg.eig(gains.closed_loop) if modes is None else modes
    condition = float(np.linalg.cond(vectors))
    if condition > MODAL_CONDITION:
        return None
    inverse = np.linalg.inv(vectors)
    kept = eigenvalues.imag >= 0.0  # real ones, and one of each conjugate pair
    weight = np.where(eigenvalues.imag[kept] > 0.0, 2.0, 1.0)
    drive = inverse[kept] @ (space.transition @ gains.gain)
    read = vectors[-2:][:, kept] * weight
    whitened, sum_of_squares = modal_innovations(
        eigenvalues[kept], drive, read, y, _cholesky(gains.innovation)
    )
    eigen = (eigenvalues, vectors, condition, inverse)
    return _profile_log_likelihood(gains, whitened, sum_of_squares, eigen)[0]
