"""Measurement noise and signal bandwidth from the spectrum of a sampled signal.

Thermocouples are low-pass sensors: above their bandwidth a reading holds only white
measurement noise, whose one-sided power spectral density is flat at 2 σ² dt. The median of
the Welch spectrum over the top of the band therefore measures σ² without knowing the signal,
and the ratio of two sensors' estimates is the φ = σ1²/σ2² that β-GTLS (Eq. 19) needs.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal, stats

from .models import lag_frequency_response
from .validation import check_sample_interval

__all__ = [
    "NoiseEstimate",
    "estimate_noise",
    "median",
    "model_noise",
    "signal_band_edge",
    "welch_spectra",
]

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


@functools.lru_cache(maxsize=16)
def _hann(length: int) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """``scipy.signal.get_window("hann", length)`` and the bins of its transform that are not 0.

    Read-only, cached (the window cost 40 µs a call). The periodic Hann window's transform is
    N/2 at bin 0 and -N/4 at bin 1 (and rounding beyond): a segment's mean, m, reaches those
    two bins alone, as m times them.
    """
    window = signal.get_window("hann", length)
    spectrum = np.fft.rfft(window)
    spectrum[np.abs(spectrum) < 1e-9 * abs(spectrum[0])] = 0.0
    leading = spectrum[: int(np.flatnonzero(spectrum)[-1]) + 1]
    for array in (window, leading):
        array.flags.writeable = False
    return window, leading


def welch_spectra(
    x: NDArray[np.float64],
    dt: float,
    nperseg: int,
    detrend: str,
    y: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.complex128] | None]:
    """Welch's averaged periodogram of x (and cross-spectrum of x with y), all segments at once.

    The same estimate as :func:`scipy.signal.welch` and :func:`scipy.signal.csd` (Hann window,
    half-overlapping segments of ``nperseg`` samples from the first, ``detrend`` 'constant' or
    'linear' per segment, one-sided densities, units²/Hz; ``test/test_noise_spectra.py``
    compares them), computed on the segments as one array: scipy detrends and transforms
    segment by segment, which made the noise measurement two fifths of the node's estimation
    time at 5 kHz. ``x`` may hold several signals (shape (k, N)); each gets its spectrum and
    its cross-spectrum with the one ``y``, whose transform is computed once.

    Returns
    -------
    freqs : ndarray, shape (nperseg // 2 + 1,)
        Hz.
    psd : ndarray, shape (nperseg // 2 + 1,), or (k, nperseg // 2 + 1) as ``x``
        S_xx.
    cross : ndarray or None
        S_xy = mean(conj(X) Y), shaped as ``psd`` (None without ``y``).
    """
    step = nperseg - nperseg // 2  # scipy's default overlap: nperseg // 2
    count = (x.shape[-1] - nperseg) // step + 1
    window, leading = _hann(nperseg)
    scale = 1.0 / (np.sum(window**2) / dt)  # density: 1 / (fs Σw²)
    ramp = np.arange(nperseg) - 0.5 * (nperseg - 1)

    def transform(values: NDArray[np.float64]) -> NDArray[np.complex128]:
        segments = np.lib.stride_tricks.sliding_window_view(values, nperseg, axis=-1)
        segments = segments[..., ::step, :][..., :count, :]
        if detrend == "linear":
            segments = segments - segments.mean(axis=-1, keepdims=True)
            slopes = segments @ ramp / np.dot(ramp, ramp)
            segments = segments - slopes[..., None] * ramp
            return np.fft.rfft(segments * window, axis=-1)
        # rfft((s - m) w) = rfft(s w) - m rfft(w): the mean comes off the window's two bins,
        # not off every sample of every segment.
        spectra = np.fft.rfft(segments * window, axis=-1)
        spectra[..., : leading.size] -= segments.mean(axis=-1)[..., None] * leading
        return spectra

    spectra_x = transform(x)
    one_sided = np.full(nperseg // 2 + 1, 2.0 * scale)
    one_sided[0] = scale
    if nperseg % 2 == 0:
        one_sided[-1] = scale
    psd = np.mean(spectra_x.real**2 + spectra_x.imag**2, axis=-2) * one_sided
    cross = None
    if y is not None:
        cross = np.mean(np.conj(spectra_x) * transform(y), axis=-2) * one_sided
    freqs = np.asarray(np.fft.rfftfreq(nperseg, dt), dtype=np.float64)
    return freqs, psd, cross


@functools.lru_cache(maxsize=64)
def _chi2_quantile(quantile: float, dof: int) -> float:
    """The ``quantile`` of χ² with ``dof`` degrees of freedom (cached: scipy's costs 0.5 ms)."""
    return float(stats.chi2.ppf(quantile, dof))


def median(values: NDArray[np.float64], overwrite: bool = False) -> float:
    """``np.median`` of a non-empty 1-D array of finite values, to the last bit (one partition).

    numpy partitions at the two middle indices at once, which cost eight times a partition
    at one on the 10 000 samples of a 2 s window at 5 kHz; the lower middle value is the
    largest of those below the upper one. With ``overwrite`` the partition reorders
    ``values`` in place (no copy).
    """
    parted = values if overwrite else values.copy()
    half = parted.size // 2
    parted.partition(half)
    if parted.size % 2:
        return float(parted[half])
    return float((parted[:half].max() + parted[half]) / 2.0)


def low_quantile(values: NDArray[np.float64], quantile: float) -> float:
    """``np.quantile(values, quantile)`` (linear interpolation) of a 1-D array, from a partition.

    The same index, weight and interpolation as numpy's default method, so the same value to
    the last bit, without its general machinery (which cost more than the partition on the
    few hundred bins of a noise band).
    """
    count = values.size
    virtual = (count - 1) * quantile  # numpy's "linear" method
    below = min(max(math.floor(virtual), 0), count - 1)
    above = min(below + 1, count - 1)
    weight = virtual - math.floor(virtual)
    parted = np.partition(values, [below, above] if above != below else below)
    low, high = float(parted[below]), float(parted[above])
    difference = high - low
    return high - difference * (1.0 - weight) if weight >= 0.5 else low + difference * weight


def _welch(values: NDArray[np.float64], dt: float) -> tuple[NDArray, NDArray, int]:
    nperseg = int(min(_SEGMENT, max(16, values.size // 8), values.size))
    freqs, psd, _ = welch_spectra(values, dt, nperseg, "linear")
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
    quantile = low_quantile(psd[band], NOISE_QUANTILE)
    floor = quantile * dof / _chi2_quantile(NOISE_QUANTILE, dof)
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


#: Part of the Nyquist band the model-based noise levels are measured in, split into
#: :data:`MODEL_SUB_BANDS` equal sub-bands.
MODEL_NOISE_BAND = (0.3, 0.95)
MODEL_SUB_BANDS = 6
#: A sub-band's signal leakage is removed only when it stands this many standard errors above 0.
LEAKAGE_Z = 2.0
#: Fast-sensor time constants skipped at the start of the model residual (its filter settles).
_SETTLE_TIME_CONSTANTS = 10.0


def _difference_spectra(
    x: NDArray[np.float64], y: NDArray[np.float64], dt: float
) -> tuple[NDArray, NDArray, NDArray]:
    """Welch auto-spectra of x and cross-spectra of x with y, of their first differences.

    First differences flatten the steep low-frequency spectrum of the readings, which would
    otherwise leak through the window's side lobes into the band; dividing by |1 - e^(-iω)|²
    undoes the difference. ``x`` is one signal (shape (N,)) or several (shape (k, N)), each
    against the one ``y``. Returns (frequencies in Hz, S_xx, S_xy), one-sided, units²/Hz,
    S_xx and S_xy shaped (bins,) or (k, bins) as ``x``.
    """
    step_x, step_y = np.diff(x, axis=-1), np.diff(y)
    nperseg = int(min(_SEGMENT, max(16, step_y.size // 8), step_y.size))
    freqs, auto, cross = welch_spectra(step_x, dt, nperseg, "constant", step_y)
    assert cross is not None
    gain = np.maximum(4.0 * np.sin(np.pi * freqs * dt) ** 2, np.finfo(float).tiny)
    return freqs, auto / gain, cross / gain


def _band_floor(
    auto: NDArray, unbiased: NDArray, freqs: NDArray, edges: NDArray, dof: int
) -> float | None:
    """Noise floor over sub-bands, inverse-variance mean; None when the data cannot tell.

    Per sub-band: where the leakage (plain minus unbiased, bin by bin) is broadband, a sign
    test at :data:`LEAKAGE_Z` standard errors finds more positive bins than noise explains and
    the unbiased cross-spectrum is averaged; otherwise the plain spectrum's low quantile is used
    as in :func:`estimate_noise`, which harmonic lines (leakage in a few bins) do not reach.
    """
    values, variances = [], []
    correction = dof / _chi2_quantile(NOISE_QUANTILE, dof)
    for low, high in itertools.pairwise(edges):
        band = (freqs >= low) & (freqs < high)
        count = int(np.count_nonzero(band))
        if count < 4:
            continue
        # Sign test: without leakage, plain minus unbiased is noise symmetric about zero, so
        # about half the bins are positive; broadband leakage makes nearly all of them so.
        positive = int(np.count_nonzero(auto[band] > unbiased[band]))
        if positive > 0.5 * count + LEAKAGE_Z * 0.5 * np.sqrt(count):
            chosen = unbiased[band]
            values.append(float(np.mean(chosen)))
            variances.append(max(float(np.var(chosen, ddof=1)) / count, 1e-300))
        else:
            level = low_quantile(auto[band], NOISE_QUANTILE) * correction
            values.append(level)
            # a χ² floor known to about 1/√(dof/2 · count) relative
            variances.append(max(level**2 * 2.0 / (dof * count), 1e-300))
    if not values:
        return None
    weights = 1.0 / np.asarray(variances)
    floor = float(np.sum(weights * np.asarray(values)) / np.sum(weights))
    return floor if floor > 0.0 else None


def model_noise(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    tau1: float,
    tau2: float,
) -> tuple[NoiseEstimate, NoiseEstimate]:
    """White-noise levels of both sensors, corrected by the model for the gas signal they share.

    Above the sensors' bandwidth a reading's spectrum is its noise floor plus what is left of
    the gas signal (the leakage); sharp edges (ramps, exhaust pulses) leave much, and a plain
    spectral floor then reads signal as noise on the fast sensor. By the model the gas reaches
    both sensors, y_i = G_i u + n_i, so the residual ε = y_f - (G_f/G_s) y_s of the faster
    sensor f predicted from the slower s holds noise only, ε = n_f - (G_f/G_s) n_s, and

        S(y_f, ε) = σ_f²,    S(y_s, ε) = -σ_s² G_f/G_s,    S(x, y) = E[conj(X) Y],

    whatever the gas does (ε is filtered in time, exactly, by a stable filter with the fast
    sensor's pole). These cross-spectra are unbiased but scatter more than the plain
    auto-spectrum, so each of :data:`MODEL_SUB_BANDS` sub-bands of :data:`MODEL_NOISE_BAND`
    uses them only where the leakage is broadband (plain above unbiased in more of the bins
    than noise explains, by a sign test at :data:`LEAKAGE_Z` standard errors, as behind
    exhaust pulses whose height varies); elsewhere the plain spectrum's low quantile, which
    harmonic lines do not reach (:func:`estimate_noise`). The sub-bands are averaged with
    inverse-variance weights. Where the gas swamps the noise everywhere, the plain spectral
    estimate is returned.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Raw thermocouple readings, degrees C.
    dt : float
        Sample interval, s.
    tau1, tau2 : float
        Time constants of the two sensors, s (e.g. from :func:`tcomp_core.estimate`).

    Returns
    -------
    noise1, noise2 : NoiseEstimate
        Noise of tc1 and of tc2; ``band_hz`` is :data:`MODEL_NOISE_BAND` in Hz.
    """
    dt = check_sample_interval(dt)
    readings = [np.asarray(tc1, dtype=np.float64), np.asarray(tc2, dtype=np.float64)]
    poles = [float(np.exp(-dt / tau1)), float(np.exp(-dt / tau2))]
    fast = 0 if tau1 <= tau2 else 1
    slow = 1 - fast
    a_fast, a_slow = poles[fast], poles[slow]
    # G_f/G_s = (1 - a_f)/(1 - a_s) (1 - a_s z⁻¹)/(1 - a_f z⁻¹), started in steady state.
    numerator = (1.0 - a_fast) / (1.0 - a_slow) * np.array([1.0, -a_slow])
    denominator = np.array([1.0, -a_fast])
    # lfilter_zi's steady state of a first-order section, (b1 - a1 b0) / (1 + a1), without its
    # general solve (40 µs a window).
    steady = (numerator[1] - denominator[1] * numerator[0]) / (1.0 + denominator[1])
    initial = np.array([steady * readings[slow][0]])
    predicted, _ = signal.lfilter(numerator, denominator, readings[slow], zi=initial)
    # The start-up mismatch decays with the fast pole: skip it.
    skip = min(math.ceil(_SETTLE_TIME_CONSTANTS * min(tau1, tau2) / dt), readings[0].size // 4)
    residual = (readings[fast] - predicted)[skip:]
    both = np.stack((readings[fast][skip:], readings[slow][skip:]))
    freqs, autos, crosses = _difference_spectra(both, residual, dt)
    (auto_fast, auto_slow), (cross_fast, cross_slow) = autos, crosses
    segment = int(min(_SEGMENT, max(16, (residual.size - 1) // 8)))
    omega = 2.0 * np.pi * freqs * dt
    ratio = lag_frequency_response(a_fast, omega) / lag_frequency_response(a_slow, omega)
    with np.errstate(divide="ignore", invalid="ignore"):
        unbiased_slow = np.real(-cross_slow / ratio)
    nyquist = 0.5 / dt
    edges = np.linspace(MODEL_NOISE_BAND[0], MODEL_NOISE_BAND[1], MODEL_SUB_BANDS + 1) * nyquist
    if np.count_nonzero((freqs >= edges[0]) & (freqs < edges[-1])) < 2 * MODEL_SUB_BANDS:
        return estimate_noise(readings[0], dt), estimate_noise(readings[1], dt)
    dof = 2 * max(1, (residual.size - 1 - segment) // (segment // 2) + 1)
    found: list[float | None] = [None, None]
    found[fast] = _band_floor(auto_fast, np.real(cross_fast), freqs, edges, dof)
    found[slow] = _band_floor(auto_slow, unbiased_slow, freqs, edges, dof)
    band_hz = (float(edges[0]), float(edges[-1]))
    noises = [
        estimate_noise(reading, dt)  # the data cannot separate noise from gas: the spectrum
        if floor is None
        else NoiseEstimate(sigma=float(np.sqrt(floor / (2.0 * dt))), floor=floor, band_hz=band_hz)
        for reading, floor in zip(readings, found, strict=True)
    ]
    return noises[0], noises[1]
