"""Figures of merit of the paper: noise level K (Eq. 22), e_τ (Eq. 23) and e_Tg (Eq. 25)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .validation import check_finite

__all__ = ["noise_level_percent", "reconstruction_error_percent", "tau_error_percent"]


def noise_level_percent(signal: ArrayLike, noise: ArrayLike) -> float:
    """Noise level K = 100 sqrt(var(Q) / var(P)) in percent (Eq. 22).

    Parameters
    ----------
    signal : array_like, shape (N,)
        Noise-free signal P.
    noise : array_like, shape (M,)
        Noise Q.
    """
    p = check_finite(signal, "signal")
    q = check_finite(noise, "noise")
    variance = float(np.var(p))
    if variance == 0.0:
        raise ValueError("signal is constant: the noise level K is undefined")
    return 100.0 * float(np.sqrt(np.var(q) / variance))


def tau_error_percent(true_tau: float, estimated_tau: float) -> float:
    """Percentage time constant error e_τ = 100 (τ - τ̂)/τ (Eq. 23); positive = underestimate."""
    if not true_tau > 0.0:
        raise ValueError(f"{true_tau=} must be > 0 s")
    return 100.0 * (true_tau - estimated_tau) / true_tau


def reconstruction_error_percent(
    reference: ArrayLike, reconstruction: ArrayLike, *, centered: bool = True
) -> float:
    """Reconstruction error level e_Tg = 100 rms(ref - T̂g) / rms(ref) in percent (Eq. 25).

    Parameters
    ----------
    reference : array_like, shape (N,)
        True or reference gas temperature, degrees C.
    reconstruction : array_like, shape (N,)
        Reconstructed gas temperature at the same instants, degrees C.
    centered : bool
        Divide by the rms of the reference about its mean (default), as Eq. (22) does for K.
        Eq. (25) taken literally divides by the rms of the reference itself, which makes the
        figure depend on where the temperature scale has its zero (°C or K): a 300 °C mean
        would shrink every error. ``centered=False`` gives the literal figure.
    """
    ref = check_finite(reference, "reference")
    rec = check_finite(reconstruction, "reconstruction")
    if ref.shape != rec.shape:
        raise ValueError(f"reference has {ref.size} samples but the reconstruction has {rec.size}")
    scale = ref - np.mean(ref) if centered else ref
    denominator = float(np.sqrt(np.mean(scale**2)))
    if denominator == 0.0:
        raise ValueError("reference has zero rms: e_Tg is undefined")
    return 100.0 * float(np.sqrt(np.mean((ref - rec) ** 2))) / denominator
