"""Butterworth low-pass filters: zero-phase pre-filter and post-filter (Secs. IV B, V B).

Pre-filtering both thermocouple signals with the same linear filter leaves the relation between
them (Eq. 8) unchanged, so the estimators still apply while out-of-band noise is removed.
Post-filtering smooths the reconstructed gas temperature, whose noise the inverse model amplifies.
Both run forward and backward (``sosfiltfilt``, Matlab's ``filtfilt``) so they add no phase lag;
second-order sections keep high orders at low cut-offs numerically stable.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from .validation import check_finite, check_sample_interval

__all__ = [
    "POSTFILTER_ORDER",
    "PREFILTER_ORDER",
    "decimate",
    "lowpass_sos",
    "postfilter",
    "prefilter",
]

#: Order of the post-filter: a fifth-order Butterworth, as in the paper (Sec. IV B).
POSTFILTER_ORDER = 5
#: Order of the pre-filter (the paper does not state one; we use the post-filter's).
PREFILTER_ORDER = 5


def lowpass_sos(cutoff_hz: float, dt: float, order: int) -> NDArray[np.float64]:
    """Second-order sections of a Butterworth low-pass with -3 dB at ``cutoff_hz``.

    Raises
    ------
    ValueError
        If the cut-off is not between 0 and the Nyquist frequency 1/(2 dt).
    """
    dt = check_sample_interval(dt)
    nyquist = 0.5 / dt
    if not (np.isfinite(cutoff_hz) and 0.0 < cutoff_hz < nyquist):
        raise ValueError(
            f"filter bandwidth {cutoff_hz!r} Hz must lie between 0 and the Nyquist frequency "
            f"{nyquist:.6g} Hz"
        )
    return signal.butter(order, cutoff_hz, btype="lowpass", output="sos", fs=1.0 / dt)


def decimate(values: NDArray[np.float64], factor: int) -> NDArray[np.float64]:
    """Anti-aliased, zero-phase decimation aligned with ``values[::factor]``, shape (⌈N/factor⌉,).

    Polyphase FIR (:func:`scipy.signal.resample_poly`) with the ends extended along a fitted
    line: padding with zeros would drag a 500 °C record towards 0 at both ends, and the edge
    transients would dominate the difference equation.
    """
    return signal.resample_poly(values, 1, factor, padtype="line")


def _zero_phase(values: ArrayLike, dt: float, cutoff_hz: float, order: int, name: str):
    samples = check_finite(values, name)
    sos = lowpass_sos(cutoff_hz, dt, order)
    # filtfilt needs more samples than its edge padding; say so instead of scipy's message.
    padding = 3 * (2 * sos.shape[0] + 1)
    if samples.size <= padding:
        raise ValueError(
            f"{name}: {samples.size} samples are too few for a zero-phase order-{order} filter "
            f"(need more than {padding})"
        )
    return signal.sosfiltfilt(sos, samples)


def prefilter(
    values: ArrayLike, dt: float, cutoff_hz: float, order: int = PREFILTER_ORDER
) -> NDArray[np.float64]:
    """Zero-phase Butterworth low-pass applied to a thermocouple signal before estimation.

    Parameters
    ----------
    values : array_like, shape (N,)
        Temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    cutoff_hz : float
        Bandwidth (-3 dB of each pass), Hz.
    order : int
        Butterworth order.

    Returns
    -------
    ndarray, shape (N,)
    """
    return _zero_phase(values, dt, cutoff_hz, order, "pre-filter input")


def postfilter(
    values: ArrayLike, dt: float, cutoff_hz: float, order: int = POSTFILTER_ORDER
) -> NDArray[np.float64]:
    """Fifth-order zero-phase Butterworth post-filter of a reconstruction (Sec. IV B).

    Parameters
    ----------
    values : array_like, shape (N,)
        Reconstructed gas temperature, degrees C.
    dt : float
        Sample interval, seconds.
    cutoff_hz : float
        Bandwidth, Hz (the paper uses 20–50 Hz).

    Returns
    -------
    ndarray, shape (N,)
    """
    return _zero_phase(values, dt, cutoff_hz, order, "post-filter input")
