"""What τ's own uncertainty adds to the fused gas's std.

The smoother's and the causal filter's std are computed at the τ they are handed (with the
first-order misfit, :mod:`.adequacy`). An error δτ_i of τ_i moves the gas by about
∂ĝ/∂log τ_i · δτ_i/τ_i, which that std leaves out, and where the noise leaves the std small it
is the larger part of the error: on lumped sinusoids (K = 1 %, 500 Hz) whose ml-eiv τ lay
within 0.2 % of the truth, the smoother's std held a median 74 % of the errors within 4 std
(18 % at worst) against 100 % at the true τ (``bench/bench_std_tau.py``).

The slope is the same path (signal model and all) run again at τ_i (1 + :data:`STEP`); τ1's
and τ2's errors are taken as independent (on those records treating them as one common error
gave the same shares within 4 std). Added in quadrature it brought the sinusoids to 100 % and
left ramp, multisine and exhaust records' std unchanged (×1.00).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..validation import check_pair
from .record import FusionResult, run_model

__all__ = ["STEP", "tau_slope", "tau_spread_std", "with_tau_spread"]

#: Relative step of τ_i for the gas's slope: the slope at 1e-3 is within 0.2 % of the slope at
#: 1e-4 (sinusoid and exhaust records, both τ), a std's worth of precision.
STEP = 1e-3


def tau_slope(
    result: FusionResult, tc1: ArrayLike, tc2: ArrayLike, which: int
) -> NDArray[np.float64] | None:
    """∂ĝ/∂log τ_i of ``result``'s gas, degrees C, shape (N,): its path again at τ_i (1 + STEP).

    Parameters
    ----------
    result : FusionResult
        What :func:`~.record.fuse` gave on ``tc1``, ``tc2``.
    tc1, tc2 : array_like, shape (N,)
        The readings it was given, degrees C.
    which : {0, 1}
        0 for τ1, 1 for τ2.

    Returns
    -------
    ndarray or None
        The slope, the smoother or causal filter and signal model of ``result`` kept; None when
        the moved run is not finite.
    """
    first, second = check_pair(tc1, tc2)
    moved = [result.model.tau1, result.model.tau2]
    moved[which] *= 1.0 + STEP
    model = replace(result.model, tau1=moved[0], tau2=moved[1])
    gas = run_model(model, first, second, result.causal)[0]
    return None if gas is None else (gas - result.gas) / STEP


def tau_spread_std(
    result: FusionResult, tc1: ArrayLike, tc2: ArrayLike, tau_log_se: tuple[float, float]
) -> NDArray[np.float64]:
    """The std τ's uncertainty adds to ``result``'s gas, degrees C, shape (N,).

    Parameters
    ----------
    result, tc1, tc2
        As for :func:`tau_slope`.
    tau_log_se : (float, float)
        Standard errors of log τ1 and log τ2 (σ_τi / τ_i), as ml-eiv gives them
        (:meth:`~tcomp_core.estimators.result.Estimate.tau_log_se`).

    Returns
    -------
    ndarray
        sqrt(Σ_i (∂ĝ/∂log τ_i σ_i)²) (:func:`tau_slope`); a τ_i whose moved run is not finite
        adds nothing.
    """
    variance = np.zeros_like(result.gas)
    for which, share in enumerate(tau_log_se):
        if not (math.isfinite(share) and share > 0.0):
            continue
        slope = tau_slope(result, tc1, tc2, which)
        if slope is not None:
            variance += (slope * share) ** 2
    return np.sqrt(variance)


def with_tau_spread(
    result: FusionResult, tc1: ArrayLike, tc2: ArrayLike, tau_log_se: tuple[float, float]
) -> FusionResult:
    """``result`` with :func:`tau_spread_std` added to its std in quadrature."""
    return replace(result, std=np.hypot(result.std, tau_spread_std(result, tc1, tc2, tau_log_se)))
