"""One sensor's chain between the gas temperature and its reading, both ways.

The base stage is the exact zero-order-hold first-order lag (Eq. 4),

    T[k+1] = a_k T[k] + (1 - a_k) u[k],    a_k = exp(-dt / τ_k),

whose inverse gives the gas temperature u[k] held over [t_k, t_k+1) from two readings. The
effects wrap it (see :mod:`tcomp_core.effects.base`):

* calibration: the sensor reads ``gain T + offset``;
* conduction: G = F⁻¹ L with F(s) = (1 + τp s)/(1 + κ + τp s) (bilinear) and L a first-order lag
  of time constant τ/(1 + κ) and DC gain 1/(1 + κ);
* velocity: τ_k = τ s(t_k);
* radiation: the lag is driven by u − r (T⁴ − T_w⁴), the loss taken at T[k] so that the forward
  recurrence stays explicit and is the exact inverse of the backward one;
* delay: the sensor sees u(t − δ); a windowed-sinc interpolator shifts its readings by
  fractions of a sample (equivalent by time invariance, and the readings are smoother).

The inverse and the forward direction are exact inverses of each other in discrete time (up to
the interpolation of a delay), so a model simulated forward and inverted again returns its input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from .base import KELVIN

__all__ = [
    "SensorChain",
    "bilinear_first_order",
    "fractional_shift",
    "gas_from_reading",
    "reading_from_gas",
]

#: Numerator and denominator ``(b, a)`` of a digital filter, as :func:`scipy.signal.lfilter` takes.
FilterCoefficients = tuple[NDArray[np.float64], NDArray[np.float64]]


@dataclass(frozen=True, kw_only=True)
class SensorChain:
    """The resolved parameters of one sensor.

    Attributes
    ----------
    tau : float
        Convective time constant, s.
    gain, offset : float
        The sensor reads ``gain * T + offset`` (degrees C).
    kappa, tau_p : float
        Conduction ratio and slow-mode time constant (s); ``kappa = 0`` means none.
    mode0 : float
        Excess of the slow mode at sample 0 over its equilibrium with the first reading,
        degrees C: a record that does not start at rest starts with the mode charged.
    factor : ndarray, shape (N,), or None
        Per-sample factor on τ (velocity), or None for a constant τ.
    level_exponent, level_ref_k : float
        τ scales as (T/T_ref)^level_exponent with the film temperature T in kelvin, halfway
        between the junction and the gas (gas properties); 0 means none.
    film_sos : ndarray or None
        Zero-phase low-pass (second-order sections) applied to the gas before it sets the film
        temperature: the gas reconstructed from readings carries their noise amplified, and
        noise in the pole biases the fit of the exponent towards 0 (errors in variables).
    additive : ndarray, shape (N,), or None
        A signal added to the readings after everything else (interference), degrees C.
    r, wall_k : float
        Radiation coefficient (K⁻³) and wall temperature (K); ``r = 0`` means none.
    delay_s : float
        How much later than the common time base the sensor sees the gas, s.
    """

    tau: float
    gain: float = 1.0
    offset: float = 0.0
    kappa: float = 0.0
    tau_p: float = 1.0
    mode0: float = 0.0
    factor: NDArray[np.float64] | None = None
    r: float = 0.0
    wall_k: float = 0.0
    delay_s: float = 0.0
    level_exponent: float = 0.0
    level_ref_k: float = 1.0
    film_sos: NDArray[np.float64] | None = None
    additive: NDArray[np.float64] | None = None

    def poles(
        self, n: int, dt: float, kelvin: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Discrete pole of every interval, shape (n - 1,).

        ``kelvin`` (shape (n - 1,)), the film temperature of each interval in K, is needed
        when τ depends on the level (``level_exponent``).
        """
        tau = self.tau / (1.0 + self.kappa)
        scale = np.ones(n - 1) if self.factor is None else self.factor[:-1]
        if self.level_exponent:
            if kelvin is None:
                raise ValueError("a level-dependent tau needs the sensor's temperature")
            # The film temperature comes from a noisy gas estimate: held within a factor 2 of
            # the mean level (in kelvin), where no real record's film strays.
            ratio = np.clip(kelvin / self.level_ref_k, 0.5, 2.0)
            scale = scale * ratio**self.level_exponent
        return np.exp(-dt / (tau * scale))

    def support_filters(self, dt: float) -> tuple[FilterCoefficients, FilterCoefficients] | None:
        """Bilinear ``(b, a)`` of F and of F⁻¹ (conduction), or None."""
        if self.kappa == 0.0:
            return None
        fs = 1.0 / dt
        forward = bilinear_first_order((self.tau_p, 1.0), (self.tau_p, 1.0 + self.kappa), fs)
        inverse = bilinear_first_order((self.tau_p, 1.0 + self.kappa), (self.tau_p, 1.0), fs)
        return forward, inverse


def bilinear_first_order(
    numerator: tuple[float, float], denominator: tuple[float, float], fs: float
) -> FilterCoefficients:
    """Bilinear transform of ``(n0 s + n1) / (d0 s + d1)``, as :func:`scipy.signal.bilinear`.

    With s = 2 fs (1 - z⁻¹)/(1 + z⁻¹) both polynomials become ``(2 fs c0 + c1) + (c1 - 2 fs c0)
    z⁻¹``; normalised by the denominator's first coefficient. Closed form because the diagnosis
    builds these filters for every candidate parameter set, and scipy's general routine (through
    numpy.polynomial objects) took two thirds of a diagnosis's time.

    Returns
    -------
    b, a : ndarray, shape (2,)
    """
    k = 2.0 * fs
    b = np.array([k * numerator[0] + numerator[1], numerator[1] - k * numerator[0]])
    a = np.array([k * denominator[0] + denominator[1], denominator[1] - k * denominator[0]])
    return b / a[0], a / a[0]


def _steady_filter(
    b: NDArray[np.float64],
    a: NDArray[np.float64],
    values: NDArray[np.float64],
    excess: float = 0.0,
) -> NDArray[np.float64]:
    """``lfilter`` of a first-order section started in its first input's steady state.

    ``a[0]`` must be 1. The output starts ``excess`` off that steady state: the state is the
    output's offset, so ``excess`` is added to the first output and then decays with the
    filter's pole. The steady state is :func:`scipy.signal.lfilter_zi`'s,
    (b1 − a1 b0)/(1 + a1), in closed form (the diagnosis calls this for every candidate).
    """
    zi = (b[1] - a[1] * b[0]) / (1.0 + a[1]) * values[0] + excess
    return signal.lfilter(b, a, values, zi=np.array([zi]))[0]


#: Half length of the fractional-delay interpolator (taps: 2 × this).
SHIFT_HALF_TAPS = 16
#: Kaiser window shape of that interpolator: error below ~1e-4 up to 0.35 × the sample rate.
_SHIFT_KAISER_BETA = 8.0


def shift_weights(fraction: float) -> NDArray[np.float64]:
    """Kaiser-windowed sinc weights reading a series ``fraction`` (0 ≤ f < 1) of a sample later.

    The weights apply to the samples at offsets ``-SHIFT_HALF_TAPS + 1 .. SHIFT_HALF_TAPS``
    and sum to 1, so a constant passes unchanged.
    """
    if fraction < 1e-12:
        weights = np.zeros(2 * SHIFT_HALF_TAPS)
        weights[SHIFT_HALF_TAPS - 1] = 1.0
        return weights
    offsets = np.arange(-SHIFT_HALF_TAPS + 1, SHIFT_HALF_TAPS + 1) - fraction
    # The Kaiser window evaluated at the fractional offsets.
    position = offsets / (SHIFT_HALF_TAPS + 0.5)
    taper = np.i0(_SHIFT_KAISER_BETA * np.sqrt(np.clip(1.0 - position**2, 0.0, 1.0)))
    weights = np.sinc(offsets) * taper / np.i0(_SHIFT_KAISER_BETA)
    return weights / weights.sum()


def fractional_shift(values: NDArray[np.float64], shift: float) -> tuple[NDArray, NDArray]:
    """Evaluate a sampled series at index ``k + shift`` (band-limited interpolation).

    Parameters
    ----------
    values : ndarray, shape (M,)
    shift : float
        Shift in samples; positive reads later samples.

    Returns
    -------
    shifted : ndarray, shape (M,)
        NaN where the interpolator's stencil leaves the record.
    weights : ndarray, shape (2 * SHIFT_HALF_TAPS,)
        The interpolation weights.
    """
    whole = math.floor(shift)
    weights = shift_weights(shift - whole)
    m = values.size
    shifted = np.full(m, np.nan)
    # Output k uses values[k + whole + j] for j = -SHIFT_HALF_TAPS + 1 .. SHIFT_HALF_TAPS.
    first_offset = whole - SHIFT_HALF_TAPS + 1
    lo = max(0, -first_offset)
    hi = min(m, m - (whole + SHIFT_HALF_TAPS))
    if hi > lo:
        # correlate's output i is sum_j w_j values[i + j]: output k is its i = k + first_offset.
        stencil = np.correlate(values, weights, mode="valid")
        shifted[lo:hi] = stencil[lo + first_offset : hi + first_offset]
    return shifted, weights


def _fill_edges(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Replace NaN at the ends by the nearest finite value."""
    finite = np.flatnonzero(np.isfinite(values))
    if finite.size == values.size or finite.size == 0:
        return values
    out = values.copy()
    out[: finite[0]] = values[finite[0]]
    out[finite[-1] + 1 :] = values[finite[-1]]
    return out


def gas_from_reading(
    chain: SensorChain,
    reading: NDArray[np.float64],
    dt: float,
    noise_kernel: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gas temperature on the common time base from one sensor's readings.

    Parameters
    ----------
    chain : SensorChain
    reading : ndarray, shape (N,)
        The sensor's readings, degrees C.
    dt : float
        Sample interval, s.
    noise_kernel : ndarray, optional
        Impulse response of a low-pass the readings went through (their white noise with it).

    Returns
    -------
    gas : ndarray, shape (N - 1,)
        Gas temperature held over [t_k, t_k+1), degrees C; NaN where a delay shifts it out of
        the record.
    noise_gain : ndarray, shape (N - 1,)
        Variance of ``gas`` per unit variance of white noise on the readings.
    """
    weights = np.array([1.0])
    edges = None
    if chain.additive is not None:
        reading = reading - chain.additive
    if chain.delay_s:
        # The chain is time-invariant, so advancing the reading advances the gas; the reading
        # is smooth (low-passed by the sensor), so it interpolates far better than the gas.
        reading, weights = fractional_shift(reading, chain.delay_s / dt)
        edges = ~np.isfinite(reading)
        reading = _fill_edges(reading)
    true = (reading - chain.offset) / chain.gain
    filters = chain.support_filters(dt)
    lagged = true if filters is None else _steady_filter(*filters[0], true, chain.mode0)
    scale = 1.0 + chain.kappa
    junction_k = scale * lagged[:-1] + KELVIN
    # A constant pole stays a scalar: the arithmetic below and the noise gain are then cheap.
    a: NDArray[np.float64] | float = (
        replace(chain, level_exponent=0.0).poles(reading.size, dt)
        if chain.factor is not None
        else math.exp(-dt * (1.0 + chain.kappa) / chain.tau)
    )
    gas, tap = _invert_lag(chain, lagged, a, junction_k)
    for _ in range(LEVEL_ITERATIONS if chain.level_exponent else 0):
        # τ follows the film temperature, halfway between the junction and the gas: the
        # implicit inverse by fixed-point steps from the constant-τ gas.
        a = chain.poles(reading.size, dt, 0.5 * (junction_k + _film_gas(chain, gas) + KELVIN))
        gas, tap = _invert_lag(chain, lagged, a, junction_k)
    if edges is not None:
        gas[edges[1:] | edges[:-1]] = np.nan
    # The noise of u[k] is (scale/gain)/(1 - a) (n[k+1] - c n[k]), c = a less the radiation
    # term's slope; an interpolator with weights w (and a low-pass before it) turns the taps
    # into w ⊛ (-c, 1), whose energy is (1 + c²) Σw² - 2c Σ w_j w_(j+1).
    if noise_kernel is not None:
        weights = np.convolve(weights, noise_kernel)
    energy = (1.0 + tap**2) * np.sum(weights**2) - 2.0 * tap * np.sum(weights[:-1] * weights[1:])
    noise_gain = (scale / chain.gain) ** 2 * energy / (1.0 - a) ** 2
    return gas, np.broadcast_to(noise_gain, gas.shape)


def _film_gas(chain: SensorChain, gas: NDArray[np.float64]) -> NDArray[np.float64]:
    """The gas temperature that sets the film temperature: low-passed when the chain says so."""
    if chain.film_sos is None or gas.size <= 3 * 2 * chain.film_sos.shape[0] + 1:
        return gas
    return signal.sosfiltfilt(chain.film_sos, gas)


#: Fixed-point steps of the inverse with a level-dependent τ: each gains the factor p Δτ/τ
#: (≲ 0.1), so three leave ~1e-3 of the τ change's own effect.
LEVEL_ITERATIONS = 3


def _invert_lag(
    chain: SensorChain,
    lagged: NDArray[np.float64],
    a: NDArray[np.float64] | float,
    junction_k: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
    """Gas held over each interval from the lagged temperature, and the noise tap c."""
    scale = 1.0 + chain.kappa
    gas = (lagged[1:] - a * lagged[:-1]) * (scale / (1.0 - a))
    tap = a  # the weight of -n[k] in u[k], relative to that of n[k+1]
    if chain.r:
        cube = junction_k * junction_k * junction_k  # products: ** 3 and ** 4 go through pow
        gas = gas + chain.r * (cube * junction_k - chain.wall_k**4)
        tap = a - (4.0 * chain.r * (1.0 - a) / scale) * cube
    return gas, tap


def reading_from_gas(
    chain: SensorChain, gas: NDArray[np.float64], dt: float, initial_reading: float
) -> NDArray[np.float64]:
    """Simulate one sensor's readings from the gas temperature (the forward chain).

    Parameters
    ----------
    chain : SensorChain
    gas : ndarray, shape (N - 1,)
        Gas temperature on the common time base, held over each interval, degrees C. NaN at
        the ends are replaced by the nearest finite value.
    dt : float
        Sample interval, s.
    initial_reading : float
        The reading at sample 0 (the sensor starts in equilibrium with it), degrees C.

    Returns
    -------
    ndarray, shape (N,)
        Simulated readings, degrees C.
    """
    seen = _fill_edges(gas)
    n = seen.size + 1
    scale = 1.0 + chain.kappa
    start = (initial_reading - chain.offset) / chain.gain / scale + chain.mode0
    drive = seen / scale
    if chain.level_exponent:
        # τ follows the sensor's own temperature: the pole of each step from the state.
        base = replace(chain, level_exponent=0.0).poles(n, dt)
        level = (chain.level_exponent, chain.level_ref_k, _film_gas(chain, seen) / scale)
        lagged = _lag_loop(drive, base, start, chain.r / scale, scale, chain.wall_k**4, level)
    elif chain.r == 0.0 and chain.factor is None:
        a = math.exp(-dt * (1.0 + chain.kappa) / chain.tau)
        lagged = np.concatenate(
            ([start], signal.lfilter([1.0 - a], [1.0, -a], drive, zi=[a * start])[0])
        )
    else:
        a_k = chain.poles(n, dt)
        lagged = _lag_loop(drive, a_k, start, chain.r / scale, scale, chain.wall_k**4)
    filters = chain.support_filters(dt)
    # F⁻¹ must return the initial reading from the charged mode: its output starts scale·mode0
    # below the steady state of lagged[0].
    true = lagged if filters is None else _steady_filter(*filters[1], lagged, -scale * chain.mode0)
    reading = chain.gain * true + chain.offset
    if chain.delay_s:
        reading = _fill_edges(fractional_shift(reading, -chain.delay_s / dt)[0])
    if chain.additive is not None:
        reading = reading + chain.additive
    return reading


def _lag_loop(
    drive: NDArray[np.float64],
    a: NDArray[np.float64],
    start: float,
    r_scaled: float,
    scale: float,
    wall4: float,
    level: tuple[float, float, NDArray[np.float64]] | None = None,
) -> NDArray[np.float64]:
    """Explicit recurrence y[k+1] = a y[k] + (1 - a)(u[k] - r' ((s y[k] + K)^4 - T_w^4)).

    With ``level = (exponent, T_ref, film_drive)`` the pole of step k is
    a_k^(1/(T/T_ref)^exponent) at the film temperature T, halfway between the state's
    s y[k] + K and the gas s film_drive[k] + K (τ varying with the level), ``a`` then holding
    the poles without that factor.
    """
    out = [start]
    y = start
    films = (drive if level is None else level[2]).tolist()
    for u, pole, film_u in zip(drive.tolist(), a.tolist(), films, strict=True):
        kelvin = scale * y + KELVIN
        if level is not None:  # τ at the film temperature, halfway to the gas
            film = 0.5 * (kelvin + scale * film_u) + 0.5 * KELVIN
            ratio = min(max(film / level[1], 0.5), 2.0)  # as in SensorChain.poles
            pole = pole ** (1.0 / ratio ** level[0])
        loss = r_scaled * (kelvin**4 - wall4) if r_scaled else 0.0
        y = pole * y + (1.0 - pole) * (u - loss)
        out.append(y)
    return np.asarray(out)
