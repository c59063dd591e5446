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

A second covariance takes for S the residuals' noise floor instead (:func:`_noise_floor`: a
running median of the periodogram, which passes over narrow lines). What a model lacks leaves
lines at the signal's own frequencies, where the Jacobian lives; they are the same on every
draw of the noise, and the smoothed periodogram counts them as noise right where they weigh
most. For a varying speed's spline on detailed physics (a rotating disk, ±20 % speed) the
lines stood 8 times above the floor, and the smoothed S put the spline's curve 3-10 times
further out (1σ 0.05-0.09 in log τ) than fits on new noise spread (0.011-0.024); the floor
gave 0.012-0.022. That covariance, :attr:`ParameterCovariance.noise_matrix`, is what a new
draw of the noise does to the estimate, so its meat has no penalty rows: priors and penalties
are the same on every draw. (As pseudo-observations of unit variance, a spline's smoothness
penalty weighed as much in the meat as residuals whose spectrum was a tenth of that where the
spline lives, and alone put its curve 2-3 times further out than fits on new noise.) The
smoothed covariance, penalties in, also bounds the misfit and what only a prior decides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ..effects import FitContext, Model
from ..effects.model import LeastSquaresProblem

__all__ = [
    "Z95",
    "ParameterCovariance",
    "parameter_covariance",
    "parameter_uncertainty",
    "parameters_at_bound",
    "sandwich_covariance",
]

#: Two-sided 95 % quantile of the normal distribution.
Z95 = 1.959963984540054
#: A parameter within this share of its range from a bound is "at the bound".
AT_BOUND_SHARE = 1e-3
#: The median of a periodogram bin over its mean for Gaussian noise (an exponential variable).
_MEDIAN_OVER_MEAN = math.log(2.0)


def _smoothing_bins(n: int) -> int:
    """Half width of the periodogram smoothing, bins: about n/1 000, at least 2."""
    return max(2, round(n / 1000))


def _floor_bins(n: int) -> int:
    """Half width of the running median of :func:`_noise_floor`, bins: n/80, at least 12.

    Wide enough that the lines a misfit leaves (a periodic signal's harmonics and the sidebands
    a slow modulation puts beside them, a few bins each) stay a minority of every window.
    """
    return max(12, round(n / 80))


def _periodogram(residuals: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.abs(np.fft.rfft(residuals)) ** 2 / residuals.size


def _smoothed(periodogram: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """The periodogram averaged over ±:func:`_smoothing_bins` bins."""
    return ndimage.uniform_filter1d(periodogram, 2 * _smoothing_bins(n) + 1, mode="mirror")


def _noise_floor(periodogram: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """The residuals' noise spectrum with narrow lines passed over, the periodogram's units.

    A running median over ±:func:`_floor_bins` bins, scaled to the mean (a Gaussian noise's
    periodogram bin is exponential: its median is ln 2 times its mean).
    """
    window = 2 * _floor_bins(n) + 1
    return ndimage.median_filter(periodogram, size=window, mode="mirror") / _MEDIAN_OVER_MEAN


def _meat(
    transform: NDArray[np.complex128], spectrum: NDArray[np.float64], n: int
) -> NDArray[np.float64]:
    """B = Jᵀ Σ J with Σ the stationary covariance of the residuals' ``spectrum``.

    ``transform`` is the Jacobian's rfft along its n rows, shape (n // 2 + 1, P);
    ``spectrum`` is one-sided, shape (n // 2 + 1,), in the periodogram's units (|DFT|²/n).
    """
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


@dataclass(frozen=True)
class ParameterCovariance:
    """The sandwich covariance of a fit's searched parameters, in the search coordinates.

    Attributes
    ----------
    names : tuple of str
        The searched parameters, in the order of ``x``.
    x : ndarray, shape (P,)
        The estimate in the search coordinates (log of every time constant).
    matrix : ndarray, shape (P, P) or None
        Its covariance; None when the fit's Jacobian is singular (the data do not determine
        the parameters).
    lower, upper : ndarray, shape (P,)
        Bounds of ``x``.
    at_bound : tuple of str
        Parameters within :data:`AT_BOUND_SHARE` of their range from a physical bound.
    noise_matrix : ndarray, shape (P, P) or None
        The covariance with the residuals' noise floor for Σ (the module docstring): what the
        noise alone does to the estimate, the misfit's lines left out. None when not computed
        or singular.
    """

    names: tuple[str, ...]
    x: NDArray[np.float64]
    matrix: NDArray[np.float64] | None
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    at_bound: tuple[str, ...]
    noise_matrix: NDArray[np.float64] | None = None

    def intervals(self) -> dict[str, tuple[float, float]]:
        """95 % interval of every parameter in its unit, clipped to its bounds.

        (nan, nan) for every parameter when the covariance is singular.
        """
        if self.matrix is None:
            return {name: (math.nan, math.nan) for name in self.names}
        half = Z95 * np.sqrt(np.clip(np.diag(self.matrix), 0.0, None))
        low = np.clip(self.x - half, self.lower, self.upper)
        high = np.clip(self.x + half, self.lower, self.upper)
        intervals = {}
        for name, lo, hi in zip(self.names, low, high, strict=True):
            log_scale = name.startswith("tau")
            intervals[name] = (math.exp(lo), math.exp(hi)) if log_scale else (float(lo), float(hi))
        return intervals

    def with_block(self, other: ParameterCovariance) -> ParameterCovariance:
        """The covariance with ``other``'s parameters taken from ``other``.

        For parameters estimated by another criterion (:meth:`tcomp_core.diagnose.heldout.
        Evaluator.polish`): their variances and covariances among themselves are ``other``'s,
        those with the rest are unknown and taken as zero. Names of ``other`` that this one
        does not search are ignored.
        """
        shared = [name for name in other.names if name in self.names]
        if not shared:
            return self
        mine = [self.names.index(name) for name in shared]
        theirs = [other.names.index(name) for name in shared]

        def merged(
            matrix: NDArray[np.float64] | None, block: NDArray[np.float64] | None
        ) -> NDArray[np.float64] | None:
            if matrix is None or block is None:
                return None
            result = matrix.copy()
            result[mine, :] = 0.0
            result[:, mine] = 0.0
            result[np.ix_(mine, mine)] = block[np.ix_(theirs, theirs)]
            return result

        x = self.x.copy()
        x[mine] = other.x[theirs]
        at_bound = {n for n in self.at_bound if n not in shared} | {
            n for n in other.at_bound if n in shared
        }
        return replace(
            self,
            x=x,
            matrix=merged(self.matrix, other.matrix),
            noise_matrix=merged(self.noise_matrix, other.noise_matrix),
            at_bound=tuple(n for n in self.names if n in at_bound),
        )

    def correlation(self, first: str, second: str) -> float:
        """Correlation of two parameters' estimates (NaN when unknown)."""
        if self.matrix is None or first not in self.names or second not in self.names:
            return math.nan
        i, j = self.names.index(first), self.names.index(second)
        scale = math.sqrt(self.matrix[i, i] * self.matrix[j, j])
        return float(self.matrix[i, j] / scale) if scale > 0.0 else math.nan


def parameter_covariance(
    model: Model,
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    context: FitContext,
    rows: NDArray[np.bool_] | None = None,
) -> ParameterCovariance:
    """The covariance of a fitted model's searched parameters (the sandwich above).

    Arguments as :func:`parameter_uncertainty`'s.
    """
    problem = model.problem(tc1, tc2, context, rows)
    x = np.clip(problem.pack(model.params), problem.lower, problem.upper)
    return sandwich_covariance(
        problem, x, problem.residuals(x), problem.jacobian(x), problem.n_rows
    )


def sandwich_covariance(
    problem: LeastSquaresProblem,
    x: NDArray[np.float64],
    residuals: NDArray[np.float64],
    jacobian: NDArray[np.float64],
    n: int,
) -> ParameterCovariance:
    """The sandwich covariance of the estimate ``x`` of ``problem``'s parameters.

    Parameters
    ----------
    problem : LeastSquaresProblem
        Its parameters (names, bounds) in the search coordinates.
    x : ndarray, shape (P,)
        The estimate.
    residuals : ndarray, shape (n + penalties,)
        The criterion's residuals at ``x``: ``n`` data residuals in time order, then penalty
        rows. The criterion need not be ``problem``'s own (a free-run error's, for one).
    jacobian : ndarray, shape (n + penalties, P)
        Their Jacobian at ``x``.
    n : int
        Number of data residuals.
    """
    names = tuple(spec.name for spec in problem.specs)
    at_bound = _at_bound(problem, x)
    bread = jacobian.T @ jacobian
    try:
        inverse = np.linalg.inv(bread)
    except np.linalg.LinAlgError:
        return ParameterCovariance(names, x, None, problem.lower, problem.upper, at_bound)
    periodogram = _periodogram(residuals[:n])
    transform = np.fft.rfft(jacobian[:n], axis=0)  # once, for both spectra
    priors = jacobian[n:].T @ jacobian[n:]

    def sandwich(meat: NDArray[np.float64]) -> NDArray[np.float64] | None:
        matrix = inverse @ meat @ inverse
        return matrix if np.all(np.isfinite(matrix)) else None

    return ParameterCovariance(
        names,
        x,
        sandwich(_meat(transform, _smoothed(periodogram, n), n) + priors),
        problem.lower,
        problem.upper,
        at_bound,
        noise_matrix=sandwich(_meat(transform, _noise_floor(periodogram, n), n)),
    )


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
    covariance = parameter_covariance(model, tc1, tc2, context, rows)
    return covariance.intervals(), covariance.at_bound
