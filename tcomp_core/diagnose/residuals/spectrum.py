"""Where in frequency the residual lies: its power per band against the signal's."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from ...validation import check_sample_interval
from .common import check_same_size, checked_series, json_list, safe_ratio

__all__ = ["BandErrors", "band_errors"]

#: Default number of frequency bands.
N_BANDS = 8


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
            "edges_hz": json_list(self.edges_hz),
            "residual_to_signal": json_list(self.residual_to_signal),
            "residual_share": json_list(self.residual_share),
            "coherence": json_list(self.coherence),
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
    y = checked_series(measured, "measured", 16)
    y_hat = checked_series(predicted, "predicted", 16)
    check_same_size(y, y_hat, "measured and predicted")
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
        [safe_ratio(r, s) for r, s in zip(residual, measured_power, strict=True)], dtype=np.float64
    )
    return BandErrors(
        edges_hz=edges,
        residual_to_signal=ratio,
        residual_share=share,
        coherence=_per_band(freqs, coherence, edges, np.mean),
        peak_band=int(np.nanargmax(share)) if np.isfinite(share).any() else 0,
    )
