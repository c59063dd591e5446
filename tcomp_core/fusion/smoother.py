"""Steady-state Rauch–Tung–Striebel smoother: the offline fused gas temperature.

The backward pass is a linear recursion like the forward one; the reported variance is the
smoothed covariance plus the part due to the generalised least-squares estimate of the initial
state (:func:`~tcomp_core.fusion.kalman.forward_pass`), widened where the readings disagree with
the model (:func:`~tcomp_core.fusion.consistency.widen_smoothed`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .consistency import widen_smoothed
from .kalman import ForwardPass, SteadyState, forward_pass, steady_state
from .recursion import (
    MAX_EIGENVECTOR_CONDITION,
    apply_matrix,
    decay_horizon,
    linear_recursion,
    matrix_powers,
)
from .signal_model import FusionModel, StateSpace

__all__ = ["smoothed_gas"]


def _smooth(
    model: StateSpace, gains: SteadyState, forward: ForwardPass
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Steady-state RTS smoother: smoothed states, their output variances and innovations.

    Returns the smoothed states (n, N), their output variances (N,) and the forward filter's
    innovations from the estimated initial state (2, N).
    ``x_{k|N} = J x_{k+1|N} + (I - J F) x_{k|k}`` with ``J = P_f Fᵀ P_p⁻¹``, run backwards.
    The variance is the smoothed covariance (``P_f`` at the end of the record, converging
    backwards to its steady state) plus the part due to the GLS estimate of x_0.
    """
    f, h, c = model.transition, model.observation, model.output
    identity = np.eye(f.shape[0])
    count = forward.innovations.shape[1]
    predicted = forward.predicted[:, :-1].copy()
    innovations = forward.innovations.copy()
    smoother = gains.filtered @ np.linalg.solve(gains.predicted, f).T
    blend = identity - smoother @ f
    rows = _output_rows(smoother, c, decay_horizon(gains.closed_loop, count))
    start = None
    if forward.initial is not None:
        start = _start_terms(gains, h, c, smoother, blend, forward.initial, count, rows)
        length = start[0].shape[1]
        predicted[:, :length] += start[0]
        innovations[:, :length] -= start[0][-2:]
    filtered = predicted + apply_matrix(gains.gain, innovations)
    states = _backward(smoother, blend, filtered[:, :, None])[:, :, 0]
    variances = _smoothed_variances(gains, smoother, rows, count)
    if start is not None and forward.initial_covariance is not None:
        output = start[1]
        variances[:length] += np.einsum("ki,ij,kj->k", output, forward.initial_covariance, output)
    return states, variances, innovations


def _start_terms(
    gains: SteadyState,
    h: NDArray[np.float64],
    c: NDArray[np.float64],
    smoother: NDArray[np.float64],
    blend: NDArray[np.float64],
    initial: NDArray[np.float64],
    count: int,
    rows: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """What the initial state x_0 does to the predictions and to the smoothed gas.

    The predictions carry ``A^k x_0`` (A the closed loop) until it dies out after L samples
    (:func:`~.recursion.decay_horizon`). The filtered states' sensitivity to x_0 is
    ``s_k = (I − K H) A^k``; the smoothed states' is ``S_k = J S_(k+1) + B s_k`` run back from
    ``S_L = 0`` (from ``S_(L−1) = s_(L−1)`` when the response lasts the whole record), and the
    smoothed gas's is the row ``o_k = c S_k``. ``rows`` are :func:`_output_rows` over the
    closed loop's decay horizon when the caller has them.

    Returns
    -------
    response : ndarray, shape (n, L)
        ``A^k x_0``.
    output : ndarray, shape (L, n)
        ``o_k``.
    """
    closed = gains.closed_loop
    n = closed.shape[0]
    length = decay_horizon(closed, count)
    update = np.eye(n) - gains.gain @ h
    eigenvalues, vectors = np.linalg.eig(closed)
    if np.linalg.cond(vectors) > MAX_EIGENVECTOR_CONDITION:
        return _start_terms_by_powers(closed, update, c, smoother, blend, initial, length, count)
    inverse = np.linalg.inv(vectors)
    powers: NDArray[Any] = eigenvalues[:, None] ** np.arange(length)  # λ_i^k, (n, L)
    response = (vectors @ (powers * (inverse @ initial)[:, None])).real
    # With A^j = V Λ^j V⁻¹ and g_m = c J^m: o_k = Σ_(j ≥ k) g_(j−k) B (I − K H) A^j
    # = [λ^k ∘ Σ_(m ≤ p) (g_m B (I − K H) V) ∘ λ^m] V⁻¹: a cumulative sum over m per mode,
    # O(n² L) where forming S_k takes O(n³ L).
    if rows is None:
        rows = _output_rows(smoother, c, length)
    terms = (rows @ (blend @ update @ vectors)) * powers.T  # (L, n)
    sums = np.cumsum(terms, axis=0)  # sums[p] = Σ_(m ≤ p)
    # The sum for o_k runs to p = L − 1 − k, or to L − 2 − k before the terminal term.
    last = length - 1 if length < count else length - 2
    reach = last - np.arange(length)
    modal = np.where(reach[:, None] >= 0, sums[np.maximum(reach, 0)], 0.0)
    output: NDArray[np.complex128] = (powers.T * modal) @ inverse
    if length == count:  # the record ends first: S_(L−1) = s_(L−1), no blend
        tail = update @ (vectors * powers[:, -1]) @ inverse  # (I − K H) A^(L−1)
        output = output + rows[::-1] @ tail
    return response, np.asarray(output.real, dtype=np.float64)


def _start_terms_by_powers(
    closed: NDArray[np.float64],
    update: NDArray[np.float64],
    c: NDArray[np.float64],
    smoother: NDArray[np.float64],
    blend: NDArray[np.float64],
    initial: NDArray[np.float64],
    length: int,
    count: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_start_terms` from the matrix powers themselves, for an ill-conditioned V."""
    response = matrix_powers(closed, length)  # (n, L, n)
    sensitivity = apply_matrix(update, response)
    if length < count:  # the response has died out: start from zero there
        sensitivity = np.concatenate((sensitivity, np.zeros_like(sensitivity[:, :1])), 1)
    output = np.einsum("i,ikj->kj", c, _backward(smoother, blend, sensitivity))[:length]
    return np.einsum("ikj,j->ik", response, initial), output


def _backward(
    smoother: NDArray[np.float64], blend: NDArray[np.float64], filtered: NDArray[np.float64]
) -> NDArray[np.float64]:
    """RTS pass ``x_{k|N} = J x_{k+1|N} + B x_{k|k}`` backwards over (n, N, m) arrays."""
    inputs = apply_matrix(blend, filtered[:, -2::-1])
    backward = linear_recursion(smoother, inputs, filtered[:, -1])
    return np.concatenate((backward[:, ::-1], filtered[:, -1:]), axis=1)


def _output_rows(
    smoother: NDArray[np.float64], output: NDArray[np.float64], length: int
) -> NDArray[np.float64]:
    """The rows ``g_m = c J^m`` for m = 0..length-1, shape (length, n)."""
    n = output.size
    rows = np.empty((length, n))
    rows[0] = output
    if length > 1:
        later = linear_recursion(smoother.T, np.zeros((n, length - 1, 1)), output[:, None])
        rows[1:] = later[:, :, 0].T
    return rows


def _smoothed_variances(
    gains: SteadyState, smoother: NDArray[np.float64], rows: NDArray[np.float64], count: int
) -> NDArray[np.float64]:
    """Output variance of the smoothed states (count,), from :func:`_output_rows` ``g_m``.

    The backward recursion ``P_k = P_f + J (P_(k+1) − P_p) Jᵀ`` from ``P_(N−1) = P_f``
    unrolls to ``P_(N−1−m) = Σ_(i<m) J^i Q J^iᵀ + J^m P_f J^mᵀ`` with ``Q = P_f − J P_p Jᵀ``
    (the covariance of x_k given x_(k+1) and the past), so the variance ``c P_k cᵀ`` is a
    cumulative sum of ``g_i Q g_iᵀ``: O(N n²) without a Python loop over samples. Beyond the
    rows' horizon ``J^m`` has died out (below 1e-13) and the variance is the sum's limit.
    """
    length = rows.shape[0]
    conditional = gains.filtered - smoother @ gains.predicted @ smoother.T
    steps = np.einsum("mi,ij,mj->m", rows, conditional, rows)
    ends = np.einsum("mi,ij,mj->m", rows, gains.filtered, rows)
    sums = np.concatenate(([0.0], np.cumsum(steps)))  # sums[m] = Σ_(i<m)
    variances = np.full(count, sums[-1])
    variances[count - length :] = (sums[:length] + ends)[::-1]
    return variances


def smoothed_gas(
    model: FusionModel, first: NDArray[np.float64], second: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Smoothed gas temperature (N,), its standard deviation (N,) and the log-likelihood."""
    space = model.state_space()
    gains = steady_state(space)
    level = float(np.mean(first))
    forward = forward_pass(space, gains, np.vstack((first - level, second - level)), None)
    states, variances, innovations = _smooth(space, gains, forward)
    c, f = space.output, space.transition
    # State k holds the gas of interval k-1; the last interval is predicted one step ahead.
    ahead = f @ states[:, -1]
    ahead_variance = c @ gains.predicted @ c + variances[-1] - c @ gains.filtered @ c
    gas = np.append(c @ states[:, 1:], c @ ahead) + level
    std = np.sqrt(np.append(variances[1:], ahead_variance))
    # Innovation k is of the readings at t_k, which close interval k-1; none closes the last.
    closing = np.hstack((innovations[:, 1:], np.zeros((2, 1))))
    inverse = np.asarray(np.linalg.inv(gains.innovation), dtype=np.float64)
    std = widen_smoothed(model, gains.closed_loop, std, closing, inverse, gas, first, second)
    return gas, np.hypot(std, model.misfit_c), forward.log_likelihood
