"""Pre-filter sweep (Fig. 10): time constant estimates against pre-filter bandwidth.

Below the signal's fundamental the pre-filter removes the excitation and every estimator becomes
ill-conditioned; just above it part of the dynamics is removed; at high bandwidths noise erodes
the estimates. The paper calls the first major local maximum of the estimates above the
fundamental the *best pre-filtering frequency*. We locate it on the mean of τ1 and τ2, each
normalised by its median over the sweep, with :func:`scipy.signal.find_peaks`: a peak counts as
major when its prominence is at least 10 % of the curve's range. When the curve has no interior
peak (estimates that only fall with bandwidth, as on clean simulated data), the largest estimate
above the fundamental is taken and ``best_is_peak`` is False.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from .errors import TcompError
from .estimators import Method, estimate
from .validation import check_excitation, check_pair, check_sample_interval

__all__ = [
    "SweepResult",
    "best_prefilter_index",
    "default_bandwidths",
    "fundamental_frequency",
    "prefilter_sweep",
]

#: Fraction of the normalised curve's range a peak must stand out by to count as major.
MAJOR_PROMINENCE = 0.10


@dataclass(frozen=True, kw_only=True)
class SweepResult:
    """Estimates over a range of pre-filter bandwidths.

    Attributes
    ----------
    method : str
    bandwidths_hz : ndarray, shape (M,)
    tau1, tau2 : ndarray, shape (M,)
        Estimates in seconds; NaN where the estimator failed.
    failures : tuple of str
        For each bandwidth, the reason the estimator failed, or '' when it succeeded.
    fundamental_hz : float
        Strongest spectral line of thermocouple 1 (excluding DC).
    best_index : int or None
        Index of the best pre-filtering frequency, None if every estimate failed.
    best_is_peak : bool
        Whether the best frequency is a true local maximum (else the largest estimate).
    """

    method: str
    bandwidths_hz: NDArray[np.float64]
    tau1: NDArray[np.float64]
    tau2: NDArray[np.float64]
    failures: tuple[str, ...]
    fundamental_hz: float
    best_index: int | None
    best_is_peak: bool

    @property
    def best_hz(self) -> float | None:
        """Best pre-filtering frequency, Hz."""
        return None if self.best_index is None else float(self.bandwidths_hz[self.best_index])


def fundamental_frequency(values: NDArray[np.float64], dt: float) -> float:
    """Frequency of the largest periodogram line of a signal, excluding DC, in Hz."""
    # scipy-stubs 1.17 spells the detrend option "linear" as "literal".
    freqs, power = signal.periodogram(  # type: ignore[call-overload]
        values, fs=1.0 / dt, detrend="linear"
    )
    power[0] = 0.0
    return float(freqs[int(np.argmax(power))])


def default_bandwidths(dt: float, fundamental_hz: float, count: int = 40) -> NDArray[np.float64]:
    """Log-spaced bandwidths from 1.2 × the fundamental to 0.9 × Nyquist, Hz."""
    nyquist = 0.5 / dt
    low = min(max(1.2 * fundamental_hz, 1e-3 * nyquist), 0.5 * nyquist)
    return np.geomspace(low, 0.9 * nyquist, count)


def best_prefilter_index(
    bandwidths_hz: NDArray[np.float64],
    tau1: NDArray[np.float64],
    tau2: NDArray[np.float64],
    fundamental_hz: float,
) -> tuple[int | None, bool]:
    """Index of the first major local maximum of the estimates above the fundamental.

    Returns
    -------
    index : int or None
    is_peak : bool
    """
    finite = np.isfinite(tau1) & np.isfinite(tau2) & (bandwidths_hz > fundamental_hz)
    candidates = np.flatnonzero(finite)
    if candidates.size == 0:
        return None, False
    curve = 0.5 * (
        tau1[candidates] / np.median(tau1[candidates])
        + tau2[candidates] / np.median(tau2[candidates])
    )
    span = float(np.ptp(curve))
    if span > 0.0:
        peaks, _ = signal.find_peaks(curve, prominence=MAJOR_PROMINENCE * span)
        if peaks.size:
            return int(candidates[peaks[0]]), True
    return int(candidates[int(np.argmax(curve))]), False


def prefilter_sweep(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    method: Method = "beta-gtls",
    *,
    bandwidths_hz: ArrayLike | None = None,
    phi: float = 1.0,
    alpha: float | None = None,
    names: tuple[str, str] = ("tc1", "tc2"),
) -> SweepResult:
    """Estimate τ1, τ2 after zero-phase pre-filtering at each bandwidth (Fig. 10).

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    method : str
        Estimator (see :data:`tcomp_core.METHODS`).
    bandwidths_hz : array_like, optional
        Pre-filter bandwidths in Hz; :func:`default_bandwidths` when omitted.
    phi, alpha :
        Passed to :func:`tcomp_core.estimate`.
    names : pair of str
        Signal names for error messages.

    Returns
    -------
    SweepResult
    """
    first, second = check_pair(tc1, tc2, names)
    dt = check_sample_interval(dt)
    check_excitation(first, second, names)
    fundamental = fundamental_frequency(first, dt)
    if bandwidths_hz is None:
        bands = default_bandwidths(dt, fundamental)
    else:
        bands = np.sort(np.asarray(bandwidths_hz, dtype=np.float64))
    tau1 = np.full(bands.size, np.nan)
    tau2 = np.full(bands.size, np.nan)
    failures = []
    for index, bandwidth in enumerate(bands):
        try:
            result = estimate(
                first, second, dt, method, phi=phi, alpha=alpha, prefilter_hz=float(bandwidth)
            )
        except (TcompError, ValueError) as exc:
            failures.append(str(exc))
            continue
        tau1[index], tau2[index] = result.tau1, result.tau2
        failures.append("")
    best, is_peak = best_prefilter_index(bands, tau1, tau2, fundamental)
    return SweepResult(
        method=method,
        bandwidths_hz=bands,
        tau1=tau1,
        tau2=tau2,
        failures=tuple(failures),
        fundamental_hz=fundamental,
        best_index=best,
        best_is_peak=is_peak,
    )
