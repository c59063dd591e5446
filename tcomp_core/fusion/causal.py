"""Causal (streaming) Kalman filter of the gas temperature, for the online node.

The filter starts from a diffuse prior with the exact time-varying Kalman recursion (a loop over
samples) and switches to the steady-state gain once its gain has converged, or after
:data:`MAX_EXACT_SAMPLES` samples; the steady-state part runs in vectorised batches.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..validation import check_pair
from .kalman import forward_pass, steady_state
from .recursion import apply_matrix
from .signal_model import FusionModel

__all__ = ["GAIN_TOLERANCE", "MAX_EXACT_SAMPLES", "CausalFuser"]

#: Relative distance of the time-varying Kalman gain from the steady-state one at which the
#: causal filter switches to the steady-state gain.
GAIN_TOLERANCE = 1e-4
#: Samples after which the causal filter switches to the steady-state gain in any case (a narrow
#: resonator's gain converges over its own time constant, which may be hours).
MAX_EXACT_SAMPLES = 4096

LOG_2PI_SQUARED = 2.0 * math.log(2.0 * math.pi)


class CausalFuser:
    """Streaming Kalman filter of the gas temperature, for the online node.

    Each new sample pair k yields the estimate of the gas temperature over the previous
    interval ``[t_{k-1}, t_k)`` (the latency of Eq. 7); the very first pair yields nothing.
    The filter starts from a diffuse prior around the first reading with the exact
    time-varying Kalman recursion (one sample at a time) and switches to the steady-state
    gain, processed in vectorised batches, once the covariance has converged.

    Parameters
    ----------
    model : FusionModel
        A fitted model (:func:`fit_fusion_model`).

    Examples
    --------
    >>> fuser = CausalFuser(model)                      # doctest: +SKIP
    >>> gas, std = fuser.extend(tc1[:100], tc2[:100])   # 99 estimates
    >>> gas, std = fuser.extend(tc1[100:], tc2[100:])   # one per new pair
    """

    def __init__(self, model: FusionModel) -> None:
        self.model = model
        self._space = model.state_space()
        self._gains = steady_state(self._space)
        self._state: NDArray[np.float64] | None = None  # x_{k|k-1}
        self._covariance = np.diag(self._space.prior_std**2)
        self._steady = False
        self._exact_samples = 0
        self.log_likelihood = 0.0

    @property
    def started(self) -> bool:
        """Whether the filter holds a state (it has taken a sample since its last reset)."""
        return self._state is not None

    @property
    def converged(self) -> bool:
        """Whether the filter runs on the steady-state gain."""
        return self._steady

    def reset(self) -> None:
        """Forget the state: the next pair starts afresh from the diffuse prior."""
        self._state = None
        self._covariance = np.diag(self._space.prior_std**2)
        self._steady = False
        self._exact_samples = 0
        self.log_likelihood = 0.0

    def retune(self, model: FusionModel) -> None:
        """Switch to new model settings (e.g. new τ) and keep what the filter knows.

        The state ``[x, T_1, T_2]`` means the same under any model with the same signal state,
        so the estimate carries over without a new diffuse start: a steady filter moves to the
        new steady-state covariance, a converging one keeps its covariance. A model whose
        signal state differs (another kind or order) starts afresh (:meth:`reset`).
        """
        space = model.state_space()
        same_state = (model.kind, model.order, len(model.ar)) == (
            self.model.kind,
            self.model.order,
            len(self.model.ar),
        )
        self.model, self._space, self._gains = model, space, steady_state(space)
        if not same_state:
            self.reset()
        elif self._steady:
            self._covariance = self._gains.predicted

    def _initial_state(self, y1: float, y2: float) -> NDArray[np.float64]:
        """Sensors at their first readings, the gas (or level) at the faster sensor's."""
        m = self._space.output.size - 2
        state = np.zeros(m + 2)
        state[0] = y1
        state[m:] = (y1, y2)
        return state

    def extend(
        self, tc1: ArrayLike, tc2: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Filter a batch of new sample pairs.

        Parameters
        ----------
        tc1, tc2 : array_like, shape (M,)
            New readings, degrees C.

        Returns
        -------
        gas, std : ndarray, shape (M,) (M-1 for the very first batch)
            Gas temperature over the interval before each new sample and its standard
            deviation, degrees C.
        """
        first, second = check_pair(tc1, tc2, min_samples=0)
        count = first.size
        if not count:
            return np.empty(0), np.empty(0)
        y = np.vstack((first, second))
        gas, std = np.empty(count), np.empty(count)
        state, skip = self._state, 0
        if state is None:
            state, skip = self._initial_state(first[0], second[0]), 1
        done = 0
        if not self._steady:
            state, exact_gas, exact_std = self._exact_batch(y, state)
            done = exact_gas.size
            gas[:done], std[:done] = exact_gas, exact_std
        if done < count:
            state, steady_gas, steady_std = self._steady_batch(y[:, done:], state)
            gas[done:], std[done:] = steady_gas, steady_std
        self._state = state
        return gas[skip:], std[skip:]

    def _exact_batch(
        self, y: NDArray[np.float64], state: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Time-varying Kalman filter over y (2, M) from the predicted ``state`` (n,).

        Runs until the gain has converged. Returns the next predicted state, and the filtered
        gas and its std for the samples processed (possibly fewer than M).
        """
        f, noise, covariance = self._space.transition, self._space.noise, self._space.covariance
        c, target = self._space.output, self._gains.gain
        tolerance = GAIN_TOLERANCE * float(np.max(np.abs(target)))
        predicted = self._covariance
        gas, std = np.empty(y.shape[1]), np.empty(y.shape[1])
        done = 0
        f_t, identity = f.T, np.eye(f.shape[0])
        while done < y.shape[1] and not self._steady:
            (s00, s01), (s10, s11) = predicted[-2:, -2:] + noise
            determinant = s00 * s11 - s01 * s10
            inverse = np.array([[s11, -s01], [-s10, s00]]) / determinant
            gain = predicted[:, -2:] @ inverse
            innovation = y[:, done] - state[-2:]
            state = state + gain @ innovation
            update = identity.copy()
            update[:, -2:] -= gain
            filtered = update @ predicted @ update.T + gain @ noise @ gain.T  # Joseph form
            gas[done], std[done] = c @ state, math.sqrt(max(c @ filtered @ c, 0.0))
            self.log_likelihood -= 0.5 * (
                math.log(determinant) + innovation @ inverse @ innovation + LOG_2PI_SQUARED
            )
            state = f @ state
            predicted = f @ filtered @ f_t + covariance
            predicted = 0.5 * (predicted + predicted.T)
            self._exact_samples += 1
            done += 1
            converged = np.abs(gain - target).max() <= tolerance
            self._steady = converged or self._exact_samples >= MAX_EXACT_SAMPLES
        self._covariance = self._gains.predicted if self._steady else predicted
        return state, gas[:done], std[:done]

    def _steady_batch(
        self, y: NDArray[np.float64], state: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Steady-state filter over y (2, M) from the predicted ``state`` (n,).

        Returns the next predicted state, and the filtered gas and its std (M,).
        """
        forward = forward_pass(self._space, self._gains, y, state)
        self.log_likelihood += forward.log_likelihood
        filtered = forward.predicted[:, :-1] + apply_matrix(self._gains.gain, forward.innovations)
        c = self._space.output
        std = float(np.sqrt(c @ self._gains.filtered @ c))
        return forward.predicted[:, -1], c @ filtered, np.full(y.shape[1], std)

    def step(self, tc1: float, tc2: float) -> tuple[float, float] | None:
        """Filter one sample pair: the previous interval's gas and its std (None at first)."""
        gas, std = self.extend([tc1], [tc2])
        return (float(gas[0]), float(std[0])) if gas.size else None

    def predict(self) -> tuple[float, float]:
        """Prediction of the gas over the current, not yet observed, interval and its std."""
        if self._state is None:
            raise ValueError("no sample has been filtered yet")
        c = self._space.output
        return float(c @ self._state), float(np.sqrt(c @ self._covariance @ c))
