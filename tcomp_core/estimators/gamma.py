"""γ estimators: the three-parameter ARX form of the two-thermocouple model (Eqs. 8–11).

Eliminating T_g from the two difference equations gives the ARX model (Eq. 11)

    T_m2(k) = γ1 T_m2(k-1) + γ2 T_m1(k) + γ3 T_m1(k-1),

with γ1 = a2, γ2 = (1-a2)/(1-a1), γ3 = -a1 (1-a2)/(1-a1) (Eq. 10): three parameters for two
unknowns. Recovering the poles:

- ``a2 = γ1``, the pole of the transfer function T_m1 → T_m2 = γ2 (1 - a1 z⁻¹)/(1 - a2 z⁻¹);
- ``a1 = -γ3/γ2``, its zero.

We take a1 from the zero rather than from the gain route a1 = 1 - (1-γ1)/γ2 because the zero
uses only the two coefficients of the T_m1 terms, which are estimated from the same regressor
pair, whereas the gain route mixes in γ1's error and relies on the fitted DC gain γ1+γ2+γ3
being exactly 1, which a noisy fit does not honour. With noise-free data both routes agree; the
gain-route value is kept as ``a1_gain`` in ``params`` and its disagreement shows how far the fit
is from the model's constraint.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import NoExcitationError
from .result import Estimate, estimate_from_poles
from .scatter import equilibrated_condition_r, gamma_r_factor, solve_gtls_r, solve_ls_r

__all__ = ["estimate_gamma_from_factor", "gamma_ls", "gamma_poles", "gamma_tls"]

MAX_CONDITION = 1e7


def gamma_poles(gamma: NDArray[np.float64]) -> tuple[float, float, float]:
    """Poles from γ (inverse of Eq. 10): ``(a1, a2, a1_gain)``; see the module notes."""
    gamma1, gamma2, gamma3 = (float(value) for value in gamma)
    a2 = gamma1
    a1 = -gamma3 / gamma2
    a1_gain = 1.0 - (1.0 - gamma1) / gamma2
    return a1, a2, a1_gain


def estimate_gamma_from_factor(
    factor: NDArray[np.float64], dt: float, n_samples: int, method: str
) -> Estimate:
    """Solve the γ model from the 4×4 triangular factor of its rows (:func:`gamma_r_factor`).

    The factor rather than the scatter matrix: the γ regressors carry the raw temperature levels,
    and squaring their condition number would cost digits.
    """
    condition = equilibrated_condition_r(factor[:3, :3])
    if not condition < MAX_CONDITION:
        raise NoExcitationError(
            f"{method}: the regressors of Eq. (11) are collinear (condition {condition:.3g}): "
            "the data carry no information on the time constants"
        )
    params: dict[str, float] = {}
    if method == "gamma-ls":
        gamma = solve_ls_r(factor)
    elif method == "gamma-tls":
        gamma, eigenvalues = solve_gtls_r(factor)
        params["noise_eigenvalue"] = float(eigenvalues[0])
    else:
        raise ValueError(f"unknown γ method {method!r}")
    a1, a2, a1_gain = gamma_poles(gamma)
    named = {"gamma1": gamma[0], "gamma2": gamma[1], "gamma3": gamma[2], "a1_gain": a1_gain}
    return estimate_from_poles(method, a1, a2, dt, n_samples, condition, {**named, **params})


def gamma_ls(tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float) -> Estimate:
    """γ-LS: least squares on the ARX model of Eq. (11). Biased when T_m1 is noisy.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Thermocouple temperatures, degrees C, validated by the caller.
    dt : float
        Sample interval, seconds.
    """
    return estimate_gamma_from_factor(gamma_r_factor(tc1, tc2), dt, tc1.size, "gamma-ls")


def gamma_tls(tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float) -> Estimate:
    """γ-TLS: total least squares on Eq. (11).

    Each column of ``[T_m2(k-1), T_m1(k), T_m1(k-1), T_m2(k)]`` carries one independent noise
    sample, so with equal noise variances the row covariance is σ²I and TLS is consistent.
    """
    return estimate_gamma_from_factor(gamma_r_factor(tc1, tc2), dt, tc1.size, "gamma-tls")
