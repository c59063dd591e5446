"""Steady-state Rauch–Tung–Striebel smoother: the offline fused gas temperature.

The backward pass is a linear recursion like the forward one; the reported variance is the
smoothed covariance plus the part due to the generalised least-squares estimate of the initial
state (:func:`~tcomp_core.fusion.kalman.forward_pass`), widened where the readings disagree with
the model (:func:`~tcomp_core.fusion.consistency.widen_smoothed`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .consistency import widen_smoothed
from .kalman import ForwardPass, SteadyState, forward_pass, steady_state
from .recursion import apply_matrix, decay_horizon, linear_recursion, matrix_powers
from .signal_model import FusionModel, StateSpace

__all__ = ["COVARIANCE_TOLERANCE", "smoothed_gas"]

#: Relative change of the backward smoothed covariance below which it counts as converged.
COVARIANCE_TOLERANCE = 1e-10


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
    if forward.initial is not None:
        response = matrix_powers(gains.closed_loop, decay_horizon(gains.closed_loop, count))
        length = response.shape[1]
        correction = np.einsum("ikj,j->ik", response, forward.initial)
        predicted[:, :length] += correction
        innovations[:, :length] -= correction[-2:]
    filtered = predicted + apply_matrix(gains.gain, innovations)
    smoother = gains.filtered @ np.linalg.solve(gains.predicted, f).T
    blend = identity - smoother @ f
    states = _backward(smoother, blend, filtered[:, :, None])[:, :, 0]
    variances = _smoothed_variances(gains, smoother, c, count)
    if forward.initial is not None and forward.initial_covariance is not None:
        sensitivity = apply_matrix(identity - gains.gain @ h, response)
        if length < count:  # the response has died out: start from zero there
            sensitivity = np.concatenate((sensitivity, np.zeros_like(sensitivity[:, :1])), 1)
        output = np.einsum("i,ikj->kj", c, _backward(smoother, blend, sensitivity))[:length]
        variances[:length] += np.einsum("ki,ij,kj->k", output, forward.initial_covariance, output)
    return states, variances, innovations


def _backward(
    smoother: NDArray[np.float64], blend: NDArray[np.float64], filtered: NDArray[np.float64]
) -> NDArray[np.float64]:
    """RTS pass ``x_{k|N} = J x_{k+1|N} + B x_{k|k}`` backwards over (n, N, m) arrays."""
    inputs = apply_matrix(blend, filtered[:, -2::-1])
    backward = linear_recursion(smoother, inputs, filtered[:, -1])
    return np.concatenate((backward[:, ::-1], filtered[:, -1:]), axis=1)


def _smoothed_variances(
    gains: SteadyState, smoother: NDArray[np.float64], output: NDArray[np.float64], count: int
) -> NDArray[np.float64]:
    """Output variance of the smoothed states (count,), from the end of the record backwards."""
    variances = np.empty(count)
    covariance = gains.filtered
    variances[-1] = output @ covariance @ output
    for k in range(count - 2, -1, -1):
        updated = gains.filtered + smoother @ (covariance - gains.predicted) @ smoother.T
        variances[k] = output @ updated @ output
        change = np.max(np.abs(updated - covariance))
        covariance = updated
        if change <= COVARIANCE_TOLERANCE * np.max(np.abs(updated)):
            variances[:k] = variances[k]
            break
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
