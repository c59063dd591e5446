"""The residual against the temperature level: bins and a quadratic fit with honest t values."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import DataError
from .common import (
    check_same_size,
    checked_series,
    json_float,
    json_list,
    safe_ratio,
    sample_acf,
)

__all__ = ["LevelErrors", "level_errors"]

#: Sokal's window: the autocorrelation time is summed up to this many times itself.
SOKAL_WINDOW = 5.0


def _integrated_time(rho: NDArray[np.float64]) -> float:
    """Integrated autocorrelation time ``1 + 2 Σ_k ρ(k)``, in samples, >= 1.

    The sum runs to the smallest lag M with ``M >= 5 (1 + 2 Σ_{k<=M} ρ(k))`` (Sokal's
    automatic window): the sample autocorrelations have noise of order 1/√N each, so
    summing them all the way would add noise of order one.
    """
    times = 1.0 + 2.0 * np.cumsum(rho[1 : rho.size // 2 + 1])
    if not times.size:
        return 1.0
    reached = np.flatnonzero(np.arange(1, times.size + 1) >= SOKAL_WINDOW * times)
    return max(1.0, float(times[reached[0]] if reached.size else times[-1]))


@dataclass(frozen=True, kw_only=True)
class LevelErrors:
    """The residual against the temperature level.

    Attributes
    ----------
    centres : ndarray, shape (M,)
        Mean level in each bin (bins hold equal numbers of samples), degrees C.
    mean, std : ndarray, shape (M,)
        Mean and standard deviation of the residual in each bin, degrees C.
    level_mean : float
        Mean level, degrees C: the centre of the fit.
    intercept : float
        c0 of ``residual = c0 + c1 (level - level_mean) + c2 (level - level_mean)²``, degC.
    slope : float
        c1, degC/degC.
    slope_t : float
        Its t statistic.
    curvature : float
        c2, 1/degC.
    curvature_t : float
        Its t statistic.
    offset : float
        Mean residual, degrees C.
    offset_t : float
        Its t statistic.
    n_eff : float
        Effective sample size behind the t statistics.
    residual_std : float
        Standard deviation of the residual, degrees C.
    r_squared : float
        Fraction of the residual's variance that the slope and curvature explain.
    """

    centres: NDArray[np.float64]
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    level_mean: float
    intercept: float
    slope: float
    slope_t: float
    curvature: float
    curvature_t: float
    offset: float
    offset_t: float
    n_eff: float
    residual_std: float
    r_squared: float

    def fitted(self, level: ArrayLike) -> NDArray[np.float64]:
        """The fitted quadratic at ``level`` (degrees C), degrees C."""
        x = np.asarray(level, dtype=np.float64) - self.level_mean
        return self.intercept + self.slope * x + self.curvature * x**2

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "centres": json_list(self.centres),
            "mean": json_list(self.mean),
            "std": json_list(self.std),
            "slope": float(self.slope),
            "slope_t": json_float(self.slope_t),
            "curvature": float(self.curvature),
            "curvature_t": json_float(self.curvature_t),
            "offset": float(self.offset),
            "offset_t": json_float(self.offset_t),
            "n_eff": float(self.n_eff),
            "residual_std": float(self.residual_std),
            "r_squared": float(self.r_squared),
        }


def _bins(
    residual: NDArray[np.float64], level: NDArray[np.float64], n_bins: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Mean level, mean and std of the residual in quantile bins of the level (empty dropped)."""
    edges = np.quantile(level, np.linspace(0.0, 1.0, n_bins + 1))
    index = np.searchsorted(edges[1:-1], level, side="right")
    rows = [
        (level[inside].mean(), residual[inside].mean(), residual[inside].std())
        for inside in (index == b for b in range(n_bins))
        if inside.any()
    ]
    centres, mean, std = np.asarray(rows).T
    return centres, mean, std


def level_errors(residual: ArrayLike, level: ArrayLike, n_bins: int = 10) -> LevelErrors:
    """How the residual depends on the temperature level: bins and a quadratic fit.

    The fit is ordinary least squares of
    ``residual = c0 + c1 (level - mean level) + c2 (level - mean level)²``. Its t statistics
    would assume independent residuals; the residual of a model is autocorrelated, so the
    standard errors are widened by the effective sample size
    ``N_eff = N / (1 + 2 Σ_k ρ(k))``, ρ the autocorrelation of what the quadratic leaves
    unexplained (summed over Sokal's automatic window, see :func:`_integrated_time`).
    ``offset_t`` is the mean residual over its standard error ``s / √N_eff``, s the standard
    deviation of that leftover.

    Parameters
    ----------
    residual : array_like, shape (N,)
        Residual, degrees C (in time order: the autocorrelation is taken along it).
    level : array_like, shape (N,)
        Temperature level at the same samples, degrees C.
    n_bins : int
        Number of quantile bins of the level (fewer when levels repeat).

    Returns
    -------
    LevelErrors

    Raises
    ------
    DataError
        If the level does not vary or there are fewer than 8 samples.
    """
    e = checked_series(residual, "residual")
    x = checked_series(level, "level")
    check_same_size(e, x, "residual and level")
    if n_bins < 1:
        raise ValueError(f"{n_bins=} must be >= 1")
    level_mean = float(x.mean())
    spread = float(np.std(x))
    if not spread > 0.0:
        raise DataError("level: constant, so the residual cannot be fitted against it")
    u = (x - level_mean) / spread
    design = np.column_stack((np.ones_like(u), u, u**2))
    coefficients, *_ = np.linalg.lstsq(design, e, rcond=None)
    leftover = e - design @ coefficients
    n = e.size
    n_eff = n / _integrated_time(sample_acf(leftover))
    variance = float(np.sum(leftover**2)) / max(n - 3, 1) * n / n_eff
    errors = np.sqrt(variance * np.diag(np.linalg.inv(design.T @ design)))
    t = [safe_ratio(float(c), float(s)) for c, s in zip(coefficients, errors, strict=True)]
    offset = float(e.mean())
    centres, mean, std = _bins(e, x, n_bins)
    return LevelErrors(
        centres=centres,
        mean=mean,
        std=std,
        level_mean=level_mean,
        intercept=float(coefficients[0]),
        slope=float(coefficients[1]) / spread,
        slope_t=t[1],
        curvature=float(coefficients[2]) / spread**2,
        curvature_t=t[2],
        offset=offset,
        offset_t=safe_ratio(offset, float(np.std(leftover)) / math.sqrt(n_eff)),
        n_eff=n_eff,
        residual_std=float(np.std(e)),
        r_squared=1.0 - safe_ratio(float(np.var(leftover)), float(np.var(e))),
    )
