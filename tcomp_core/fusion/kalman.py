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
from scipy import signal

from .recursion import (
    MAX_EIGENVECTOR_CONDITION,
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

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        If the Riccati equation has no stabilising solution (scipy's errors).
    """
    f, h = model.transition, model.observation
    predicted = np.asarray(
        scipy.linalg.solve_discrete_are(f.T, h.T, model.covariance, model.noise), dtype=np.float64
    )
    predicted = 0.5 * (predicted + predicted.T)
    innovation = h @ predicted @ h.T + model.noise
    gain = scipy.linalg.solve(innovation, h @ predicted, assume_a="pos").T
    filtered = predicted - gain @ innovation @ gain.T
    closed_loop = f @ (np.eye(f.shape[0]) - gain @ h)
    return SteadyState(predicted, 0.5 * (filtered + filtered.T), gain, innovation, closed_loop)


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


def _whiten(values: NDArray[np.float64], covariance: NDArray[np.float64]) -> NDArray:
    """``L⁻¹ values`` for ``covariance = L Lᵀ`` (2×2), values of shape (2, ...)."""
    l00 = math.sqrt(covariance[0, 0])
    l10 = covariance[1, 0] / l00
    l11 = math.sqrt(covariance[1, 1] - l10**2)
    first = values[0] / l00
    return np.stack((first, (values[1] - l10 * first) / l11))


def _gaussian_log_likelihood(whitened: NDArray, covariance: NDArray) -> float:
    """Log-likelihood (nats) of Gaussian innovations of covariance (2, 2), whitened (2, N)."""
    _, logdet = np.linalg.slogdet(covariance)
    count = whitened.shape[1]
    return -0.5 * (count * (logdet + 2.0 * math.log(2.0 * math.pi)) + float(np.sum(whitened**2)))


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
    if initial is not None:
        log_likelihood = _gaussian_log_likelihood(whitened, gains.innovation)
        return ForwardPass(predicted, innovations, log_likelihood)
    normal, projection = _initial_state_equations(gains, whitened)
    covariance = np.asarray(np.linalg.pinv(normal, rcond=1e-13, hermitian=True), np.float64)
    estimate = covariance @ projection
    # Σ|w - D x̂|² = Σ|w|² - pᵀ x̂ at the least-squares x̂ (p = Dᵀ w).
    log_likelihood = _gaussian_log_likelihood(whitened, gains.innovation)
    log_likelihood += 0.5 * float(projection @ estimate)
    return ForwardPass(predicted, innovations, log_likelihood, estimate, covariance)


def _initial_state_equations(
    gains: SteadyState, whitened: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normal equations ``DᵀD x_0 = Dᵀ w`` of the initial state, D_k = L⁻¹ H A^k.

    With ``A = V Λ V⁻¹``, ``D_k = Σ_i a_i λ_i^k b_iᵀ`` (a_i = L⁻¹ H V e_i, b_i the i-th row
    of V⁻¹), so ``DᵀD`` is a sum of geometric series and ``Dᵀw`` needs ``Σ_k λ̄_i^k w_k``
    (a backward first-order recursion per eigenvalue): O(N n) work without forming D. Falls
    back to forming D when V is ill conditioned.

    Returns
    -------
    normal : ndarray, shape (n, n)
    projection : ndarray, shape (n,)
    """
    count = whitened.shape[1]
    eigenvalues, vectors = np.linalg.eig(gains.closed_loop)
    if np.linalg.cond(vectors) > MAX_EIGENVECTOR_CONDITION:
        length = decay_horizon(gains.closed_loop, count)
        powers = matrix_powers(gains.closed_loop, length, slice(-2, None))  # (2, L, n)
        design = _whiten(powers, gains.innovation)
        normal = np.einsum("rki,rkj->ij", design, design)
        return normal, np.einsum("rki,rk->i", design, whitened[:, :length])
    rows = np.linalg.inv(vectors)
    columns = _whiten(vectors[-2:], gains.innovation)  # a_i as columns, (2, n)
    ratio = eigenvalues.conj()[:, None] * eigenvalues[None, :]
    near_one = np.abs(1.0 - ratio) < 1e-12
    series = np.where(near_one, count, (1.0 - ratio**count) / np.where(near_one, 1.0, 1.0 - ratio))
    inner = (columns.conj().T @ columns) * series
    normal = (rows.conj().T @ inner @ rows).real
    transforms = np.stack(
        [_discounted_sum(whitened, pole.conj()) for pole in eigenvalues], axis=1
    )  # Σ_k λ̄_i^k w_k as columns, (2, n)
    projection = (rows.conj().T @ np.sum(columns.conj() * transforms, axis=0)).real
    return 0.5 * (normal + normal.T), projection


def _discounted_sum(values: NDArray[np.float64], pole: complex) -> NDArray[np.complex128]:
    """``Σ_k pole^k values[:, k]``, shape (2,), over the terms that reach the sum's precision.

    A term k is below ``|values|·ε`` once ``|pole|^k ≤ ε (1 − |pole|)`` (the tail after it sums
    to less): a closed-loop mode decays long before the end of a long record, and summing only
    its first samples makes the likelihood of a 20 kHz record several times cheaper.
    """
    count = values.shape[1]
    radius = abs(pole)
    if radius < 1.0 - 1e-12:
        floor = _EPS * (1.0 - radius)
        reach = math.log(floor) / math.log(radius) if radius > 0.0 else 1.0
        count = min(count, math.ceil(reach) + 1)
    # Backwards through the first ``count`` samples: the last output is the sum.
    return signal.lfilter([1.0], [1.0, -pole], values[:, count - 1 :: -1], axis=1)[:, -1]


_EPS = float(np.finfo(np.float64).eps)


def innovation_log_likelihood(model: FusionModel, y: NDArray[np.float64]) -> float:
    """Profile log-likelihood of the innovations, nats (−inf where the Riccati equation fails)."""
    space = model.state_space()
    try:
        gains = steady_state(space)
        value = forward_pass(space, gains, y, None, states=False).log_likelihood
    except (np.linalg.LinAlgError, ValueError):
        return -math.inf
    return value if math.isfinite(value) else -math.inf
