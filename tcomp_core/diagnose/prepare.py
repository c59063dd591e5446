"""Data for the diagnosis: working rate, noise levels, held-out blocks.

Records sampled far faster than the thermocouples respond (a 5 kHz rig for a 10 Hz signal) are
decimated first: the difference equation then sees a usable change per sample, and the
anti-alias filter leaves white noise white (its variance divided by the factor). The noise of
each sensor is measured on the raw record, from the model with the default estimator's τ
(:func:`tcomp_core.noise.model_noise`: the spectra less the gas signal both sensors share), or
from the spectra alone when no τ can be estimated. The record is cut into
equal blocks; even blocks estimate, odd blocks validate, so slowly varying effects are seen on
both sides of every held-out block.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, NoExcitationError, TcompError
from ..estimators import estimate
from ..filters import decimate
from ..fusion.adequacy import phase_beyond_lags
from ..io import Record
from ..noise import NoiseEstimate, estimate_noise, model_noise, signal_band_edge
from ..validation import check_excitation, check_shared_signal
from .quantisation import Quantisation, detect_quantisation, in_band_variance

__all__ = ["PreparedData", "block_length_s", "prepare"]

#: The working rate is at least this many samples per second ...
MIN_WORKING_RATE_HZ = 500.0
#: ... and at least this many times the highest frequency the signals carry (Nyquist 2.5 times
#: above it: the difference equation needs a visible change per sample, see Sec. IV B).
RATE_PER_BANDWIDTH = 5.0
#: Blocks per record (before the limits of :func:`block_length_s`).
TARGET_BLOCKS = 20
#: Fewest samples of a usable record at the working rate.
MIN_WORKING_SAMPLES = 400


@dataclass(frozen=True, kw_only=True)
class PreparedData:
    """A record ready for fitting and validation.

    Attributes
    ----------
    source : str
        Where the data came from.
    time : ndarray, shape (N,)
        Times at the working rate, s from 0.
    tc1, tc2 : ndarray, shape (N,)
        Readings at the working rate, degrees C.
    ref : ndarray, shape (N,) or None
        Reference at the working rate, degrees C.
    dt : float
        Working sample interval, s.
    decimation : int
        Raw samples per working sample.
    noise1, noise2 : NoiseEstimate
        Noise of each sensor on the raw record.
    noise_source : {'model', 'spectra'}
        Where the noise levels came from (:func:`_raw_noise`).
    band_edge_hz : tuple of float
        Highest frequency each sensor carries above its noise, Hz (raw record).
    validation : ndarray of bool, shape (N,)
        True on held-out samples.
    block_starts : ndarray of int, shape (B + 1,)
        Sample index where each block starts, then N.
    quantisation : tuple of (Quantisation or None)
        The ADC grid each raw reading lies on (:mod:`.quantisation`), or None.
    """

    source: str
    time: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    ref: NDArray[np.float64] | None
    dt: float
    decimation: int
    noise1: NoiseEstimate
    noise2: NoiseEstimate
    band_edge_hz: tuple[float, float]
    validation: NDArray[np.bool_]
    block_starts: NDArray[np.intp]
    noise_source: str = "spectra"
    quantisation: tuple[Quantisation | None, Quantisation | None] = (None, None)

    @functools.cached_property
    def channel_phase_deg(self) -> float:
        """Phase of tc2 against tc1 beyond the ±90° of any two first-order lags, degrees.

        NaN when it lies within (:func:`~tcomp_core.fusion.adequacy.phase_beyond_lags`):
        measured, not fitted, the mark of a delay between the channels.
        """
        return phase_beyond_lags(self.tc1, self.tc2, self.dt)[0]

    @property
    def phi_hat(self) -> float:
        """Noise variance ratio σ1²/σ2², in-band quantisation counted (:meth:`in_band_noise`)."""
        variances = [
            self.noise1.sigma**2 + self.in_band_noise(1),
            self.noise2.sigma**2 + self.in_band_noise(2),
        ]
        return float(np.clip(variances[0] / variances[1], 1e-3, 1e3))

    def in_band_noise(self, sensor: int) -> float:
        """Variance of sensor's rounding error that lies in the signal's band, degC²."""
        return in_band_variance(self.quantisation[sensor - 1])

    @property
    def training_rows(self) -> NDArray[np.bool_]:
        """Intervals (k, k+1) whose both ends are estimation samples, shape (N - 1,)."""
        estimation = ~self.validation
        return estimation[:-1] & estimation[1:]

    def blocks(self, held_out: bool) -> list[slice]:
        """The validation (``held_out``) or estimation blocks as slices."""
        starts = self.block_starts
        return [
            slice(int(starts[b]), int(starts[b + 1]))
            for b in range(starts.size - 1)
            if bool(b % 2) == held_out
        ]


def block_length_s(duration_s: float, dt: float) -> float:
    """Length of the held-out blocks: a twentieth of the record, within 0.25–2 s, ≥ 50 samples."""
    length = min(max(duration_s / TARGET_BLOCKS, 0.25), 2.0)
    length = max(length, 50.0 * dt)
    return min(length, duration_s / 4.0)


def _decimation_factor(dt: float, band_edge_hz: float) -> int:
    rate = max(MIN_WORKING_RATE_HZ, RATE_PER_BANDWIDTH * band_edge_hz)
    return max(1, math.floor(1.0 / (dt * rate)))


def _raw_noise(record: Record) -> tuple[NoiseEstimate, NoiseEstimate, str]:
    """Noise of each sensor on the raw record and its source: the model, else the spectra."""
    try:
        found = estimate(record.tc1, record.tc2, record.dt)
    except TcompError:
        spectral = estimate_noise(record.tc1, record.dt), estimate_noise(record.tc2, record.dt)
        return *spectral, "spectra"
    return *model_noise(record.tc1, record.tc2, record.dt, found.tau1, found.tau2), "model"


def prepare(record: Record) -> PreparedData:
    """Decimate, measure the noise and cut the held-out blocks of a record.

    Raises
    ------
    DataError
        If the record is too short to hold estimation and validation blocks.
    NoExcitationError
        If a signal is constant, or the two share no signal (noise alone, or sensors in
        different gases: the default path refuses them too, and a fit of any model to them
        finds only what the noise happens to correlate over).
    """
    if record.tc1.size < MIN_WORKING_SAMPLES:  # before decimation too: nothing to measure
        raise DataError(
            f"{record.source}: {record.tc1.size} samples are too few to diagnose; need at "
            f"least {MIN_WORKING_SAMPLES}"
        )
    try:
        check_excitation(record.tc1, record.tc2)
        check_shared_signal(record.tc1, record.tc2, record.dt)
    except NoExcitationError as exc:
        raise NoExcitationError(f"{record.source}: {exc}") from exc
    noise1, noise2, noise_source = _raw_noise(record)
    edges = (
        signal_band_edge(record.tc1, record.dt, noise1.floor),
        signal_band_edge(record.tc2, record.dt, noise2.floor),
    )
    factor = _decimation_factor(record.dt, max(edges))
    arrays = [record.tc1, record.tc2] + ([record.ref] if record.ref is not None else [])
    if factor > 1:
        arrays = [decimate(values, factor) for values in arrays]
    dt = record.dt * factor
    n = arrays[0].size
    if n < MIN_WORKING_SAMPLES:
        raise DataError(
            f"{record.source}: {n} samples at {1 / dt:.6g} Hz are too few to diagnose; "
            f"need at least {MIN_WORKING_SAMPLES}"
        )
    time = np.arange(n, dtype=np.float64) * dt
    length = block_length_s(n * dt, dt)
    starts = np.arange(0, n, max(1, round(length / dt)))
    if n - starts[-1] < 0.5 * length / dt:
        starts = starts[:-1]  # merge a short tail into the last block
    starts = np.append(starts, n)
    validation = np.zeros(n, dtype=bool)
    for b in range(1, starts.size - 1, 2):
        validation[starts[b] : starts[b + 1]] = True
    return PreparedData(
        source=record.source,
        time=time,
        tc1=arrays[0],
        tc2=arrays[1],
        ref=arrays[2] if len(arrays) > 2 else None,
        dt=dt,
        decimation=factor,
        noise1=noise1,
        noise2=noise2,
        noise_source=noise_source,
        band_edge_hz=edges,
        validation=validation,
        block_starts=starts,
        quantisation=(detect_quantisation(record.tc1), detect_quantisation(record.tc2)),
    )
