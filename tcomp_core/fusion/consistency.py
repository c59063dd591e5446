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

import math

import numpy as np
from numpy.typing import NDArray
from scipy import signal

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


def _moving_average(
    values: NDArray[np.float64], memory: int, carried: float
) -> NDArray[np.float64]:
    """Exponential average of ``values`` (M,) over ``memory`` samples from ``carried``."""
    rate = 1.0 / memory
    average, _ = signal.lfilter([rate], [1.0, rate - 1.0], values, zi=[(1.0 - rate) * carried])
    return np.asarray(average, dtype=float)


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
        self._innovation_average = 1.0
        self._offset = np.zeros(2)  # running mean of the innovations
        self._offset_count = 0  # innovations in it (a plain mean until OFFSET_MEMORY)
        self._innovation_held = 1.0
        self._gas_ratio = 1.0
        self._gas_held = 0.0  # °C², the held excess variance of the gas
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

    def _debiased_square(
        self, innovations: NDArray[np.float64], inverse: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Normalised squares (M,) of the innovations (2, M) less their mean before each.

        The mean is the plain one over the innovations seen since the reset until there are
        :data:`OFFSET_MEMORY` of them, then an exponential average over that many.
        """
        count = innovations.shape[1]
        means = np.empty((2, count + 1))
        means[:, 0] = self._offset
        seen = self._offset_count
        head = min(count, max(OFFSET_MEMORY - seen, 0))
        if head:
            sums = self._offset[:, None] * seen + np.cumsum(innovations[:, :head], axis=1)
            means[:, 1 : head + 1] = sums / (seen + np.arange(1, head + 1))
        if head < count:
            rate = 1.0 / OFFSET_MEMORY
            means[:, head + 1 :] = signal.lfilter(
                [rate],
                [1.0, rate - 1.0],
                innovations[:, head:],
                axis=1,
                zi=(1.0 - rate) * means[:, head : head + 1],
            )[0]
        self._offset, self._offset_count = means[:, -1].copy(), seen + count
        debiased = innovations - means[:, :-1]
        return np.einsum("ik,kij,jk->k", debiased, inverse, debiased)

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
        square = self._debiased_square(innovations, inverse)
        average = _moving_average(0.5 * square, CONSISTENCY_MEMORY, self._innovation_average)
        self._innovation_average = float(average[-1])
        held = 1.0 + self._hold(
            np.maximum(average - 1.0, 0.0), self._innovation_held - 1.0, self._log_decay
        )
        self._innovation_held = float(held[-1])
        widened = std * np.where(held > CONSISTENCY_THRESHOLD, np.sqrt(held), 1.0)

        variance = std**2
        expected = np.maximum(self.inversion_variance - variance, 1e-3 * self.inversion_variance)
        ratio = _moving_average((gas - inversion) ** 2 / expected, GAS_MEMORY, self._gas_ratio)
        self._gas_ratio = float(ratio[-1])
        # The filter's error the difference implies: E d² = var_inv + E e² - 2 cov, cov ≈ var.
        implied = ratio * expected - self.inversion_variance + 2.0 * variance
        excess = np.where(ratio > GAS_THRESHOLD, np.maximum(implied - variance, 0.0), 0.0)
        # The difference sees the gas error itself: held only across the zeros of a ringing.
        held_excess = self._hold(excess, self._gas_held, -1.0 / GAS_MEMORY)
        self._gas_held = float(held_excess[-1])
        published = np.maximum(widened, np.sqrt(variance + held_excess))
        material = published >= MATERIAL_WIDENING * std
        self.last_widened = int(np.count_nonzero(material))
        self._last_material = bool(material[-1])
        return published

    def widen_prediction(self, std: float) -> float:
        """The std of the prediction over the next interval, widened as the last sample's."""
        held = 1.0 + (self._innovation_held - 1.0) * math.exp(self._log_decay)
        factor = math.sqrt(held) if held > CONSISTENCY_THRESHOLD else 1.0
        excess = self._gas_held * math.exp(-1.0 / GAS_MEMORY)
        return max(std * factor, math.sqrt(std**2 + excess))

    @property
    def widened(self) -> bool:
        """Whether the last sample's std was widened materially (by MATERIAL_WIDENING or more)."""
        return self._last_material

    @staticmethod
    def _hold(
        excess: NDArray[np.float64], carried: float, log_decay: float
    ) -> NDArray[np.float64]:
        """Running maximum of ``excess`` (M,), each value decaying at the closed loop's rate.

        ``h_k = max(excess_k, h_{k-1} ρ)`` from the carried ``h_{-1}``, computed in logs as a
        cumulative maximum: ``log h_k = k log ρ + max_{j ≤ k} (log excess_j - j log ρ)``.
        """
        steps = np.arange(excess.size)
        with np.errstate(divide="ignore"):
            logs = np.log(excess) - steps * log_decay
            start = math.log(carried) + log_decay if carried > 0.0 else -np.inf
        logs[0] = max(logs[0], start)
        return np.exp(np.maximum.accumulate(logs) + steps * log_decay)


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
