"""Input checks, JSON conversion and the basic statistics shared by the residual analyses."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from ...errors import DataError
from ...validation import check_finite

__all__ = [
    "check_same_size",
    "checked_series",
    "json_float",
    "json_list",
    "normal_quantile",
    "safe_ratio",
    "sample_acf",
    "standardised",
]


def json_float(value: float) -> float | None:
    """A float for JSON, None for inf or NaN (JSON has neither)."""
    return float(value) if math.isfinite(value) else None


def json_list(values: ArrayLike) -> list[float | None]:
    """The values of a 1-D array as JSON floats (None for inf or NaN)."""
    return [json_float(float(v)) for v in np.asarray(values, dtype=np.float64)]


def checked_series(values: ArrayLike, name: str, min_size: int = 8) -> NDArray[np.float64]:
    """``values`` as a finite float array of at least ``min_size`` samples.

    Raises
    ------
    DataError
        Naming ``name`` when a value is not finite or there are too few samples.
    """
    array = check_finite(values, name)
    if array.size < min_size:
        raise DataError(f"{name}: {array.size} samples are too few; need at least {min_size}")
    return array


def check_same_size(first: NDArray, second: NDArray, names: str) -> None:
    """Raise :class:`DataError` naming ``names`` unless both arrays hold as many samples."""
    if first.size != second.size:
        raise DataError(f"{names}: lengths differ ({first.size} and {second.size})")


def normal_quantile(confidence: float) -> float:
    """Two-sided standard normal quantile of ``confidence``."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"{confidence=} must be in (0, 1)")
    return float(stats.norm.ppf(0.5 + 0.5 * confidence))


def safe_ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator``; ±inf (or 0 for 0/0) when the denominator is 0."""
    if denominator != 0.0:
        return numerator / denominator
    return math.copysign(math.inf, numerator) if numerator else 0.0


def standardised(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Zero mean, unit variance; a constant series becomes zeros (uncorrelated with all)."""
    centred = values - values.mean()
    spread = float(np.sqrt(np.mean(centred**2)))
    return centred / spread if spread > 0.0 else centred


def sample_acf(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample autocorrelation (biased estimator) at lags 0..N-1; 1, 0, 0... if constant."""
    x = standardised(values)
    n = x.size
    if not x.any():
        return np.eye(1, n)[0]
    return signal.correlate(x, x, mode="full", method="fft")[n - 1 :] / n
