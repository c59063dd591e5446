"""How far the causal filter's gas may be off where the readings disagree with its model.

A Kalman filter's standard deviation holds only while its signal model is right. Where it is
not (a model fitted on a sine meeting a 500 °C step), the filter rings far beyond its std:
from −17 to 1 113 °C for readings of 274–801 °C while claiming 0.7 °C. Two checks on what the
filter computes anyway widen the std there, and only there:

* **The innovations** (covariance matching): less their running mean over
  :data:`OFFSET_MEMORY` samples (two sensors of one class differ by a degree or two in level,
  a hundred times their noise: a constant the filter's gas barely feels), their normalised
  square, 2 on average for a right model, is averaged over :data:`CONSISTENCY_MEMORY`
  samples; where the average stands above :data:`CONSISTENCY_THRESHOLD` times its expectation
  the std is widened by its square root. This sees a slow, moderate mismatch.
* **The gas against the sensors' inversion**: each sensor's first-order model inverted over
  one sample, ``g_k = (T_{k+1} - a T_k) / (1 - a)``, is an estimate of the gas that no signal
  model shapes, unbiased and noisy (its variance is known). For a right model the filter's
  gas is the better estimate and their difference has the variance of the inversion less the
  filter's; its square is averaged over :data:`GAS_MEMORY` samples, and where the average
  stands above :data:`GAS_THRESHOLD` times that expectation the std becomes the error the
  difference implies. This sees a step within a sample or two, where the readings have barely
  moved but the gas they imply has.

The innovations follow a surprise at once while the filter's state keeps the error for as long
as its slowest closed-loop mode lasts, so their excess is held and decays at that mode's rate
(time constant at most :data:`MAX_HOLD_SAMPLES`). On the node's hostile phases (a sine model
meeting 500 °C steps at 2 kHz, replayed through ``tcomp process``) the values more than 4 std
off fell from 3 284 of 5 999 (the model's std) to 695 (the innovations alone, not held) and
to 76 (both), all within 50 ms of the change from the sine to the steps.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..compiled import compile_loops
from ..models import tau_to_pole
from .signal_model import FusionModel

__all__ = [
    "CONSISTENCY_MEMORY",
    "CONSISTENCY_THRESHOLD",
    "GAS_MEMORY",
    "GAS_THRESHOLD",
    "MATERIAL_WIDENING",
    "MAX_HOLD_SAMPLES",
    "OFFSET_MEMORY",
    "ConsistencyCheck",
    "widen_smoothed",
]

#: Memory of the average of the innovations' normalised square, samples.
CONSISTENCY_MEMORY = 64
#: Ratio of that average to its expectation above which the readings disagree with the model
#: (the average of a right model scatters by ±0.09 about 1: this is 5.6 of those).
CONSISTENCY_THRESHOLD = 1.5
#: Memory of the running mean of the innovations (the sensors' relative offset), samples.
OFFSET_MEMORY = 4 * CONSISTENCY_MEMORY
#: Memory of the average of the squared difference between the filter's gas and the sensors'
#: inversion, samples (short: a step must be seen within a few samples).
GAS_MEMORY = 8
#: Ratio of that average to its expectation above which the filter's gas is off (on a record
#: the model fits, its 99th percentile is 2.5).
GAS_THRESHOLD = 4.0
#: Factor on the model's std from which a widening counts (:attr:`ConsistencyCheck.last_widened`):
#: the model's std is then less than half the error it is to bound, while the small, decaying
#: widenings after a ramp's corner leave it within 40 %.
MATERIAL_WIDENING = 2.0
#: Longest time constant, samples, over which a widening decays after the readings agree again
#: (a narrow resonator's closed loop may keep a state error for hours; its std then says so
#: for this long, not for ever).
MAX_HOLD_SAMPLES = 8 * CONSISTENCY_MEMORY


def _widen_loop(
    std: NDArray[np.float64],
    innovations: NDArray[np.float64],
    inverse: NDArray[np.float64],
    gas: NDArray[np.float64],
    inversion: NDArray[np.float64],
    state: NDArray[np.float64],
    settings: NDArray[np.float64],
    out: NDArray[np.float64],
) -> int:
    # One pass of ConsistencyCheck.widen (see there). state: [offset 1, offset 2, offsets seen,
    # innovation average, innovation held, gas ratio, gas held], carried in and out. settings:
    # [inversion variance, log decay, OFFSET_MEMORY, CONSISTENCY_MEMORY, CONSISTENCY_THRESHOLD,
    # GAS_MEMORY, GAS_THRESHOLD, MATERIAL_WIDENING]. Writes the std to publish into out;
    # returns how many were widened materially.
    inversion_variance = settings[0]
    decay = math.exp(settings[1])
    offset_memory = settings[2]
    innovation_rate = 1.0 / settings[3]
    consistency_threshold = settings[4]
    gas_rate = 1.0 / settings[5]
    gas_decay = math.exp(-1.0 / settings[5])
    gas_threshold = settings[6]
    material_widening = settings[7]
    offset_rate = 1.0 / offset_memory
    mean1 = state[0]
    mean2 = state[1]
    seen = state[2]
    base1 = mean1 * seen  # the plain mean's running sum: seen means plus those added
    base2 = mean2 * seen
    added1 = 0.0
    added2 = 0.0
    average = state[3]
    held = state[4] - 1.0
    ratio = state[5]
    gas_held = state[6]
    material = 0
    for k in range(std.size):
        # The innovations less their mean before this sample, normalised and squared.
        first = innovations[0, k] - mean1
        second = innovations[1, k] - mean2
        square = first * (inverse[k, 0, 0] * first + inverse[k, 0, 1] * second) + second * (
            inverse[k, 1, 0] * first + inverse[k, 1, 1] * second
        )
        if seen < offset_memory:  # a plain mean until OFFSET_MEMORY, then exponential
            added1 += innovations[0, k]
            added2 += innovations[1, k]
            seen += 1.0
            mean1 = (base1 + added1) / seen
            mean2 = (base2 + added2) / seen
        else:
            seen += 1.0
            mean1 = offset_rate * innovations[0, k] + (1.0 - offset_rate) * mean1
            mean2 = offset_rate * innovations[1, k] + (1.0 - offset_rate) * mean2
        average = innovation_rate * (0.5 * square) + (1.0 - innovation_rate) * average
        held = max(max(average - 1.0, 0.0), held * decay)
        widened = std[k] * (math.sqrt(1.0 + held) if 1.0 + held > consistency_threshold else 1.0)
        variance = std[k] * std[k]
        expected = max(inversion_variance - variance, 1e-3 * inversion_variance)
        difference = gas[k] - inversion[k]
        ratio = gas_rate * (difference * difference / expected) + (1.0 - gas_rate) * ratio
        excess = 0.0
        if ratio > gas_threshold:
            # The filter's error the difference implies: E d² = var_inv + E e² - 2 cov, cov ≈ var.
            excess = max(ratio * expected - inversion_variance + 2.0 * variance - variance, 0.0)
        gas_held = max(excess, gas_held * gas_decay)
        published = max(widened, math.sqrt(variance + gas_held))
        out[k] = published
        if published >= material_widening * std[k]:
            material += 1
    state[0] = mean1
    state[1] = mean2
    state[2] = seen
    state[3] = average
    state[4] = 1.0 + held
    state[5] = ratio
    state[6] = gas_held
    return material


@functools.cache
def _widen_kernel() -> Callable[..., Any]:
    """:func:`_widen_loop`, compiled where numba is installed (once per process, on disk)."""
    return compile_loops(_widen_loop)[0]


class ConsistencyCheck:
    """Widening of the causal filter's std where the readings disagree with its model.

    Parameters
    ----------
    model : FusionModel
        The filter's model (its τ, dt and noise give the sensors' inversion).
    closed_loop : ndarray, shape (n, n)
        The steady-state filter's closed-loop transition (its slowest mode sets how long a
        widening is held).
    """

    def __init__(self, model: FusionModel, closed_loop: NDArray[np.float64]) -> None:
        self.retune(model, closed_loop)
        self.reset()

    def retune(self, model: FusionModel, closed_loop: NDArray[np.float64]) -> None:
        """Switch to a new model and keep the averages (the filter keeps its state too)."""
        slowest = float(np.max(np.abs(np.linalg.eigvals(closed_loop)), initial=1e-300))
        # A state error decays as the slowest mode, its variance as that mode squared.
        self._log_decay = min(2.0 * math.log(slowest), -1.0 / MAX_HOLD_SAMPLES)
        poles = tau_to_pole([model.tau1, model.tau2], model.dt)
        self._poles = (float(poles[0]), float(poles[1]))
        variances = [
            sigma**2 * (1.0 + a**2) / (1.0 - a) ** 2
            for sigma, a in zip((model.sigma1, model.sigma2), self._poles, strict=True)
        ]
        self._weight = variances[1] / (variances[0] + variances[1])
        self.inversion_variance = variances[0] * variances[1] / (variances[0] + variances[1])

    def reset(self) -> None:
        """Forget the averages: the next batch starts from a model that agrees."""
        # The running mean of the innovations (2) and how many are in it (a plain mean until
        # OFFSET_MEMORY), the innovations' average and held excess, the gas ratio's average
        # and its held excess variance (°C²): what :func:`_widen_loop` carries over.
        self._state = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0])
        #: Samples of the last :meth:`widen` whose std was widened materially (by
        #: :data:`MATERIAL_WIDENING` or more).
        self.last_widened = 0
        self._last_material = False

    def inversion(self, tc1: NDArray[np.float64], tc2: NDArray[np.float64]) -> NDArray[np.float64]:
        """The gas over each interval from the two sensors' inversion, shape (M-1,), °C.

        ``tc1``, ``tc2`` (M,) are consecutive readings; variance :attr:`inversion_variance`.
        """
        a1, a2 = self._poles
        gas1 = (tc1[1:] - a1 * tc1[:-1]) / (1.0 - a1)
        gas2 = (tc2[1:] - a2 * tc2[:-1]) / (1.0 - a2)
        return self._weight * gas1 + (1.0 - self._weight) * gas2

    def widen(
        self,
        std: NDArray[np.float64],
        innovations: NDArray[np.float64],
        inverse: NDArray[np.float64],
        gas: NDArray[np.float64],
        inversion: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """The std of each new sample, widened where the readings disagree with the model.

        Parameters
        ----------
        std : ndarray, shape (M,)
            The model's standard deviation of the filtered gas, degrees C.
        innovations : ndarray, shape (2, M)
            The filter's innovations, degrees C.
        inverse : ndarray, shape (M, 2, 2)
            Their inverse covariances, 1/°C².
        gas, inversion : ndarray, shape (M,)
            The filter's gas and the sensors' inversion over the same intervals, degrees C.

        Returns
        -------
        ndarray, shape (M,)
            The standard deviation to publish, degrees C.
        """
        self.last_widened = 0
        if not std.size:
            return std
        settings = np.array(
            [
                self.inversion_variance,
                self._log_decay,
                OFFSET_MEMORY,
                CONSISTENCY_MEMORY,
                CONSISTENCY_THRESHOLD,
                GAS_MEMORY,
                GAS_THRESHOLD,
                MATERIAL_WIDENING,
            ],
            dtype=np.float64,
        )
        published = np.empty(std.size)
        self.last_widened = int(
            _widen_kernel()(
                std, innovations, inverse, gas, inversion, self._state, settings, published
            )
        )
        self._last_material = bool(published[-1] >= MATERIAL_WIDENING * std[-1])
        return published

    def widen_prediction(self, std: float) -> float:
        """The std of the prediction over the next interval, widened as the last sample's."""
        held = 1.0 + (self._state[4] - 1.0) * math.exp(self._log_decay)
        factor = math.sqrt(held) if held > CONSISTENCY_THRESHOLD else 1.0
        excess = self._state[6] * math.exp(-1.0 / GAS_MEMORY)
        return max(std * factor, math.sqrt(std**2 + excess))

    @property
    def widened(self) -> bool:
        """Whether the last sample's std was widened materially (by MATERIAL_WIDENING or more)."""
        return self._last_material


def widen_smoothed(
    model: FusionModel,
    closed_loop: NDArray[np.float64],
    std: NDArray[np.float64],
    innovations: NDArray[np.float64],
    inverse: NDArray[np.float64],
    gas: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The smoother's std (N,), widened where the readings disagree with the model.

    The smoother's error around a surprise spreads both ways in time, so the checks of
    :class:`ConsistencyCheck` run forwards and backwards over the record and the wider of the
    two is kept. ``innovations`` (2, N) are the forward filter's, of the readings that close
    each interval, ``inverse`` (2, 2) their inverse covariance, ``gas`` (N,) the smoothed gas
    (element k over ``[t_k, t_{k+1})``), ``tc1``, ``tc2`` (N,) the readings; degrees C.
    """
    count = std.size
    if count < 2:
        return std
    check = ConsistencyCheck(model, closed_loop)
    inversion = check.inversion(tc1, tc2)
    # Interval k's inversion uses readings k and k+1; the last interval is the prediction.
    inversion = np.append(inversion, gas[-1])
    inverses = np.broadcast_to(inverse, (count, 2, 2))
    forwards = check.widen(std, innovations, inverses, gas, inversion)
    check.reset()
    backwards = check.widen(std[::-1], innovations[:, ::-1], inverses, gas[::-1], inversion[::-1])[
        ::-1
    ]
    return np.maximum(forwards, backwards)
