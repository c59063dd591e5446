"""Whiteness of a residual and its correlation with other series, with honest bounds.

A residual that is white and uncorrelated with the input is what a model that captures the
physics leaves; the tests here say how far a residual departs from that.

The series compared here are autocorrelated (the residual of a smooth model error, the rate of
a smooth signal), so the usual white-noise bound ±z/√N of a cross-correlation is far too
narrow. The bounds use Bartlett's formula instead (Box, Jenkins & Reinsel, *Time Series
Analysis*, §11.1.3): for two series uncorrelated with each other

    var r_xy(k) ≈ (1/N) Σ_j ρ_xx(j) ρ_yy(j),

summed over the lags where the autocorrelations are not negligible: the sum is cut where its
partial sum is largest (see :func:`_variance_factor`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from ...validation import check_sample_interval
from .common import (
    check_same_size,
    checked_series,
    json_float,
    normal_quantile,
    sample_acf,
    standardised,
)

__all__ = [
    "Autocorrelation",
    "CandidateCorrelation",
    "CrossCorrelation",
    "autocorrelation",
    "candidate_correlations",
    "cross_correlation",
]

#: Default longest lag of the correlations, s ...
DEFAULT_MAX_LAG_S = 0.5
#: ... but at least this many lags ...
MIN_LAGS = 10
#: ... and at most this many (and a quarter of the record).
MAX_LAGS = 200


def _variance_factor(rho_a: NDArray[np.float64], rho_b: NDArray[np.float64]) -> float:
    """Bartlett's ``Σ_j ρ_a(j) ρ_b(j)`` over all lags j, truncated where it stops growing.

    ``var r_ab ≈ factor / N`` for two mutually uncorrelated series. The one-sided sum is cut at
    the lag (up to N/2) where its partial sum is largest: beyond it the autocorrelations are
    negligible and the products add only estimation noise, of order 1/N each. Taking the
    largest partial sum errs on the safe side (a wider bound) and keeps a slow component under
    white noise, whose small autocorrelations persist over many lags. The factor is >= 1.
    """
    half = rho_a.size // 2
    partial = np.cumsum(rho_a[1 : half + 1] * rho_b[1 : half + 1])
    return 1.0 + 2.0 * max(0.0, float(partial.max())) if partial.size else 1.0


def _max_lag(n: int, dt: float, max_lag_s: float | None) -> int:
    if max_lag_s is None:
        lags = max(MIN_LAGS, round(DEFAULT_MAX_LAG_S / dt))
        return max(1, min(lags, MAX_LAGS, n // 4))
    if not max_lag_s > 0.0:
        raise ValueError(f"{max_lag_s=} must be > 0 s")
    return max(1, min(round(max_lag_s / dt), n - 1))


@dataclass(frozen=True, kw_only=True)
class Autocorrelation:
    """Sample autocorrelation of a residual and its whiteness tests.

    Attributes
    ----------
    lags_s : ndarray, shape (L + 1,)
        Lags 0, dt, ..., L dt, s.
    values : ndarray, shape (L + 1,)
        Autocorrelation ρ(k); ``values[0] == 1``.
    bound : float
        White-noise bound ``z / √N`` at the chosen confidence.
    fraction_outside : float
        Fraction of lags 1..L with ``|ρ(k)| > bound`` (about 1 - confidence for white noise).
    ljung_box_q : float
        Ljung–Box statistic ``Q = N (N + 2) Σ_{k=1..L} ρ(k)² / (N - k)``.
    p_value : float
        Probability of a Q this large for white noise (χ² with L degrees of freedom).
    """

    lags_s: NDArray[np.float64]
    values: NDArray[np.float64]
    bound: float
    fraction_outside: float
    ljung_box_q: float
    p_value: float

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (statistics only, no arrays)."""
        return {
            "max_lag_s": float(self.lags_s[-1]),
            "bound": float(self.bound),
            "fraction_outside": float(self.fraction_outside),
            "ljung_box_q": json_float(self.ljung_box_q),
            "p_value": float(self.p_value),
        }


def autocorrelation(
    residual: ArrayLike, dt: float, max_lag_s: float | None = None, confidence: float = 0.95
) -> Autocorrelation:
    """Sample autocorrelation of a residual, its white-noise bound and the Ljung–Box test.

    Parameters
    ----------
    residual : array_like, shape (N,)
        Residual, degrees C, uniformly sampled.
    dt : float
        Sample interval, s.
    max_lag_s : float, optional
        Longest lag L dt, s. Default: 0.5 s, but at least 10 and at most 200 lags and N/4.
    confidence : float
        Confidence level of the bound.

    Returns
    -------
    Autocorrelation
    """
    e = checked_series(residual, "residual")
    dt = check_sample_interval(dt)
    z = normal_quantile(confidence)
    n = e.size
    lags = _max_lag(n, dt, max_lag_s)
    rho = sample_acf(e)[: lags + 1]
    bound = z / math.sqrt(n)
    k = np.arange(1, lags + 1)
    q = n * (n + 2.0) * float(np.sum(rho[1:] ** 2 / (n - k)))
    return Autocorrelation(
        lags_s=np.arange(lags + 1, dtype=np.float64) * dt,
        values=rho,
        bound=bound,
        fraction_outside=float(np.mean(np.abs(rho[1:]) > bound)),
        ljung_box_q=q,
        p_value=float(stats.chi2.sf(q, lags)),
    )


@dataclass(frozen=True, kw_only=True)
class CrossCorrelation:
    """Cross-correlation ``r(k) = corr(residual(t + k), other(t))`` and its Bartlett bound.

    Attributes
    ----------
    lags_s : ndarray, shape (2L + 1,)
        Lags -L dt .. L dt, s. A positive lag means the residual follows (lags) the other
        series.
    values : ndarray, shape (2L + 1,)
        Normalised cross-correlation r(k).
    bound : float
        Bound of one lag for two mutually uncorrelated series, ``z √(Σ_j ρ_ee(j) ρ_uu(j) / N)``
        (Bartlett), the same for all lags.
    peak : float
        r at the lag of largest |r|.
    peak_lag_s : float
        That lag, s.
    significant : bool
        Whether |peak| exceeds the bound widened for the 2L + 1 lags searched (Šidák).
    """

    lags_s: NDArray[np.float64]
    values: NDArray[np.float64]
    bound: float
    peak: float
    peak_lag_s: float
    significant: bool

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (statistics only, no arrays)."""
        return {
            "max_lag_s": float(self.lags_s[-1]),
            "bound": float(self.bound),
            "peak": float(self.peak),
            "peak_lag_s": float(self.peak_lag_s),
            "significant": bool(self.significant),
        }


def cross_correlation(
    residual: ArrayLike,
    other: ArrayLike,
    dt: float,
    max_lag_s: float | None = None,
    confidence: float = 0.95,
) -> CrossCorrelation:
    """Normalised cross-correlation of a residual with another series, with Bartlett's bound.

    Parameters
    ----------
    residual, other : array_like, shape (N,)
        The residual and, e.g., the input's rate of change, uniformly sampled together.
    dt : float
        Sample interval, s.
    max_lag_s : float, optional
        Longest lag L dt, s (default as :func:`autocorrelation`).
    confidence : float
        Confidence level of the bound.

    Returns
    -------
    CrossCorrelation
        ``values[k] = Σ_t ẽ(t + k) ũ(t) / (N σ_e σ_u)`` for k = -L..L (ẽ, ũ the series less
        their means).
    """
    e = checked_series(residual, "residual")
    u = checked_series(other, "other")
    check_same_size(e, u, "residual and other")
    dt = check_sample_interval(dt)
    z = normal_quantile(confidence)
    n = e.size
    lags = _max_lag(n, dt, max_lag_s)
    full = signal.correlate(standardised(e), standardised(u), mode="full", method="fft") / n
    values = full[n - 1 - lags : n + lags]
    bound = z * math.sqrt(_variance_factor(sample_acf(e), sample_acf(u)) / n)
    best = int(np.argmax(np.abs(values)))
    searched = 2 * lags + 1
    family_z = normal_quantile(confidence ** (1.0 / searched))
    return CrossCorrelation(
        lags_s=np.arange(-lags, lags + 1, dtype=np.float64) * dt,
        values=values,
        bound=bound,
        peak=float(values[best]),
        peak_lag_s=(best - lags) * dt,
        significant=bool(abs(values[best]) > bound * family_z / z),
    )


@dataclass(frozen=True, kw_only=True)
class CandidateCorrelation:
    """Zero-lag correlation of the residual with one candidate signal.

    Attributes
    ----------
    name : str
        The candidate's name.
    correlation : float
        Pearson correlation r with the residual.
    bound : float
        Bartlett bound of r for mutually uncorrelated series at the chosen confidence.
    z : float
        ``r / standard error``: about standard normal when the two are uncorrelated.
    """

    name: str
    correlation: float
    bound: float
    z: float

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "name": self.name,
            "correlation": float(self.correlation),
            "bound": float(self.bound),
            "z": json_float(self.z),
        }


def candidate_correlations(
    residual: ArrayLike, candidates: Mapping[str, ArrayLike], confidence: float = 0.95
) -> list[CandidateCorrelation]:
    """Correlate the residual with named candidate signals (level, rate, trend, ...).

    Parameters
    ----------
    residual : array_like, shape (N,)
        Residual, uniformly sampled.
    candidates : mapping of str to array_like, shape (N,)
        Signals that could explain the residual.
    confidence : float
        Confidence level of the bounds.

    Returns
    -------
    list of CandidateCorrelation
        Sorted by |z|, largest first.
    """
    e = checked_series(residual, "residual")
    z = normal_quantile(confidence)
    n = e.size
    e_std, rho_e = standardised(e), sample_acf(e)
    found = []
    for name, values in candidates.items():
        u = checked_series(values, f"candidate {name!r}")
        check_same_size(e, u, f"residual and candidate {name!r}")
        r = float(np.mean(e_std * standardised(u)))
        error = math.sqrt(_variance_factor(rho_e, sample_acf(u)) / n)
        found.append(CandidateCorrelation(name=name, correlation=r, bound=z * error, z=r / error))
    return sorted(found, key=lambda c: -abs(c.z))
