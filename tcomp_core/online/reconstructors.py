"""Causal reconstruction of the gas temperature from matched pairs: Eq. (7) and the post-filter.

A reconstructor takes a run of pairs (the previous run's last pair first, so every new pair has
a predecessor) with the stamp steps and the gap flags, and returns the gas temperature and its
variance for each pair that follows its predecessor without a gap (pair k reconstructs the gas
held from pair k-1's stamp); the compensator wraps them in a :class:`GasBatch`.

- :class:`DifferenceReconstructor`: Eq. (7) per sensor with the actual stamp step for the
  pole, combined by ``reconstruct_from`` (inverse-variance for ``'fused'``); variance 0
  (unknown). The causal Kalman filter of both sensors is :mod:`.kalman`'s.
- :class:`PostFilter`: the optional causal Butterworth low-pass applied to either result (a
  forward-backward filter cannot run online).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from ..reconstruct import combination_weight
from .config import OnlineConfig

__all__ = ["DifferenceReconstructor", "GasBatch", "PostFilter"]


class GasBatch(NamedTuple):
    """Reconstructed gas samples.

    Attributes
    ----------
    stamps_ns : ndarray of int64, shape (R,)
        Stamps of the reconstructed samples (each pair's predecessor), ns.
    gas : ndarray of float64, shape (R,)
        Gas temperature, degrees C.
    variance : ndarray of float64, shape (R,)
        Its variance, degrees C squared (0 = unknown, as for the difference equation).
    """

    stamps_ns: NDArray[np.int64]
    gas: NDArray[np.float64]
    variance: NDArray[np.float64]

    @classmethod
    def empty(cls) -> GasBatch:
        """No samples."""
        return cls(np.empty(0, dtype=np.int64), np.empty(0), np.empty(0))

    def split(self, count: int) -> tuple[GasBatch, GasBatch]:
        """The first ``count`` samples and the rest."""
        head = GasBatch(self.stamps_ns[:count], self.gas[:count], self.variance[:count])
        tail = GasBatch(self.stamps_ns[count:], self.gas[count:], self.variance[count:])
        return head, tail

    @classmethod
    def concatenate(cls, parts: list[GasBatch]) -> GasBatch:
        """One batch of several, in the given order."""
        if len(parts) == 1:
            return parts[0]
        if not parts:
            return cls.empty()
        stamps, gas, variance = zip(*parts, strict=True)
        return cls(np.concatenate(stamps), np.concatenate(gas), np.concatenate(variance))


class DifferenceReconstructor:
    """Eq. (7) over each contiguous step, with the actual step for the poles.

    Parameters
    ----------
    config : OnlineConfig
        ``reconstruct_from`` and ``phi`` choose the combination of the two reconstructions.
    period_s : float
        Sample period, seconds (sets the combination weight).
    tau : (float, float)
        τ1, τ2, seconds.
    phi : float, optional
        Noise variance ratio σ1²/σ2² of the estimate in use (measured when ``config.phi`` is
        0); by default ``config.phi``, or 1 when that is 0.
    """

    def __init__(
        self,
        config: OnlineConfig,
        period_s: float,
        tau: tuple[float, float],
        phi: float | None = None,
    ) -> None:
        self._config = config
        self._period = period_s
        self._tau = tau
        self._phi = phi
        self._weight = self._combination_weight()
        #: Values of the last reconstruction whose std was widened (Eq. 7 has none).
        self.last_widened = 0

    def _combination_weight(self) -> float:
        tau1, tau2 = self._tau
        choice = self._config.reconstruct_from
        return combination_weight(
            math.exp(-self._period / tau1),
            math.exp(-self._period / tau2),
            self._phi or self._config.fixed_phi or 1.0,
            "inverse-variance" if choice == "fused" else choice,  # type: ignore[arg-type]
        )

    @property
    def tau(self) -> tuple[float, float]:
        """τ1, τ2 in use, seconds."""
        return self._tau

    @property
    def phi(self) -> float | None:
        """The estimate's noise variance ratio in use (None: the configured one)."""
        return self._phi

    def retune(self, tau: tuple[float, float], phi: float | None = None) -> None:
        """Use new time constants, seconds, and the noise variance ratio estimated with them."""
        self._tau = tau
        self._phi = phi
        self._weight = self._combination_weight()

    def reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Gas of each contiguous step, degrees C, and a zero (unknown) variance."""
        tau1, tau2 = self._tau
        a1 = np.exp(-steps_s / tau1)
        a2 = np.exp(-steps_s / tau2)
        gas1 = (tc1[1:] - a1 * tc1[:-1]) / (1.0 - a1)
        gas2 = (tc2[1:] - a2 * tc2[:-1]) / (1.0 - a2)
        weight = self._weight
        gas = (weight * gas1 + (1.0 - weight) * gas2)[contiguous]
        return gas, np.zeros(gas.size)


class PostFilter:
    """Causal Butterworth low-pass of the reconstruction, its state kept across batches.

    Parameters
    ----------
    cutoff_hz : float
        Cut-off, Hz (> 0; clipped to 0.99 of Nyquist).
    order : int
        Filter order.
    period_s : float
        Sample period, seconds.
    """

    def __init__(self, cutoff_hz: float, order: int, period_s: float) -> None:
        nyquist = 0.5 / period_s
        self._sos = signal.butter(
            order, min(cutoff_hz, 0.99 * nyquist), output="sos", fs=1.0 / period_s
        )
        self._state: NDArray[np.float64] | None = None

    def __call__(self, gas: NDArray[np.float64]) -> NDArray[np.float64]:
        """Filter the next samples, degrees C (the first call starts at rest at its value)."""
        if gas.size == 0:
            return gas
        if self._state is None:
            self._state = signal.sosfilt_zi(self._sos) * gas[0]
        filtered, self._state = signal.sosfilt(self._sos, gas, zi=self._state)
        return filtered
