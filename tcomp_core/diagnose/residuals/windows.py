"""The residual and the time constants over time: statistics per window of the record."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import TcompError
from ...estimators import estimate
from ...validation import check_sample_interval
from .common import (
    check_same_size,
    checked_series,
    json_float,
    json_list,
    safe_ratio,
    standardised,
)

__all__ = [
    "WindowedError",
    "WindowedTau",
    "default_window_s",
    "windowed_error",
    "windowed_tau",
]

#: Fewest samples in a window for its error to count.
MIN_WINDOW_SAMPLES = 10
#: Robust spread: 1.4826 MAD estimates the standard deviation of normal data.
MAD_TO_SD = 1.4826
#: Correlation of log τ1 and log τ2 across windows above which they "vary together".
TOGETHER_CORRELATION = 0.7
#: Least spread of the time constants across windows, %, that counts as a drift.
MIN_TAU_SPREAD_PCT = 5.0
#: Default number of windows per record.
TARGET_WINDOWS = 10
#: Fewest dominant periods and samples in a default window.
MIN_WINDOW_PERIODS = 3.0
MIN_WINDOW_LENGTH = 100


def _windows(n: int, dt: float, window_s: float) -> list[slice]:
    """``round(N dt / window_s)`` (at least 1) equal, contiguous windows."""
    if not window_s > 0.0:
        raise ValueError(f"{window_s=} must be > 0 s")
    count = min(n, max(1, round(n * dt / window_s)))
    bounds = np.linspace(0, n, count + 1).round().astype(int)
    return [slice(int(lo), int(hi)) for lo, hi in itertools.pairwise(bounds)]


def _robust_spread_pct(values: NDArray[np.float64]) -> float:
    """``100 · 1.4826 MAD / median`` of the finite values; NaN with fewer than 3."""
    finite = values[np.isfinite(values)]
    if finite.size < 3:
        return math.nan
    median = float(np.median(finite))
    mad = float(np.median(np.abs(finite - median)))
    return 100.0 * MAD_TO_SD * safe_ratio(mad, abs(median))


def default_window_s(fast: ArrayLike, dt: float) -> float:
    """Window length for the windowed statistics, s.

    A tenth of the record, but at least 3 periods of the fast sensor's dominant frequency
    (so each window excites the sensors enough to estimate τ) and 100 samples, and at most a
    third of the record.
    """
    values = checked_series(fast, "fast")
    dt = check_sample_interval(dt)
    duration = values.size * dt
    spectrum = np.abs(np.fft.rfft(values - values.mean()))
    dominant_hz = max(1, int(np.argmax(spectrum[1:])) + 1) / duration
    window = max(
        duration / TARGET_WINDOWS, MIN_WINDOW_PERIODS / dominant_hz, MIN_WINDOW_LENGTH * dt
    )
    return min(window, duration / 3.0)


@dataclass(frozen=True, kw_only=True)
class WindowedError:
    """Normalised error in consecutive windows.

    Attributes
    ----------
    centres_s : ndarray, shape (W,)
        Window centres, s.
    error_pct : ndarray, shape (W,)
        ``100 rms(measured - predicted) / std(measured)`` over the window's masked samples, %;
        NaN for windows with fewer than 10 of them.
    """

    centres_s: NDArray[np.float64]
    error_pct: NDArray[np.float64]

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {"centres_s": json_list(self.centres_s), "error_pct": json_list(self.error_pct)}


def windowed_error(
    measured: ArrayLike,
    predicted: ArrayLike,
    time: ArrayLike,
    window_s: float,
    mask: ArrayLike | None = None,
) -> WindowedError:
    """Error of the prediction in each of consecutive, non-overlapping windows.

    Parameters
    ----------
    measured, predicted : array_like, shape (N,)
        The measured series and the model's simulation of it, degrees C.
    time : array_like, shape (N,)
        Sample times, s, uniformly spaced.
    window_s : float
        Window length, s; the record is cut into ``round(duration / window_s)`` equal windows.
    mask : array_like of bool, shape (N,), optional
        Samples that count (default all).

    Returns
    -------
    WindowedError
        The normalisation ``std(measured)`` is taken over all masked samples of the record,
        so the windows' errors are on the scale of the record's held-out error.
    """
    y = checked_series(measured, "measured", 2)
    y_hat = checked_series(predicted, "predicted", 2)
    t = checked_series(time, "time", 2)
    check_same_size(y, y_hat, "measured and predicted")
    check_same_size(y, t, "measured and time")
    keep = np.ones(y.size, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    check_same_size(y, keep, "measured and mask")
    spread = float(np.std(y[keep])) if keep.any() else 0.0
    dt = (t[-1] - t[0]) / (t.size - 1)
    centres, errors = [], []
    for window in _windows(y.size, dt, window_s):
        centres.append(0.5 * (t[window.start] + t[window.stop - 1]))
        use = keep[window]
        if use.sum() < MIN_WINDOW_SAMPLES:
            errors.append(math.nan)
            continue
        rms = float(np.sqrt(np.mean((y[window][use] - y_hat[window][use]) ** 2)))
        errors.append(100.0 * safe_ratio(rms, spread))
    return WindowedError(centres_s=np.asarray(centres), error_pct=np.asarray(errors))


@dataclass(frozen=True, kw_only=True)
class WindowedTau:
    """β-GTLS time constants estimated in consecutive windows.

    Attributes
    ----------
    centres_s : ndarray, shape (W,)
        Window centres, s from the first sample.
    tau1, tau2 : ndarray, shape (W,)
        Time constants of thermocouples 1 and 2 in each window, s; NaN where estimation failed.
    ratio : ndarray, shape (W,)
        ``tau2 / tau1``.
    """

    centres_s: NDArray[np.float64]
    tau1: NDArray[np.float64]
    tau2: NDArray[np.float64]
    ratio: NDArray[np.float64]

    @property
    def tau1_spread_pct(self) -> float:
        """Robust coefficient of variation of τ1 across windows, ``1.4826 MAD / median``, %."""
        return _robust_spread_pct(self.tau1)

    @property
    def tau2_spread_pct(self) -> float:
        """Robust coefficient of variation of τ2 across windows, %."""
        return _robust_spread_pct(self.tau2)

    @property
    def ratio_spread_pct(self) -> float:
        """Robust coefficient of variation of τ2/τ1 across windows, %."""
        return _robust_spread_pct(self.ratio)

    @property
    def log_correlation(self) -> float:
        """Correlation of log τ1 and log τ2 across windows; NaN with fewer than 3 windows."""
        ok = np.isfinite(self.tau1) & np.isfinite(self.tau2)
        if ok.sum() < 3:
            return math.nan
        a, b = standardised(np.log(self.tau1[ok])), standardised(np.log(self.tau2[ok]))
        return float(np.mean(a * b))

    @property
    def vary_together(self) -> bool:
        """τ1 and τ2 drift together (correlated logs, spreads over 5 %) at a steady ratio.

        The signature of a changing gas velocity: both time constants scale alike.
        """
        spread = min(self.tau1_spread_pct, self.tau2_spread_pct)
        return bool(
            self.log_correlation > TOGETHER_CORRELATION
            and spread > MIN_TAU_SPREAD_PCT
            and self.ratio_spread_pct < 0.5 * spread
        )

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "centres_s": json_list(self.centres_s),
            "tau1": json_list(self.tau1),
            "tau2": json_list(self.tau2),
            "tau1_spread_pct": json_float(self.tau1_spread_pct),
            "tau2_spread_pct": json_float(self.tau2_spread_pct),
            "ratio_spread_pct": json_float(self.ratio_spread_pct),
            "log_correlation": json_float(self.log_correlation),
            "vary_together": self.vary_together,
        }


def windowed_tau(tc1: ArrayLike, tc2: ArrayLike, dt: float, window_s: float) -> WindowedTau:
    """Estimate τ1 and τ2 by β-GTLS (φ = 1) in consecutive, non-overlapping windows.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Readings of thermocouples 1 and 2, degrees C.
    dt : float
        Sample interval, s.
    window_s : float
        Window length, s (the record is cut into ``round(N dt / window_s)`` equal windows).

    Returns
    -------
    WindowedTau
    """
    first = checked_series(tc1, "tc1", 2)
    second = checked_series(tc2, "tc2", 2)
    check_same_size(first, second, "tc1 and tc2")
    dt = check_sample_interval(dt)
    centres, taus = [], []
    for window in _windows(first.size, dt, window_s):
        centres.append(0.5 * (window.start + window.stop - 1) * dt)
        try:
            found = estimate(first[window], second[window], dt, method="beta-gtls")
            taus.append((found.tau1, found.tau2))
        except TcompError:
            taus.append((math.nan, math.nan))
    tau1, tau2 = np.asarray(taus, dtype=np.float64).T
    return WindowedTau(centres_s=np.asarray(centres), tau1=tau1, tau2=tau2, ratio=tau2 / tau1)
