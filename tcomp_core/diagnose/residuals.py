"""Where a fitted model fails: statistics of its free-run residual.

The residual of a model that captures the physics is white noise, uncorrelated with the input
and with the temperature level, spread over the spectrum like the noise and steady over time.
Each departure points somewhere:

* autocorrelation outside the white-noise bound (Ljung–Box): the model misses some dynamics;
* correlation with the fast sensor's rate of change at a lag: a delay or a wrong time constant;
* a slope or curvature against the temperature level: calibration or radiation;
* time constants of both sensors drifting together over the record: a velocity change;
* residual power in a narrow frequency band: dynamics missing in that band (conduction when
  it is slow).

The series compared here are autocorrelated (the residual of a smooth model error, the rate of
a smooth signal), so the usual white-noise bound ±z/√N of a cross-correlation is far too
narrow. The bounds use Bartlett's formula instead (Box, Jenkins & Reinsel, *Time Series
Analysis*, §11.1.3): for two series uncorrelated with each other

    var r_xy(k) ≈ (1/N) Σ_j ρ_xx(j) ρ_yy(j),

summed over the lags where the autocorrelations are not negligible: the sum is cut where its
partial sum is largest (see :func:`_variance_factor`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from ..errors import DataError, TcompError
from ..estimators import estimate
from ..validation import check_finite, check_sample_interval

__all__ = [
    "Autocorrelation",
    "BandErrors",
    "CandidateCorrelation",
    "CrossCorrelation",
    "FailureAnalysis",
    "LevelErrors",
    "WindowedError",
    "WindowedTau",
    "analyse_failure",
    "autocorrelation",
    "band_errors",
    "candidate_correlations",
    "cross_correlation",
    "default_window_s",
    "level_errors",
    "windowed_error",
    "windowed_tau",
]

#: Default longest lag of the correlations, s ...
DEFAULT_MAX_LAG_S = 0.5
#: ... but at least this many lags ...
MIN_LAGS = 10
#: ... and at most this many (and a quarter of the record).
MAX_LAGS = 200
#: Fewest masked samples :func:`analyse_failure` accepts.
MIN_SAMPLES = 16
#: Fewest samples in a window for its error to count.
MIN_WINDOW_SAMPLES = 10
#: Default number of frequency bands.
N_BANDS = 8
#: Sokal's window: the autocorrelation time is summed up to this many times itself.
SOKAL_WINDOW = 5.0
#: Kelvin at 0 degrees C.
KELVIN = 273.15
#: Robust spread: 1.4826 MAD estimates the standard deviation of normal data.
MAD_TO_SD = 1.4826
#: Correlation of log τ1 and log τ2 across windows above which they "vary together".
TOGETHER_CORRELATION = 0.7
#: Smallest correlation worth a finding (the signal explains 1 % of the residual's variance);
#: an offset is worth one from a tenth of the residual's standard deviation.
MIN_CORRELATION = 0.1
#: Least spread of the time constants across windows, %, that counts as a drift.
MIN_TAU_SPREAD_PCT = 5.0
#: Default number of windows per record.
TARGET_WINDOWS = 10
#: Fewest dominant periods and samples in a default window.
MIN_WINDOW_PERIODS = 3.0
MIN_WINDOW_LENGTH = 100


# -- helpers ------------------------------------------------------------------------------------


def _json(value: float) -> float | None:
    """A float for JSON, None for inf or NaN (JSON has neither)."""
    return float(value) if math.isfinite(value) else None


def _json_list(values: ArrayLike) -> list[float | None]:
    return [_json(float(v)) for v in np.asarray(values, dtype=np.float64)]


def _series(values: ArrayLike, name: str, min_size: int = 8) -> NDArray[np.float64]:
    array = check_finite(values, name)
    if array.size < min_size:
        raise DataError(f"{name}: {array.size} samples are too few; need at least {min_size}")
    return array


def _same_size(first: NDArray, second: NDArray, names: str) -> None:
    if first.size != second.size:
        raise DataError(f"{names}: lengths differ ({first.size} and {second.size})")


def _z(confidence: float) -> float:
    """Two-sided standard normal quantile of ``confidence``."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"{confidence=} must be in (0, 1)")
    return float(stats.norm.ppf(0.5 + 0.5 * confidence))


def _ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator``; ±inf (or 0 for 0/0) when the denominator is 0."""
    if denominator != 0.0:
        return numerator / denominator
    return math.copysign(math.inf, numerator) if numerator else 0.0


def _standardised(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Zero mean, unit variance; a constant series becomes zeros (uncorrelated with all)."""
    centred = values - values.mean()
    spread = float(np.sqrt(np.mean(centred**2)))
    return centred / spread if spread > 0.0 else centred


def _acf(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample autocorrelation (biased estimator) at lags 0..N-1; 1, 0, 0... if constant."""
    x = _standardised(values)
    n = x.size
    if not x.any():
        return np.eye(1, n)[0]
    return signal.correlate(x, x, mode="full", method="fft")[n - 1 :] / n


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


def _max_lag(n: int, dt: float, max_lag_s: float | None) -> int:
    if max_lag_s is None:
        lags = max(MIN_LAGS, round(DEFAULT_MAX_LAG_S / dt))
        return max(1, min(lags, MAX_LAGS, n // 4))
    if not max_lag_s > 0.0:
        raise ValueError(f"{max_lag_s=} must be > 0 s")
    return max(1, min(round(max_lag_s / dt), n - 1))


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
    return 100.0 * MAD_TO_SD * _ratio(mad, abs(median))


# -- 1. autocorrelation -------------------------------------------------------------------------


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
            "ljung_box_q": _json(self.ljung_box_q),
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
    e = _series(residual, "residual")
    dt = check_sample_interval(dt)
    z = _z(confidence)
    n = e.size
    lags = _max_lag(n, dt, max_lag_s)
    rho = _acf(e)[: lags + 1]
    bound = z / math.sqrt(n)
    k = np.arange(1, lags + 1)
    q = n * (n + 2.0) * float(np.sum(rho[1:] ** 2 / (n - k)))
    return Autocorrelation(
        lags_s=np.arange(lags + 1) * dt,
        values=rho,
        bound=bound,
        fraction_outside=float(np.mean(np.abs(rho[1:]) > bound)),
        ljung_box_q=q,
        p_value=float(stats.chi2.sf(q, lags)),
    )


# -- 2. cross-correlation -----------------------------------------------------------------------


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
    e = _series(residual, "residual")
    u = _series(other, "other")
    _same_size(e, u, "residual and other")
    dt = check_sample_interval(dt)
    z = _z(confidence)
    n = e.size
    lags = _max_lag(n, dt, max_lag_s)
    full = signal.correlate(_standardised(e), _standardised(u), mode="full", method="fft") / n
    values = full[n - 1 - lags : n + lags]
    bound = z * math.sqrt(_variance_factor(_acf(e), _acf(u)) / n)
    best = int(np.argmax(np.abs(values)))
    searched = 2 * lags + 1
    family_z = _z(confidence ** (1.0 / searched))
    return CrossCorrelation(
        lags_s=np.arange(-lags, lags + 1) * dt,
        values=values,
        bound=bound,
        peak=float(values[best]),
        peak_lag_s=(best - lags) * dt,
        significant=bool(abs(values[best]) > bound * family_z / z),
    )


# -- 3. candidate signals -----------------------------------------------------------------------


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
            "z": _json(self.z),
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
    e = _series(residual, "residual")
    z = _z(confidence)
    n = e.size
    e_std, rho_e = _standardised(e), _acf(e)
    found = []
    for name, values in candidates.items():
        u = _series(values, f"candidate {name!r}")
        _same_size(e, u, f"residual and candidate {name!r}")
        r = float(np.mean(e_std * _standardised(u)))
        error = math.sqrt(_variance_factor(rho_e, _acf(u)) / n)
        found.append(CandidateCorrelation(name=name, correlation=r, bound=z * error, z=r / error))
    return sorted(found, key=lambda c: -abs(c.z))


# -- 4. error over time -------------------------------------------------------------------------


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
        return {"centres_s": _json_list(self.centres_s), "error_pct": _json_list(self.error_pct)}


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
    y = _series(measured, "measured", 2)
    y_hat = _series(predicted, "predicted", 2)
    t = _series(time, "time", 2)
    _same_size(y, y_hat, "measured and predicted")
    _same_size(y, t, "measured and time")
    keep = np.ones(y.size, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    _same_size(y, keep, "measured and mask")
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
        errors.append(100.0 * _ratio(rms, spread))
    return WindowedError(centres_s=np.asarray(centres), error_pct=np.asarray(errors))


# -- 5. time constants over time ----------------------------------------------------------------


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
        a, b = _standardised(np.log(self.tau1[ok])), _standardised(np.log(self.tau2[ok]))
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
            "centres_s": _json_list(self.centres_s),
            "tau1": _json_list(self.tau1),
            "tau2": _json_list(self.tau2),
            "tau1_spread_pct": _json(self.tau1_spread_pct),
            "tau2_spread_pct": _json(self.tau2_spread_pct),
            "ratio_spread_pct": _json(self.ratio_spread_pct),
            "log_correlation": _json(self.log_correlation),
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
    first = _series(tc1, "tc1", 2)
    second = _series(tc2, "tc2", 2)
    _same_size(first, second, "tc1 and tc2")
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


# -- 6. error per frequency band ----------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class BandErrors:
    """Residual power per frequency band.

    Attributes
    ----------
    edges_hz : ndarray, shape (B + 1,)
        Band edges, Hz; band b is ``[edges_hz[b], edges_hz[b + 1])`` (the last includes its top).
    residual_to_signal : ndarray, shape (B,)
        Residual power over the measured signal's power in each band (a ratio; NaN for a band
        without frequency bins).
    residual_share : ndarray, shape (B,)
        Fraction of the residual power (summed over the bands) in each band.
    coherence : ndarray, shape (B,)
        Magnitude-squared coherence of measured and predicted, averaged over each band.
    peak_band : int
        The band holding the largest share of the residual power.
    """

    edges_hz: NDArray[np.float64]
    residual_to_signal: NDArray[np.float64]
    residual_share: NDArray[np.float64]
    coherence: NDArray[np.float64]
    peak_band: int

    @property
    def peak_band_hz(self) -> tuple[float, float]:
        """Lower and upper edge of the band holding the largest share, Hz."""
        return float(self.edges_hz[self.peak_band]), float(self.edges_hz[self.peak_band + 1])

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "edges_hz": _json_list(self.edges_hz),
            "residual_to_signal": _json_list(self.residual_to_signal),
            "residual_share": _json_list(self.residual_share),
            "coherence": _json_list(self.coherence),
            "peak_band_hz": list(self.peak_band_hz),
        }


def _default_edges(freqs: NDArray[np.float64]) -> NDArray[np.float64]:
    """About 8 log-spaced bands from the first non-zero bin to Nyquist, none empty."""
    edges = np.geomspace(freqs[1], freqs[-1], N_BANDS + 1)
    kept = [edges[0]]
    for edge in edges[1:-1]:
        if np.any((freqs >= kept[-1]) & (freqs < edge)):
            kept.append(edge)
    return np.asarray([*kept, edges[-1]])


def _per_band(
    freqs: NDArray[np.float64],
    values: NDArray[np.float64],
    edges: NDArray[np.float64],
    reduce: Callable[[NDArray[np.float64]], float],
) -> NDArray[np.float64]:
    """``reduce`` of ``values`` over each band's bins; NaN for a band without bins."""
    out = np.full(edges.size - 1, np.nan)
    for b in range(edges.size - 1):
        top = freqs <= edges[b + 1] if b == edges.size - 2 else freqs < edges[b + 1]
        inside = (freqs >= edges[b]) & top
        if inside.any():
            out[b] = reduce(values[inside])
    return out


def band_errors(
    measured: ArrayLike, predicted: ArrayLike, dt: float, edges_hz: ArrayLike | None = None
) -> BandErrors:
    """Where in frequency the residual ``measured - predicted`` lies (Welch spectra).

    Parameters
    ----------
    measured, predicted : array_like, shape (N,)
        The measured series and the model's simulation of it, degrees C.
    dt : float
        Sample interval, s.
    edges_hz : array_like, shape (B + 1,), optional
        Increasing band edges, Hz. Default: 8 log-spaced bands from the lowest resolved
        frequency (1 / segment length) to Nyquist, merged where a band would hold no bin.

    Returns
    -------
    BandErrors
        Welch segments are N/4 samples long (at least 16), Hann windowed, half overlapping.
    """
    y = _series(measured, "measured", 16)
    y_hat = _series(predicted, "predicted", 16)
    _same_size(y, y_hat, "measured and predicted")
    fs = 1.0 / check_sample_interval(dt)
    segment = max(16, y.size // 4)
    freqs, p_res = signal.welch(y - y_hat, fs=fs, nperseg=segment)
    _, p_sig = signal.welch(y, fs=fs, nperseg=segment)
    _, coherence = signal.coherence(y, y_hat, fs=fs, nperseg=segment)
    if edges_hz is None:
        edges = _default_edges(freqs)
    else:
        edges = np.asarray(edges_hz, dtype=np.float64)
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0.0):
            raise ValueError(f"edges_hz {edges!r} must be at least two increasing frequencies")
    residual = _per_band(freqs, p_res, edges, np.sum)
    measured_power = _per_band(freqs, p_sig, edges, np.sum)
    total = float(np.nansum(residual))
    share = residual / total if total > 0.0 else np.zeros_like(residual)
    ratio = np.array(
        [_ratio(r, s) for r, s in zip(residual, measured_power, strict=True)], dtype=np.float64
    )
    return BandErrors(
        edges_hz=edges,
        residual_to_signal=ratio,
        residual_share=share,
        coherence=_per_band(freqs, coherence, edges, np.mean),
        peak_band=int(np.nanargmax(share)) if np.isfinite(share).any() else 0,
    )


# -- 7. error against temperature level ---------------------------------------------------------


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
            "centres": _json_list(self.centres),
            "mean": _json_list(self.mean),
            "std": _json_list(self.std),
            "slope": float(self.slope),
            "slope_t": _json(self.slope_t),
            "curvature": float(self.curvature),
            "curvature_t": _json(self.curvature_t),
            "offset": float(self.offset),
            "offset_t": _json(self.offset_t),
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
    e = _series(residual, "residual")
    x = _series(level, "level")
    _same_size(e, x, "residual and level")
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
    n_eff = n / _integrated_time(_acf(leftover))
    variance = float(np.sum(leftover**2)) / max(n - 3, 1) * n / n_eff
    errors = np.sqrt(variance * np.diag(np.linalg.inv(design.T @ design)))
    t = [_ratio(float(c), float(s)) for c, s in zip(coefficients, errors, strict=True)]
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
        offset_t=_ratio(offset, float(np.std(leftover)) / math.sqrt(n_eff)),
        n_eff=n_eff,
        residual_std=float(np.std(e)),
        r_squared=1.0 - _ratio(float(np.var(leftover)), float(np.var(e))),
    )


# -- 8. everything together ---------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class FailureAnalysis:
    """Where a model fails, from its residual.

    Attributes
    ----------
    acf : Autocorrelation
        Whiteness of the (unfiltered) residual.
    ccf_input : CrossCorrelation
        Cross-correlation of the residual with the fast sensor's rate of change.
    candidates : list of CandidateCorrelation
        Zero-lag correlations with candidate signals, largest |z| first.
    windowed_error : WindowedError
        Held-out error over time.
    windowed_tau : WindowedTau
        β-GTLS time constants over time.
    bands : BandErrors
        Residual power per frequency band.
    levels : LevelErrors
        Residual against the slow sensor's level.
    window_s : float
        Window length of ``windowed_error`` and ``windowed_tau``, s.
    findings : list of str
        Plain sentences saying where the model fails.
    """

    acf: Autocorrelation
    ccf_input: CrossCorrelation
    candidates: list[CandidateCorrelation]
    windowed_error: WindowedError
    windowed_tau: WindowedTau
    bands: BandErrors
    levels: LevelErrors
    window_s: float
    findings: list[str]

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: the findings and every statistic behind them."""
        return {
            "findings": list(self.findings),
            "whiteness": self.acf.summary(),
            "input_rate": self.ccf_input.summary(),
            "candidates": [candidate.summary() for candidate in self.candidates],
            "window_s": float(self.window_s),
            "windowed_error": self.windowed_error.summary(),
            "windowed_tau": self.windowed_tau.summary(),
            "bands": self.bands.summary(),
            "levels": self.levels.summary(),
        }


def _p_text(p: float) -> str:
    return "p < 1e-6" if p < 1e-6 else f"p = {p:.2g}"


def _whiteness_finding(acf: Autocorrelation, confidence: float) -> str:
    outside = f"{100 * acf.fraction_outside:.0f} % of autocorrelation lags outside the " + (
        f"{100 * confidence:.0f} % bound (Ljung-Box {_p_text(acf.p_value)})"
    )
    if acf.p_value < 1.0 - confidence:
        return f"residual not white: {outside}"
    return f"residual consistent with white noise: {outside}"


def _band_finding(bands: BandErrors) -> str:
    low, high = bands.peak_band_hz
    share = bands.residual_share[bands.peak_band]
    ratio = bands.residual_to_signal[bands.peak_band]
    return (
        f"largest share of the residual power in {low:.3g}–{high:.3g} Hz: {100 * share:.0f} %, "
        f"where the residual holds {100 * ratio:.3g} % of the signal's power"
    )


def _level_findings(levels: LevelErrors, z: float) -> list[str]:
    found = []
    if abs(levels.offset_t) > z and abs(levels.offset) >= MIN_CORRELATION * levels.residual_std:
        found.append(f"residual offset {levels.offset:.3g} degC (t = {levels.offset_t:.3g})")
    if levels.r_squared < MIN_CORRELATION**2:
        return found
    if abs(levels.slope_t) > z:
        found.append(
            f"error changes with temperature level: slope {levels.slope:.3g} degC/degC "
            f"(t = {levels.slope_t:.3g})"
        )
    if abs(levels.curvature_t) > z:
        found.append(
            f"error curves with temperature level: curvature {levels.curvature:.3g} /degC "
            f"(t = {levels.curvature_t:.3g})"
        )
    return found


def _tau_finding(taus: WindowedTau) -> str | None:
    spreads = (taus.tau1_spread_pct, taus.tau2_spread_pct, taus.ratio_spread_pct)
    if not all(math.isfinite(s) for s in spreads):
        return None
    if taus.vary_together:
        return (
            f"tau1 and tau2 vary together across windows (corr {taus.log_correlation:.2f}, "
            f"spread {spreads[0]:.2g} % and {spreads[1]:.2g} %) at a constant ratio "
            f"(spread {spreads[2]:.2g} %)"
        )
    return (
        f"tau1 and tau2 across windows: spread {spreads[0]:.2g} % and {spreads[1]:.2g} %, "
        f"ratio spread {spreads[2]:.2g} % (corr of logs {taus.log_correlation:.2f})"
    )


def _input_finding(ccf: CrossCorrelation) -> str:
    at = f"correlation {ccf.peak:.2f} at {1e3 * ccf.peak_lag_s:.3g} ms, bound {ccf.bound:.2f}"
    if not ccf.significant:
        return f"residual not significantly correlated with the input rate ({at})"
    if abs(ccf.peak) < MIN_CORRELATION:
        return f"the residual follows the input rate only weakly ({at}: under 1 % of its variance)"
    if ccf.peak_lag_s == 0.0:
        return f"the residual moves with the input rate ({at})"
    way = "lags" if ccf.peak_lag_s > 0.0 else "leads"
    return (
        f"the residual {way} the input rate by {1e3 * abs(ccf.peak_lag_s):.3g} ms "
        f"(correlation {ccf.peak:.2f}, bound {ccf.bound:.2f})"
    )


def _window_finding(errors: WindowedError) -> str | None:
    e = errors.error_pct
    finite = np.isfinite(e)
    if finite.sum() < 2:
        return None
    median = float(np.median(e[finite]))
    worst = int(np.nanargmax(e))
    if e[worst] < 1.5 * median:
        return (
            f"error spread evenly over time: {np.min(e[finite]):.3g}–{e[worst]:.3g} % "
            "across windows"
        )
    first = last = worst
    while first > 0 and e[first - 1] >= 1.5 * median:
        first -= 1
    while last < e.size - 1 and e[last + 1] >= 1.5 * median:
        last += 1
    c = errors.centres_s
    half = 0.5 * (c[1] - c[0])
    which = (
        f"window {first + 1} holds" if first == last else f"windows {first + 1}–{last + 1} hold"
    )
    return (
        f"{which} the largest error ({max(c[first] - half, 0.0):.3g}–{c[last] + half:.3g} s): up "
        f"to {e[worst]:.3g} % against a median of {median:.3g} %"
    )


def _candidate_finding(candidates: list[CandidateCorrelation], z: float) -> str | None:
    if not candidates or not abs(candidates[0].z) > z:
        return None
    if abs(candidates[0].correlation) < MIN_CORRELATION:
        return None
    best = candidates[0]
    return (
        f"of the candidate signals the residual follows {best.name!r} most "
        f"(r = {best.correlation:.2f}, z = {best.z:.3g})"
    )


def _findings(analysis: FailureAnalysis, confidence: float) -> list[str]:
    z = _z(confidence)
    found = [
        _whiteness_finding(analysis.acf, confidence),
        _band_finding(analysis.bands),
        *_level_findings(analysis.levels, z),
        _tau_finding(analysis.windowed_tau),
        _input_finding(analysis.ccf_input),
        _window_finding(analysis.windowed_error),
        _candidate_finding(analysis.candidates, z),
    ]
    return [sentence for sentence in found if sentence]


def default_window_s(fast: ArrayLike, dt: float) -> float:
    """Window length for the windowed statistics, s.

    A tenth of the record, but at least 3 periods of the fast sensor's dominant frequency
    (so each window excites the sensors enough to estimate τ) and 100 samples, and at most a
    third of the record.
    """
    values = _series(fast, "fast")
    dt = check_sample_interval(dt)
    duration = values.size * dt
    spectrum = np.abs(np.fft.rfft(values - values.mean()))
    dominant_hz = max(1, int(np.argmax(spectrum[1:])) + 1) / duration
    window = max(
        duration / TARGET_WINDOWS, MIN_WINDOW_PERIODS / dominant_hz, MIN_WINDOW_LENGTH * dt
    )
    return min(window, duration / 3.0)


def _candidates(
    time: NDArray, fast: NDArray, slow: NDArray, dt: float, window_s: float
) -> dict[str, NDArray[np.float64]]:
    sos = signal.butter(2, min(0.2 / window_s, 0.25 / dt), output="sos", fs=1.0 / dt)
    return {
        "level": slow,
        "level^4": (slow + KELVIN) ** 4,
        "rate": np.gradient(fast, dt),
        "slow_rate": np.gradient(slow, dt),
        "trend": time,
        "drift": signal.sosfiltfilt(sos, fast),
    }


def analyse_failure(
    time: ArrayLike,
    tc1: ArrayLike,
    tc2: ArrayLike,
    predicted: ArrayLike,
    measured: ArrayLike,
    residual: ArrayLike,
    *,
    dt: float,
    slow: int,
    mask: ArrayLike,
    window_s: float | None = None,
    confidence: float = 0.95,
) -> FailureAnalysis:
    """Analyse a model's free-run residual: where in time, frequency and level it fails.

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample times, s, uniformly spaced by ``dt``.
    tc1, tc2 : array_like, shape (N,)
        Readings of both thermocouples, degrees C.
    predicted : array_like, shape (N,)
        Free-run simulation of the slow sensor from the fast one, low-passed, degrees C.
    measured : array_like, shape (N,)
        The slow sensor's readings, low-passed like ``predicted``, degrees C.
    residual : array_like, shape (N,)
        Unfiltered slow reading minus unfiltered simulation, degrees C.
    dt : float
        Sample interval, s.
    slow : {1, 2}
        The slow sensor (simulated from the other one).
    mask : array_like of bool, shape (N,)
        Held-out samples that count.
    window_s : float, optional
        Window length of the windowed error and time constants, s (default
        :func:`default_window_s` of the fast sensor).
    confidence : float
        Confidence level of every bound and test.

    Returns
    -------
    FailureAnalysis
        The autocorrelation, the cross-correlation with the fast sensor's rate (``rate``), the
        candidate correlations and the frequency bands use the contiguous stretch from the
        first to the last masked sample (the start-up transient is left out); the windowed
        error and the level fit use the masked samples only; the windowed time constants use
        the whole record. The candidates are ``level`` (the slow reading), ``level^4`` (its
        fourth power in kelvin), ``rate`` and ``slow_rate`` (the fast and slow sensors'
        rates of change), ``trend`` (time) and ``drift`` (the fast reading low-passed at
        0.2 / window_s Hz).

    Raises
    ------
    DataError
        If the arrays differ in length, hold non-finite values or fewer than 16 samples are
        masked.
    """
    if slow not in (1, 2):
        raise ValueError(f"{slow=} must be 1 or 2")
    dt = check_sample_interval(dt)
    t, first, second, y_hat, y, e = (
        _series(values, name)
        for values, name in zip(
            (time, tc1, tc2, predicted, measured, residual),
            ("time", "tc1", "tc2", "predicted", "measured", "residual"),
            strict=True,
        )
    )
    keep = np.asarray(mask, dtype=bool)
    others = {"tc1": first, "tc2": second, "predicted": y_hat, "measured": y, "residual": e}
    for name, values in {**others, "mask": keep}.items():
        _same_size(t, values, f"time and {name}")
    if keep.sum() < MIN_SAMPLES:
        raise DataError(f"mask: {int(keep.sum())} samples are too few; need {MIN_SAMPLES}")
    fast, level = (second, first) if slow == 1 else (first, second)
    window_s = default_window_s(fast, dt) if window_s is None else float(window_s)
    used = np.flatnonzero(keep)
    span = slice(int(used[0]), int(used[-1]) + 1)
    candidates = _candidates(t, fast, level, dt, window_s)
    analysis = FailureAnalysis(
        acf=autocorrelation(e[span], dt, confidence=confidence),
        ccf_input=cross_correlation(e[span], candidates["rate"][span], dt, confidence=confidence),
        candidates=candidate_correlations(
            e[span], {name: values[span] for name, values in candidates.items()}, confidence
        ),
        windowed_error=windowed_error(y, y_hat, t, window_s, keep),
        windowed_tau=windowed_tau(first, second, dt, window_s),
        bands=band_errors(y[span], y_hat[span], dt),
        levels=level_errors(e[keep], level[keep]),
        window_s=window_s,
        findings=[],
    )
    return replace(analysis, findings=_findings(analysis, confidence))
