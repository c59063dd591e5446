"""Boundary checks for sampled two-thermocouple data.

All checks raise :class:`~tcomp_core.errors.DataError` with a message naming the signal (the
``names`` given by the caller: a CSV column, a bag topic), the first offending sample and its
value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DataError, NoExcitationError

__all__ = [
    "MIN_SAMPLES",
    "UNIFORM_TOLERANCE",
    "check_excitation",
    "check_finite",
    "check_pair",
    "check_sample_interval",
    "check_shared_signal",
    "sample_interval_from_time",
]

#: Fewest samples any estimator accepts: a few sample periods are not enough to see a lag.
MIN_SAMPLES = 16

#: Largest relative deviation of a sample step from the median step still called uniform.
UNIFORM_TOLERANCE = 1e-3


def check_finite(values: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return ``values`` as a 1-D float array, refusing NaN and infinities.

    Parameters
    ----------
    values : array_like, shape (N,)
        Samples of one signal.
    name : str
        What to call the signal in an error (column, topic).

    Returns
    -------
    ndarray of float64, shape (N,)

    Raises
    ------
    DataError
        If the array is not one-dimensional or holds a non-finite sample; the message names the
        first such sample, its value and how many there are.
    """
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise DataError(f"{name}: expected a 1-D series of samples, got shape {array.shape}")
    bad = ~np.isfinite(array)
    if bad.any():
        index = int(np.flatnonzero(bad)[0])
        raise DataError(
            f"{name}: sample {index} is {float(array[index])!r}; {int(bad.sum())} of {array.size} "
            "samples are not finite"
        )
    return array


def check_sample_interval(dt: float) -> float:
    """Return ``dt`` as a float after checking that it is a finite positive interval in seconds."""
    dt = float(dt)
    if not np.isfinite(dt) or dt <= 0.0:
        raise DataError(f"{dt=} must be a finite sample interval > 0 s")
    return dt


def check_pair(
    tc1: ArrayLike,
    tc2: ArrayLike,
    names: Sequence[str] = ("tc1", "tc2"),
    min_samples: int = MIN_SAMPLES,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Check two simultaneously sampled thermocouple signals and return them as float arrays.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Measured temperatures of the two thermocouples, in degrees C, sampled at the same instants.
    names : pair of str
        What to call the signals in errors.
    min_samples : int
        Fewest samples accepted.

    Raises
    ------
    DataError
        On non-finite samples, unequal lengths or too few samples.
    """
    first = check_finite(tc1, names[0])
    second = check_finite(tc2, names[1])
    if first.size != second.size:
        raise DataError(
            f"{names[0]} has {first.size} samples but {names[1]} has {second.size}: "
            "the two thermocouples must be sampled at the same instants"
        )
    if first.size < min_samples:
        raise DataError(
            f"{names[0]}/{names[1]}: {first.size} samples are too few; "
            f"at least {min_samples} are needed"
        )
    return first, second


def check_excitation(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], names: Sequence[str] = ("tc1", "tc2")
) -> None:
    """Refuse signals that carry no information on the time constants.

    A constant signal, or two identical signals, leave the regressions of Eqs. (11) and (14)
    singular: no time constant explains them better than another.

    Raises
    ------
    NoExcitationError
        If either signal is constant or the two signals are identical.
    """
    for values, name in zip((tc1, tc2), names, strict=True):
        if np.ptp(values) == 0.0:
            raise NoExcitationError(
                f"{name} is constant ({float(values[0])!r} in all {values.size} samples): "
                "the data carry no information on the time constants"
            )
    if np.array_equal(tc1, tc2):
        raise NoExcitationError(
            f"{names[0]} and {names[1]} are identical in all {tc1.size} samples: two equal "
            "signals carry no information on the time constants"
        )


#: Segments the shared-signal check averages (Hann-windowed, not overlapping, together the
#: whole record but for a few percent), finest resolution first: independent noise stays below
#: :data:`SHARED_COHERENCE` in every bin with 32 segments (P = 0.5^31 per bin); 8 segments of
#: four times the length resolve a slow gas (ramps of a few seconds, whose 32 segments at a
#: decimated rate put their first bin above the gas's band) and are held to the coherence that
#: keeps that chance per bin.
SHARED_SEGMENTS = (32, 8)
#: Samples per segment at least (a record shorter than 32 of them is not checked).
SHARED_MIN_LENGTH = 64
#: Magnitude-squared coherence that two sensors in one gas reach in some band, with 32
#: segments; with n segments the bound of equal chance, 1 − (1 − 0.5)^(31/(n − 1)).
SHARED_COHERENCE = 0.5
#: Chance that independent noise passes any one bin's test: the 32-segment bound's.
_SHARED_CHANCE = (1.0 - SHARED_COHERENCE) ** (SHARED_SEGMENTS[0] - 1)
#: Bins pooled at the bottom of the spectrum, every other one from the first. A slow gas
#: spreads over the first few bins of every resolution, each short of the one-bin bound where
#: the slow sensor's lag smears its response across segment edges, a static nonlinearity
#: between the sensors (radiation, an unequal calibration) or the noise caps its coherence:
#: step-ramp records of 6 s at 1-10 kHz, 3.5-4 % noise, readings that correlate at 0.91-0.98,
#: reached 0.6-0.94 in each of their first bins against the one-bin bounds (0.5 and 0.954),
#: and were refused as "no shared signal".
SHARED_POOLED_BINS = (2, 4, 8, 16)
#: Chance that independent noise passes the pooled test at some band and resolution: about the
#: one-bin test's over the 640 bins of a window of the node's (10 000 samples, 3e-7).
SHARED_POOLED_CHANCE = 1e-6


def _shared_threshold(segments: int) -> float:
    """Coherence independent noise exceeds in a bin with the chance 32 segments give 0.5."""
    return 1.0 - _SHARED_CHANCE ** (1.0 / (segments - 1))


def _coherence(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], segments: int
) -> tuple[NDArray[np.float64], int] | None:
    """Magnitude-squared coherence over ``segments`` segments, bins 1.. (no 0 Hz), and length.

    None when the segments would be shorter than :data:`SHARED_MIN_LENGTH`.
    """
    from scipy.fft import prev_fast_len  # not at import: the replay node loads no scipy

    if tc1.size // segments < SHARED_MIN_LENGTH:
        return None
    # The longest length whose transform is fast: a large prime length took six times as long
    # (8 segments of a one-hour 5 kHz record: 4.9 s against 0.76 s); the next is at most a few
    # percent shorter.
    length = prev_fast_len(tc1.size // segments, real=True)
    used = length * segments
    window = np.hanning(length)
    spectra = []
    for values in (tc1, tc2):
        parts = values[:used].reshape(segments, length)
        parts = parts - parts.mean(axis=1, keepdims=True)
        spectra.append(np.fft.rfft(parts * window, axis=1)[:, 1:])
    first, second = spectra
    cross = np.abs(np.mean(first * np.conj(second), axis=0)) ** 2
    powers = np.mean(np.abs(first) ** 2, axis=0) * np.mean(np.abs(second) ** 2, axis=0)
    return cross / np.maximum(powers, np.finfo(float).tiny), length


def _pooled_log_chance(coherence: NDArray[np.float64], segments: int, bins: int) -> float:
    """The log of the chance that independent noise pools as much coherence in the lowest bins.

    Under independence each bin's coherence over n segments is Beta(1, n − 1), so
    −(n − 1) log(1 − C) is exponential with mean 1, and the sum over ``bins`` bins, every other
    one from the first (a Hann window's neighbours share two thirds of their noise, bins two
    apart a sixth), is Gamma(bins, 1). Returns log P(Gamma ≥ that sum) (−inf where it
    underflows); 0 when the spectrum has fewer bins.
    """
    from scipy.special import gammaincc  # not at import: the replay node loads no scipy

    picked = coherence[0 : 2 * bins - 1 : 2]
    if picked.size < bins:
        return 0.0
    pooled = -(segments - 1) * float(np.sum(np.log1p(-np.minimum(picked, 1.0 - 1e-16))))
    chance = float(gammaincc(bins, max(pooled, 0.0)))
    return math.log(chance) if chance > 0.0 else -math.inf


def _pools_shared_signal(coherence: NDArray[np.float64], segments: int) -> bool:
    """Whether the lowest bins pool more coherence than independent noise would.

    Each pooled band is held to :data:`SHARED_POOLED_CHANCE` shared among all the bands of all
    the resolutions (Bonferroni).
    """
    tests = len(SHARED_POOLED_BINS) * len(SHARED_SEGMENTS)
    bound = math.log(SHARED_POOLED_CHANCE / tests)
    return any(
        _pooled_log_chance(coherence, segments, bins) <= bound for bins in SHARED_POOLED_BINS
    )


def check_shared_signal(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    names: Sequence[str] = ("tc1", "tc2"),
) -> None:
    """Refuse two signals that share nothing: noise alone, or sensors in different gases.

    Two thermocouples in one gas carry its signal, so their coherence comes near 1 where the
    gas moves them above their noise; two independent noises stay near 0 at every frequency,
    and a fit of τ to them only finds the few samples the noise happens to correlate over.
    The coherence is looked at with :data:`SHARED_SEGMENTS` segments, each held to its bound
    of equal chance (:func:`_shared_threshold`) in its best bin, and pooled over the lowest
    bins (:data:`SHARED_POOLED_BINS`, :func:`_pooled_log_chance`), where a slow gas spreads;
    ``dt`` (s) names the frequency in the message.

    Raises
    ------
    NoExcitationError
        If the coherence stays below its bound at every frequency, at every resolution, and
        pooled over the lowest bins.
    """
    finest = None
    for segments in SHARED_SEGMENTS:
        found = _coherence(tc1, tc2, segments)
        if found is None:
            break  # segments too short to resolve the gas's band: the estimators' checks apply
        coherence, length = found
        best = int(np.argmax(coherence))
        if coherence[best] >= _shared_threshold(segments):
            return
        if _pools_shared_signal(coherence, segments):
            return
        finest = finest or (float(coherence[best]), best, length)
    if finest is None:
        return
    value, best, length = finest
    raise NoExcitationError(
        f"{names[0]} and {names[1]} share no signal: their coherence is at most "
        f"{value:.2f} at any frequency (near {(best + 1) / (length * dt):.3g} Hz; "
        "two sensors in one gas reach near 1 where it moves them): noise alone, or not "
        "two thermocouples in the same gas, or a gas that changes too seldom in the record "
        "for its few changes to tell from chance (a longer record shows more of them)"
    )


def sample_interval_from_time(
    time: ArrayLike, name: str = "time", tolerance: float = UNIFORM_TOLERANCE
) -> float:
    """Return the sample interval of a uniformly sampled time vector, in seconds.

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample times in seconds.
    name : str
        What to call the time vector in errors.
    tolerance : float
        Largest accepted relative deviation of any step from the median step.

    Returns
    -------
    float
        The mean sample interval in seconds.

    Raises
    ------
    DataError
        If time is not finite, not strictly increasing or not uniformly sampled; the message names
        the sample, the step found and by how much it deviates.
    """
    t = check_finite(time, name)
    if t.size < 2:
        raise DataError(f"{name}: {t.size} sample(s) give no sample interval")
    steps = np.diff(t)
    not_increasing = steps <= 0.0
    if not_increasing.any():
        index = int(np.flatnonzero(not_increasing)[0]) + 1
        raise DataError(
            f"{name} is not strictly increasing at sample {index}: "
            f"{float(t[index - 1])!r} s is followed by {float(t[index])!r} s"
        )
    median = float(np.median(steps))
    deviation = np.abs(steps - median) / median
    worst = int(np.argmax(deviation))
    if deviation[worst] > tolerance:
        raise DataError(
            f"{name} is not uniformly sampled: the step before sample {worst + 1} is "
            f"{steps[worst]:.9g} s against a median step of {median:.9g} s "
            f"({100.0 * deviation[worst]:.3g} % off, tolerance {100.0 * tolerance:.3g} %)"
            + _rate_change_hint(steps, tolerance)
        )
    return float((t[-1] - t[0]) / (t.size - 1))


def _rate_change_hint(steps: NDArray[np.float64], tolerance: float) -> str:
    """Words for steps (N,) that are uniform at one value and then at another ('' if not)."""
    first = float(steps[0])
    leaves = np.flatnonzero(np.abs(steps - first) > tolerance * first)
    at = int(leaves[0])
    after = steps[at:]
    second = float(np.median(after))
    if not np.all(np.abs(after - second) <= tolerance * second):
        return ""
    return (
        f"; the step changes from {first:.9g} s to {second:.9g} s at sample {at + 1} and stays "
        "there: the rate changed (tcomp process follows a change of rate; the other verbs need "
        "one rate: split the record there)"
    )
