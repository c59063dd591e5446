"""TDR-Kee: time-derivative reconstruction with the time constant ratio known a priori.

The continuous model (Eq. 2) reconstructs the gas temperature from each sensor,
``T_gi = T_mi + τi dT_mi/dt``. With τ1 = α τ2 the difference of the two reconstructions is

    T_g1 - T_g2 = (T_m1 - T_m2) + τ2 (α D1 - D2),   Di = dT_mi/dt,

and minimising its sum of squares over a window gives the analytical estimate

    τ2 = -Σ (T_m1 - T_m2)(α D1 - D2) / Σ (α D1 - D2)²,   τ1 = α τ2.

The signals and their derivatives come from sliding-window polynomial smoothing
(Savitzky–Golay). τ is estimated in consecutive windows and the median taken.

When α is not given it is estimated as the paper did for the rig data: at a crossover of the two
signals T_m1 = T_m2, so T_g1 = T_g2 implies τ1 D1 = τ2 D2 and α = D2/D1 there.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from ..errors import EstimationError, PhysicalRangeError
from ..models import tau_to_pole
from .result import Estimate

__all__ = ["crossover_alpha", "smoothed_derivative", "tdr_kee"]

DEFAULT_SMOOTH_SAMPLES = 11
DEFAULT_POLYORDER = 3


def smoothed_derivative(
    values: NDArray[np.float64], dt: float, smooth_samples: int, polyorder: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Savitzky–Golay smoothed signal and its time derivative (degrees C and C/s)."""
    smooth = savgol_filter(values, smooth_samples, polyorder)
    derivative = savgol_filter(values, smooth_samples, polyorder, deriv=1, delta=dt)
    return smooth, derivative


def crossover_alpha(
    smooth1: NDArray[np.float64],
    smooth2: NDArray[np.float64],
    derivative1: NDArray[np.float64],
    derivative2: NDArray[np.float64],
) -> float:
    """Time constant ratio α = D2/D1 at the crossovers of the two signals (median over them).

    Raises
    ------
    EstimationError
        If the signals never cross with a usable slope.
    """
    difference = smooth1 - smooth2
    crossings = np.flatnonzero(np.signbit(difference[1:]) != np.signbit(difference[:-1]))
    # Interpolate the derivatives linearly to the zero of the difference.
    weight = difference[crossings] / (difference[crossings] - difference[crossings + 1])
    d1 = derivative1[crossings] + weight * (derivative1[crossings + 1] - derivative1[crossings])
    d2 = derivative2[crossings] + weight * (derivative2[crossings + 1] - derivative2[crossings])
    usable = np.abs(d1) > 1e-3 * np.max(np.abs(derivative1))
    ratios = d2[usable] / d1[usable]
    ratios = ratios[ratios > 0.0]
    if ratios.size == 0:
        raise EstimationError(
            "tdr-kee: alpha was not given and the two signals never cross with a usable slope, "
            "so it cannot be estimated; pass alpha = tau1/tau2"
        )
    return float(np.median(ratios))


def tdr_kee(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    alpha: float | None = None,
    *,
    smooth_samples: int = DEFAULT_SMOOTH_SAMPLES,
    polyorder: int = DEFAULT_POLYORDER,
    window_samples: int | None = None,
) -> Estimate:
    """TDR-Kee time constants (Kee et al. 1999, as compared in Sec. IV).

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Thermocouple temperatures, degrees C; tc1 is the sensor with τ1 = α τ2.
    dt : float
        Sample interval, seconds.
    alpha : float, optional
        Time constant ratio τ1/τ2 known a priori; estimated at signal crossovers when omitted.
    smooth_samples : int
        Odd length of the Savitzky–Golay smoothing window, samples.
    polyorder : int
        Order of the smoothing polynomial.
    window_samples : int, optional
        Samples per estimation window; a tenth of the record (at least 50) by default.

    Returns
    -------
    Estimate
        ``params`` holds ``alpha``, ``alpha_estimated`` (1 or 0), ``windows`` and
        ``tau2_window_std`` (s); ``condition`` is 1 + the coefficient of variation of the
        per-window τ2.
    """
    n = tc1.size
    if smooth_samples % 2 == 0 or smooth_samples <= polyorder or smooth_samples > n:
        raise ValueError(
            f"{smooth_samples=} must be odd, > {polyorder=} and no longer than the {n} samples"
        )
    smooth1, derivative1 = smoothed_derivative(tc1, dt, smooth_samples, polyorder)
    smooth2, derivative2 = smoothed_derivative(tc2, dt, smooth_samples, polyorder)
    alpha_estimated = alpha is None
    if alpha is None:
        alpha = crossover_alpha(smooth1, smooth2, derivative1, derivative2)
    elif not (np.isfinite(alpha) and alpha > 0.0):
        raise ValueError(f"{alpha=} must be a finite time constant ratio > 0")

    window = max(50, n // 10) if window_samples is None else int(window_samples)
    window = min(window, n)
    combined = alpha * derivative1 - derivative2
    gap = smooth1 - smooth2
    estimates = []
    for start in range(0, n - window + 1, window):
        part = slice(start, start + window)
        denominator = float(np.dot(combined[part], combined[part]))
        if denominator > 0.0:
            estimates.append(-float(np.dot(gap[part], combined[part])) / denominator)
    if not estimates:
        raise EstimationError("tdr-kee: no window has a non-zero derivative combination")
    per_window = np.asarray(estimates)
    tau2 = float(np.median(per_window))
    if not tau2 > 0.0:
        raise PhysicalRangeError(
            f"tdr-kee: estimated tau2 = {tau2!r} s is not positive (alpha = {alpha:.6g})"
        )
    tau1 = alpha * tau2
    spread = float(np.std(per_window))
    return Estimate(
        method="tdr-kee",
        tau1=tau1,
        tau2=tau2,
        a1=float(tau_to_pole(tau1, dt)),
        a2=float(tau_to_pole(tau2, dt)),
        dt=dt,
        n_samples=n,
        condition=1.0 + spread / tau2,
        params={
            "alpha": float(alpha),
            "alpha_estimated": float(alpha_estimated),
            "windows": float(per_window.size),
            "tau2_window_std": spread,
        },
    )
