"""β estimators: the two-parameter difference-equation model (Eqs. 12–21).

Eliminating T_g from the two ZOH difference equations (Eq. 7) and writing β = b2/b1 gives (Eq. 13)

    ΔT_m2(k) = β ΔT_m1(k) + b1 β (T_m1(k-1) - T_m2(k-1)),

linear in θ = [β, b1 β] (Eq. 15). Noise on both thermocouples enters X and Y, so LS is biased;
ordinary TLS is also biased because the row noise covariance is not a multiple of I; GTLS with
the covariance C0(φ) of Eq. (19) is consistent.

Each estimator works from the 3×3 scatter matrix of ``[X Y]``, so the same solvers serve the
batch functions here and the sliding window in :mod:`tcomp_core.window`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import NoExcitationError
from .result import Estimate, estimate_from_poles
from .scatter import beta_scatter, equilibrated_condition, solve_gtls, solve_ls

__all__ = [
    "beta_gtls",
    "beta_ls",
    "beta_noise_covariance",
    "beta_tls",
    "estimate_beta_from_scatter",
]

#: Condition number of the equilibrated regressor above which the data carry no usable
#: information on θ (the normal equations lose all significant digits near 1e8).
MAX_CONDITION = 1e7


def beta_noise_covariance(phi: float = 1.0) -> NDArray[np.float64]:
    """Normalized row noise covariance C0(φ) of ``[x1, x2, y]`` (Eq. 19).

    With white noise of variances σ1² and σ2² on the two thermocouples and φ = σ1²/σ2², the
    covariance of one row is σ2² C0(φ).

    Parameters
    ----------
    phi : float
        Noise variance ratio σ1²/σ2², > 0.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    if not (np.isfinite(phi) and phi > 0.0):
        raise ValueError(f"{phi=} must be a finite noise variance ratio > 0")
    return np.array(
        [
            [2.0 * phi, -phi, 0.0],
            [-phi, phi + 1.0, 1.0],
            [0.0, 1.0, 2.0],
        ]
    )


def estimate_beta_from_scatter(
    scatter: NDArray[np.float64],
    dt: float,
    n_samples: int,
    method: str = "beta-gtls",
    phi: float = 1.0,
) -> Estimate:
    """Solve a β model from its 3×3 scatter matrix.

    Parameters
    ----------
    scatter : ndarray, shape (3, 3)
        ``[X Y]ᵀ [X Y]`` of Eq. (14).
    dt : float
        Sample interval in seconds.
    n_samples : int
        Samples per signal behind the scatter (rows + 1).
    method : {'beta-ls', 'beta-tls', 'beta-gtls'}
    phi : float
        Noise variance ratio σ1²/σ2² for β-GTLS.

    Returns
    -------
    Estimate
        ``params`` holds ``beta``, ``b1`` and, for the TLS variants, ``noise_eigenvalue`` (the
        smallest generalized eigenvalue, the residual noise variance times N-1).

    Raises
    ------
    NoExcitationError
        If the regressors are collinear to working precision.
    PhysicalRangeError
        If a pole falls outside (0, 1).
    """
    condition = equilibrated_condition(scatter[:2, :2])
    if not condition < MAX_CONDITION:
        raise NoExcitationError(
            f"{method}: the regressors of Eq. (14) are collinear (condition {condition:.3g}): "
            "the data carry no information on the time constants"
        )
    params: dict[str, float] = {}
    if method == "beta-ls":
        theta = solve_ls(scatter)
    elif method == "beta-tls":
        theta, eigenvalues = solve_gtls(scatter)
        params["noise_eigenvalue"] = float(eigenvalues[0])
    elif method == "beta-gtls":
        theta, eigenvalues = solve_gtls(scatter, beta_noise_covariance(phi))
        params["noise_eigenvalue"] = float(eigenvalues[0])
    else:
        raise ValueError(f"unknown β method {method!r}")
    beta, b1 = float(theta[0]), float(theta[1] / theta[0])  # Eq. (17)
    a1 = 1.0 - b1
    a2 = 1.0 - beta * b1
    return estimate_from_poles(
        method,
        a1,
        a2,
        dt,
        n_samples,
        condition,
        {"beta": beta, "b1": b1, **params},
        phi=phi if method == "beta-gtls" else None,
    )


def beta_ls(tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float) -> Estimate:
    """β-LS: least squares on the β model (Eqs. 14–17). Biased when both signals are noisy.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Thermocouple temperatures, degrees C, validated by the caller.
    dt : float
        Sample interval, seconds.
    """
    return estimate_beta_from_scatter(beta_scatter(tc1, tc2), dt, tc1.size, "beta-ls")


def beta_tls(tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float) -> Estimate:
    """β-TLS: ordinary total least squares on the β model; biased since C0 ≠ νI (Sec. III D)."""
    return estimate_beta_from_scatter(beta_scatter(tc1, tc2), dt, tc1.size, "beta-tls")


def beta_gtls(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float, phi: float = 1.0
) -> Estimate:
    """β-GTLS: generalized TLS with the noise covariance C0(φ) (Eqs. 18–21); consistent.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
    dt : float
        Sample interval, seconds.
    phi : float
        Noise variance ratio σ1²/σ2² of the two thermocouples (1 for equal noise).
    """
    return estimate_beta_from_scatter(beta_scatter(tc1, tc2), dt, tc1.size, "beta-gtls", phi)
