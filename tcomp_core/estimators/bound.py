"""Cramér–Rao bound of (τ1, τ2) for the errors-in-variables model of two thermocouples.

The model of every estimator here: both sensors see the same gas temperature u, an unknown
sequence, through zero-order-hold first-order lags G_i (Eq. 4), and each reading carries white
Gaussian noise of its own variance σ_i². The unknowns are τ1, τ2 and all N gas samples. In the
frequency domain (the record taken as one period of a periodic steady state, exact for the
circulant model and the asymptotic bound otherwise) the bins are independent: bin m observes
Y(ω_m) = g(ω_m) U(ω_m) + noise, g = (G1, G2), noise covariance C = N diag(σ1², σ2²). The gas
bin U is a nuisance; the Fisher information on τ left after it is known is the Schur complement,
per bin

    F_jk(ω) = c_m |U(ω)|² Re[conj(∂G_j/∂τ_j) P_jk ∂G_k/∂τ_k],
    P = C⁻¹ - C⁻¹ g (gᴴ C⁻¹ g)⁻¹ gᴴ C⁻¹,

(c_m = 2 for complex bins, 1 for the real DC and Nyquist bins), summed over the bins: the part
of each sensor's sensitivity to its τ that does not look like a change of the gas. Its inverse
bounds the covariance of any unbiased estimator that does not know the gas; the oracle, which
knows it, can do better.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..models import lag_frequency_response
from ..validation import check_sample_interval

__all__ = ["cramer_rao_bound", "crb_fisher_information"]


def _response_and_derivative(
    tau: float, dt: float, omega: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """G(ω) = (1 - a) z / (1 - a z), z = e^(-iω), a = e^(-dt/τ), and ∂G/∂τ, per second."""
    a = math.exp(-dt / tau)
    z = np.exp(-1j * omega)
    # ∂G/∂a = z (z - 1) / (1 - a z)², ∂a/∂τ = a dt / τ².
    derivative = z * (z - 1.0) / (1.0 - a * z) ** 2 * (a * dt / tau**2)
    return lag_frequency_response(a, omega), derivative


def crb_fisher_information(
    gas: ArrayLike, tau1: float, tau2: float, dt: float, sigma1: float, sigma2: float
) -> NDArray[np.float64]:
    """Fisher information on (τ1, τ2) with the gas an unknown sequence (see the module).

    Parameters
    ----------
    gas : array_like, shape (N,)
        The gas temperature the record was made from, degrees C (only its spectrum matters;
        the mean carries no information).
    tau1, tau2 : float
        True time constants, s.
    dt : float
        Sample interval, s.
    sigma1, sigma2 : float
        Noise standard deviations of the two readings, degrees C (> 0).

    Returns
    -------
    ndarray, shape (2, 2)
        Fisher information, s⁻².
    """
    dt = check_sample_interval(dt)
    if not (sigma1 > 0.0 and sigma2 > 0.0):
        raise ValueError(f"noise sigma1={sigma1!r}, sigma2={sigma2!r} must both be > 0")
    values = np.asarray(gas, dtype=np.float64)
    n = values.size
    spectrum = np.fft.rfft(values)
    omega = 2.0 * np.pi * np.arange(spectrum.size) / n
    weights = np.full(spectrum.size, 2.0)
    weights[0] = 1.0
    if n % 2 == 0:
        weights[-1] = 1.0
    g1, d1 = _response_and_derivative(tau1, dt, omega)
    g2, d2 = _response_and_derivative(tau2, dt, omega)
    w1, w2 = 1.0 / (n * sigma1**2), 1.0 / (n * sigma2**2)
    q = w1 * np.abs(g1) ** 2 + w2 * np.abs(g2) ** 2
    # P for the 2-vector of one bin: P_11 = w1 w2 |G2|²/q, P_22 = w1 w2 |G1|²/q,
    # P_12 = -w1 w2 G1 conj(G2)/q.
    common = weights * np.abs(spectrum) ** 2 * w1 * w2 / q
    f11 = np.sum(common * np.abs(d1) ** 2 * np.abs(g2) ** 2)
    f22 = np.sum(common * np.abs(d2) ** 2 * np.abs(g1) ** 2)
    f12 = np.sum(common * np.real(-np.conj(d1) * g1 * np.conj(g2) * d2))
    return np.array([[f11, f12], [f12, f22]])


def cramer_rao_bound(
    gas: ArrayLike, tau1: float, tau2: float, dt: float, sigma1: float, sigma2: float
) -> NDArray[np.float64]:
    """Lower bound on the covariance of unbiased (τ1, τ2) estimates from the two readings.

    Parameters are those of :func:`crb_fisher_information`.

    Returns
    -------
    ndarray, shape (2, 2)
        The inverse Fisher information, s²; ``sqrt(diag)`` bounds the standard deviations.
    """
    information = crb_fisher_information(gas, tau1, tau2, dt, sigma1, sigma2)
    return np.asarray(np.linalg.inv(information), dtype=np.float64)
