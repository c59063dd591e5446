"""Oracle time constants: each sensor fitted to the *known* gas temperature.

Only a simulation knows T_g, so this is a yardstick, not an estimator: with the input known,
the output-error fit of one first-order lag is the maximum-likelihood estimate under white
measurement noise, and no method that sees only the two readings can do better.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import minimize_scalar

from ..errors import DataError
from ..validation import check_finite, check_sample_interval

__all__ = ["oracle_tau", "oracle_taus"]

#: Half-width of the output-error search around the ARX start, in log τ (a factor e each way).
_LOG_SEARCH = 1.0


def _arx_tau(reading: NDArray[np.float64], gas: NDArray[np.float64], dt: float) -> float:
    """Least-squares τ of T(k+1) - T(k) = (1 - a)(T_g(k) - T(k)), seconds (the start)."""
    rise = np.diff(reading)
    drive = gas[:-1] - reading[:-1]
    b = float(rise @ drive) / float(drive @ drive)
    b = min(max(b, 1e-9), 1.0 - 1e-9)
    return -dt / math.log1p(-b)


def _output_error(
    log_tau: float, reading: NDArray[np.float64], gas: NDArray[np.float64], dt: float
) -> float:
    """Sum of squared output errors with the initial state fitted by linear least squares."""
    a = math.exp(-dt / math.exp(log_tau))
    forced = signal.lfilter([0.0, 1.0 - a], [1.0, -a], gas)
    free = a ** np.arange(gas.size)
    misfit = reading - forced
    start = float(free @ misfit) / float(free @ free)
    error = misfit - start * free
    return float(error @ error)


def oracle_tau(reading: ArrayLike, gas: ArrayLike, dt: float) -> float:
    """Output-error time constant of one sensor driven by a known gas temperature.

    Parameters
    ----------
    reading : array_like, shape (N,)
        Sensor temperature, degrees C (noisy).
    gas : array_like, shape (N,)
        Gas temperature T_g(k), degrees C, zero-order held over each sample interval.
    dt : float
        Sample interval, s.

    Returns
    -------
    float
        τ in seconds minimising Σ (T(k) - T̂(k; τ, T̂(0)))², T̂ the ZOH response (Eq. 4).
    """
    reading = check_finite(reading, "reading")
    gas = check_finite(gas, "gas temperature")
    dt = check_sample_interval(dt)
    if reading.shape != gas.shape:
        raise DataError(f"reading has {reading.size} samples but gas has {gas.size}")
    centre = math.log(_arx_tau(reading, gas, dt))
    best = minimize_scalar(
        _output_error,
        bounds=(centre - _LOG_SEARCH, centre + _LOG_SEARCH),
        args=(reading, gas, dt),
        method="bounded",
        options={"xatol": 1e-10},
    )
    return math.exp(best.x)


def oracle_taus(tc1: ArrayLike, tc2: ArrayLike, gas: ArrayLike, dt: float) -> tuple[float, float]:
    """Time constants of both thermocouples fitted with the true gas temperature known.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Readings of thermocouples 1 and 2, degrees C.
    gas : array_like, shape (N,)
        True gas temperature, degrees C (e.g. ``SimulatedPair.gas``).
    dt : float
        Sample interval, s.

    Returns
    -------
    tau1, tau2 : float
        Seconds; see :func:`oracle_tau`.
    """
    return oracle_tau(tc1, gas, dt), oracle_tau(tc2, gas, dt)
