"""Measurement noise and signal bandwidth from the spectrum of a sampled signal.

Thermocouples are low-pass sensors: above their bandwidth a reading holds only white
measurement noise, whose one-sided power spectral density is flat at 2 σ² dt. The median of
the Welch spectrum over the top of the band therefore measures σ² without knowing the signal,
and the ratio of two sensors' estimates is the φ = σ1²/σ2² that β-GTLS (Eq. 19) needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal, stats

from .validation import check_sample_interval

__all__ = ["NoiseEstimate", "estimate_noise", "signal_band_edge"]

#: Fraction of the Nyquist band, from the top, whose spectrum is taken as noise.
NOISE_BAND = (0.6, 0.95)
#: Quantile of the band's spectral densities taken as the floor: harmonic lines occupy the bins
#: above it.
NOISE_QUANTILE = 0.2
#: Samples per Welch segment (fewer when the record is short).
_SEGMENT = 1024


@dataclass(frozen=True, kw_only=True)
class NoiseEstimate:
    """White-noise level of one signal.

    Attributes
    ----------
    sigma : float
        Noise standard deviation, in the signal's units.
    floor : float
        One-sided noise power spectral density, units²/Hz.
    band_hz : tuple of float
        The frequency band it was measured in, Hz.
    """

    sigma: float
    floor: float
    band_hz: tuple[float, float]


def _welch(values: NDArray[np.float64], dt: float) -> tuple[NDArray, NDArray, int]:
    nperseg = int(min(_SEGMENT, max(16, values.size // 8)))
    # scipy-stubs 1.17 spells the detrend option "linear" as "literal".
    freqs, psd = signal.welch(  # type: ignore[call-overload]
        values, fs=1.0 / dt, nperseg=nperseg, detrend="linear"
    )
    n_segments = max(1, (values.size - nperseg) // (nperseg // 2) + 1)
    return freqs, psd, n_segments


def estimate_noise(values: NDArray[np.float64], dt: float) -> NoiseEstimate:
    """Noise standard deviation of a signal from the top of its spectrum.

    Parameters
    ----------
    values : ndarray, shape (N,)
        The signal (e.g. degrees C).
    dt : float
        Sample interval, s.

    Returns
    -------
    NoiseEstimate
        σ from a low quantile (:data:`NOISE_QUANTILE`) of the spectral density in
        :data:`NOISE_BAND` of the Nyquist band, corrected to the mean of a χ² with the Welch
        estimate's degrees of freedom. The low quantile ignores the harmonics of periodic
        signals that reach the band; a broadband signal tail there still biases σ upwards.
    """
    dt = check_sample_interval(dt)
    freqs, psd, n_segments = _welch(np.asarray(values, dtype=np.float64), dt)
    nyquist = 0.5 / dt
    band = (freqs >= NOISE_BAND[0] * nyquist) & (freqs <= NOISE_BAND[1] * nyquist)
    dof = 2 * n_segments
    quantile = float(np.quantile(psd[band], NOISE_QUANTILE))
    floor = quantile * dof / float(stats.chi2.ppf(NOISE_QUANTILE, dof))
    return NoiseEstimate(
        sigma=float(np.sqrt(floor / (2.0 * dt))),
        floor=floor,
        band_hz=(NOISE_BAND[0] * nyquist, NOISE_BAND[1] * nyquist),
    )


def signal_band_edge(
    values: NDArray[np.float64], dt: float, floor: float, ratio: float = 10.0
) -> float:
    """Highest frequency at which a signal's spectrum stands ``ratio`` times above its noise.

    Parameters
    ----------
    values : ndarray, shape (N,)
    dt : float
        Sample interval, s.
    floor : float
        Noise spectral density (see :func:`estimate_noise`).
    ratio : float
        How far above the floor counts as signal.

    Returns
    -------
    float
        Frequency in Hz (the lowest non-zero Welch frequency when nothing stands out).
    """
    freqs, psd, _ = _welch(np.asarray(values, dtype=np.float64), dt)
    above = np.flatnonzero(psd[1:] > ratio * floor) + 1
    return float(freqs[above[-1]] if above.size else freqs[1])
