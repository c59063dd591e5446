"""ml-eiv's covariance with the noise's share of its Gauss–Newton information taken out.

ml-eiv minimises ‖w(x)‖² with w = P L(x)⁻¹ e(x) the whitened, offset-projected cross-relation
residual, x = (log τ1, log τ2, h). w and its Jacobian J are linear in the readings, so each is a
clean part (the gas through the sensors) plus a noise part: J = J_S + J_N. The usual
σ² (JᵀJ)⁻¹ takes JᵀJ for the information, but E[JᵀJ] = J_SᵀJ_S + E[J_NᵀJ_N]: the noise in the
regressors ΔT_mi adds information that is not there. Where the gas excites the sensors across
their band the clean part dominates and the two agree to a fraction of a percent; where it
does not (a slow signal: a sine of 0.05–0.5 Hz seen by sensors of 20 and 100 ms, whose lags
show only as a phase and a 1e-3 change of amplitude that the gain between the sensors can
take) the noise part is most of JᵀJ, and the intervals were 3–10 times too narrow: 47–95 % of
them missed the truth.

The criterion's expectation is the clean part plus a constant (the estimator is consistent),
so its expected curvature is the clean information alone, H = J_SᵀJ_S = JᵀJ − E[J_NᵀJ_N], and
the estimate's covariance is the sandwich H⁻¹ V H⁻¹ with V the variance of the score Jᵀw at
the truth: σ² H from the clean part plus the fourth-order noise term
V₄ = Var(J_Nᵀ w_N) = σ² E[J_NᵀJ_N] + M T, by Isserlis' theorem for Gaussian noise.

For a stationary record both noise terms are integrals over frequency of the transfer
functions G_i (tc_i's noise to w, the asymptotic whitening filter times the residual's MA(1)
taps) and G_ai = ∂G_i/∂x_a, with the noise variances φσ² and σ² of the two readings:

    E[J_NᵀJ_N]_ab = M ⟨Σ_i σ_i² Re(G_ai* G_bi)⟩,    T_ab = ⟨Re(S_a S_b)⟩,
    S_a(ω) = Σ_i σ_i² G_ai(ω)* G_i(ω),

with ⟨f⟩ = (1/π) ∫₀^π f(ω) dω. Monte Carlo on slow sines (40 records each, τ 20/100 ms,
2 ms sampling, K = 2 %): the standard error of log τ1 now 0.20 where the estimates scatter
0.204 (0.5 Hz; was 0.083) and 0.79 against 0.89 (0.2 Hz; was 0.090); on broadband records
(multisine, ramp, engine pulses) unchanged to the printed digits.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..errors import NoExcitationError

__all__ = ["FREQUENCY_POINTS", "noise_moments", "sandwich_covariance"]

#: Frequencies of the integrals, log-spaced from 1e-4 of the slower sensor's bandwidth to
#: Nyquist: the terms change fastest below that bandwidth. 256 points are within 1e-3 of
#: 4 000 on sensors of 1e-3 to 3 s at 0.2–2 ms sampling; 512 within 3e-4.
FREQUENCY_POINTS = 512
#: Relative step of the central differences of the transfer functions in x.
_STEP = 1e-6

#: ω (rad per sample, shape (K,)) → the transfer functions of tc1's and tc2's noise to the
#: whitened residual, each scaled by its noise σ relative to tc2's, shape (K,) complex.
Responses = Callable[
    [NDArray[np.float64], NDArray[np.float64]],
    tuple[NDArray[np.complex128], NDArray[np.complex128]],
]


def _frequency_grid(decay_samples: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ω = 0 and a log-spaced grid up to π (shape (K + 1,)), and trapezoid weights of (1/π)∫."""
    lowest = 1e-4 / max(decay_samples, 1.0)
    omega = np.concatenate(([0.0], np.geomspace(lowest, math.pi, FREQUENCY_POINTS)))
    widths = np.diff(omega)
    weights = np.zeros_like(omega)
    weights[:-1] += 0.5 * widths
    weights[1:] += 0.5 * widths
    return omega, weights / math.pi


def noise_moments(
    responses: Responses,
    x: NDArray[np.float64],
    variance: float,
    rows: int,
    decay_samples: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """E[J_NᵀJ_N] and the score's fourth-order noise variance V₄ at ``x``, each (P, P).

    Parameters
    ----------
    responses : callable
        (x, ω) → the two readings' noise transfer functions to the whitened residual, each
        scaled by its σ relative to tc2's (so that σ² = ``variance`` is tc2's noise).
    x : ndarray, shape (P,)
        The search coordinates of the estimate.
    variance : float
        σ², tc2's noise variance in the residual's units (degrees C²).
    rows : int
        Residual samples M.
    decay_samples : float
        The slower sensor's time constant in samples (c = 1/(1 - a)): where the grid starts.

    Returns
    -------
    noise_information : ndarray, shape (P, P)
        M ⟨Σ_i σ_i² Re(G_ai* G_bi)⟩, the noise's share of JᵀJ.
    fourth : ndarray, shape (P, P)
        σ² E[J_NᵀJ_N] + M ⟨Re(S_a S_b)⟩.
    """
    omega, weights = _frequency_grid(decay_samples)
    base = np.stack(responses(x, omega))  # (2, K)
    derivatives = np.empty((x.size, *base.shape), dtype=np.complex128)
    for a in range(x.size):
        step = np.zeros_like(x)
        step[a] = _STEP
        ahead, behind = np.stack(responses(x + step, omega)), np.stack(responses(x - step, omega))
        derivatives[a] = (ahead - behind) / (2.0 * _STEP)
    cross = variance * np.einsum("aik,bik->abk", derivatives.conj(), derivatives).real
    noise_information = rows * (cross @ weights)
    score = variance * np.einsum("aik,ik->ak", derivatives.conj(), base)  # S_a(ω)
    products = (score[:, None, :] * score[None, :, :]).real
    fourth = variance * noise_information + rows * (products @ weights)
    return noise_information, fourth


def sandwich_covariance(
    information: NDArray[np.float64],
    noise_information: NDArray[np.float64],
    fourth: NDArray[np.float64],
    variance: float,
) -> NDArray[np.float64]:
    """H⁻¹ (σ² H + V₄) H⁻¹ with H = JᵀJ − E[J_NᵀJ_N] (shape (P, P) each).

    Raises
    ------
    NoExcitationError
        If H is not positive definite: the noise accounts for all the information JᵀJ shows
        in some direction of the parameters.
    """
    clean = information - noise_information
    try:
        np.linalg.cholesky(clean)
    except np.linalg.LinAlgError:
        raise NoExcitationError(
            "ml-eiv: the time constants are not determined: the readings' noise accounts for "
            "all the information the fit shows on them (the gas does not excite the sensors "
            "enough for their lags to show above the noise)"
        ) from None
    inverse = np.linalg.inv(clean)
    return inverse @ (variance * clean + fourth) @ inverse
