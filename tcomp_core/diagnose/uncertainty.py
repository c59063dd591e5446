"""Confidence intervals of fitted parameters, and which parameters sit on a bound.

The fit minimises Σ r_k² over the estimation rows (:meth:`tcomp_core.effects.Model.fit`). Its
residuals are far from white: the inverse chains difference the readings (noise n[k+1] − a n[k]
with a near 1, so the residuals' spectrum is small at the low frequencies where the signal and
hence the Jacobian live and large above them), the readings are low-passed before the fit, and
what a model lacks is slow. So the covariance is the sandwich

    cov(x̂) = A⁻¹ B A⁻¹,    A = JᵀJ,    B = Jᵀ Σ J = (1/n) Σ_f S(f) Ĵ(f)ᴴ Ĵ(f),

with B evaluated in the frequency domain: Ĵ the DFT of the Jacobian's columns and S the
residuals' periodogram smoothed over :func:`_smoothing_bins` neighbouring bins (a lag-window
estimate in time, such as Newey & West's, cannot follow the spectrum's dip at zero frequency and
overstates the variance several times). Penalty rows (priors) enter B as pseudo-observations of
unit variance. The estimation rows are taken as one sequence; the joins of their blocks add a
little noise to S. Intervals are x̂ ± 1.96 √cov in the search coordinates (log τ for the time
constants, so their intervals are asymmetric in seconds), clipped to the parameter's bounds.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ..effects import FitContext, Model
from ..effects.model import LeastSquaresProblem

__all__ = ["Z95", "parameter_uncertainty", "parameters_at_bound"]

#: Two-sided 95 % quantile of the normal distribution.
Z95 = 1.959963984540054
#: A parameter within this share of its range from a bound is "at the bound".
AT_BOUND_SHARE = 1e-3


def _smoothing_bins(n: int) -> int:
    """Half width of the periodogram smoothing, bins: about n/1 000, at least 2."""
    return max(2, round(n / 1000))


def _meat(jacobian: NDArray[np.float64], residuals: NDArray[np.float64]) -> NDArray[np.float64]:
    """B = Jᵀ Σ J with Σ the residuals' covariance, from their smoothed periodogram."""
    n = residuals.size
    spectrum = np.abs(np.fft.rfft(residuals)) ** 2 / n
    spectrum = ndimage.uniform_filter1d(spectrum, 2 * _smoothing_bins(n) + 1, mode="mirror")
    transform = np.fft.rfft(jacobian, axis=0)
    weights = np.full(spectrum.size, 2.0)  # one-sided: every bin but 0 (and n/2) twice
    weights[0] = 1.0
    if n % 2 == 0:
        weights[-1] = 1.0
    weighted = transform * (weights * spectrum)[:, None]
    return np.real(transform.conj().T @ weighted) / n


def _at_bound(problem: LeastSquaresProblem, x: NDArray[np.float64]) -> tuple[str, ...]:
    """Parameters within :data:`AT_BOUND_SHARE` of their range from a physical bound."""
    span = problem.upper - problem.lower
    return tuple(
        spec.name
        for spec, value, low, high, width in zip(
            problem.specs, x, problem.lower, problem.upper, span, strict=True
        )
        if spec.physical and min(value - low, high - value) <= AT_BOUND_SHARE * width
    )


def parameters_at_bound(
    model: Model,
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    context: FitContext,
    rows: NDArray[np.bool_] | None = None,
) -> tuple[str, ...]:
    """The fitted parameters on a bound of their range; cheap (no Jacobian).

    Arguments as :func:`parameter_uncertainty`'s.
    """
    problem = model.problem(tc1, tc2, context, rows)
    return _at_bound(problem, np.clip(problem.pack(model.params), problem.lower, problem.upper))


def parameter_uncertainty(
    model: Model,
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    context: FitContext,
    rows: NDArray[np.bool_] | None = None,
) -> tuple[dict[str, tuple[float, float]], tuple[str, ...]]:
    """95 % intervals of a fitted model's parameters, and the parameters at a bound.

    Parameters
    ----------
    model : Model
        A fitted model (its parameters are the optimum of the fit on these data).
    tc1, tc2 : ndarray, shape (N,)
        The readings the fit saw, degrees C.
    context : FitContext
    rows : ndarray of bool, shape (N - 1,), optional
        The intervals the fit used.

    Returns
    -------
    intervals : dict of str to (float, float)
        Lower and upper 95 % limit of every searched parameter, in its unit; (nan, nan) when
        the Jacobian is singular.
    at_bound : tuple of str
        Parameters within :data:`AT_BOUND_SHARE` of their range from a physical bound
        (:attr:`~tcomp_core.effects.base.ParamSpec.physical`).
    """
    problem = model.problem(tc1, tc2, context, rows)
    x = np.clip(problem.pack(model.params), problem.lower, problem.upper)
    at_bound = _at_bound(problem, x)
    residuals = problem.residuals(x)
    jacobian = problem.jacobian(x)
    n = problem.n_rows
    meat = _meat(jacobian[:n], residuals[:n]) + jacobian[n:].T @ jacobian[n:]
    bread = jacobian.T @ jacobian
    try:
        inverse = np.linalg.inv(bread)
    except np.linalg.LinAlgError:
        return {spec.name: (math.nan, math.nan) for spec in problem.specs}, at_bound
    covariance = inverse @ meat @ inverse
    half = Z95 * np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    low = np.clip(x - half, problem.lower, problem.upper)
    high = np.clip(x + half, problem.lower, problem.upper)
    intervals = {}
    for spec, lo, hi in zip(problem.specs, low, high, strict=True):
        log_scale = spec.name.startswith("tau")
        intervals[spec.name] = (
            (math.exp(lo), math.exp(hi)) if log_scale else (float(lo), float(hi))
        )
    return intervals, at_bound
