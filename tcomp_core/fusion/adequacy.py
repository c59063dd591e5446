"""Whether the first-order model fits a pair of readings, measured without trusting it.

Two sensors identify only the ratio of their transfer functions, and a Kalman filter's std
holds only while its model is right. When the model is wrong for the record as a whole (a delay
between the channels, conduction to the supports), the fitted τ can be far off while the
filter's std, built from the noise alone, stays small: on a 0.5 kHz exhaust record with a delay
of 3.8 samples between the channels, ml-eiv's τ1 came out 3.3 ms (truth 57 ms), the smoother's
gas was 92 % off (50 °C rms) and its median std claimed 1.4 °C.

What the data do show is the disagreement of the two sensors' first-order inversions at the
fitted τ, ``D_k = g1_k - g2_k`` with ``g_i,k = (T_i,k+1 - a_i T_i,k) / (1 - a_i)``: for a right
model it is the two readings' white noise through the inversions, whose spectrum is known from
σ1 and σ2; whatever stands above that spectrum is model error. At least one of the two
inversions is off by half of it, and an effect that acts on both wires moves the gas by a
multiple of it (:data:`~tcomp_core.diagnose.identification.MAX_CHANGE_PER_EVIDENCE`): the
excess is what the gas's std must hold (:func:`first_order_misfit`). It bounds the error of the
inversions, not of a filter that rejects part of it: mains on one channel, amplified by the
inversions, gave an excess of 188 °C where the smoother's gas was 20 °C off (and its std,
already 108 °C, said so). Its mean is left out (two sensors of one class differ in level by a
degree or two: a calibration matter, the same for any τ).

A second check needs no model at all: the ratio of two first-order lags,
``(1 + iωτ1) / (1 + iωτ2)``, has a phase within ±90° at every frequency, whatever τ1 and τ2.
Where the measured ratio of tc2 to tc1 (Welch cross-spectrum) goes beyond that, clearly and
where the two readings are coherent, no first-order pair explains the record; a delay between
the channels is the common cause (:attr:`Misfit.phase_note`; which channel lags is not told: a
phase of -200° reads as +160°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal, stats

__all__ = [
    "COHERENT",
    "EXCESS_QUANTILE",
    "MATERIAL_SHARE",
    "PHASE_POWER_SHARE",
    "PHASE_Z",
    "SIGNAL_COHERENCE",
    "Misfit",
    "first_order_misfit",
    "phase_beyond_lags",
]

#: Upper quantile of the highest of the band's Welch bins of pure noise (χ² with the
#: estimate's degrees of freedom) above which a bin counts as model error.
EXCESS_QUANTILE = 0.999
#: Coherence of the two readings from which a frequency counts as the signal's band: there the
#: gas, not the noise, makes the readings, and the model decides the gas the filter gives.
SIGNAL_COHERENCE = 0.5
#: Coherence of the two readings above which their measured ratio's phase is tested.
COHERENT = 0.9
#: Share of the readings' coherent power a frequency band must carry for its phase to count.
PHASE_POWER_SHARE = 0.02
#: The phase must stand this many standard errors beyond ±90°.
PHASE_Z = 3.0
#: Share of the gas's fluctuation from which the excess disagreement is worth a warning:
#: beyond twice the gain difference IEC 60584 class 2 allows between two sensors (0.75 %).
MATERIAL_SHARE = 0.015
#: Longest and shortest Welch segment, samples (the spectrum resolves 1/(segment · dt) Hz).
MAX_SEGMENT, MIN_SEGMENT = 1 << 16, 32
#: Fewest Welch segments a verdict needs: with fewer the coherence of two unrelated signals is
#: near 1 and the spectra scatter by their own size (a record too short to judge is let be).
MIN_SEGMENTS = 8


@dataclass(frozen=True)
class Misfit:
    """How far a pair of readings departs from the first-order model at given τ.

    Attributes
    ----------
    excess_c : float
        Rms of the sensors' first-order disagreement beyond their noise, degrees C (0 when
        it does not stand above it).
    disagreement_c : float
        Rms of the disagreement, noise included (mean removed), degrees C.
    noise_c : float
        Rms the disagreement would have from the readings' noise alone, degrees C.
    phase_deg : float
        Measured phase of tc2 relative to tc1 where it lies clearly beyond ±90° (at the
        strongest such frequency), degrees (NaN when it nowhere does).
    phase_hz : float
        The frequency of that phase, Hz (NaN when none).
    """

    excess_c: float
    disagreement_c: float
    noise_c: float
    phase_deg: float = math.nan
    phase_hz: float = math.nan

    @property
    def phase_note(self) -> str:
        """Why no first-order pair fits, from the measured phase ('' when it does not say)."""
        if not math.isfinite(self.phase_deg):
            return ""
        return (
            f"the phase of tc2 relative to tc1 is {self.phase_deg:+.0f}° at "
            f"{self.phase_hz:.3g} Hz, beyond the ±90° any two first-order sensors allow: the "
            "channels are not read at the same time (a delay between them) or a sensor is not "
            "first order"
        )

    def material(self, gas_std_c: float) -> bool:
        """Whether the excess is worth a warning for a gas fluctuating by ``gas_std_c`` °C."""
        return math.isfinite(self.phase_deg) or self.excess_c > MATERIAL_SHARE * gas_std_c

    def describe(self, gas_std_c: float) -> str:
        """One sentence for a user: the disagreement, its share of the gas, the phase."""
        share = 100.0 * self.excess_c / gas_std_c if gas_std_c > 0.0 else math.inf
        text = (
            f"the two sensors' first-order reconstructions disagree by {self.excess_c:.3g} °C "
            f"rms beyond their noise ({share:.3g} % of the reconstructed gas's fluctuation): "
            "the first-order model does not describe this pair, and the gas's std includes "
            "that disagreement"
        )
        if self.phase_note:
            text += f"; {self.phase_note}"
        return text


def _segment(size: int) -> int:
    """Welch segment length for ``size`` samples (15 half-overlapping segments, if it can)."""
    return int(min(MAX_SEGMENT, max(MIN_SEGMENT, size // 8), size))


def _segments(size: int, nperseg: int) -> int:
    """Half-overlapping Welch segments of ``nperseg`` samples in ``size`` samples."""
    return max(1, (size - nperseg) // (nperseg - nperseg // 2) + 1)


def _inversion_gain(freqs: NDArray[np.float64], dt: float, tau: float) -> NDArray[np.float64]:
    """|H|² of the one-sample inversion ``(T_k+1 - a T_k) / (1 - a)`` at ``freqs`` (Hz)."""
    a = math.exp(-dt / tau)
    omega = 2.0 * math.pi * freqs * dt
    return (1.0 - 2.0 * a * np.cos(omega) + a * a) / (1.0 - a) ** 2


@dataclass(frozen=True)
class _Spectra:
    """Welch estimates of a pair of readings, on segments of ``nperseg`` samples.

    ``freqs`` (Hz), ``coherence``, ``ratio`` (tc2/tc1) and ``power`` (tc2's coherent power,
    °C²/Hz), shape (M,) each; ``segments`` half-overlapping segments.
    """

    freqs: NDArray[np.float64]
    coherence: NDArray[np.float64]
    ratio: NDArray[np.complex128]
    power: NDArray[np.float64]
    nperseg: int
    segments: int


def _spectra(
    first: NDArray[np.float64], second: NDArray[np.float64], dt: float
) -> _Spectra | None:
    """The readings' Welch estimates (None for a record too short to judge)."""
    nperseg = _segment(first.size)
    segments = _segments(first.size, nperseg)
    if segments < MIN_SEGMENTS:
        return None
    options = {"fs": 1.0 / dt, "nperseg": nperseg, "detrend": "linear"}
    freqs, p11 = signal.welch(first, **options)  # type: ignore[call-overload]
    _, p22 = signal.welch(second, **options)  # type: ignore[call-overload]
    _, p12 = signal.csd(first, second, **options)  # type: ignore[call-overload]
    with np.errstate(divide="ignore", invalid="ignore"):
        coherence = np.abs(p12) ** 2 / (p11 * p22)
        ratio = p12 / p11
    coherence = np.where(np.isfinite(coherence), coherence, 0.0)
    return _Spectra(freqs, coherence, ratio, p22 * coherence, nperseg, segments)


def _excess(
    disagreement: NDArray[np.float64],
    dt: float,
    nperseg: int,
    band: NDArray[np.bool_],
    taus: tuple[float, float],
    sigmas: tuple[float, float],
) -> tuple[float, float]:
    """(excess variance, noise variance) of the disagreement in ``band``, degrees C²."""
    freqs, psd = signal.welch(disagreement, fs=1.0 / dt, nperseg=nperseg, detrend="constant")
    # The inversions' white noise, independent between the sensors: one-sided density.
    noise_density = (
        2.0
        * dt
        * (
            sigmas[0] ** 2 * _inversion_gain(freqs, dt, taus[0])
            + sigmas[1] ** 2 * _inversion_gain(freqs, dt, taus[1])
        )
    )
    dof = 2 * _segments(disagreement.size, nperseg)
    # One bin in a thousand of pure noise stands that high in the whole band (Bonferroni).
    tested = max(1, int(np.count_nonzero(band)))
    quantile = 1.0 - (1.0 - EXCESS_QUANTILE) / tested
    limit = float(stats.chi2.ppf(quantile, dof)) / dof
    df = float(freqs[1] - freqs[0]) if freqs.size > 1 else 0.0
    standing = band[: psd.size] & (psd > limit * noise_density)
    standing[0] = False  # the mean: a calibration matter
    excess = float(np.sum((psd - noise_density)[standing]) * df)
    return max(excess, 0.0), float(np.sum(noise_density[band[: psd.size]]) * df)


def _phase_beyond_lags(spectra: _Spectra) -> tuple[float, float]:
    """(phase in degrees, frequency in Hz) of tc2/tc1 beyond ±90°, or NaNs.

    Of the frequencies where the measured phase lies clearly beyond ±90° and that carry at
    least :data:`PHASE_POWER_SHARE` of tc2's coherent power, the one carrying the most.
    """
    freqs, coherence, ratio, power = (
        spectra.freqs,
        spectra.coherence,
        spectra.ratio,
        spectra.power,
    )
    coherent = coherence > COHERENT
    coherent[0] = False
    total = float(np.sum(power[1:]))
    if total <= 0.0 or not np.any(coherent):
        return math.nan, math.nan
    # Standard error of the phase of a Welch transfer estimate (Bendat & Piersol), radians.
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.sqrt((1.0 - coherence) / (2.0 * spectra.segments * coherence))
    beyond = np.abs(np.degrees(np.angle(ratio))) - 90.0 - PHASE_Z * np.degrees(spread)
    counts = coherent & (beyond > 0.0) & (power >= PHASE_POWER_SHARE * total)
    if not np.any(counts):
        return math.nan, math.nan
    strongest = int(np.argmax(np.where(counts, power, -np.inf)))
    return float(np.degrees(np.angle(ratio[strongest]))), float(freqs[strongest])


def phase_beyond_lags(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float
) -> tuple[float, float]:
    """The measured phase of tc2 relative to tc1 where it lies clearly beyond ±90°.

    Needs no model: no two first-order sensors, whatever their τ, gain or offset, give it.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C, every ``dt`` seconds.
    dt : float
        Sample interval, s.

    Returns
    -------
    phase_deg, freq_hz : float
        The phase (degrees) and its frequency (Hz) at the strongest coherent frequency where
        it lies beyond ±90° by :data:`PHASE_Z` standard errors; NaNs when there is none or the
        record is too short to tell.
    """
    spectra = _spectra(np.asarray(tc1, np.float64), np.asarray(tc2, np.float64), dt)
    return (math.nan, math.nan) if spectra is None else _phase_beyond_lags(spectra)


def first_order_misfit(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
    sigma1: float,
    sigma2: float,
) -> Misfit:
    """The sensors' first-order disagreement beyond their noise, and the ratio's phase.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C, every ``dt`` seconds.
    dt : float
        Sample interval, s.
    tau1, tau2 : float
        The first-order model's time constants, s.
    sigma1, sigma2 : float
        The readings' white-noise standard deviations, degrees C.

    Returns
    -------
    Misfit
        The excess is the disagreement's Welch spectrum summed over the bins that stand above
        the noise's spectrum by more than a pure-noise bin would (:data:`EXCESS_QUANTILE`),
        less that spectrum; the mean (a level offset between the sensors) is left out.
    """
    first = np.asarray(tc1, dtype=np.float64)
    second = np.asarray(tc2, dtype=np.float64)
    spectra = _spectra(first, second, dt)
    if spectra is None:
        return Misfit(excess_c=0.0, disagreement_c=0.0, noise_c=0.0)
    inversions = []
    for reading, tau in ((first, tau1), (second, tau2)):
        a = math.exp(-dt / tau)
        inversions.append((reading[1:] - a * reading[:-1]) / (1.0 - a))
    disagreement = inversions[0] - inversions[1]
    disagreement = disagreement - float(np.mean(disagreement))
    band = spectra.coherence >= SIGNAL_COHERENCE
    excess, noise = _excess(
        disagreement, dt, spectra.nperseg, band, (tau1, tau2), (sigma1, sigma2)
    )
    phase_deg, phase_hz = _phase_beyond_lags(spectra)
    return Misfit(
        excess_c=math.sqrt(excess),
        disagreement_c=float(np.sqrt(np.mean(disagreement**2))),
        noise_c=math.sqrt(noise),
        phase_deg=phase_deg,
        phase_hz=phase_hz,
    )
