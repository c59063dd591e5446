"""Butterworth low-pass filters: zero-phase pre-filter and post-filter (Secs. IV B, V B).

Pre-filtering both thermocouple signals with the same linear filter leaves the relation between
them (Eq. 8) unchanged, so the estimators still apply while out-of-band noise is removed.
Post-filtering smooths the reconstructed gas temperature, whose noise the inverse model amplifies.
Both run forward and backward (``sosfiltfilt``, Matlab's ``filtfilt``) so they add no phase lag;
second-order sections keep high orders at low cut-offs numerically stable.

Near the ends of a record the zero-phase filter reads its padding (the record reflected about
its end point), which the two sensors' relation does not hold for: the first and last samples
of a pre-filtered pair carry start-up transients that differ between the sensors.
:func:`prefilter_pair` leaves them out.
"""

from __future__ import annotations

import functools
import math

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
    "prefilter_pair",
    "transient_samples",
]

#: Order of the post-filter: a fifth-order Butterworth, as in the paper (Sec. IV B).
POSTFILTER_ORDER = 5
#: Order of the pre-filter (the paper does not state one; we use the post-filter's).
PREFILTER_ORDER = 5
#: A filter's start-up transient counts as gone once its slowest pole has decayed this far.
TRANSIENT_DECAY = 1e-3


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


@functools.lru_cache(maxsize=32)
def transient_samples(cutoff_hz: float, dt: float, order: int = PREFILTER_ORDER) -> int:
    """Samples at each end where the pre-filter's start-up transient has not decayed, ≥ 1.

    The slowest pole p of the Butterworth sections decays to :data:`TRANSIENT_DECAY` in
    log(decay)/log|p| samples (90 for 20 Hz at 500 Hz, order 5). Cached: designing the filter
    for it takes 0.7 ms, and the online engine asks once per gap-free segment of every window.
    """
    sos = lowpass_sos(cutoff_hz, dt, order)
    slowest = float(np.max(np.abs(signal.sos2zpk(sos)[1])))
    return max(1, math.ceil(math.log(TRANSIENT_DECAY) / math.log(slowest)))


def prefilter_pair(
    tc1: ArrayLike, tc2: ArrayLike, dt: float, cutoff_hz: float, order: int = PREFILTER_ORDER
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Both readings pre-filtered (:func:`prefilter`), less the ends the padding disturbs.

    The reflected padding at each end gives each sensor a start-up transient the two sensors'
    relation does not hold for: on engine pulses at 500 Hz with a 20 Hz pre-filter it bent
    ml-eiv's τ1 by −1.9 % (three standard errors); without the :func:`transient_samples` at
    each end, −0.05 % (the sampling spread of the check); on records that start mid-run, as
    a rig's do, +0.98 → +0.08 % with the same spread.

    Returns
    -------
    tc1, tc2 : ndarray, shape (N - 2E,) each
        E = :func:`transient_samples`.

    Raises
    ------
    ValueError
        If the record is not longer than twice the transient plus the filter's padding.
    """
    first, second = prefilter(tc1, dt, cutoff_hz, order), prefilter(tc2, dt, cutoff_hz, order)
    edge = transient_samples(cutoff_hz, dt, order)
    if first.size <= 2 * edge + 3 * (order + 1):
        raise ValueError(
            f"pre-filter input: {first.size} samples are too few for a {cutoff_hz:g} Hz "
            f"pre-filter, whose start-up transients take {edge} samples at each end"
        )
    return first[edge:-edge], second[edge:-edge]


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
