"""Independent, physically detailed simulator of two fine-wire type-K thermocouples in a gas flow.

This module is the *outside truth* the project's diagnosis is tested against. It shares no model
code with :mod:`tcomp_core`; it uses numpy and scipy only.

Physics (temperatures in kelvin inside, degrees C at the interface)
-------------------------------------------------------------------
Each junction is a bead (a cylinder of diameter ``D = bead_factor * d`` and length
``junction_length_m``, default D, end faces ignored, or a sphere of diameter D) at the tip of two
legs of wire of diameter ``d`` and length ``L`` whose far ends sit on supports. Its balance is

    ρ c(Tj) V dTj/dt = h A (Tg − Tj) − ε σ A (Tj⁴ − Tw⁴) + (conduction from the legs).

* **Convection.** ``h = Nu k_air / D``. Cylinder in cross flow: Collis & Williams (1959,
  J. Fluid Mech. 6, 357-384, constants of their Table 3), ``Nu = (0.24 + 0.56 Re^0.45)
  (Tm/Tg)^0.17`` for 0.02 < Re < 44 and ``0.48 Re^0.51 (Tm/Tg)^0.17`` for 44 < Re < 140, blended
  smoothly in ln Re over ±5 % around Re = 44 where the two differ by 0.4 %. Spherical bead:
  Ranz & Marshall (1952, Chem. Eng. Prog. 48, 141-146), ``Nu = 2 + 0.6 Re^½ Pr^⅓``.
  ``Re = ρg U D / μg``. The air properties are evaluated at the film temperature
  ``Tm = (Tj + Tg)/2``: viscosity by Sutherland's law and conductivity by the Sutherland-type fit,
  with White's constants for air (White 2006, *Viscous Fluid Flow*, 3rd ed., Tables 1-2 and 1-3:
  μ0 = 1.716e-5 Pa s, S = 111 K; k0 = 0.0241 W/m/K, S = 194 K; T0 = 273 K; about ±2 % from
  roughly 170 to 1900 K; at 300 and 800 K they give k = 0.0262 and 0.0568 W/m/K against 0.0263 and
  0.0573 in Incropera & DeWitt, *Fundamentals of Heat and Mass Transfer*, Table A.4), density from
  the ideal gas at the rig's pressure (R = 287.05 J/kg/K), Pr = 0.71 (Incropera & DeWitt Table
  A.4: 0.69-0.72 from 250 to 1000 K). With ``frozen_gas_properties`` the properties are taken at
  one fixed reference temperature and the loading factor is 1, so h depends on the speed only.
* **Wire.** Type K (chromel/alumel): ρ = 8700 kg/m³ (chromel 8730, alumel 8600); specific heat a
  linear fit to handbook values, c = 480 J/kg/K at 20 °C rising by 0.1 J/kg/K per K (chromel
  448, alumel 523 J/kg/K at 20 °C; nickel-chromium alloys rise by about that slope below 700 K);
  axial conductivity the mean of chromel (19.2) and alumel (29.7 W/m/K), 24.5 W/m/K. These are
  the nominal values tabulated for thermoelement materials (ASTM MNL 12, *Manual on the Use of
  Thermocouples in Temperature Measurement*, 4th ed., 1993, ch. 2, and wire makers' data
  sheets); take them as ±5 %.
* **Radiation** ε σ (Tj⁴ − Tw⁴) per unit area to a wall at a constant temperature or at a
  first-order lag of the gas at sensor 1 (σ = 5.670374419e-8 W/m²/K⁴, CODATA 2018).
* **Conduction** (optional): each leg is a 1-D fin of N finite volumes exchanging convectively and
  radiatively with the gas and conducting axially; the junction is a lumped node at the tip and
  the support temperature (constant, or a first-order lag of the gas at the sensor with a time
  constant of seconds) the boundary at the far end, half a volume beyond the last node. Both legs
  get the mean conductivity, so they are identical and one is solved with half the junction. The
  leg nodes use h at the junction's film temperature, the wire's heat capacity at the record's
  mean gas temperature and the radiation linearised about the junction temperature: their own
  temperatures would change h by at most 0.07 % and c by 0.02 % per kelvin of T − Tj, a small
  change of a conduction error that is itself a fraction of the junction error. The junction
  node's balance is exact.
* **Flow.** ``U(t) = U0 [1 + a sin(2π t/P) + drift (t − T/2)/T]``. Sensor 2 sits ``s`` downstream
  and sees the gas that passed sensor 1 at the time t' with ∫_{t'}^{t} U dt = s (Newton on the
  analytic integral of U).

"The record's mean" is the mean over the output samples (t from 0 to the duration).

Gas signals (:func:`make_gas`, seeded, smooth functions of time)
----------------------------------------------------------------
* ``rotating_disk``: a hot/cold mixing rig, cold ≈ 20 °C and hot ≈ 80 °C alternating at ≈ 10 Hz
  through tanh-shaped transitions (60 °C in about 5 ms at the steepest), cycle lengths jittered by
  1 % and levels by 1 % of the swing from cycle to cycle, plus 0.2 °C of turbulence (Gaussian
  noise band-limited to 80 Hz).
* ``engine_pulses``: exhaust at a ≈ 450 °C baseline with one pulse per firing (40 Hz, shape
  sin²(π φ^0.6): fast rise, slow decay, peak ≈ 600 °C), amplitudes varying 12 % from cycle to
  cycle, a slow drift (a spline through random knots every 2 s, σ = 10 % of the pulse height)
  and 1.5 °C of turbulence (100 Hz band).
* ``step_ramp``: random levels within 20-300 °C reached by steps (2 ms wide) or slow ramps
  (corners rounded over 20 ms), about one every 2 s, plus 0.1 °C of turbulence (20 Hz band).
* ``step``: one step (an error function at least 10 µs and two fine steps wide) from
  ``gas_low_c`` to ``gas_high_c`` at the output sample nearest a quarter of the record.

Numerics
--------
The state is integrated on a grid ``substeps`` times finer than the output sample interval, with
the gas, speed, wall and support temperatures evaluated on that grid (not held); the output is
the junction temperature at the output instants. The nonlinear coefficients (film temperature,
c(Tj), radiation) are resolved by Picard sweeps over the whole record: with the junction
trajectory of the previous sweep in the coefficients (the first guess is the gas through a lag
with the effective τ), the system is linear, ``x' = −(S + β(t) I) x + g(t)`` with S the constant
conduction matrix and β(t) one rate shared by all nodes, so it splits into the eigenmodes of S.
Each mode is integrated exactly for a piecewise-linear forcing (an exponential integrator) after
an integrating factor for the time-varying part of β, ``scipy.signal.lfilter`` doing the
recursion. Radiation is linearised about the previous sweep (Newton); the junction's deviation
from the shared rate (bead, c(Tj)) enters the next sweep as a forcing. Sweeps (3 to 7) repeat
until the junction trajectory changes by less than ``tol_k``. The scheme is second order in the
fine step (1e-5 K against an adaptive ODE solver at 20 substeps) and unconditionally stable.

Public functions
----------------
:func:`simulate_rig` makes a record; :func:`make_gas` and :func:`speed_at` give the gas signal
and the speed as functions of time; :func:`heat_transfer_coefficient`, :func:`junction_response`
and :func:`junction_time_constant` give the truth at chosen conditions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal as sps
from scipy.interpolate import CubicSpline, PchipInterpolator
from scipy.special import ndtr

__all__ = [
    "KELVIN",
    "SIGNALS",
    "STEFAN_BOLTZMANN",
    "DetailedRecord",
    "Rig",
    "Wire",
    "air_conductivity",
    "air_viscosity",
    "gas_span",
    "heat_transfer_coefficient",
    "junction_response",
    "junction_time_constant",
    "make_gas",
    "nusselt_collis_williams",
    "nusselt_ranz_marshall",
    "simulate_rig",
    "speed_at",
]

FloatArray = NDArray[np.float64]
GasFunction = Callable[[FloatArray], FloatArray]

KELVIN = 273.15
#: Stefan–Boltzmann constant, W/m²/K⁴ (CODATA 2018).
STEFAN_BOLTZMANN = 5.670374419e-8
#: Specific gas constant of dry air, J/kg/K.
GAS_CONSTANT_AIR = 287.05
#: Prandtl number of air (Incropera & DeWitt Table A.4, 250-1000 K: 0.69-0.72).
PRANDTL_AIR = 0.71
#: Signals :func:`make_gas` knows.
SIGNALS = ("rotating_disk", "engine_pulses", "step_ramp", "step")

# Sutherland constants, White (2006) Tables 1-2 (viscosity) and 1-3 (conductivity) for air.
_MU_REF, _MU_T0, _MU_S = 1.716e-5, 273.0, 111.0
_K_REF, _K_T0, _K_S = 0.0241, 273.0, 194.0
_MU_C = _MU_REF * (_MU_T0 + _MU_S) / _MU_T0**1.5
_K_C = _K_REF * (_K_T0 + _K_S) / _K_T0**1.5
# Collis & Williams (1959): switch from the low- to the high-Reynolds constants at Re = 44.
_RE_SWITCH = 44.0
_BLEND_WIDTH = 0.05  # in ln Re
_T20 = KELVIN + 20.0


# --------------------------------------------------------------------------------------------
# Air properties and heat transfer
# --------------------------------------------------------------------------------------------


def air_viscosity(temp_k: ArrayLike) -> FloatArray:
    """Dynamic viscosity of air by Sutherland's law (White 2006, Eq. 1-36, Table 1-2).

    Parameters
    ----------
    temp_k : array_like
        Temperature, K, any shape.

    Returns
    -------
    ndarray
        μ, Pa s, same shape.
    """
    t = np.asarray(temp_k, dtype=np.float64)
    return _MU_C * t * np.sqrt(t) / (t + _MU_S)


def air_conductivity(temp_k: ArrayLike) -> FloatArray:
    """Thermal conductivity of air, Sutherland-type fit (White 2006, Eq. 1-44, Table 1-3).

    Parameters
    ----------
    temp_k : array_like
        Temperature, K, any shape.

    Returns
    -------
    ndarray
        k, W/m/K, same shape (0.0262 at 300 K, 0.0568 at 800 K; Incropera Table A.4: 0.0263,
        0.0573).
    """
    t = np.asarray(temp_k, dtype=np.float64)
    return _K_C * t * np.sqrt(t) / (t + _K_S)


def nusselt_collis_williams(reynolds: ArrayLike, loading: ArrayLike = 1.0) -> FloatArray:
    """Nusselt number of a fine cylinder in cross flow, Collis & Williams (1959), Eq. 14.

    ``Nu = (0.24 + 0.56 Re^0.45) (Tm/Tg)^0.17`` for 0.02 < Re < 44 and ``0.48 Re^0.51
    (Tm/Tg)^0.17`` for 44 < Re < 140, blended over ±5 % in ln Re around 44.

    Parameters
    ----------
    reynolds : array_like
        Reynolds number with film properties, any shape.
    loading : array_like
        Temperature loading ``Tm / Tg`` (film over gas temperature), broadcastable.

    Returns
    -------
    ndarray
        Nu (based on the film conductivity), broadcast shape.
    """
    re = np.asarray(reynolds, dtype=np.float64)
    nu = 0.24 + 0.56 * np.power(re, 0.45)
    if np.any(re > _RE_SWITCH * 0.7):
        high = 0.48 * np.power(re, 0.51)
        weight = 0.5 * (1.0 + np.tanh(np.log(re / _RE_SWITCH) / _BLEND_WIDTH))
        nu = nu + weight * (high - nu)
    load = np.asarray(loading, dtype=np.float64)
    if np.ndim(load) == 0 and float(load) == 1.0:
        return nu
    return nu * np.power(load, 0.17)


def nusselt_ranz_marshall(reynolds: ArrayLike) -> FloatArray:
    """Nusselt number of a sphere, Ranz & Marshall (1952): ``Nu = 2 + 0.6 Re^½ Pr^⅓``.

    Parameters
    ----------
    reynolds : array_like
        Reynolds number with film properties, any shape.

    Returns
    -------
    ndarray
        Nu, same shape (Pr = 0.71 for air).
    """
    re = np.asarray(reynolds, dtype=np.float64)
    return 2.0 + 0.6 * PRANDTL_AIR ** (1.0 / 3.0) * np.sqrt(re)


def _kinematic_viscosity(film_k: FloatArray, pressure_pa: float) -> FloatArray:
    """ν = μ / ρ with ρ = p / (R T), m²/s, same shape as ``film_k``."""
    return air_viscosity(film_k) * GAS_CONSTANT_AIR * film_k / pressure_pa


def heat_transfer_coefficient(
    diameter_m: float,
    speed_m_s: ArrayLike,
    gas_k: ArrayLike,
    surface_k: ArrayLike,
    pressure_pa: float = 101325.0,
    shape: str = "cylinder",
) -> FloatArray:
    """Convective heat transfer coefficient of a wire or bead in cross flow of air.

    Parameters
    ----------
    diameter_m : float
        Diameter of the cylinder or sphere, m.
    speed_m_s : array_like
        Flow speed, m/s.
    gas_k, surface_k : array_like
        Gas and surface temperatures, K (the film temperature is their mean). Pass the same
        reference temperature for both to get frozen properties.
    pressure_pa : float
        Static pressure, Pa.
    shape : {"cylinder", "sphere"}
        Collis & Williams (1959) for a cylinder, Ranz & Marshall (1952) for a sphere.

    Returns
    -------
    ndarray
        h, W/m²/K, broadcast shape of the array arguments.
    """
    gas = np.asarray(gas_k, dtype=np.float64)
    film = 0.5 * (gas + np.asarray(surface_k, dtype=np.float64))
    reynolds = np.asarray(speed_m_s, dtype=np.float64) * diameter_m
    reynolds = reynolds / _kinematic_viscosity(film, pressure_pa)
    if shape == "cylinder":
        nusselt = nusselt_collis_williams(reynolds, film / gas)
    elif shape == "sphere":
        nusselt = nusselt_ranz_marshall(reynolds)
    else:
        raise ValueError(f"unknown junction shape {shape!r}")
    return np.asarray(nusselt * air_conductivity(film) / diameter_m, dtype=np.float64)


# --------------------------------------------------------------------------------------------
# Configuration and result
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Wire:
    """One thermocouple: the junction bead and its two legs.

    Parameters
    ----------
    diameter_m : float
        Wire diameter d, m (25-50 µm gives τ ≈ 5-40 ms, 75-125 µm τ ≈ 30-200 ms at a few m/s).
    length_m : float
        Length L of each leg from the junction to its support, m.
    emissivity : float
        Total hemispherical emissivity ε of the junction and wire (0 = no radiation).
    bead_factor : float
        Junction diameter D over the wire diameter d.
    junction_shape : {"cylinder", "sphere"}
        A cylinder of diameter D and length ``junction_length_m`` (end faces ignored), or a
        sphere of diameter D.
    junction_length_m : float or None
        Length of a cylindrical junction, m; None = D.
    density_kg_m3 : float
        Wire density ρ, kg/m³.
    cp_j_kg_k : float
        Specific heat at 20 °C, J/kg/K.
    cp_slope_j_kg_k2 : float
        dc/dT, J/kg/K² (0 = constant heat capacity).
    conductivity_w_m_k : float
        Axial thermal conductivity of the wire, W/m/K.
    fin_nodes : int or None
        Finite volumes per leg when conduction is on; None = enough for m·Δx ≤ 0.25 at the
        record's mean conditions (at least 10, at most 80), which keeps the steady fin error
        below about 0.5 %.
    """

    diameter_m: float
    length_m: float = 1e-3
    emissivity: float = 0.0
    bead_factor: float = 1.0
    junction_shape: str = "cylinder"
    junction_length_m: float | None = None
    density_kg_m3: float = 8700.0
    cp_j_kg_k: float = 480.0
    cp_slope_j_kg_k2: float = 0.1
    conductivity_w_m_k: float = 24.5
    fin_nodes: int | None = None

    def __post_init__(self) -> None:
        if not self.diameter_m > 0.0 or not self.length_m > 0.0:
            raise ValueError("wire diameter and length must be positive")
        if not 0.0 <= self.emissivity <= 1.0:
            raise ValueError("emissivity must be in [0, 1]")
        if not self.bead_factor > 0.0:
            raise ValueError("bead_factor must be positive")
        if self.junction_shape not in ("cylinder", "sphere"):
            raise ValueError("junction_shape must be 'cylinder' or 'sphere'")
        if self.fin_nodes is not None and self.fin_nodes < 2:
            raise ValueError("fin_nodes must be at least 2")

    @property
    def bead_diameter_m(self) -> float:
        """Junction diameter D = bead_factor · d, m."""
        return self.bead_factor * self.diameter_m

    def junction_geometry(self) -> tuple[float, float]:
        """Volume (m³) and convective surface area (m²) of the junction."""
        bead = self.bead_diameter_m
        if self.junction_shape == "sphere":
            return math.pi * bead**3 / 6.0, math.pi * bead**2
        length = bead if self.junction_length_m is None else self.junction_length_m
        return math.pi * bead**2 / 4.0 * length, math.pi * bead * length

    def specific_heat(self, temp_k: ArrayLike) -> FloatArray:
        """Specific heat c(T) of the wire, J/kg/K, for temperatures in K (any shape)."""
        t = np.asarray(temp_k, dtype=np.float64)
        return self.cp_j_kg_k + self.cp_slope_j_kg_k2 * (t - _T20)


def _default_wires() -> tuple[Wire, Wire]:
    return (Wire(50e-6), Wire(125e-6))


@dataclass(frozen=True)
class Rig:
    """A two-thermocouple rig: gas signal, flow, sensors and measurement chain.

    Parameters
    ----------
    signal : str
        One of :data:`SIGNALS`: ``"rotating_disk"`` (hot/cold mixing rig), ``"engine_pulses"``
        (exhaust pulses), ``"step_ramp"`` (slow ramps and steps between levels) or ``"step"``
        (one step from ``gas_low_c`` to ``gas_high_c`` at a quarter of the record).
    duration_s : float
        Length of the output record, s.
    rate_hz : float
        Output sample rate, Hz.
    seed : int
        Seeds the gas signal, the noise and the mains phases.
    wires : (Wire, Wire)
        Sensors 1 and 2.
    speed_m_s : float
        Mean flow speed U0, m/s.
    speed_fluctuation : float
        Relative amplitude a of the sinusoidal speed fluctuation.
    speed_period_s : float
        Period of the speed fluctuation, s.
    speed_drift : float
        Relative linear change of the speed over the record (centred on the record).
    pressure_pa : float
        Static pressure, Pa.
    frozen_gas_properties : bool
        Evaluate the gas properties at ``property_reference_c`` instead of the film temperature.
    property_reference_c : float or None
        Reference temperature of the frozen properties, °C; None = the mean gas temperature at
        sensor 1.
    wall_c : float or None
        Constant wall temperature for radiation, °C; None = a first-order lag (``wall_lag_s``)
        of the gas at sensor 1 that starts at the record's mean gas temperature. Radiation is
        off when a wire's emissivity is 0.
    wall_lag_s : float
        Time constant of the wall lag, s.
    conduction : bool
        Conduction along the legs to the supports (False = junction alone, insulated).
    support_c : float or None
        Constant support temperature, °C; None = a first-order lag (``support_lag_s``) of the
        gas at the sensor that starts at the record's mean gas temperature.
    support_lag_s : float
        Time constant of the support lag, s.
    spacing_m : float
        Distance of junction 2 downstream of junction 1, m.
    gas_low_c, gas_high_c, gas_frequency_hz, turbulence_c : float or None
        Signal levels (°C), frequency (Hz) and band-limited turbulence σ (°C); None = the
        signal's defaults (rotating_disk: 20, 80 °C, 10 Hz, 0.2 °C; engine_pulses: baseline 450,
        peak 600 °C, 40 Hz firing, 1.5 °C; step_ramp: levels within 20-300 °C, 0.5 events/s,
        0.1 °C; step: 20 -> 80 °C, no turbulence).
    noise_c : (float, float)
        White noise σ per channel, °C.
    adc_bits : int or None
        ADC resolution (None = no quantisation).
    adc_range_c : (float, float)
        ADC input range, °C; the step is (high − low) / 2**bits.
    mains_hz : float or None
        Mains frequency (50 or 60 Hz); None = no interference.
    mains_amplitude_c : float
        Amplitude of the mains fundamental, °C.
    mains_harmonics : tuple of (int, float)
        Harmonic order and amplitude relative to the fundamental.
    mains_channel : int
        Channel (1 or 2) that picks up the interference.
    calibration : (int, float, float) or None
        ``(channel, gain, offset_c)``: that channel reads ``gain * T + offset_c``.
    substeps : int
        Internal steps per output sample (at least 10).
    warmup_s : float
        Simulated before t = 0 and discarded, s.
    tol_k : float
        Convergence tolerance of the Picard sweeps on the junction temperature, K.
    """

    signal: str = "rotating_disk"
    duration_s: float = 10.0
    rate_hz: float = 2000.0
    seed: int = 0
    wires: tuple[Wire, Wire] = field(default_factory=_default_wires)
    speed_m_s: float = 3.0
    speed_fluctuation: float = 0.0
    speed_period_s: float = 1.0
    speed_drift: float = 0.0
    pressure_pa: float = 101325.0
    frozen_gas_properties: bool = False
    property_reference_c: float | None = None
    wall_c: float | None = 20.0
    wall_lag_s: float = 30.0
    conduction: bool = False
    support_c: float | None = None
    support_lag_s: float = 2.0
    spacing_m: float = 0.0
    gas_low_c: float | None = None
    gas_high_c: float | None = None
    gas_frequency_hz: float | None = None
    turbulence_c: float | None = None
    noise_c: tuple[float, float] = (0.0, 0.0)
    adc_bits: int | None = None
    adc_range_c: tuple[float, float] = (-270.0, 1372.0)
    mains_hz: float | None = None
    mains_amplitude_c: float = 0.05
    mains_harmonics: tuple[tuple[int, float], ...] = ((3, 0.3), (5, 0.1))
    mains_channel: int = 1
    calibration: tuple[int, float, float] | None = None
    substeps: int = 20
    warmup_s: float = 0.5
    tol_k: float = 1e-5

    def __post_init__(self) -> None:
        if self.signal not in SIGNALS:
            raise ValueError(f"unknown signal {self.signal!r}; expected one of {SIGNALS}")
        if not self.duration_s > 0.0 or not self.rate_hz > 0.0:
            raise ValueError("duration_s and rate_hz must be positive")
        if self.substeps < 10:
            raise ValueError("substeps must be at least 10")
        if not self.speed_m_s > 0.0:
            raise ValueError("speed_m_s must be positive")
        if abs(self.speed_fluctuation) + 0.5 * abs(self.speed_drift) >= 0.95:
            raise ValueError("speed fluctuation and drift would stop the flow")
        if self.spacing_m < 0.0 or self.warmup_s < 0.0:
            raise ValueError("spacing_m and warmup_s must not be negative")
        if self.mains_channel not in (1, 2):
            raise ValueError("mains_channel must be 1 or 2")
        if self.calibration is not None and self.calibration[0] not in (1, 2):
            raise ValueError("calibration channel must be 1 or 2")
        if len(self.wires) != 2:
            raise ValueError("a rig has two wires")


@dataclass(frozen=True)
class DetailedRecord:
    """A simulated record: output samples and the truth.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times, s, starting at 0.
    gas, gas2 : ndarray, shape (N,)
        Gas temperature at junction 1 and at junction 2, °C.
    tc1, tc2 : ndarray, shape (N,)
        Measured readings, °C (calibration, mains, noise and ADC applied).
    junction1, junction2 : ndarray, shape (N,)
        Noise-free junction temperatures, °C.
    dt : float
        Sample interval, s.
    truth : dict of str to float
        Parameters at the record's mean conditions (see :func:`simulate_rig`).
    speed : ndarray, shape (N,)
        Flow speed, m/s.
    """

    time: FloatArray
    gas: FloatArray
    gas2: FloatArray
    tc1: FloatArray
    tc2: FloatArray
    junction1: FloatArray
    junction2: FloatArray
    dt: float
    truth: dict[str, float]
    speed: FloatArray


# --------------------------------------------------------------------------------------------
# Flow speed and gas signals
# --------------------------------------------------------------------------------------------


def speed_at(rig: Rig, time_s: ArrayLike) -> FloatArray:
    """Flow speed ``U0 [1 + a sin(2π t/P) + drift (t − T/2)/T]``, m/s, same shape as time."""
    t = np.asarray(time_s, dtype=np.float64)
    rel = rig.speed_fluctuation * np.sin(2.0 * np.pi * t / rig.speed_period_s)
    rel = rel + rig.speed_drift * (t - 0.5 * rig.duration_s) / rig.duration_s
    return np.asarray(rig.speed_m_s * (1.0 + rel), dtype=np.float64)


def _distance(rig: Rig, t: FloatArray) -> FloatArray:
    """∫ U dt (analytic antiderivative of :func:`speed_at`), m."""
    period = rig.speed_period_s
    x = t - rig.speed_fluctuation * period / (2.0 * np.pi) * np.cos(2.0 * np.pi * t / period)
    x = x + rig.speed_drift * (t - 0.5 * rig.duration_s) ** 2 / (2.0 * rig.duration_s)
    return np.asarray(rig.speed_m_s * x, dtype=np.float64)


def _upstream_time(rig: Rig, t: FloatArray) -> FloatArray:
    """Time t' at which the gas reaching junction 2 at t passed junction 1 (∫_{t'}^{t} U = s)."""
    if rig.spacing_m == 0.0:
        return t
    target = _distance(rig, t) - rig.spacing_m
    earlier = t - rig.spacing_m / speed_at(rig, t)
    for _ in range(50):
        step = (_distance(rig, earlier) - target) / speed_at(rig, earlier)
        earlier = earlier - step
        if float(np.max(np.abs(step))) < 1e-13:
            break
    else:  # pragma: no cover - Newton on a monotone smooth function converges in a few steps
        raise RuntimeError("transport time did not converge")
    return earlier


def _band_noise(
    rng: np.random.Generator, t_lo: float, t_hi: float, sigma: float, cutoff_hz: float
) -> GasFunction:
    """Band-limited Gaussian noise of standard deviation σ as a smooth function of time.

    White noise on a grid 8 times finer than the cutoff, low-passed forwards and backwards by a
    4th-order Butterworth filter, scaled to σ and interpolated by a cubic spline.
    """
    if sigma == 0.0:
        return lambda t: np.zeros_like(np.asarray(t, dtype=np.float64))
    step = 1.0 / (8.0 * cutoff_hz)
    pad = 64
    knots = t_lo - pad * step + step * np.arange(math.ceil((t_hi - t_lo) / step) + 2 * pad)
    sos = sps.butter(4, cutoff_hz, fs=1.0 / step, output="sos")
    values = sps.sosfiltfilt(sos, rng.standard_normal(knots.size))
    values *= sigma / float(np.std(values[pad:-pad]))
    spline = CubicSpline(knots, values)
    return lambda t: np.asarray(spline(t), dtype=np.float64)


def _cycle_phase(
    rng: np.random.Generator, t_lo: float, t_hi: float, frequency: float, jitter: float
) -> tuple[PchipInterpolator, FloatArray, FloatArray]:
    """Cycle count Φ(t) (monotone, C¹) for cycles of seeded random length; bounds and lengths."""
    period = 1.0 / frequency
    count = math.ceil((t_hi - t_lo) / period) + 8
    lengths = period * (1.0 + jitter * np.clip(rng.standard_normal(count), -3.0, 3.0))
    bounds = t_lo - 4.0 * period + np.concatenate(([0.0], np.cumsum(lengths)))
    return PchipInterpolator(bounds, np.arange(count + 1.0)), bounds, lengths


def _rotating_disk(rig: Rig, rng: np.random.Generator, t_lo: float, t_hi: float) -> GasFunction:
    low = 20.0 if rig.gas_low_c is None else rig.gas_low_c
    high = 80.0 if rig.gas_high_c is None else rig.gas_high_c
    freq = 10.0 if rig.gas_frequency_hz is None else rig.gas_frequency_hz
    turb = 0.2 if rig.turbulence_c is None else rig.turbulence_c
    phase, bounds, lengths = _cycle_phase(rng, t_lo, t_hi, freq, 0.01)
    centres = bounds[:-1] + 0.5 * lengths
    spread = 0.01 * abs(high - low)
    cold = PchipInterpolator(centres, low + spread * rng.standard_normal(centres.size))
    hot = PchipInterpolator(centres, high + spread * rng.standard_normal(centres.size))
    noise = _band_noise(rng, t_lo, t_hi, turb, 80.0)
    width = 0.15  # 10-90 % transition in about 5 % of a period
    norm = 0.5 / math.tanh(1.0 / width)

    def gas(t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        shape = 0.5 + norm * np.tanh(np.sin(2.0 * np.pi * phase(t)) / width)
        c = cold(t)
        return np.asarray(c + (hot(t) - c) * shape + noise(t), dtype=np.float64)

    return gas


def _engine_pulses(rig: Rig, rng: np.random.Generator, t_lo: float, t_hi: float) -> GasFunction:
    base = 450.0 if rig.gas_low_c is None else rig.gas_low_c
    peak = 600.0 if rig.gas_high_c is None else rig.gas_high_c
    freq = 40.0 if rig.gas_frequency_hz is None else rig.gas_frequency_hz
    turb = 1.5 if rig.turbulence_c is None else rig.turbulence_c
    phase, _, lengths = _cycle_phase(rng, t_lo, t_hi, freq, 0.005)
    amplitudes = (peak - base) * np.clip(1.0 + 0.12 * rng.standard_normal(lengths.size), 0.5, 1.5)
    knot_step = 2.0
    knots = np.arange(t_lo - 2 * knot_step, t_hi + 3 * knot_step, knot_step)
    drift = CubicSpline(knots, 0.1 * (peak - base) * rng.standard_normal(knots.size))
    noise = _band_noise(rng, t_lo, t_hi, turb, 100.0)

    def gas(t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        cycles = phase(t)
        index = np.floor(cycles)
        frac = cycles - index
        # Fast rise, slow decay; zero with zero slope at both ends of a cycle.
        pulse = np.sin(np.pi * np.power(frac, 0.6)) ** 2
        amp = amplitudes[np.clip(index.astype(np.int64), 0, amplitudes.size - 1)]
        return np.asarray(base + drift(t) + amp * pulse + noise(t), dtype=np.float64)

    return gas


def _smooth_ramp(t: FloatArray, start: float, stop: float, sigma: float) -> FloatArray:
    """A 0 -> 1 linear ramp over [start, stop] convolved with a Gaussian of width σ."""
    out = (t >= stop + 8.0 * sigma).astype(np.float64)
    inside = (t > start - 8.0 * sigma) & (t < stop + 8.0 * sigma)
    ti = t[inside]
    if stop - start < 1e-3 * sigma:
        out[inside] = ndtr((ti - start) / sigma)
        return out

    def integral(x: FloatArray) -> FloatArray:
        u = x / sigma
        return np.asarray(
            x * ndtr(u) + sigma * np.exp(-0.5 * u * u) / math.sqrt(2.0 * np.pi),
            dtype=np.float64,
        )

    out[inside] = (integral(ti - start) - integral(ti - stop)) / (stop - start)
    return out


def _step_ramp(rig: Rig, rng: np.random.Generator, t_lo: float, t_hi: float) -> GasFunction:
    low = 20.0 if rig.gas_low_c is None else rig.gas_low_c
    high = 300.0 if rig.gas_high_c is None else rig.gas_high_c
    rate = 0.5 if rig.gas_frequency_hz is None else rig.gas_frequency_hz
    turb = 0.1 if rig.turbulence_c is None else rig.turbulence_c
    span = high - low
    level = low + span * rng.uniform()
    start_level = level
    events: list[tuple[float, float, float, float]] = []  # (start, stop, change, sigma)
    t = t_lo + rng.uniform(0.3, 1.0) / rate
    while t < t_hi:
        gap = rng.uniform(0.6, 1.4) / rate
        new = level
        while abs(new - level) < 0.2 * abs(span):
            new = low + span * rng.uniform()
        if rng.uniform() < 0.5:
            events.append((t, t, new - level, 2e-3))  # a step, 2 ms wide
        else:
            events.append((t, t + rng.uniform(0.3, 0.6) * gap, new - level, 20e-3))  # a ramp
        level = new
        t += gap
    noise = _band_noise(rng, t_lo, t_hi, turb, 20.0)

    def gas(time: FloatArray) -> FloatArray:
        time = np.asarray(time, dtype=np.float64)
        out = np.full(time.shape, start_level) + noise(time)
        for start, stop, change, sigma in events:
            out += change * _smooth_ramp(time, start, stop, sigma)
        return out

    return gas


def _single_step(rig: Rig, t_step: float, width: float) -> GasFunction:
    low = 20.0 if rig.gas_low_c is None else rig.gas_low_c
    high = 80.0 if rig.gas_high_c is None else rig.gas_high_c

    def gas(t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        return np.asarray(low + (high - low) * ndtr((t - t_step) / width), dtype=np.float64)

    return gas


def _step_time(rig: Rig) -> float:
    """Time of the ``"step"`` signal's step: the output sample nearest a quarter of the record."""
    return round(0.25 * rig.duration_s * rig.rate_hz) / rig.rate_hz


def gas_span(rig: Rig) -> tuple[float, float]:
    """Interval (s) on which :func:`make_gas` defines the rig's gas signal.

    From ``warmup_s`` plus 2 s plus ten nominal transport times before 0 to 2 s after the end of
    the record; the seeded cycles are laid out from its start, so the signal depends on the rig
    only.
    """
    return (
        -rig.warmup_s - 2.0 - 10.0 * rig.spacing_m / rig.speed_m_s,
        rig.duration_s + 2.0,
    )


def make_gas(rig: Rig) -> GasFunction:
    """The rig's gas temperature at junction 1 as a smooth function of time.

    Parameters
    ----------
    rig : Rig
        Signal name, levels, frequency, turbulence and seed.

    Returns
    -------
    callable
        ``gas(t)`` for an array of times (s, any shape, within :func:`gas_span`) returning °C,
        same shape. The same rig gives the same function.
    """
    t_lo, t_hi = gas_span(rig)
    gas_seed = np.random.SeedSequence([rig.seed, 1])
    rng = np.random.default_rng(gas_seed)
    if rig.signal == "rotating_disk":
        return _rotating_disk(rig, rng, t_lo, t_hi)
    if rig.signal == "engine_pulses":
        return _engine_pulses(rig, rng, t_lo, t_hi)
    if rig.signal == "step_ramp":
        return _step_ramp(rig, rng, t_lo, t_hi)
    fine_step = 1.0 / (rig.rate_hz * rig.substeps)
    return _single_step(rig, _step_time(rig), max(1e-5, 2.0 * fine_step))


# --------------------------------------------------------------------------------------------
# Integration
# --------------------------------------------------------------------------------------------


def _foh_weights(rate: FloatArray, step: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Exponential integrator weights of ``y' = −rate y + v`` for v linear over one step.

    Returns ``E, P, Q`` with ``y1 = E y0 + (P − Q) v0 + Q v1``; shapes of ``rate``.
    """
    x = rate * step
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    e = np.exp(-x)
    p = np.where(small, step * (1.0 - x / 2.0 + x * x / 6.0 - x**3 / 24.0), -np.expm1(-xs) / xs)
    p = np.where(small, p, p * step)
    q = np.where(
        small,
        step * (0.5 - x / 6.0 + x * x / 24.0 - x**3 / 120.0),
        (step - p) / xs,
    )
    return e, p, q


def _first_order_lag(values: FloatArray, lag_s: float, step: float, start: float) -> FloatArray:
    """First-order lag of a signal on a uniform grid (exact for piecewise-linear input)."""
    e, p, q = (float(a[0]) for a in _foh_weights(np.array([1.0 / lag_s]), step))
    rate = 1.0 / lag_s
    b = [rate * q, rate * (p - q)]
    zi = [rate * (p - q) * values[0] + e * start]
    out = np.empty_like(values)
    out[0] = start
    out[1:] = sps.lfilter(b, [1.0, -e], values[1:], zi=zi)[0]
    return out


@dataclass(frozen=True)
class _Modes:
    """Eigenmodes of the conduction matrix S = C⁻¹K of junction + one leg (n nodes)."""

    rates: FloatArray  # (n,) eigenvalues of S, 1/s
    sources: FloatArray  # (n, 3) modal weights of [uniform, support, junction] forcing
    rows: FloatArray  # (2, n) junction and first leg node from the modes
    s00: float  # S[0, 0], 1/s (0 without conduction)
    junction_conduction: float  # 2 G / (ρ V_j); divided by c(Tj) it is the rate, 1/s


def _build_modes(wire: Wire, c_ref: float, conduction: bool, n_leg: int) -> _Modes:
    if not conduction:
        return _Modes(
            rates=np.zeros(1),
            sources=np.array([[1.0, 0.0, 1.0]]),
            rows=np.array([[1.0], [1.0]]),
            s00=0.0,
            junction_conduction=0.0,
        )
    d = wire.diameter_m
    vol_j, _ = wire.junction_geometry()
    area = math.pi * d * d / 4.0
    dx = wire.length_m / n_leg
    g_half = 2.0 * wire.conductivity_w_m_k * area / dx  # across half a volume
    g_full = wire.conductivity_w_m_k * area / dx
    n = n_leg + 1
    cap = np.full(n, wire.density_kg_m3 * c_ref * area * dx)
    cap[0] = 0.5 * wire.density_kg_m3 * c_ref * vol_j  # half the junction per leg
    kmat = np.zeros((n, n))
    for i in range(n - 1):
        g = g_half if i == 0 else g_full
        kmat[i, i] += g
        kmat[i + 1, i + 1] += g
        kmat[i, i + 1] -= g
        kmat[i + 1, i] -= g
    kmat[-1, -1] += g_half  # to the support
    root = np.sqrt(cap)
    rates, vecs = np.linalg.eigh(kmat / np.outer(root, root))
    to_nodes = vecs / root[:, None]
    to_modes = vecs.T * root[None, :]
    sources = np.stack(
        [to_modes @ np.ones(n), to_modes[:, -1] * g_half / cap[-1], to_modes[:, 0]], axis=1
    )
    return _Modes(
        rates=rates,
        sources=sources,
        rows=to_nodes[:2].copy(),
        s00=g_half / cap[0],
        junction_conduction=2.0 * g_half / (wire.density_kg_m3 * vol_j),
    )


def _leg_nodes(wire: Wire, speed_m_s: float, temp_k: float) -> int:
    """Finite volumes per leg: ``wire.fin_nodes`` or enough for m·Δx ≤ 0.25 (10 to 80)."""
    if wire.fin_nodes is not None:
        return wire.fin_nodes
    h_w = float(heat_transfer_coefficient(wire.diameter_m, speed_m_s, temp_k, temp_k))
    ml = math.sqrt(4.0 * h_w / (wire.conductivity_w_m_k * wire.diameter_m)) * wire.length_m
    return int(min(80, max(10, math.ceil(4.0 * ml))))


def _solve_modes(
    modes: _Modes, beta: FloatArray, forcing: FloatArray, step: float
) -> tuple[FloatArray, FloatArray]:
    """Integrate ``z' = −(λ + β(t)) z + W f(t)`` from its steady state at t0.

    Parameters
    ----------
    modes : _Modes
        λ (n,), W (n, 3) and the output rows (2, n).
    beta : ndarray, shape (K,)
        Shared loss rate on the fine grid, 1/s.
    forcing : ndarray, shape (3, K)
        Uniform, support and junction forcing, K/s.
    step : float
        Fine step, s.

    Returns
    -------
    junction, first : ndarray, shape (K,)
        Deviation of the junction and the first leg node from the reference temperature, K.
    """
    count = beta.size
    out = np.empty((2, count))
    z = (modes.sources @ forcing[:, 0]) / (modes.rates + beta[0])
    chunk = int(min(8192, max(16, 200.0 / (step * float(np.max(np.abs(beta))) + 1e-300))))
    k0 = 0
    while k0 < count - 1:
        k1 = min(count - 1, k0 + chunk)
        seg = beta[k0 : k1 + 1]
        mean = float(np.mean(seg))
        dev = seg - mean
        integ = np.empty(seg.size)
        integ[0] = 0.0
        np.cumsum(0.5 * step * (dev[1:] + dev[:-1]), out=integ[1:])
        factor = np.exp(integ)
        drive = modes.sources @ (forcing[:, k0 : k1 + 1] * factor)
        e, p, q = _foh_weights(modes.rates + mean, step)
        ys = np.empty_like(drive)
        for m in range(drive.shape[0]):
            em, pm, qm = float(e[m]), float(p[m]), float(q[m])
            ys[m, 0] = z[m]
            zi = [(pm - qm) * drive[m, 0] + em * z[m]]
            ys[m, 1:] = sps.lfilter([qm, pm - qm], [1.0, -em], drive[m, 1:], zi=zi)[0]
        ys /= factor
        out[:, k0 : k1 + 1] = modes.rows @ ys
        z = ys[:, -1].copy()
        k0 = k1
    if count == 1:
        out[:, 0] = modes.rows @ z
    return out[0], out[1]


def _integrate_wire(
    wire: Wire,
    step: float,
    gas_k: FloatArray,
    speed: FloatArray,
    wall_k: FloatArray,
    support_k: FloatArray | None,
    pressure_pa: float,
    frozen_k: float | None,
    ref_k: float,
    tol_k: float,
    leg_nodes: int,
    max_sweeps: int = 80,
) -> tuple[FloatArray, int]:
    """Junction temperature (K) on the fine grid and the number of Picard sweeps."""
    conduction = support_k is not None
    d = wire.diameter_m
    bead = wire.bead_diameter_m
    vol_j, area_j = wire.junction_geometry()
    rho = wire.density_kg_m3
    c_ref = float(wire.specific_heat(ref_k))
    modes = _build_modes(wire, c_ref, conduction, leg_nodes)
    eps_sigma = wire.emissivity * STEFAN_BOLTZMANN
    same_geometry = wire.junction_shape == "cylinder" and wire.bead_factor == 1.0
    wall4 = wall_k**4 if eps_sigma > 0.0 else None
    gas_dev = gas_k - ref_k
    forcing = np.zeros((3, gas_k.size))
    if conduction:
        assert support_k is not None
        forcing[1] = support_k - ref_k

    frozen_h: tuple[FloatArray, FloatArray] | None = None
    if frozen_k is not None:
        h_frozen = heat_transfer_coefficient(
            bead, speed, frozen_k, frozen_k, pressure_pa, wire.junction_shape
        )
        if not same_geometry and conduction:
            frozen_h = (
                h_frozen,
                heat_transfer_coefficient(d, speed, frozen_k, frozen_k, pressure_pa),
            )
        else:
            frozen_h = (h_frozen, h_frozen)

    def coefficients(tj: FloatArray) -> tuple[FloatArray, FloatArray]:
        """h of the junction and of the wire (W/m²/K) at the film temperature."""
        if frozen_h is not None:
            return frozen_h
        film = 0.5 * (tj + gas_k)
        nu_kin = _kinematic_viscosity(film, pressure_pa)
        k_air = air_conductivity(film)
        load = film / gas_k
        if wire.junction_shape == "cylinder":
            h_j = nusselt_collis_williams(speed * bead / nu_kin, load) * k_air / bead
        else:
            h_j = nusselt_ranz_marshall(speed * bead / nu_kin) * k_air / bead
        if same_geometry or not conduction:
            return h_j, h_j
        return h_j, nusselt_collis_williams(speed * d / nu_kin, load) * k_air / d

    # First guess: the gas through a first-order lag with the effective τ at the mean conditions.
    guess_tau = junction_response(
        wire,
        ref_k - KELVIN,
        float(np.mean(speed)),
        pressure_pa=pressure_pa,
        conduction=conduction,
        frozen_reference_c=None if frozen_k is None else frozen_k - KELVIN,
    )["tau_eff"]
    tj = _first_order_lag(gas_k, guess_tau, step, float(gas_k[0]))
    t1 = tj
    for sweep in range(1, max_sweeps + 1):
        h_j, h_w = coefficients(tj)
        c_j = wire.specific_heat(tj)
        a_j = area_j / (rho * c_j * vol_j)  # junction: per W/m² to K/s
        if eps_sigma > 0.0:
            assert wall4 is not None
            tj3 = tj**3
            h_rad = 4.0 * eps_sigma * tj3
            rad_net = eps_sigma * (tj3 * tj - wall4)  # W/m² lost at the current iterate
        else:
            h_rad = np.zeros(1)
            rad_net = np.zeros(1)
        if not conduction:
            beta = a_j * (h_j + h_rad)
            forcing[0] = a_j * (h_j * gas_dev - rad_net + h_rad * (tj - ref_k))
        else:
            a_w = 4.0 / (rho * c_ref * d)
            beta = a_w * (h_w + h_rad)
            forcing[0] = a_w * (h_w * gas_dev - rad_net + h_rad * (tj - ref_k))
            exact = (modes.junction_conduction / c_j) * (t1 - tj) + a_j * (
                h_j * (gas_k - tj) - rad_net
            )
            reference = modes.s00 * (t1 - tj) - beta * (tj - ref_k) + forcing[0]
            forcing[2] = exact - reference
        beta = np.broadcast_to(beta, gas_k.shape)
        dev_j, dev_1 = _solve_modes(modes, np.ascontiguousarray(beta), forcing, step)
        new = ref_k + dev_j
        change = float(np.max(np.abs(new - tj)))
        tj = new
        t1 = ref_k + dev_1
        if change < tol_k:
            return tj, sweep
    raise RuntimeError(f"Picard sweeps did not converge (last change {change:.3g} K)")


# --------------------------------------------------------------------------------------------
# Truth at chosen conditions
# --------------------------------------------------------------------------------------------


def junction_response(
    wire: Wire,
    gas_c: float,
    speed_m_s: float,
    *,
    pressure_pa: float = 101325.0,
    junction_c: float | None = None,
    conduction: bool = False,
    frozen_reference_c: float | None = None,
) -> dict[str, float]:
    """Linearised response of one junction at steady conditions (the first-order truth).

    Parameters
    ----------
    wire : Wire
        The sensor.
    gas_c : float
        Gas temperature, °C; the film temperature is that of a junction at the gas temperature.
    speed_m_s : float
        Flow speed, m/s.
    pressure_pa : float
        Static pressure, Pa.
    junction_c : float or None
        Junction temperature for the radiation linearisation, °C; None = ``gas_c``.
    conduction : bool
        Include the legs (fin) with their supports held at a fixed temperature.
    frozen_reference_c : float or None
        Evaluate the gas properties at this temperature (frozen properties).

    Returns
    -------
    dict
        ``h`` and ``h_wire`` (W/m²/K), ``tau`` = ρ c V / (h A) (s), ``rho`` = 4 ε σ T³ / h,
        ``gain`` and ``tau_eff`` (s): the gain and first-order lag -G'(0)/G(0) of the junction's
        transfer function from the gas with the supports and the wall held, including the
        radiation linearisation and the fin; ``mL`` (m = sqrt(4 h / (k d))), ``kappa`` = 1/g − 1
        with g the fin-only gain (the lumped conductive/convective ratio giving the same band
        gain), ``kappa_junction`` = 2 k A m coth(mL) / (h A_j) (conductance of the two legs over
        the junction's convective conductance), ``velocity_exponent`` = −d ln τ / d ln U.
    """
    gas_k = gas_c + KELVIN
    tj_k = gas_k if junction_c is None else junction_c + KELVIN
    props_gas = gas_k if frozen_reference_c is None else frozen_reference_c + KELVIN
    props_surface = gas_k if frozen_reference_c is None else props_gas
    bead = wire.bead_diameter_m
    d = wire.diameter_m

    def h_at(speed: float, diameter: float, shape: str) -> float:
        return float(
            heat_transfer_coefficient(
                diameter, speed, props_gas, props_surface, pressure_pa, shape
            )
        )

    h_j = h_at(speed_m_s, bead, wire.junction_shape)
    h_w = h_at(speed_m_s, d, "cylinder")
    c = float(wire.specific_heat(gas_k))
    vol_j, area_j = wire.junction_geometry()
    cap_j = wire.density_kg_m3 * c * vol_j
    h_rad = 4.0 * wire.emissivity * STEFAN_BOLTZMANN * tj_k**3
    tau = cap_j / (h_j * area_j)
    k_w = wire.conductivity_w_m_k
    area_w = math.pi * d * d / 4.0
    length = wire.length_m

    def transfer(s: complex, radiation: float) -> complex:
        if not conduction:
            return h_j * area_j / (cap_j * s + (h_j + radiation) * area_j)
        m_s = np.sqrt(
            (math.pi * d * (h_w + radiation) + wire.density_kg_m3 * c * area_w * s)
            / (k_w * area_w)
        )
        local = h_w / (h_w + radiation + wire.density_kg_m3 * c * d * s / 4.0)
        coth = 1.0 / np.tanh(m_s * length)
        csch = 1.0 / np.sinh(m_s * length)
        num = h_j * area_j + 2.0 * k_w * area_w * m_s * local * (coth - csch)
        den = cap_j * s + (h_j + radiation) * area_j + 2.0 * k_w * area_w * m_s * coth
        return complex(num / den)

    probe = 1e-12 / tau
    gain = transfer(0j, h_rad).real
    tau_eff = -transfer(1j * probe, h_rad).imag / probe / gain
    result = {
        "h": h_j,
        "h_wire": h_w,
        "tau": tau,
        "rho": h_rad / h_j,
        "gain": gain,
        "tau_eff": tau_eff,
        "mL": math.nan,
        "kappa": 0.0,
        "kappa_junction": 0.0,
    }
    if conduction:
        m = math.sqrt(4.0 * h_w / (k_w * d))
        fin_gain = transfer(0j, 0.0).real
        result["mL"] = m * length
        result["kappa"] = 1.0 / fin_gain - 1.0
        result["kappa_junction"] = 2.0 * k_w * area_w * m / math.tanh(m * length) / (h_j * area_j)
    up = h_at(speed_m_s * 1.01, bead, wire.junction_shape)
    down = h_at(speed_m_s / 1.01, bead, wire.junction_shape)
    result["velocity_exponent"] = math.log(up / down) / (2.0 * math.log(1.01))
    return result


def junction_time_constant(
    wire: Wire,
    gas_c: float,
    speed_m_s: float,
    *,
    pressure_pa: float = 101325.0,
    frozen_reference_c: float | None = None,
) -> float:
    """τ = ρ c(T) V / (h A) of the junction at the gas temperature ``gas_c`` (°C), s."""
    return junction_response(
        wire,
        gas_c,
        speed_m_s,
        pressure_pa=pressure_pa,
        frozen_reference_c=frozen_reference_c,
    )["tau"]


# --------------------------------------------------------------------------------------------
# The record
# --------------------------------------------------------------------------------------------


def simulate_rig(rig: Rig) -> DetailedRecord:
    """Simulate a two-thermocouple record.

    Parameters
    ----------
    rig : Rig
        The configuration.

    Returns
    -------
    DetailedRecord
        N = round(duration_s * rate_hz) samples. ``truth`` holds, per sensor i = 1, 2 at the
        record's mean gas temperature at that sensor and the mean speed (see
        :func:`junction_response`): ``tau{i}`` (s), ``tau{i}_eff`` (s), ``gain{i}``,
        ``rho{i}``, ``h{i}`` (W/m²/K), ``velocity_exponent{i}``, ``mL{i}``, ``kappa{i}``,
        ``kappa_junction{i}``; and ``tau_p`` (support lag, s; nan without conduction),
        ``wall_c`` (mean wall temperature, °C), ``delay_s`` (spacing / mean speed),
        ``speed_m_s`` (mean), ``mean_gas_c``, ``mean_gas2_c``, ``gain`` and ``offset_c`` (tc2
        relative to tc1: tc2 reads gain·T + offset where tc1 reads T), ``calibration_channel``
        (0 = none), ``calibration_gain``, ``calibration_offset_c``, ``mains_hz`` (nan = none),
        ``mains_amplitude_c``, ``adc_step_c`` (0 = none), ``noise1_c``, ``noise2_c``, ``phi``
        (σ1²/σ2², nan if σ2 = 0), ``sweeps1``/``sweeps2`` (Picard sweeps used) and, for the
        ``"step"`` signal, ``step_time_s``.
    """
    dt = 1.0 / rig.rate_hz
    n_out = round(rig.duration_s * rig.rate_hz)
    n_warm = math.ceil(rig.warmup_s * rig.rate_hz)
    step = dt / rig.substeps
    n_fine = (n_warm + n_out - 1) * rig.substeps + 1
    t_fine = (np.arange(n_fine, dtype=np.float64) - n_warm * rig.substeps) * step
    speed = speed_at(rig, t_fine)
    if float(np.min(speed)) <= 0.0:
        raise ValueError("the flow speed must stay positive")
    upstream = _upstream_time(rig, t_fine)
    if float(upstream[0]) < gas_span(rig)[0]:
        raise ValueError("the transport time is too long for the gas signal's span")
    gas_fn = make_gas(rig)
    gas1 = gas_fn(t_fine) + KELVIN
    gas2 = gas1 if rig.spacing_m == 0.0 else gas_fn(upstream) + KELVIN
    out_idx = (n_warm + np.arange(n_out)) * rig.substeps
    mean_gas_k = float(np.mean(gas1[out_idx]))  # "the record's mean": over the output samples
    frozen_k: float | None = None
    if rig.frozen_gas_properties:
        frozen_k = mean_gas_k
        if rig.property_reference_c is not None:
            frozen_k = rig.property_reference_c + KELVIN

    if rig.wall_c is None:
        wall_k = _first_order_lag(gas1, rig.wall_lag_s, step, mean_gas_k)
    else:
        wall_k = np.full(n_fine, rig.wall_c + KELVIN)

    junctions = []
    sweeps = []
    nodes = []
    for gas_k, wire in zip((gas1, gas2), rig.wires, strict=True):
        ref_k = float(np.mean(gas_k[out_idx]))
        nodes.append(
            _leg_nodes(wire, float(np.mean(speed[out_idx])), ref_k) if rig.conduction else 0
        )
        support: FloatArray | None = None
        if rig.conduction:
            if rig.support_c is None:
                support = _first_order_lag(gas_k, rig.support_lag_s, step, ref_k)
            else:
                support = np.full(n_fine, rig.support_c + KELVIN)
        tj, used = _integrate_wire(
            wire,
            step,
            gas_k,
            speed,
            wall_k,
            support,
            rig.pressure_pa,
            frozen_k,
            ref_k,
            rig.tol_k,
            nodes[-1],
        )
        junctions.append(tj[out_idx] - KELVIN)
        sweeps.append(used)

    time = np.arange(n_out, dtype=np.float64) * dt
    gas_out = gas1[out_idx] - KELVIN
    gas2_out = gas2[out_idx] - KELVIN
    speed_out = speed[out_idx]

    # Measurement chain: calibration -> mains -> noise -> ADC.
    noise_seq, mains_seq = np.random.SeedSequence([rig.seed, 2]).spawn(2)
    noise_rng = np.random.default_rng(noise_seq)
    mains_rng = np.random.default_rng(mains_seq)
    measured = [j.copy() for j in junctions]
    if rig.calibration is not None:
        channel, gain, offset = rig.calibration
        measured[channel - 1] = gain * measured[channel - 1] + offset
    if rig.mains_hz is not None:
        hum = np.zeros(n_out)
        for order, rel in ((1, 1.0), *rig.mains_harmonics):
            phase = mains_rng.uniform(0.0, 2.0 * np.pi)
            hum += rel * np.sin(2.0 * np.pi * order * rig.mains_hz * time + phase)
        measured[rig.mains_channel - 1] = measured[rig.mains_channel - 1] + (
            rig.mains_amplitude_c * hum
        )
    for i, sigma in enumerate(rig.noise_c):
        noise = noise_rng.standard_normal(n_out)
        if sigma > 0.0:
            measured[i] = measured[i] + sigma * noise
    adc_step = 0.0
    if rig.adc_bits is not None:
        lo, hi = rig.adc_range_c
        adc_step = (hi - lo) / 2.0**rig.adc_bits
        for i in range(2):
            code = np.clip(np.round((measured[i] - lo) / adc_step), 0, 2**rig.adc_bits - 1)
            measured[i] = lo + code * adc_step

    # Truth at the record's mean conditions.
    mean_speed = float(np.mean(speed_out))
    truth: dict[str, float] = {}
    for i, (wire, gas_o, junction) in enumerate(
        zip(rig.wires, (gas_out, gas2_out), junctions, strict=True), start=1
    ):
        resp = junction_response(
            wire,
            float(np.mean(gas_o)),
            mean_speed,
            pressure_pa=rig.pressure_pa,
            junction_c=float(np.mean(junction)),
            conduction=rig.conduction,
            frozen_reference_c=None if frozen_k is None else frozen_k - KELVIN,
        )
        truth[f"tau{i}"] = resp["tau"]
        truth[f"tau{i}_eff"] = resp["tau_eff"]
        truth[f"gain{i}"] = resp["gain"]
        truth[f"rho{i}"] = resp["rho"]
        truth[f"h{i}"] = resp["h"]
        truth[f"velocity_exponent{i}"] = resp["velocity_exponent"]
        truth[f"mL{i}"] = resp["mL"]
        truth[f"kappa{i}"] = resp["kappa"]
        truth[f"kappa_junction{i}"] = resp["kappa_junction"]
        truth[f"sweeps{i}"] = float(sweeps[i - 1])
        truth[f"fin_nodes{i}"] = float(nodes[i - 1])
    truth["tau_p"] = rig.support_lag_s if rig.conduction and rig.support_c is None else math.nan
    truth["wall_c"] = float(np.mean(wall_k[out_idx])) - KELVIN
    truth["delay_s"] = rig.spacing_m / mean_speed
    truth["speed_m_s"] = mean_speed
    truth["mean_gas_c"] = float(np.mean(gas_out))
    truth["mean_gas2_c"] = float(np.mean(gas2_out))
    gain, offset, channel = 1.0, 0.0, 0
    if rig.calibration is not None:
        channel, gain, offset = rig.calibration
    truth["calibration_channel"] = float(channel)
    truth["calibration_gain"] = float(gain)
    truth["calibration_offset_c"] = float(offset)
    if channel == 1:  # tc1 = g T + o  ->  tc2 = T = tc1 / g - o / g
        truth["gain"], truth["offset_c"] = 1.0 / gain, -offset / gain
    else:
        truth["gain"], truth["offset_c"] = float(gain), float(offset)
    truth["mains_hz"] = math.nan if rig.mains_hz is None else float(rig.mains_hz)
    truth["mains_amplitude_c"] = 0.0 if rig.mains_hz is None else rig.mains_amplitude_c
    truth["adc_step_c"] = adc_step
    truth["noise1_c"], truth["noise2_c"] = (float(s) for s in rig.noise_c)
    truth["phi"] = rig.noise_c[0] ** 2 / rig.noise_c[1] ** 2 if rig.noise_c[1] > 0.0 else math.nan
    if rig.signal == "step":
        truth["step_time_s"] = _step_time(rig)

    return DetailedRecord(
        time=time,
        gas=gas_out,
        gas2=gas2_out,
        tc1=measured[0],
        tc2=measured[1],
        junction1=junctions[0],
        junction2=junctions[1],
        dt=dt,
        truth=truth,
        speed=speed_out,
    )
