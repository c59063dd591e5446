"""How well the fitted two-thermocouple model explains the measurements.

The model says thermocouple 2 follows thermocouple 1 through (Eq. 8)

    T_m2(k) = a2 T_m2(k-1) + b2/b1 (T_m1(k) - a1 T_m1(k-1)),

so a fitted pair (a1, a2) predicts the whole tc2 record from tc1 and one initial value. The
free-run (simulation) error of that prediction, as a normalised RMS in percent of tc2's spread,
is the fit figure: it is small when the first-order model holds and grows when a physical effect
the model lacks (conduction, radiation, a delay...) shapes the signals. Unlike the one-step
regression residual it is not dominated by sample-to-sample noise at high sample rates.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray
from scipy import signal

__all__ = ["fit_error_percent", "rms_about_mean", "simulate_tc2_from_tc1"]


def simulate_tc2_from_tc1(
    tc1: NDArray[np.float64], initial_tc2: float, a1: float, a2: float
) -> NDArray[np.float64]:
    """Free-run prediction of thermocouple 2 from thermocouple 1 (Eq. 8).

    Parameters
    ----------
    tc1 : ndarray, shape (N,)
        Thermocouple 1 temperatures, degrees C.
    initial_tc2 : float
        Thermocouple 2 at sample 0, degrees C.
    a1, a2 : float
        Discrete poles of the two sensors.

    Returns
    -------
    ndarray, shape (N,)
        Predicted thermocouple 2, degrees C; element 0 is ``initial_tc2``.
    """
    gain = (1.0 - a2) / (1.0 - a1)
    numerator = [gain, -gain * a1]
    denominator = [1.0, -a2]
    # The filter's state before tc1[1] carries tc1[0] and tc2[0] (what scipy.signal.lfiltic
    # computes for a first-order section, without its per-call cost).
    zi = np.array([numerator[1] * float(tc1[0]) + a2 * initial_tc2])
    predicted = np.empty(tc1.size)
    predicted[0] = initial_tc2
    predicted[1:], _ = signal.lfilter(numerator, denominator, tc1[1:], zi=zi)
    return predicted


def fit_error_percent(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    a1: float,
    a2: float,
    segment_starts: NDArray[np.intp] | None = None,
) -> float:
    """Free-run fit error of tc2 from tc1: ``100 rms(tc2 - tc2_sim) / std(tc2)``, in percent.

    This is 100 − MATLAB ``compare``'s fit percentage, up to its use of the rms about the mean.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Temperatures, degrees C.
    a1, a2 : float
        Discrete poles of the fitted pair.
    segment_starts : ndarray of int, optional
        Indices where the record resumes after a gap; the simulation restarts from the
        measured tc2 there, as it does at index 0.
    """
    bounds = [0, *(() if segment_starts is None else segment_starts.tolist()), tc1.size]
    parts = [
        simulate_tc2_from_tc1(tc1[start:stop], float(tc2[start]), a1, a2)
        for start, stop in itertools.pairwise(bounds)
        if stop > start
    ]
    predicted = parts[0] if len(parts) == 1 else np.concatenate(parts)
    spread = rms_about_mean(tc2)
    if spread == 0.0:
        return float("inf")
    residual = tc2 - predicted
    return 100.0 * math.sqrt(float(residual @ residual) / residual.size) / spread


def rms_about_mean(values: NDArray[np.float64]) -> float:
    """``np.std(values)`` (population), with one dot product: the window statistics call it often.

    Parameters
    ----------
    values : ndarray, shape (N,)
        Any strides.
    """
    deviation = values - values.mean()
    return math.sqrt(float(deviation @ deviation) / deviation.size)
