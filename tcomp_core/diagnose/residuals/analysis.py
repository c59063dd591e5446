"""Everything together: where in time, frequency and level a model's free-run residual fails."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from ...errors import DataError
from ...validation import check_sample_interval
from .common import check_same_size, checked_series
from .correlation import (
    Autocorrelation,
    CandidateCorrelation,
    CrossCorrelation,
    autocorrelation,
    candidate_correlations,
    cross_correlation,
)
from .findings import describe_failure
from .level import LevelErrors, level_errors
from .spectrum import BandErrors, band_errors
from .windows import WindowedError, WindowedTau, default_window_s, windowed_error, windowed_tau

__all__ = ["FailureAnalysis", "analyse_failure"]

#: Fewest masked samples :func:`analyse_failure` accepts.
MIN_SAMPLES = 16
#: Kelvin at 0 degrees C.
KELVIN = 273.15


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
        checked_series(values, name)
        for values, name in zip(
            (time, tc1, tc2, predicted, measured, residual),
            ("time", "tc1", "tc2", "predicted", "measured", "residual"),
            strict=True,
        )
    )
    keep = np.asarray(mask, dtype=bool)
    others = {"tc1": first, "tc2": second, "predicted": y_hat, "measured": y, "residual": e}
    for name, values in {**others, "mask": keep}.items():
        check_same_size(t, values, f"time and {name}")
    if keep.sum() < MIN_SAMPLES:
        raise DataError(f"mask: {int(keep.sum())} samples are too few; need {MIN_SAMPLES}")
    fast, level = (second, first) if slow == 1 else (first, second)
    window_s = default_window_s(fast, dt) if window_s is None else float(window_s)
    used = np.flatnonzero(keep)
    span = slice(int(used[0]), int(used[-1]) + 1)
    candidates = _candidates(t, fast, level, dt, window_s)
    acf = autocorrelation(e[span], dt, confidence=confidence)
    ccf_input = cross_correlation(e[span], candidates["rate"][span], dt, confidence=confidence)
    correlations = candidate_correlations(
        e[span], {name: values[span] for name, values in candidates.items()}, confidence
    )
    errors = windowed_error(y, y_hat, t, window_s, keep)
    taus = windowed_tau(first, second, dt, window_s)
    bands = band_errors(y[span], y_hat[span], dt)
    levels = level_errors(e[keep], level[keep])
    return FailureAnalysis(
        acf=acf,
        ccf_input=ccf_input,
        candidates=correlations,
        windowed_error=errors,
        windowed_tau=taus,
        bands=bands,
        levels=levels,
        window_s=window_s,
        findings=describe_failure(
            acf=acf,
            ccf_input=ccf_input,
            candidates=correlations,
            windowed_error=errors,
            windowed_tau=taus,
            bands=bands,
            levels=levels,
            confidence=confidence,
        ),
    )
