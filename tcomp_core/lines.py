"""Foreign spectral lines: a line one sensor carries that the other does not (mains pick-up).

A thermocouple's millivolts pick up the mains (50 or 60 Hz) and its odd harmonics through the
extension cable and the amplifier's input. The gas does not carry the line, so the first-order
relation between the sensors (Eq. 8) does not hold at its frequency, and an estimator bends τ to
explain it: a line a fifth of the signal's swing on one channel put ml-eiv's τ1 41 % off on an
engine-pulse record of the detailed simulator, and the inverse amplifies the line by |1 + jωτ|
into the gas.

Two facts make the line harmless to τ:

* the same linear filter on both signals leaves the relation unchanged (the paper's argument
  for its pre-filter, Sec. IV B), so a notch common to both channels at the line removes it
  from the fit and biases nothing, whether the line was foreign or the gas's own;
* the gas's own lines appear in tc2 as in tc1 times |G2/G1|; a foreign one does not.

:func:`foreign_lines` finds the lines in either channel's spectrum that stand out of their
neighbourhood and that the other channel does not explain with the τ given, then confirms them
with a τ fitted on both channels with every such candidate notched. :func:`notch` takes lines
off a signal (zero phase); :func:`line_free_pair` takes the foreign lines off the channel that
carries them, for a reconstruction of the gas.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.ndimage import median_filter

from .noise import estimate_noise, welch_spectra

__all__ = [
    "LINE_EXCESS",
    "LINE_PROMINENCE",
    "NOTCH_Q",
    "ForeignLine",
    "fitted_tone",
    "foreign_lines",
    "line_free_pair",
    "notch",
    "remove_lines",
    "segment_length",
    "subtract_tones",
]

#: A line's power over the median of its neighbourhood (±:data:`LINE_NEIGHBOURS` bins), and
#: its excess over what the other channel and the first-order relation predict.
LINE_PROMINENCE = 20.0
LINE_NEIGHBOURS = 12
LINE_EXCESS = 4.0
#: A peak on the other channel at least this prominent, and within this ratio of the line's
#: own prominence, makes the line the gas's: pick-up on one sensor leaves the other flat
#: there (a 50 Hz line 26 917 times its neighbourhood on tc2 met 14.5 on tc1) or far below
#: (mains on a gas with its own 50 Hz line: 20 460 against 2 585), while a first-order model
#: that misses a physics (a delay) misjudges the power ratio of a line both sensors carry
#: alike (285 and 222 times their neighbourhoods).
SHARED_PROMINENCE = 4.0
SHARED_RATIO = 4.0
#: Welch segments averaged at least.
MIN_SEGMENTS = 8
#: Quality factor of the notches: -3 dB over f/Q (1.7 Hz at 50 Hz), a line and its drift.
NOTCH_Q = 30.0
#: Notches kept below this share of the sample rate (a notch at Nyquist has no width).
NOTCH_LIMIT = 0.45
#: Candidate lines notched for the refit at most (the most prominent): the cost of a notch
#: each, where the gas is a sum of lines (a multisine) that notching all would leave bare.
MAX_CANDIDATES = 24


@dataclass(frozen=True)
class ForeignLine:
    """A spectral line one channel carries beyond what the other explains.

    Attributes
    ----------
    frequency_hz : float
        Centre of the line, Hz (Welch bin refined by a parabola through the log powers).
    channel : int
        1 or 2: the sensor that carries it.
    amplitude_c : float
        Amplitude of the line, degrees C (from the power in its three bins).
    """

    frequency_hz: float
    channel: int
    amplitude_c: float


@dataclass(frozen=True)
class _Spectra:
    """Welch spectra of the two readings and each bin's prominence (:func:`_prominence`)."""

    freq: NDArray[np.float64]
    power: tuple[NDArray[np.float64], NDArray[np.float64]]
    fs: float
    nperseg: int
    prominence: tuple[NDArray[np.float64], NDArray[np.float64]]


def segment_length(samples: int, dt: float) -> int:
    """Samples per Welch segment: ~1 Hz bins, or coarser to average :data:`MIN_SEGMENTS`.

    A single segment's periodogram has noise bins 20 times their neighbours' median often
    enough to call noise a line; half-overlapping segments, averaged, do not.
    """
    longest = 2.0 * samples / (MIN_SEGMENTS + 1)
    finest = 2 ** math.ceil(math.log2(1.0 / dt))
    return int(min(finest, 2 ** math.floor(math.log2(max(longest, 8.0)))))


def _spectra(tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float) -> _Spectra:
    """Welch's spectra (as :func:`scipy.signal.welch` with its defaults) of both readings."""
    nperseg = segment_length(tc1.size, dt)
    freq, p1, _ = welch_spectra(np.asarray(tc1, dtype=np.float64), dt, nperseg, "constant")
    _, p2, _ = welch_spectra(np.asarray(tc2, dtype=np.float64), dt, nperseg, "constant")
    return _Spectra(freq, (p1, p2), 1.0 / dt, nperseg, (_prominence(p1), _prominence(p2)))


def _local_median(power: NDArray[np.float64]) -> NDArray[np.float64]:
    """The median of each bin's ±:data:`LINE_NEIGHBOURS` bins, the spectrum mirrored at its ends.

    :func:`scipy.ndimage.median_filter`'s "mirror" mode is ``np.pad``'s "reflect" (the end
    bin not repeated); the median of an odd count of values is one of them, so the result is
    the same as a median of each padded window, at a fraction of the cost.
    """
    if power.size <= LINE_NEIGHBOURS:  # mirroring needs more bins than the half window
        padded = np.pad(power, LINE_NEIGHBOURS, mode="reflect")
        windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * LINE_NEIGHBOURS + 1)
        return np.median(windows, axis=1)
    return np.asarray(median_filter(power, size=2 * LINE_NEIGHBOURS + 1, mode="mirror"))


def _prominence(power: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each bin's power over the median of its neighbourhood."""
    return power / np.maximum(_local_median(power), 1e-300)


def _peaks(power: NDArray[np.float64], prominence: NDArray[np.float64]) -> NDArray[np.intp]:
    """Bins (from the third on) where ``power`` peaks at :data:`LINE_PROMINENCE` × its median.

    ``prominence`` is :func:`_prominence` of ``power``. The Nyquist bin counts as a peak when
    it stands above the bin below it: a harmonic that aliases onto fs/2 (the fifth of 50 Hz
    at 500 Hz) lies there, where :func:`scipy.signal.find_peaks` never looks.
    """
    found, _ = signal.find_peaks(power)
    last = power.size - 1
    if last >= 2 and power[last] > power[last - 1]:
        found = np.append(found, last)
    return found[(found >= 2) & (prominence[found] >= LINE_PROMINENCE)]


def _excess(spectra: _Spectra, tau1: float, tau2: float) -> NDArray[np.float64]:
    """Log of tc2's power over tc1's times |G2/G1|², per bin: 0 where the gas explains both.

    Shape (2, bins): with the continuous sensors' ratio (1 + (ωτ1)²)/(1 + (ωτ2)²), and with
    that of their zero-order-hold discretisations (Eq. 5), which differ near the Nyquist
    frequency; a line must stand out under both to be foreign (a gas held between samples
    follows the second, physics sampled without an anti-alias filter neither exactly).
    """
    omega = 2.0 * np.pi * spectra.freq
    continuous = (1.0 + (omega * tau1) ** 2) / (1.0 + (omega * tau2) ** 2)
    dt = 1.0 / spectra.fs
    rotation = np.exp(-1j * omega * dt)
    a1, a2 = math.exp(-dt / tau1), math.exp(-dt / tau2)
    held = ((1.0 - a2) / (1.0 - a1)) ** 2 * np.abs(1.0 - a1 * rotation) ** 2
    held /= np.abs(1.0 - a2 * rotation) ** 2
    p1, p2 = spectra.power
    ratio = np.maximum(p2, 1e-300) / np.maximum(p1, 1e-300)
    return np.log(ratio / np.stack([continuous, held]))


def _line(spectra: _Spectra, peak: int, channel: int) -> ForeignLine:
    power = spectra.power[channel - 1]
    amplitude = math.sqrt(
        2.0 * float(power[peak - 1 : peak + 2].sum()) * spectra.fs / spectra.nperseg
    )
    if peak == power.size - 1:  # the Nyquist bin: no bin above to refine the centre with
        return ForeignLine(float(spectra.freq[peak]), channel, amplitude)
    left, centre, right = np.log(np.maximum(power[peak - 1 : peak + 2], 1e-300))
    curvature = left - 2.0 * centre + right
    shift = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    step = float(spectra.freq[1] - spectra.freq[0])
    return ForeignLine(float(spectra.freq[peak] + shift * step), channel, amplitude)


def _foreign(
    spectra: _Spectra, tau1: float, tau2: float, channel: int | None = None
) -> list[ForeignLine]:
    excess = _excess(spectra, tau1, tau2)
    lines = []
    for number, sign in ((1, -1.0), (2, 1.0)):
        if channel is not None and number != channel:
            continue
        own, other = spectra.prominence[number - 1], spectra.prominence[2 - number]
        for peak in _peaks(spectra.power[number - 1], own):
            beside = float(other[peak - 1 : peak + 2].max())
            if beside >= max(SHARED_PROMINENCE, own[peak] / SHARED_RATIO):
                continue  # the other channel peaks there too: the gas's line, off the model
            if np.all(sign * excess[:, peak] >= math.log(LINE_EXCESS)):
                lines.append(_line(spectra, int(peak), number))
    return sorted(lines, key=lambda line: -line.amplitude_c)


def foreign_lines(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    taus: tuple[float, float] | None,
    refit: Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[float, float]] | None = None,
    channel: int | None = None,
) -> list[ForeignLine]:
    """Lines one channel carries that the other does not explain, strongest first.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C.
    dt : float
        Sample interval, s.
    taus : (float, float) or None
        τ1, τ2 (s) that predict one channel's lines from the other's; None when the readings
        gave none (a fit the line threw to the edge of its range): ``refit`` alone judges.
    refit : callable, optional
        τ1, τ2 of a pair of signals. When given, it is called on the readings with every
        candidate line notched from both (the lines cannot bend that τ), and a line is foreign
        only if it is so with both ``taus`` and the refit's: a line strong enough to bend
        ``taus`` stays foreign with them, and the gas's own lines (a multisine's, whose
        notching leaves the refit little to go on) stay the gas's with ``taus``. A refit that
        raises ``TcompError`` leaves ``taus`` alone to judge.
    channel : int, optional
        Look on this channel only (1 or 2).

    Returns
    -------
    list of ForeignLine
        Empty when every line is the gas's (or there is none).

    Raises
    ------
    ValueError
        If neither ``taus`` nor ``refit`` is given.
    """
    from .errors import TcompError

    if taus is None and refit is None:
        raise ValueError("foreign_lines needs taus or a refit to judge the lines with")
    spectra = _spectra(tc1, tc2, dt)
    found = None if taus is None else _foreign(spectra, *taus, channel)
    if refit is None or found == []:
        return found or []
    frequencies = _strongest_candidates(spectra)
    if not frequencies:
        return []
    try:
        refitted = refit(remove_lines(tc1, dt, frequencies), remove_lines(tc2, dt, frequencies))
    except TcompError:
        return found or []
    confirmed = _foreign(spectra, *refitted, channel)
    if found is None:
        return confirmed
    kept = {(line.channel, line.frequency_hz) for line in confirmed}
    return [line for line in found if (line.channel, line.frequency_hz) in kept]


def _strongest_candidates(spectra: _Spectra) -> list[float]:
    """Frequencies (Hz) of the :data:`MAX_CANDIDATES` most prominent peaks of either channel."""
    ranked: dict[int, float] = {}
    for power, prominence in zip(spectra.power, spectra.prominence, strict=True):
        for peak in _peaks(power, prominence):
            ranked[int(peak)] = max(ranked.get(int(peak), 0.0), float(prominence[peak]))
    best = sorted(ranked, key=lambda peak: -ranked[peak])[:MAX_CANDIDATES]
    return [float(spectra.freq[peak]) for peak in sorted(best)]


def notch(
    values: NDArray[np.float64], dt: float, frequencies: Sequence[float]
) -> NDArray[np.float64]:
    """``values`` with a zero-phase notch (Q = :data:`NOTCH_Q`) at each of ``frequencies`` (Hz).

    Frequencies at or beyond :data:`NOTCH_LIMIT` of the sample rate are left alone
    (:func:`remove_lines` fits a tone there), as is a signal too short for the filter's edge
    padding.
    """
    fs = 1.0 / dt
    out = np.asarray(values, dtype=np.float64)
    for frequency in frequencies:
        if not 0.0 < frequency < NOTCH_LIMIT * fs:
            continue
        b, a = signal.iirnotch(frequency, NOTCH_Q, fs=fs)
        if out.size <= 3 * max(a.size, b.size):
            continue
        out = signal.filtfilt(b, a, out)
    return out


def remove_lines(
    values: NDArray[np.float64], dt: float, frequencies: Sequence[float]
) -> NDArray[np.float64]:
    """``values`` without the lines at ``frequencies`` (Hz), on one channel.

    Below :data:`NOTCH_LIMIT` of the sample rate a zero-phase notch (:func:`notch`) takes each
    off; at and above it, where a notch has no room, the line's least-squares tone
    (:func:`fitted_tone`) is subtracted: a harmonic aliased onto fs/2 (the fifth of 50 Hz at
    500 Hz) put ml-eiv's τ1 55 % off a 0.5 kHz record of the detailed simulator when left in.
    """
    fs = 1.0 / dt
    out = notch(values, dt, [f for f in frequencies if f < NOTCH_LIMIT * fs])
    return subtract_tones(out, dt, [f for f in frequencies if f >= NOTCH_LIMIT * fs])


def subtract_tones(
    values: NDArray[np.float64], dt: float, frequencies: Sequence[float]
) -> NDArray[np.float64]:
    """``values`` less the least-squares tone (:func:`fitted_tone`) of each of ``frequencies``.

    What a noise measurement needs from a reading with lines: the lines gone and the noise
    floor whole. A notch leaves a hole in the spectrum that a low quantile of it reads as a
    quieter sensor (φ 1.39 instead of 1.01 on a 0.5 kHz record with 50 and 150 Hz notched);
    a tone takes two degrees of freedom.
    """
    out = np.asarray(values, dtype=np.float64)
    for frequency in frequencies:
        if 0.0 < frequency <= 0.5 / dt:
            out = out - fitted_tone(out, dt, frequency)
    return out


def fitted_tone(values: NDArray[np.float64], dt: float, frequency: float) -> NDArray[np.float64]:
    """The least-squares sinusoid of ``values`` at the line nearest ``frequency`` (Hz).

    The line's frequency is searched within a Welch bin (:func:`segment_length`) of
    ``frequency``: at the peak of the Hann-windowed DFT (zero-padded twice, the peak refined by
    a parabola through its log magnitudes); within two Welch bins of fs/2, where the line's
    mirror image bends the DFT's peak, then by maximising the power a real cos/sin pair
    explains (bounded, which reaches fs/2 exactly, where the sine vanishes and the cosine
    alone is fitted). One
    amplitude and phase over the whole series: a stationary line, as the mains is over the
    seconds of a window.

    Returns
    -------
    ndarray, shape like ``values``
        The tone, in the units of ``values``.
    """
    from scipy.optimize import minimize_scalar

    centred = np.asarray(values, dtype=np.float64) - float(np.mean(values))
    n = centred.size
    nyquist = 0.5 / dt
    width = 1.0 / (segment_length(n, dt) * dt)
    # The Hann-windowed DFT, zero-padded twice, and a parabola through the log magnitudes at
    # its peak: within 0.02 of a DFT bin for a line as strong as the noise (one FFT; a zoomed
    # DFT cost 2 s on 3 M samples).
    magnitude = np.abs(np.fft.rfft(centred * signal.get_window("hann", n, fftbins=False), 2 * n))
    step = 1.0 / (2 * n * dt)
    first = max(math.floor((frequency - width) / step), 0)
    last = min(math.ceil((frequency + width) / step), magnitude.size - 1)
    peak = first + int(np.argmax(magnitude[first : last + 1]))
    chosen = peak * step
    if 0 < peak < magnitude.size - 1:
        left, centre, right = np.log(np.maximum(magnitude[peak - 1 : peak + 2], 1e-300))
        curvature = left - 2.0 * centre + right
        chosen += 0.5 * (left - right) / curvature * step if curvature < 0 else 0.0
    samples = np.arange(n) * dt

    def fit(f: float) -> tuple[tuple[NDArray[np.float64], ...], NDArray[np.float64], float]:
        """cos, sin at ``f``, their coefficients and the tone's squared norm.

        The coefficients by the 2 × 2 normal equations; the norm is them times the projections.
        """
        phase = 2.0 * np.pi * f * samples
        waves = (np.cos(phase), np.sin(phase))
        gram = np.array([[float(a @ b) for b in waves] for a in waves])
        rhs = np.array([float(wave @ centred) for wave in waves])
        # At fs/2 the sine is rounding only: the pseudo-inverse fits the cosine alone.
        coefficients = np.linalg.lstsq(gram, rhs, rcond=1e-10)[0]
        return waves, coefficients, float(coefficients @ rhs)

    def power(f: float) -> float:
        return fit(f)[2]

    if nyquist - chosen < 2.0 * width:
        # Near fs/2 the line's mirror image bends the DFT's peak: maximise the real fit.
        bounds = (max(chosen - 2.0 * step, 0.0), min(chosen + 2.0 * step, nyquist))
        best = minimize_scalar(
            lambda f: -power(f), bounds=bounds, method="bounded", options={"xatol": step * 1e-3}
        )
        edge = max(bounds, key=power)
        chosen = float(best.x) if -best.fun >= power(edge) else edge
    (cos, sin), (a, b), _ = fit(chosen)
    return a * cos + b * sin


def line_free_pair(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    lines: Sequence[ForeignLine],
    taus: tuple[float, float],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The readings with each foreign line taken off the channel that carries it.

    Within each line's band (what :func:`notch` removes) the carrying channel keeps what the
    other channel predicts through the sensors' relation, G_c/G_o = (1 + jωτ_o)/(1 + jωτ_c)
    at the line: the gas's own content there stays, and the two readings stay consistent (a
    bare notch on one channel would leave the other's gas content at the line unmatched). The
    prediction is shrunk by the share of the other channel's band power that is not its noise
    (:func:`~tcomp_core.noise.estimate_noise`, white over the band): at a harmonic far above
    the slow sensor's bandwidth the other channel holds only noise, which the prediction would
    scale by |G_c/G_o| into the carrying channel, where a smoother trusts it.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C.
    dt : float
        Sample interval, s.
    lines : sequence of ForeignLine
        From :func:`foreign_lines`.
    taus : (float, float)
        τ1, τ2 of the sensors, s.

    Returns
    -------
    (ndarray, ndarray)
        tc1 and tc2 without the lines, degrees C, shape (N,) each.
    """
    readings = [np.asarray(tc1, dtype=np.float64), np.asarray(tc2, dtype=np.float64)]
    sigmas: dict[int, float] = {}
    for line in lines:
        carrier, other = line.channel - 1, 2 - line.channel
        if line.frequency_hz >= NOTCH_LIMIT / dt:
            # No notch fits here; the sensors pass next to no gas this fast: the tone is
            # the line's.
            readings[carrier] = remove_lines(readings[carrier], dt, [line.frequency_hz])
            continue
        omega = 2.0 * np.pi * line.frequency_hz
        gain = (1.0 + 1j * omega * taus[other]) / (1.0 + 1j * omega * taus[carrier])
        carried = _band(readings[carrier], dt, line.frequency_hz)
        seen = _band(readings[other], dt, line.frequency_hz)
        if other not in sigmas:
            sigmas[other] = estimate_noise(readings[other], dt).sigma
        # Wiener: only the gas's share of what the other channel holds in the band is
        # predicted; its noise, scaled by |G_c/G_o| and then by the inverse lag, was the
        # gas's largest error (a 180 Hz harmonic on a 0.1 s wire at 2 kHz: 64 % full band).
        power = float(np.mean(seen**2))
        noise = sigmas[other] ** 2 * _band_noise_gain(dt, line.frequency_hz)
        weight = max(0.0, 1.0 - noise / power) if power > 0.0 else 0.0
        predicted = weight * np.real(gain * signal.hilbert(seen))
        readings[carrier] = readings[carrier] - (carried - predicted)
    return readings[0], readings[1]


@functools.lru_cache(maxsize=64)
def _band_noise_gain(dt: float, frequency: float) -> float:
    """The share of white noise's variance that :func:`_band` keeps at ``frequency`` (Hz).

    ``_band`` is 1 − |N|² with N the notch that :func:`notch` runs forwards and backwards;
    its power gain averaged over 0 .. fs/2 on a grid fine enough for the notch's width.
    """
    fs = 1.0 / dt
    if not 0.0 < frequency < NOTCH_LIMIT * fs:
        return 0.0
    b, a = signal.iirnotch(frequency, NOTCH_Q, fs=fs)
    points = max(4096, math.ceil(20.0 * 0.5 * fs / (frequency / NOTCH_Q)))
    _, response = signal.freqz(b, a, worN=points, fs=fs)
    kept = 1.0 - np.abs(response) ** 2
    return float(np.mean(kept**2))


def _band(values: NDArray[np.float64], dt: float, frequency: float) -> NDArray[np.float64]:
    """The part of ``values`` a notch at ``frequency`` takes off (zero phase)."""
    return values - notch(values, dt, [frequency])
