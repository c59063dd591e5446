"""One sensor's chain between the gas temperature and its reading, both ways.

The base stage is the exact zero-order-hold first-order lag (Eq. 4),

    T[k+1] = a_k T[k] + (1 - a_k) u[k],    a_k = exp(-dt / τ_k),

whose inverse gives the gas temperature u[k] held over [t_k, t_k+1) from two readings. The
effects wrap it (see :mod:`tcomp_core.effects.base`):

* calibration: the sensor reads ``gain T + offset``;
* conduction: G = M L with L the first-order lag and M the legs' fin filter
  (:mod:`tcomp_core.effects.conduction`; bilinear, second-order sections), plus
  the supports' initial excess ``mode0`` e^(−t/τp) on the reading;
* velocity: τ_k = τ s(t_k);
* radiation: the lag is driven by u − r (T⁴ − T_w⁴), the loss taken at T[k] so that the forward
  recurrence stays explicit and is the exact inverse of the backward one;
* delay: the sensor sees u(t − δ); a windowed-sinc interpolator shifts its readings by
  fractions of a sample (equivalent by time invariance, and the readings are smoother).

The inverse and the forward direction are exact inverses of each other in discrete time (up to
the interpolation of a delay), so a model simulated forward and inverted again returns its input.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import signal, special

from ..sections import sosfilt_from, zero_phase
from .base import KELVIN
from .conduction import fin_filter
from .recurrence import lag_steps, level_lag_steps

__all__ = [
    "SensorChain",
    "first_order_reading",
    "fractional_shift",
    "gas_from_reading",
    "reading_from_gas",
]


@dataclass(frozen=True, kw_only=True)
class SensorChain:
    """The resolved parameters of one sensor.

    Attributes
    ----------
    tau : float
        Convective time constant, s.
    gain, offset : float
        The sensor reads ``gain * T + offset`` (degrees C).
    fin_ml, tau_p : float
        mL of the legs (fin theory) and time constant of the supports' lag (s); an infinite
        ``fin_ml`` (legs without end) means no conduction.
    mode0 : float
        The supports' excess over their equilibrium at sample 0 as the reading sees it,
        degrees C, decaying with τp: a record that does not start at rest starts with it.
    factor : ndarray, shape (N,), or None
        Per-sample factor on τ (velocity), or None for a constant τ.
    level_exponent, level_ref_k : float
        τ scales as (T/T_ref)^level_exponent with the film temperature T in kelvin, halfway
        between the junction and the gas (gas properties); 0 means none.
    level_weight, film_weight : float
        How that temperature is made: T = T_ref + a (Tj − T_ref) + w (Tg − Tj) with a the
        level weight and w the film weight. a = 1, w = 0.5 is the film (the gas properties at
        the film temperature), a = 1, w = 0 the junction's own temperature (its heat
        capacity), a = 0, w = 0.5 the film's departure from the level alone (how far the
        junction lags the gas: the temperature loading of the heat transfer).
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
    fin_ml: float = math.inf
    tau_p: float = 1.0
    mode0: float = 0.0
    factor: NDArray[np.float64] | None = None
    r: float = 0.0
    wall_k: float = 0.0
    delay_s: float = 0.0
    level_exponent: float = 0.0
    level_ref_k: float = 1.0
    level_weight: float = 1.0
    film_weight: float = 0.5
    film_sos: NDArray[np.float64] | None = None
    additive: NDArray[np.float64] | None = None

    def poles(
        self, n: int, dt: float, kelvin: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Discrete pole of every interval, shape (n - 1,).

        ``kelvin`` (shape (n - 1,)), the film temperature of each interval in K, is needed
        when τ depends on the level (``level_exponent``).
        """
        tau = self.tau
        scale = np.ones(n - 1) if self.factor is None else self.factor[:-1]
        if self.level_exponent:
            if kelvin is None:
                raise ValueError("a level-dependent tau needs the sensor's temperature")
            # The film temperature comes from a noisy gas estimate: held within a factor 2 of
            # the mean level (in kelvin), where no real record's film strays.
            ratio = np.clip(kelvin / self.level_ref_k, 0.5, 2.0)
            scale = scale * ratio**self.level_exponent
        return np.exp(-dt / (tau * scale))

    def support_filters(self, dt: float) -> tuple[CascadeFilter, CascadeFilter] | None:
        """The fin filter M and its inverse (conduction), or None."""
        if not math.isfinite(self.fin_ml):
            return None
        return _fin_filters(self.tau, self.fin_ml, self.tau_p, dt)

    def support_forward(self, dt: float) -> CascadeFilter | None:
        """The fin filter M alone (what a simulated reading needs), or None."""
        if not math.isfinite(self.fin_ml):
            return None
        return _fin_forward(self.tau, self.fin_ml, self.tau_p, dt)

    def support_inverse(self, dt: float) -> CascadeFilter | None:
        """The fin filter's inverse M⁻¹ alone (what the gas needs), or None."""
        if not math.isfinite(self.fin_ml):
            return None
        return _fin_inverse(self.tau, self.fin_ml, self.tau_p, dt)

    def support_transient(self, n: int, dt: float) -> NDArray[np.float64] | None:
        """The supports' initial excess on the reading, shape (n,), degrees C, or None."""
        if not math.isfinite(self.fin_ml) or self.mode0 == 0.0:
            return None
        return self.mode0 * _decay(n, dt, self.tau_p)


@functools.lru_cache(maxsize=4)
def _decay(n: int, dt: float, tau_p: float) -> NDArray[np.float64]:
    """e^(−k dt/τp) for k = 0 .. n − 1, shape (n,).

    Cached (read-only): a fit's Jacobian moves mode0 at a few τp; a few records' worth of
    memory at most.
    """
    decay = np.exp(-(dt / tau_p) * np.arange(n))
    decay.flags.writeable = False
    return decay


@dataclass(frozen=True)
class CascadeFilter:
    """A unity-DC-gain filter as second-order sections, applied from a steady start.

    Built from continuous zeros and poles by the bilinear transform s = k (z − 1)/(z + 1),
    k = 2/dt: z = (k + s)/(k − s), scaled to unity gain at DC. Conjugate pairs make one
    quadratic, real roots are paired in order of size, and the zero and pole quadratics are
    each ordered by their largest root and matched in that order, so the slow zeros share a
    section with the slow poles they nearly cancel. (scipy's ``zpk2sos`` took most of a fit's
    time; a fit builds these filters for every parameter it moves.)
    """

    sos: NDArray[np.float64]

    @classmethod
    def from_zeros_poles(
        cls, zeros: NDArray[np.complex128], poles: NDArray[np.complex128], dt: float
    ) -> CascadeFilter:
        k = 2.0 / dt
        return cls.from_quadratics(
            _quadratics((k + zeros) / (k - zeros)), _quadratics((k + poles) / (k - poles))
        )

    @classmethod
    def from_quadratics(
        cls, numerators: NDArray[np.float64], denominators: NDArray[np.float64]
    ) -> CascadeFilter:
        """The sections of matched numerator and denominator quadratics (shape (S, 3) each).

        Scaled to unity gain at DC, in Python floats: the sums and the product in numpy's
        order, so the sections are those of the array expressions to the bit.
        """
        rows = [
            [*top, *bottom]
            for top, bottom in zip(
                np.asarray(numerators).tolist(), np.asarray(denominators).tolist(), strict=True
            )
        ]
        gain = 1.0  # Π (b0 + b1 + b2)/(1 + a1 + a2), the cascade's gain at DC
        for row in rows:
            gain *= (row[0] + row[1] + row[2]) / (row[3] + row[4] + row[5])
        rows[0][:3] = [value / gain for value in rows[0][:3]]
        return cls(sos=np.array(rows))

    @functools.cached_property
    def _rows(self) -> tuple[tuple[float, ...], ...]:
        """The sections as Python floats (the steady state is a short scalar loop)."""
        return tuple(tuple(row) for row in self.sos.tolist())

    def steady_state(self, value: float) -> NDArray[np.float64]:
        """The sections' state (``sosfilt``'s ``zi``, shape (S, 2)) at rest at ``value``."""
        # Steady state of each direct-form-II-transposed section for a constant input x:
        # y = x (b0 + b1 + b2)/(1 + a1 + a2), z1 = y − b0 x, z2 = b2 x − a2 y.
        zi = []
        x = float(value)
        for b0, b1, b2, _, a1, a2 in self._rows:
            y = x * (b0 + b1 + b2) / (1.0 + a1 + a2)
            zi.append((y - b0 * x, b2 * x - a2 * y))
            x = y
        return np.array(zi)

    def __call__(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        return sosfilt_from(self.sos, values, self.steady_state(values[0]))


def _quadratics(roots: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Monic quadratics [1, c1, c2] whose roots are ``roots`` (an even count; pairs conjugate).

    Ordered by the size of their largest root, descending (the slow ones first). In Python
    complex numbers: a handful of roots, designed for every parameter a fit moves.
    """
    values = roots.tolist()
    moduli = [abs(root) for root in values]
    if any(math.isnan(modulus) for modulus in moduli):
        raise ValueError("the roots of a filter section are not numbers")
    tolerance = 1e-9 * max(1.0, *moduli)
    quads = [
        (modulus, 1.0, -2.0 * root.real, modulus**2)
        for root, modulus in zip(values, moduli, strict=True)
        if root.imag > tolerance
    ]
    real = sorted((root.real for root in values if abs(root.imag) <= tolerance), reverse=True)
    quads += [
        (max(abs(p), abs(q)), 1.0, -(p + q), p * q)
        for p, q in zip(real[::2], real[1::2], strict=True)
    ]
    quads.sort(key=lambda quad: -quad[0])
    return np.array([quad[1:] for quad in quads])


def _fin_filters(
    tau: float, fin_ml: float, tau_p: float, dt: float
) -> tuple[CascadeFilter, CascadeFilter]:
    """M and M⁻¹ in discrete time."""
    return _fin_forward(tau, fin_ml, tau_p, dt), _fin_inverse(tau, fin_ml, tau_p, dt)


@functools.lru_cache(maxsize=256)
def _fin_quadratics(
    tau: float, fin_ml: float, tau_p: float, dt: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The zero and the pole quadratics of M in discrete time (M⁻¹ swaps them).

    Cached, as are the filters: a fit asks for the same ones often, and a fit needs only M⁻¹
    (the free-run simulation M).
    """
    zeros, poles = fin_filter(tau, fin_ml, tau_p)
    k = 2.0 / dt
    return _quadratics((k + zeros) / (k - zeros)), _quadratics((k + poles) / (k - poles))


@functools.lru_cache(maxsize=256)
def _fin_forward(tau: float, fin_ml: float, tau_p: float, dt: float) -> CascadeFilter:
    """M in discrete time (:meth:`CascadeFilter.from_zeros_poles` of its zeros and poles)."""
    zeros, poles = _fin_quadratics(tau, fin_ml, tau_p, dt)
    return CascadeFilter.from_quadratics(zeros, poles)


@functools.lru_cache(maxsize=256)
def _fin_inverse(tau: float, fin_ml: float, tau_p: float, dt: float) -> CascadeFilter:
    """M⁻¹ in discrete time (the zeros and poles of M swapped)."""
    zeros, poles = _fin_quadratics(tau, fin_ml, tau_p, dt)
    return CascadeFilter.from_quadratics(poles, zeros)


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
    # scipy's compiled I0 (numpy's is a Python loop of Chebyshev series: 0.1 ms a call, for
    # every delay a fit's Jacobian tries); the two agree within 5e-16.
    taper = special.i0(_SHIFT_KAISER_BETA * np.sqrt(np.clip(1.0 - position**2, 0.0, 1.0)))
    weights = np.sinc(offsets) * taper / special.i0(_SHIFT_KAISER_BETA)
    return weights / weights.sum()


@functools.lru_cache(maxsize=64)
def _shared_shift_weights(fraction: float) -> NDArray[np.float64]:
    """:func:`shift_weights`, cached and read-only: a fit asks for one delay in many columns."""
    weights = shift_weights(fraction)
    weights.flags.writeable = False
    return weights


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
    weights = _shared_shift_weights(shift - whole)
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
    aligned: Aligned | None = None,
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
    aligned : Aligned, optional
        :func:`aligned_reading` of these readings and of a chain with the same line and delay,
        when the caller has it (a fit moving other parameters); computed otherwise.

    Returns
    -------
    gas : ndarray, shape (N - 1,)
        Gas temperature held over [t_k, t_k+1), degrees C; NaN where a delay shifts it out of
        the record.
    noise_gain : ndarray, shape (N - 1,)
        Variance of ``gas`` per unit variance of white noise on the readings.
    """
    gas, noise_gain = gas_and_noise_gain(chain, reading, dt, noise_kernel, aligned)
    return gas, np.broadcast_to(noise_gain, gas.shape)


def gas_and_noise_gain(
    chain: SensorChain,
    reading: NDArray[np.float64],
    dt: float,
    noise_kernel: NDArray[np.float64] | None = None,
    aligned: Aligned | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
    """:func:`gas_from_reading` with the noise gain a scalar where it is one (constant τ)."""
    lagged, weights, edges = _lagged_temperature(chain, reading, dt, aligned)
    gas, a, tap = _lag_inverse(chain, lagged, dt)
    if edges is not None:
        gas[edges[1:] | edges[:-1]] = np.nan
    # The noise of u[k] is (1/gain)/(1 - a) (n[k+1] - c n[k]), c = a less the radiation term's
    # slope (M⁻¹ of conduction is 1 at high frequency, where the noise is); an interpolator
    # with weights w (and a low-pass before it) turns the taps into w ⊛ (-c, 1), whose energy
    # is (1 + c²) Σw² - 2c Σ w_j w_(j+1).
    squares, products = _weight_energy(weights, noise_kernel)
    energy = (1.0 + tap**2) * squares - 2.0 * tap * products
    return gas, energy / (chain.gain * (1.0 - a)) ** 2


def _weight_energy(
    weights: NDArray[np.float64], noise_kernel: NDArray[np.float64] | None
) -> tuple[float, float]:
    """Σ w_j² and Σ w_j w_(j+1) of the interpolator's weights after the low-pass's kernel."""
    key = (weights.tobytes(), id(noise_kernel))
    found = _ENERGIES.get(key)
    if found is None or found[0] is not noise_kernel:
        kernel = noise_kernel
        if kernel is not None:
            weights = np.convolve(weights, kernel)
        found = (kernel, (np.sum(weights**2), np.sum(weights[:-1] * weights[1:])))
        if len(_ENERGIES) >= 64:
            _ENERGIES.clear()
        _ENERGIES[key] = found
    return found[1]


#: :func:`_weight_energy` by the weights' bytes and the kernel's identity (each entry holds
#: its kernel, so that identity is not another array's while it is kept): a fit asks for a
#: few, many times.
_ENERGIES: dict[tuple[bytes, int], tuple[NDArray[np.float64] | None, tuple[float, float]]] = {}


def _lag_inverse(
    chain: SensorChain, lagged: NDArray[np.float64], dt: float
) -> tuple[NDArray[np.float64], NDArray[np.float64] | float, NDArray[np.float64] | float]:
    """Gas from the lag's output (shape (N,) -> (N - 1,)), the poles used and the noise tap."""
    # The junction's temperature in kelvin: for a radiative loss or a level-dependent τ only.
    junction_k = lagged[:-1] + KELVIN if chain.r or chain.level_exponent else None
    # A constant pole stays a scalar: the arithmetic below and the noise gain are then cheap.
    a: NDArray[np.float64] | float = (
        np.exp(-dt / (chain.tau * chain.factor[:-1]))  # the poles without the level's factor
        if chain.factor is not None
        else math.exp(-dt / chain.tau)
    )
    gas, tap = _invert_lag(chain, lagged, a, junction_k)
    if not (chain.level_exponent and junction_k is not None):
        return gas, a, tap
    for _ in range(LEVEL_ITERATIONS):
        # τ follows the film temperature, between the junction and the gas: the implicit
        # inverse by fixed-point steps from the constant-τ gas.
        lag_k = _film_gas(chain, gas) + KELVIN - junction_k
        film_k = chain.film_weight * lag_k + (
            junction_k
            if chain.level_weight == 1.0
            else chain.level_ref_k + chain.level_weight * (junction_k - chain.level_ref_k)
        )
        a = chain.poles(lagged.size, dt, film_k)
        gas, tap = _invert_lag(chain, lagged, a, junction_k)
    return gas, a, tap


#: The readings with a line taken off and a delay undone (:func:`aligned_reading`).
Aligned = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_] | None]
#: The interpolation weights of no delay.
_NO_SHIFT = np.array([1.0])
_NO_SHIFT.flags.writeable = False


def aligned_reading(chain: SensorChain, reading: NDArray[np.float64], dt: float) -> Aligned:
    """The readings with ``chain``'s line (``additive``) taken off and its delay undone.

    Depends on ``chain.additive`` and ``chain.delay_s`` only.

    Returns
    -------
    reading : ndarray, shape (N,)
        Degrees C; the ends a delay shifts out of the record hold the nearest value.
    weights : ndarray
        The delay interpolator's weights (``[1.0]`` without a delay; read-only).
    edges : ndarray of bool, shape (N,), or None
        Where the interpolator's stencil left the record (None without a delay).
    """
    weights = _NO_SHIFT
    edges = None
    if chain.additive is not None:
        reading = reading - chain.additive
    if chain.delay_s:
        # The chain is time-invariant, so advancing the reading advances the gas; the reading
        # is smooth (low-passed by the sensor), so it interpolates far better than the gas.
        reading, weights = fractional_shift(reading, chain.delay_s / dt)
        edges = ~np.isfinite(reading)
        reading = _fill_edges(reading)
    return reading, weights, edges


def _lagged_temperature(
    chain: SensorChain,
    reading: NDArray[np.float64],
    dt: float,
    aligned: Aligned | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_] | None]:
    """The first-order lag's output from the readings: every stage after the lag undone.

    Returns the lagged temperature (shape (N,), degrees C), the delay interpolator's weights
    and where the delay's stencil left the record (None without a delay). ``aligned`` is
    :func:`aligned_reading`'s result when the caller has it.
    """
    reading, weights, edges = aligned_reading(chain, reading, dt) if aligned is None else aligned
    true = (reading - chain.offset) / chain.gain
    transient = chain.support_transient(true.size, dt)
    if transient is not None:
        true = true - transient
    inverse = chain.support_inverse(dt)
    return (true if inverse is None else inverse(true)), weights, edges


def first_order_reading(
    chain: SensorChain, reading: NDArray[np.float64], dt: float
) -> NDArray[np.float64]:
    """What a first-order sensor of time constant ``chain.tau`` would read of the same gas.

    Every stage of the chain but the lag is undone (interference, delay, calibration, the
    supports' transient, the fin filter); a lag that is not the plain first-order one
    (radiation, a τ varying with velocity or level) is inverted to the gas and that gas lagged
    again by the constant ``chain.tau``, from equilibrium at sample 0. The result is the
    reading of the paper's model, so the first-order reconstructions (Eq. 7, the Kalman
    smoother and filter) apply to it unchanged; its noise is the reading's, divided by the
    gain (the fin filter and the re-lag are near 1 where the noise is).

    Parameters
    ----------
    chain : SensorChain
    reading : ndarray, shape (N,)
        The sensor's readings, degrees C.
    dt : float
        Sample interval, s.

    Returns
    -------
    ndarray, shape (N,)
        Equivalent first-order readings, degrees C (ends a delay shifts out of the record
        hold the nearest value).
    """
    lagged = _lagged_temperature(chain, reading, dt)[0]
    if not (chain.r or chain.factor is not None or chain.level_exponent):
        return lagged
    gas = _lag_inverse(chain, lagged, dt)[0]  # the delay's ends are filled in ``lagged``
    # At rest, the gas equals the lag's output plus the radiation loss at that temperature.
    loss = chain.r * ((lagged[0] + KELVIN) ** 4 - chain.wall_k**4) if chain.r else 0.0
    return reading_from_gas(SensorChain(tau=chain.tau), gas, dt, float(lagged[0] + loss))


def _film_gas(chain: SensorChain, gas: NDArray[np.float64]) -> NDArray[np.float64]:
    """The gas temperature that sets the film temperature: low-passed when the chain says so."""
    if chain.film_sos is None or gas.size <= 3 * 2 * chain.film_sos.shape[0] + 1:
        return gas
    return zero_phase(chain.film_sos, gas)


#: Fixed-point steps of the inverse with a level-dependent τ: each gains the factor p Δτ/τ
#: (≲ 0.1), so three leave ~1e-3 of the τ change's own effect.
LEVEL_ITERATIONS = 3


def _invert_lag(
    chain: SensorChain,
    lagged: NDArray[np.float64],
    a: NDArray[np.float64] | float,
    junction_k: NDArray[np.float64] | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
    """Gas held over each interval from the lagged temperature, and the noise tap c.

    ``junction_k`` (the lagged temperature in K, shape (N - 1,)) is needed with radiation.
    """
    gas = (lagged[1:] - a * lagged[:-1]) / (1.0 - a)
    tap = a  # the weight of -n[k] in u[k], relative to that of n[k+1]
    if chain.r and junction_k is not None:
        cube = junction_k * junction_k * junction_k  # products: ** 3 and ** 4 go through pow
        gas = gas + chain.r * (cube * junction_k - chain.wall_k**4)
        tap = a - (4.0 * chain.r * (1.0 - a)) * cube
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
    transient = chain.support_transient(n, dt)
    # The reading at sample 0 holds the supports' initial excess; the lag starts without it.
    start = (initial_reading - chain.offset) / chain.gain - (
        0.0 if transient is None else transient[0]
    )
    if chain.level_exponent:
        # τ follows the sensor's own temperature: the pole of each step from the state.
        base = replace(chain, level_exponent=0.0).poles(n, dt)
        level = (
            chain.level_exponent,
            chain.level_ref_k,
            _film_gas(chain, seen),
            chain.film_weight,
            chain.level_weight,
        )
        lagged = _lag_loop(seen, base, start, chain.r, chain.wall_k**4, level)
    elif chain.r == 0.0 and chain.factor is None:
        a = math.exp(-dt / chain.tau)
        lagged = np.concatenate(
            ([start], signal.lfilter([1.0 - a], [1.0, -a], seen, zi=[a * start])[0])
        )
    else:
        a_k = chain.poles(n, dt)
        lagged = _lag_loop(seen, a_k, start, chain.r, chain.wall_k**4)
    forward = chain.support_forward(dt)
    true = lagged if forward is None else forward(lagged)
    if transient is not None:
        true = true + transient
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
    r: float,
    wall4: float,
    level: tuple[float, float, NDArray[np.float64], float, float] | None = None,
) -> NDArray[np.float64]:
    """Explicit recurrence y[k+1] = a y[k] + (1 - a)(u[k] - r ((y[k] + K)^4 - T_w^4)).

    With ``level = (exponent, T_ref, film_drive, w, c)`` the pole of step k is
    a_k^(1/(T/T_ref)^exponent) at the film temperature T = T_ref + c (y[k] + K − T_ref) +
    w (film_drive[k] − y[k]) (τ varying with the level; :class:`SensorChain`'s level and film
    weights), ``a`` then holding the poles without that factor. Compiled loops
    (:mod:`tcomp_core.effects.recurrence`): every free-run simulation of a radiating or
    level-dependent sensor runs one.
    """
    if level is not None:
        return level_lag_steps(drive, a, start, r, wall4, level)
    return lag_steps(drive, a, start, r, wall4)
