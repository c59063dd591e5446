"""Gas temperature reconstruction through the difference equation (Eq. 7).

Each thermocouple alone gives ``T̂_gi(k) = (T_mi(k+1) - a_i T_mi(k)) / (1 - a_i)``, the gas
temperature held over ``[t_k, t_{k+1})``. With white noise of variance σi² on T_mi this estimate
carries noise of variance ``σi² (1 + a_i²) / (1 - a_i)²``: the slower sensor amplifies its noise
more. Both estimates are unbiased for the same T_g and their noises are independent, so the
minimum-variance combination is the inverse-variance weighted mean

    T̂_g3 = w T̂_g1 + (1 - w) T̂_g2,   w = v2 / (v1 + v2),   vi = σi² (1 + a_i²)/(1 - a_i)²,

with σ1²/σ2² = φ. The paper's alternatives (plain average, faster sensor only) are available as
``combine='mean'`` and ``combine='tc1'``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .choices import COMBINATIONS, Combination
from .filters import postfilter
from .models import FirstOrderLag
from .validation import check_pair, check_sample_interval

__all__ = ["COMBINATIONS", "Combination", "Reconstruction", "combination_weight", "reconstruct"]


@dataclass(frozen=True, kw_only=True)
class Reconstruction:
    """Reconstructed gas temperature.

    Attributes
    ----------
    time : ndarray, shape (N-1,)
        Start of the interval over which each reconstructed sample holds, seconds.
    gas1, gas2 : ndarray, shape (N-1,)
        Reconstructions from thermocouple 1 and 2 alone (T̂_g1, T̂_g2), degrees C.
    gas : ndarray, shape (N-1,)
        Combined reconstruction T̂_g3, degrees C.
    weight1 : float
        Weight of T̂_g1 in the combination (T̂_g2 has 1 - weight1).
    postfilter_hz : float or None
        Bandwidth of the zero-phase post-filter applied, Hz.
    """

    time: NDArray[np.float64]
    gas1: NDArray[np.float64]
    gas2: NDArray[np.float64]
    gas: NDArray[np.float64]
    weight1: float
    postfilter_hz: float | None = None


def _noise_variance(a: float) -> float:
    """Variance of Eq. (7)'s reconstruction noise per unit reading variance: (1 + a²)/(1 - a)²."""
    return (1.0 + a**2) / (1.0 - a) ** 2


def combination_weight(
    a1: float, a2: float, phi: float = 1.0, combine: Combination = "inverse-variance"
) -> float:
    """Weight of the thermocouple-1 reconstruction in the combined estimate T̂_g3."""
    if combine == "inverse-variance":
        variance1, variance2 = phi * _noise_variance(a1), _noise_variance(a2)
        return variance2 / (variance1 + variance2)
    if combine == "mean":
        return 0.5
    if combine == "tc1":
        return 1.0
    if combine == "tc2":
        return 0.0
    raise ValueError(f"unknown combination {combine!r}; choose one of {', '.join(COMBINATIONS)}")


def noise_gain(a1: float, a2: float, weight1: float) -> float:
    """How many times Eq. (7)'s combined gas multiplies the readings' noise σ (equal σ).

    Each reconstruction's noise has variance (1 + a_i²)/(1 - a_i)² σ²; the combination weighs
    them by ``weight1`` and 1 - ``weight1``.
    """
    return float(np.sqrt(gas_noise_variance(a1, a2, weight1, 1.0, 1.0)))


def gas_noise_variance(
    a1: float, a2: float, weight1: float, sigma1: float, sigma2: float
) -> float:
    """Variance of Eq. (7)'s combined gas from the readings' white noise, (degrees C)².

    Parameters
    ----------
    a1, a2 : float
        Poles exp(-dt/τi) of the two sensors.
    weight1 : float
        Weight of T̂_g1 in the combination.
    sigma1, sigma2 : float
        Noise standard deviations of the two readings, degrees C.
    """
    variance1 = _noise_variance(a1) * sigma1**2
    variance2 = _noise_variance(a2) * sigma2**2
    return float(weight1**2 * variance1 + (1.0 - weight1) ** 2 * variance2)


def reconstruct(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    phi: float = 1.0,
    combine: Combination = "inverse-variance",
    postfilter_hz: float | None = None,
    time: ArrayLike | None = None,
) -> Reconstruction:
    """Reconstruct the gas temperature from both thermocouples (Eq. 7).

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds (from :func:`tcomp_core.estimate`).
    phi : float
        Noise variance ratio σ1²/σ2² used to weight the two reconstructions.
    combine : {'inverse-variance', 'mean', 'tc1', 'tc2'}
        How T̂_g1 and T̂_g2 are combined.
    postfilter_hz : float, optional
        Bandwidth of the fifth-order zero-phase Butterworth post-filter, Hz.
    time : array_like, shape (N,), optional
        Sample times in seconds; ``k * dt`` when omitted.

    Returns
    -------
    Reconstruction
    """
    first, second = check_pair(tc1, tc2, min_samples=2)
    dt = check_sample_interval(dt)
    sensor1, sensor2 = FirstOrderLag(tau=tau1), FirstOrderLag(tau=tau2)
    gas1 = sensor1.invert(first, dt)
    gas2 = sensor2.invert(second, dt)
    if postfilter_hz is not None:
        gas1 = postfilter(gas1, dt, postfilter_hz)
        gas2 = postfilter(gas2, dt, postfilter_hz)
    weight1 = combination_weight(sensor1.pole(dt), sensor2.pole(dt), phi, combine)
    times = (
        np.arange(first.size, dtype=np.float64) * dt
        if time is None
        else np.asarray(time, dtype=np.float64)
    )
    if times.shape != first.shape:
        raise ValueError(f"time has shape {times.shape}, the signals {first.shape}")
    return Reconstruction(
        time=times[:-1],
        gas1=gas1,
        gas2=gas2,
        gas=weight1 * gas1 + (1.0 - weight1) * gas2,
        weight1=weight1,
        postfilter_hz=postfilter_hz,
    )
