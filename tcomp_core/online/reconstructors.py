"""Causal reconstruction of the gas temperature from matched pairs: one class per kind.

Each reconstructor takes a run of pairs (the previous run's last pair first, so every new pair
has a predecessor) with the stamp steps and the gap flags, and returns a :class:`GasBatch`:
the stamps, the gas temperature and its variance, for each pair that follows its predecessor
without a gap (pair k reconstructs the gas held from pair k-1's stamp).

- :class:`DifferenceReconstructor`: Eq. (7) per sensor with the actual stamp step for the
  pole, combined by ``reconstruct_from`` (inverse-variance for ``'fused'``); variance 0
  (unknown).
- :class:`KalmanReconstructor`: the causal Kalman filter of both sensors
  (:class:`~tcomp_core.fusion.CausalFuser`), restarted after a gap, its variance its own. Its
  signal model is fitted by maximum likelihood on the window when the first τ is accepted,
  again as the gap-free stretch it is fitted on doubles (up to
  :data:`~.config.FUSION_FIT_SAMPLES`) and whenever τ has moved by
  :data:`~.config.FUSION_REFIT_CHANGE` since; smaller moves only retune its τ. Until a model
  could be fitted it reconstructs by Eq. (7).
- :class:`PostFilter`: the optional causal Butterworth low-pass applied to either result (a
  forward-backward filter cannot run online).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from ..errors import TcompError
from ..fusion import CausalFuser, FusionModel, fit_fusion_model
from ..reconstruct import combination_weight
from .config import FUSION_FIT_SAMPLES, FUSION_REFIT_CHANGE, OnlineConfig
from .estimation import gap_free_runs

#: Gives the window's longest gap-free stretch, shape (n, 2), degrees C, when called.
SegmentSource = Callable[[], NDArray[np.float64]]

__all__ = [
    "DifferenceReconstructor",
    "GasBatch",
    "KalmanReconstructor",
    "PostFilter",
    "Reconstructor",
    "SegmentSource",
    "make_reconstructor",
]


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

    @classmethod
    def concatenate(cls, parts: list[GasBatch]) -> GasBatch:
        """One batch of several, in the given order."""
        if len(parts) == 1:
            return parts[0]
        if not parts:
            return cls.empty()
        stamps, gas, variance = zip(*parts, strict=True)
        return cls(np.concatenate(stamps), np.concatenate(gas), np.concatenate(variance))


class Reconstructor(Protocol):
    """What the engine asks of a reconstructor."""

    def reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Gas (degrees C) and variance (degrees C squared) of each contiguous step."""

    def retune(self, tau: tuple[float, float], segment: SegmentSource) -> None:
        """Use new time constants (s); ``segment()`` gives the window's longest stretch (n, 2).

        ``segment`` is called only by a reconstructor that refits on the window (it copies it).
        """


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
    """

    def __init__(self, config: OnlineConfig, period_s: float, tau: tuple[float, float]) -> None:
        self._config = config
        self._period = period_s
        self._tau = tau
        self._weight = self._combination_weight()

    def _combination_weight(self) -> float:
        tau1, tau2 = self._tau
        choice = self._config.reconstruct_from
        return combination_weight(
            math.exp(-self._period / tau1),
            math.exp(-self._period / tau2),
            self._config.phi,
            "inverse-variance" if choice == "fused" else choice,  # type: ignore[arg-type]
        )

    @property
    def tau(self) -> tuple[float, float]:
        """τ1, τ2 in use, seconds."""
        return self._tau

    def retune(self, tau: tuple[float, float], segment: SegmentSource) -> None:
        """Use new time constants, seconds (the window is not needed)."""
        self._tau = tau
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


class KalmanReconstructor:
    """The causal Kalman filter of both sensors, with its signal model's refit policy.

    Parameters
    ----------
    config : OnlineConfig
        ``signal_model`` names the gas model fitted; ``reconstruct_from`` and ``phi`` set the
        Eq. (7) fallback used until a model could be fitted.
    period_s : float
        Sample period, seconds.
    tau : (float, float)
        τ1, τ2, seconds.
    segment : ndarray, shape (n, 2)
        The window's longest gap-free stretch (tc1, tc2 in degrees C) to fit the model on.
    """

    def __init__(
        self,
        config: OnlineConfig,
        period_s: float,
        tau: tuple[float, float],
        segment: NDArray[np.float64],
    ) -> None:
        self._config = config
        self._period = period_s
        self._fallback = DifferenceReconstructor(config, period_s, tau)
        self._fuser: CausalFuser | None = None
        self._fuser_stamp: int | None = None  # stamp of the last sample the fuser took
        self._fusion_tau: tuple[float, float] | None = None  # τ its model was fitted at
        self._fusion_samples = 0  # samples it was fitted on
        #: Why the signal model could not be fitted ('' when it could).
        self.error = ""
        self.retune(tau, lambda: segment)

    def configure(self, config: OnlineConfig) -> None:
        """Take settings that keep the signal model (``reconstruct_from``, ``phi``, ...)."""
        self._config = config
        self._fallback = DifferenceReconstructor(config, self._period, self._fallback.tau)

    @property
    def model(self) -> FusionModel | None:
        """The fitted signal model (None until one could be fitted)."""
        return None if self._fuser is None else self._fuser.model

    def retune(self, tau: tuple[float, float], segment: SegmentSource) -> None:
        """Retune the filter to the new τ, or refit its signal model on ``segment()``."""
        self._fallback.retune(tau, segment)
        tau1, tau2 = tau
        stretch = segment()[-FUSION_FIT_SAMPLES:]
        if self._fuser is not None and self._fusion_tau is not None:
            moved = max(
                abs(new / old - 1.0) for new, old in zip(tau, self._fusion_tau, strict=True)
            )
            # Early fits see few samples (noise levels from short spectra): refit as the
            # stretch doubles, up to FUSION_FIT_SAMPLES.
            grown = stretch.shape[0] >= 2 * self._fusion_samples
            if moved < FUSION_REFIT_CHANGE and not grown:
                self._fuser.retune(replace(self._fuser.model, tau1=tau1, tau2=tau2))
                return
        try:
            model, _, _ = fit_fusion_model(
                stretch[:, 0],
                stretch[:, 1],
                self._period,
                tau1,
                tau2,
                model=self._config.signal_model,  # type: ignore[arg-type]
            )
        except (TcompError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self.error = f"signal model not fitted: {exc}"
            if self._fuser is not None:
                self._fuser.retune(replace(self._fuser.model, tau1=tau1, tau2=tau2))
            return
        self.error = ""
        if self._fuser is None:
            self._fuser = CausalFuser(model)
        else:
            self._fuser.retune(model)
        self._fusion_tau = (tau1, tau2)
        self._fusion_samples = stretch.shape[0]

    def reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Causal estimate over each contiguous step (degrees C) and its variance (°C²).

        The filter continues from the last sample it took when this run starts with it, and
        starts afresh after a gap or a lost one.
        """
        fuser = self._fuser
        if fuser is None:
            return self._fallback.reconstruct(stamps, tc1, tc2, steps_s, contiguous)
        gas, std = [], []
        for start, stop in gap_free_runs(contiguous):
            begin = start
            if start == 0 and fuser.started and self._fuser_stamp == int(stamps[0]):
                begin = 1
            else:
                fuser.reset()
            estimates, deviations = fuser.extend(tc1[begin:stop], tc2[begin:stop])
            gas.append(estimates)
            std.append(deviations)
        self._fuser_stamp = int(stamps[-1])
        return np.concatenate(gas), np.concatenate(std) ** 2


def make_reconstructor(
    config: OnlineConfig,
    period_s: float,
    tau: tuple[float, float],
    segment: NDArray[np.float64],
) -> DifferenceReconstructor | KalmanReconstructor:
    """The reconstructor ``config.reconstruction`` names, set to ``tau`` (s)."""
    if config.reconstruction == "kalman":
        return KalmanReconstructor(config, period_s, tau, segment)
    return DifferenceReconstructor(config, period_s, tau)


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
