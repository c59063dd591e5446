"""Causal (streaming) Kalman filter of the gas temperature, for the online node.

The filter starts from a diffuse prior with the exact time-varying Kalman recursion and switches
to the steady-state gain once its gain has converged, or after :data:`MAX_EXACT_SAMPLES`
samples. Its standard deviation is the model's, widened where the readings disagree with the
model (:mod:`.consistency`).

The covariances of the time-varying part do not depend on the data: their gains are
computed once per model (:class:`ExactSchedule`), so a start (or a restart after a gap) costs
one small state update per sample. The steady-state part is a fixed linear recursion run in
batches at compiled speed (:class:`~tcomp_core.fusion.recursion.ModalRecursion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..validation import check_pair
from .consistency import ConsistencyCheck
from .kalman import SteadyState, steady_state
from .loops import exact_schedule
from .recursion import ModalRecursion
from .signal_model import FusionModel, StateSpace

__all__ = [
    "GAIN_TOLERANCE",
    "MAX_EXACT_SAMPLES",
    "CausalFuser",
    "ExactSchedule",
]

#: Relative distance of the time-varying Kalman gain from the steady-state one at which the
#: causal filter switches to the steady-state gain.
GAIN_TOLERANCE = 1e-4
#: Samples after which the causal filter switches to the steady-state gain in any case (a narrow
#: resonator's gain converges over its own time constant, which may be hours).
MAX_EXACT_SAMPLES = 4096

LOG_2PI_SQUARED = 2.0 * math.log(2.0 * math.pi)


@dataclass(frozen=True)
class ExactSchedule:
    """The time-varying Kalman filter from the diffuse prior, step by step (L steps).

    Attributes
    ----------
    gains : ndarray, shape (L, n, 2)
        Kalman gain of each step.
    std : ndarray, shape (L,)
        Standard deviation of the filtered gas at each step, degrees C.
    inverse : ndarray, shape (L, 2, 2)
        Inverse innovation covariance of each step, 1/°C².
    log_det : ndarray, shape (L,)
        Log-determinant of the innovation covariance of each step.
    predicted_var : ndarray, shape (L + 1,)
        Variance of the predicted gas before each step (and after the last), °C².
    drive : ndarray, shape (L, n, 2)
        ``F K_k``: how each step's innovation moves the next prediction.
    read : ndarray, shape (L, 2)
        ``c K_k``: how it moves the filtered gas.
    """

    gains: NDArray[np.float64]
    std: NDArray[np.float64]
    inverse: NDArray[np.float64]
    log_det: NDArray[np.float64]
    predicted_var: NDArray[np.float64]
    drive: NDArray[np.float64]
    read: NDArray[np.float64]

    @classmethod
    def of(cls, space: StateSpace, target: NDArray[np.float64]) -> ExactSchedule:
        """Run the covariance recursion until the gain is within tolerance of ``target``."""
        tolerance = GAIN_TOLERANCE * float(np.max(np.abs(target)))
        gains, std, inverse, log_det, predicted_var = exact_schedule(
            space.transition,
            space.covariance,
            space.noise,
            space.output,
            np.diag(space.prior_std**2),
            target,
            tolerance,
            MAX_EXACT_SAMPLES,
        )
        return cls(
            gains,
            std,
            inverse,
            log_det,
            predicted_var,
            np.einsum("ij,kjl->kil", space.transition, gains),
            np.einsum("i,kil->kl", space.output, gains),
        )

    @property
    def length(self) -> int:
        """Steps before the steady-state gain takes over."""
        return int(self.std.size)


class CausalFuser:
    """Streaming Kalman filter of the gas temperature, for the online node.

    Each new sample pair k yields the estimate of the gas temperature over the previous
    interval ``[t_{k-1}, t_k)`` (the latency of Eq. 7); the very first pair yields nothing.
    The filter starts from a diffuse prior around the first reading with the exact
    time-varying Kalman recursion (one sample at a time, its gains computed once per model) and
    switches to the steady-state gain, a fixed linear recursion run in compiled batches, once
    the gain has converged.

    Parameters
    ----------
    model : FusionModel
        A fitted model (:func:`fit_fusion_model`).

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        When the model has no steady-state Kalman filter (no stabilising Riccati solution).

    Examples
    --------
    >>> fuser = CausalFuser(model)                      # doctest: +SKIP
    >>> gas, std = fuser.extend(tc1[:100], tc2[:100])   # 99 estimates
    >>> gas, std = fuser.extend(tc1[100:], tc2[100:])   # one per new pair
    """

    def __init__(self, model: FusionModel) -> None:
        gains = self._set_model(model)
        #: Where the readings disagree with the model, and how far that widens the std.
        self.consistency = ConsistencyCheck(model, gains.closed_loop)
        self._state: NDArray[np.float64] | None = None  # x_{k|k-1}
        self._step = 0  # time-varying steps taken since the start
        self.log_likelihood = 0.0
        self._last: NDArray[np.float64] | None = None  # the last readings (tc1, tc2)

    def _set_model(self, model: FusionModel) -> SteadyState:
        self.model = model
        self._space = space = model.state_space()
        self._gains = gains = steady_state(space)
        self._schedule: ExactSchedule | None = None
        h, c = space.observation, space.output
        update = np.eye(space.transition.shape[0]) - gains.gain @ h
        # Prediction x_{k+1|k} = F (I - K H) x_{k|k-1} + F K y_k; read out the filtered gas
        # c x_{k|k} and the predicted readings H x_{k|k-1} (for the innovations).
        self._recursion = ModalRecursion(
            gains.closed_loop,
            space.transition @ gains.gain,
            np.vstack((c @ update, h)),
            np.vstack((c @ gains.gain, np.zeros((2, 2)))),
        )
        self._steady_std = math.sqrt(max(float(c @ gains.filtered @ c), 0.0))
        innovation = gains.innovation
        self._inverse_innovation = np.linalg.inv(innovation)
        self._log_det = float(np.linalg.slogdet(innovation)[1])
        return gains

    @property
    def schedule(self) -> ExactSchedule:
        """The time-varying start of the filter (computed on first use, then kept)."""
        if self._schedule is None:
            self._schedule = ExactSchedule.of(self._space, self._gains.gain)
        return self._schedule

    @property
    def started(self) -> bool:
        """Whether the filter holds a state (it has taken a sample since its last reset)."""
        return self._state is not None

    @property
    def converged(self) -> bool:
        """Whether the filter runs on the steady-state gain."""
        return self._step >= self.schedule.length

    def reset(self) -> None:
        """Forget the state: the next pair starts afresh from the diffuse prior."""
        self._state = None
        self._step = 0
        self.log_likelihood = 0.0
        self._last = None
        self.consistency.reset()

    def retune(self, model: FusionModel) -> None:
        """Switch to new model settings (e.g. new τ) and keep what the filter knows.

        The state ``[x, T_1, T_2]`` means the same under any model with the same signal state,
        so the estimate carries over without a new diffuse start, and a filter still converging
        continues the new model's time-varying start where it stood. A model whose signal state
        differs (another kind or order) starts afresh (:meth:`reset`). The consistency check keeps
        what it has seen (:meth:`~.consistency.ConsistencyCheck.retune`).
        """
        same_state = (model.kind, model.order, len(model.ar)) == (
            self.model.kind,
            self.model.order,
            len(self.model.ar),
        )
        gains = self._set_model(model)
        self.consistency.retune(model, gains.closed_loop)
        if not same_state:
            self.reset()

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
        innovations, inverse = np.empty((2, count)), np.empty((count, 2, 2))
        state, skip = self._state, 0
        if state is None:
            state, skip = self._initial_state(first[0], second[0]), 1
        done = 0
        if self._step < self.schedule.length:
            state, done = self._exact_batch(y, state, gas, std, innovations, inverse)
        if done < count:
            state = self._steady_batch(
                y[:, done:], state, gas[done:], std[done:], innovations[:, done:]
            )
            inverse[done:] = self._inverse_innovation
        self._state = state
        if self._last is not None:
            y = np.hstack((self._last[:, None], y))
        self._last = y[:, -1].copy()
        inversion = self.consistency.inversion(y[0], y[1])
        gas, std = gas[skip:], std[skip:]
        widened = self.consistency.widen(
            std, innovations[:, skip:], inverse[skip:], gas, inversion
        )
        return gas, np.hypot(widened, self.model.misfit_c)

    def _exact_batch(
        self,
        y: NDArray[np.float64],
        state: NDArray[np.float64],
        gas: NDArray[np.float64],
        std: NDArray[np.float64],
        innovations: NDArray[np.float64],
        inverse: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], int]:
        """Time-varying filter over y (2, M) from the predicted ``state`` (n,).

        Writes gas, std, the innovations (2, M) and their inverse covariances (M, 2, 2) of the
        samples it takes (until the schedule ends); returns the next predicted state and the
        number of samples taken.
        """
        schedule = self.schedule
        count = min(y.shape[1], schedule.length - self._step)
        f = self._space.transition
        steps = slice(self._step, self._step + count)
        drive = schedule.drive[steps]  # F K_k, (count, n, 2)
        taken = np.empty((count, 2))
        predicted = np.empty((count, state.size))
        # Only the state recursion is sequential: x_{k+1|k} = F x_{k|k-1} + F K_k e_k.
        for k in range(count):
            predicted[k] = state
            taken[k] = innovation = y[:, k] - state[-2:]
            state = f @ state + drive[k] @ innovation
        # The outputs of all the samples at once: c x_{k|k} = c x_{k|k-1} + (c K_k) e_k.
        gas[:count] = predicted @ self._space.output + np.einsum(
            "ki,ki->k", schedule.read[steps], taken
        )
        innovations[:, :count] = taken.T
        inverse[:count] = schedule.inverse[steps]
        square = np.einsum("ki,kij,kj->k", taken, schedule.inverse[steps], taken)
        std[:count] = schedule.std[steps]
        self.log_likelihood -= 0.5 * (
            float(np.sum(schedule.log_det[steps])) + float(square.sum()) + count * LOG_2PI_SQUARED
        )
        self._step += count
        return state, count

    def _steady_batch(
        self,
        y: NDArray[np.float64],
        state: NDArray[np.float64],
        gas: NDArray[np.float64],
        std: NDArray[np.float64],
        innovations: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Steady-state filter over y (2, M) from the predicted ``state`` (n,).

        Writes the filtered gas, its std and the innovations (2, M); returns the next
        predicted state.
        """
        outputs, state = self._recursion.run(y, state)
        gas[:] = outputs[0]
        std[:] = self._steady_std
        innovations[:] = y - outputs[1:]
        square = np.einsum("ik,ij,jk->k", innovations, self._inverse_innovation, innovations)
        self.log_likelihood -= 0.5 * (
            y.shape[1] * (self._log_det + LOG_2PI_SQUARED) + float(square.sum())
        )
        return state

    def step(self, tc1: float, tc2: float) -> tuple[float, float] | None:
        """Filter one sample pair: the previous interval's gas and its std (None at first)."""
        gas, std = self.extend([tc1], [tc2])
        return (float(gas[0]), float(std[0])) if gas.size else None

    def predict(self) -> tuple[float, float]:
        """Prediction of the gas over the current, not yet observed, interval and its std."""
        if self._state is None:
            raise ValueError("no sample has been filtered yet")
        c = self._space.output
        if self._step < self.schedule.length:
            variance = float(self.schedule.predicted_var[self._step])
        else:
            variance = float(c @ self._gains.predicted @ c)
        std = self.consistency.widen_prediction(math.sqrt(max(variance, 0.0)))
        return float(c @ self._state), math.hypot(std, self.model.misfit_c)
