"""The first-order thermocouple model and its zero-order-hold difference equation.

A fine-wire thermocouple with negligible conduction and radiation obeys (Eq. 2)

    T_g(t) = T_m(t) + τ dT_m/dt,

a unity-gain first-order lag. With the gas temperature held constant over each sample interval
τ_s (zero-order hold) the sampled response obeys exactly (Eqs. 4–6)

    T_m(k) = a T_m(k-1) + b T_g(k-1),   a = exp(-τ_s/τ),   b = 1 - a.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from .errors import PhysicalRangeError
from .validation import check_finite, check_sample_interval

__all__ = ["FirstOrderLag", "lag_frequency_response", "pole_to_tau", "tau_to_pole"]


def tau_to_pole(tau: ArrayLike, dt: float) -> NDArray[np.float64]:
    """Discrete pole ``a = exp(-dt/τ)`` of the ZOH model (Eq. 5).

    Parameters
    ----------
    tau : array_like
        Time constant(s) in seconds, > 0.
    dt : float
        Sample interval τ_s in seconds.
    """
    tau = np.asarray(tau, dtype=np.float64)
    if np.any(~(tau > 0.0)):
        raise ValueError(f"time constant {tau!r} s must be > 0")
    return np.exp(-check_sample_interval(dt) / tau)


def lag_frequency_response(pole: float, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Frequency response G(ω) = (1 - a) e^(-iω) / (1 - a e^(-iω)) of the ZOH lag (Eq. 4).

    Parameters
    ----------
    pole : float
        Discrete pole a = exp(-dt/τ).
    omega : ndarray
        Angular frequency, rad per sample.
    """
    delay = np.exp(-1j * np.asarray(omega, dtype=np.float64))
    return (1.0 - pole) * delay / (1.0 - pole * delay)


def pole_to_tau(a: float, dt: float, label: str = "a") -> float:
    """Time constant ``τ = -dt / ln(a)`` in seconds from a discrete pole (inverse of Eq. 5).

    Raises
    ------
    PhysicalRangeError
        If ``a`` is outside the open interval (0, 1), where no positive finite τ exists.
    """
    a = float(a)
    if not (0.0 < a < 1.0):
        raise PhysicalRangeError(
            f"{label} = {a!r} lies outside (0, 1): no positive time constant gives this pole"
        )
    return float(-check_sample_interval(dt) / np.log(a))


@dataclass(frozen=True, kw_only=True)
class FirstOrderLag:
    """A unity-gain first-order lag, the thermocouple model of Eq. (2).

    Parameters
    ----------
    tau : float
        Time constant in seconds, > 0.
    """

    tau: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.tau) and self.tau > 0.0):
            raise ValueError(f"tau={self.tau!r} s must be finite and > 0")

    def pole(self, dt: float) -> float:
        """Discrete pole ``a`` of the ZOH difference equation for interval ``dt`` (Eq. 5)."""
        return float(tau_to_pole(self.tau, dt))

    def respond(
        self, gas: ArrayLike, dt: float, initial: float | None = None
    ) -> NDArray[np.float64]:
        """Sampled sensor temperature for a zero-order-held gas temperature (Eq. 4).

        Parameters
        ----------
        gas : array_like, shape (N,)
            Gas temperature T_g(k) in degrees C, held constant over each interval.
        dt : float
            Sample interval in seconds.
        initial : float, optional
            Sensor temperature at sample 0; defaults to ``gas[0]`` (sensor in equilibrium).

        Returns
        -------
        ndarray, shape (N,)
            T_m(k) in degrees C; exactly the difference equation, so the DE estimators recover τ
            from it to rounding.
        """
        tg = check_finite(gas, "gas temperature")
        a = self.pole(dt)
        start = tg[0] if initial is None else float(initial)
        # T_m(k) = a T_m(k-1) + (1-a) T_g(k-1): numerator [0, 1-a], the state holds T_m(0).
        response, _ = signal.lfilter([0.0, 1.0 - a], [1.0, -a], tg, zi=[start])
        return response

    def invert(self, measured: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Gas temperature from the sensor temperature through the difference equation (Eq. 7).

        ``T_g(k-1) = (T_m(k) - a T_m(k-1)) / (1 - a)``, so the result has one sample fewer than
        the input: element k is the gas temperature held over ``[t_k, t_{k+1})``.

        Parameters
        ----------
        measured : array_like, shape (N,)
            Sensor temperature in degrees C.
        dt : float
            Sample interval in seconds.

        Returns
        -------
        ndarray, shape (N-1,)
        """
        tm = check_finite(measured, "measured temperature")
        a = self.pole(dt)
        return (tm[1:] - a * tm[:-1]) / (1.0 - a)
