"""Two-thermocouple records with a hidden physical effect, simulated in continuous time.

The records test the diagnosis: each holds one effect that the first-order model of Eq. (2)
lacks (names as in :mod:`tcomp_core.effects`). Unlike :func:`tcomp_core.simulate.simulate_pair`,
which uses the estimators' zero-order-hold difference equation (Eq. 4), the sensors here are
integrated independently on a grid ``oversample`` times finer than the samples, with the gas
temperature evaluated on that grid, and then point-sampled:

* linear time-invariant sensors (no effect, ``conduction``, ``delay``, ``calibration``,
  ``noise_ratio``) are solved exactly for the gas interpolated linearly between grid points,
  which is what :func:`scipy.signal.lsim` computes; the first-order-hold discretisation is
  applied with :func:`scipy.signal.lfilter`, as ``lsim`` steps in a Python loop;
* ``radiation``, ``property`` (nonlinear) and ``velocity`` (time-varying) are integrated with
  classical RK4
  in steps of two grid intervals, the gas at the odd grid points being the exact midpoint
  values; an odd ``oversample`` is rounded up to even for them.

Every sensor starts in equilibrium with the gas at t = 0. Noise follows
:func:`tcomp_core.simulate.add_noise`: K in percent of std(clean1), sensor 1 drawn first.

=============  ===============================================================================
effect         sensor i (τi dTi/dt = Tg − Ti unless stated)
=============  ===============================================================================
conduction     ``fin legs``: Gi(s) = (1 − Si)/(1 + τi s) + Si/(1 + τp s), Si = sech(mLi
               √(1 + τi s)), mLi = √(tau_leg/τi): a junction between two fin legs on supports
               lagging τp. ``lumped prong``: τi dTi/dt = Tg − Ti + κi (Tp − Ti) with a prong
               τp dTp/dt = Tg − Tp, i.e. Gi(s) = [1 + κi/(1 + τp s)]/(1 + κi + τi s)
radiation      τi dTi/dt = Tg − Ti − ri (Ti⁴ − Tw⁴), temperatures in kelvin in the law,
               ri = rhoi / (4 T̄³) with the gas mean T̄ in K (rhoi as the fit's ρi);
               ``constant wall``: Tw = wall_c; ``lagging wall``: Tw starts at wall_c and
               follows the gas through a first-order lag of wall_lag_s (a duct warming up)
velocity       τi(t) = τi0 (v(t)/v0)^(−m); ``sine``: v(t)/v0 = 1 + depth sin(2π t / period_s
               + 0.3); ``steps``: the same sine's sign, v/v0 switching between 1 ± depth every
               half period through a tanh edge of period_s/100 (a valve or throttle moved)
property       τi(t) = τi0 (Tf/T̄)^property_exponent, film Tf = (Ti + Tg)/2, gas mean T̄ in K
delay          junction 2 sees the gas δ = delay_s later than junction 1
calibration    tc2 reads gain · T2 + offset_c
interference   tc2 reads T2 + interference_c (sin 2π f t + 0.3 sin 6π f t + 0.1 sin 10π f t),
               f = interference_hz
noise_ratio    σ2 = sigma_ratio · σ1, so φ = σ1²/σ2² = 1/sigma_ratio²
=============  ===============================================================================

Each effect's forms, its default parameters and the gas level it needs are its own module's
(:attr:`~tcomp_core.effects.base.Effect.simulation_forms`,
:meth:`~tcomp_core.effects.base.Effect.simulation_defaults`,
:attr:`~tcomp_core.effects.base.Effect.simulation_gas`); the physics here shares no code with
the fitted models. The first form of each effect is the one the fit assumes, the others the
literature's alternatives: compensation fitted with the project's form on a record made with
another must not be materially worse than first order (``test/test_effect_forms.py``).
Parameters that the fitted effects also have carry their names (``rho1``, ``rho2``,
``wall_c``, ``tau_leg``, ``tau_p``, ``delay_s``, ``gain``, ``offset_c``, ``interference_hz``,
``property_exponent``), so a record's true parameters compare with a fit's by name; those of
other forms (a sine of the speed, a prong's κi, a line of fixed harmonics) keep their own.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, signal

from .choices import EFFECT_NAMES
from .effects import EFFECTS
from .simulate import PAPER_DT, PAPER_TAU1, PAPER_TAU2, SignalKind, add_noise, gas_signal
from .validation import check_sample_interval

__all__ = [
    "EFFECT_NAMES",
    "EffectRecord",
    "default_effect_params",
    "effect_forms",
    "simulate_effect",
]

#: Offset between degrees C and kelvin (the simulator's own, as its physics is).
KELVIN = 273.15
#: Factors of the product S(s) = Π 1/((1 + a_n)(1 + τ_n s)) of sech simulated as lags.
FIN_PRODUCT_TERMS = 200
#: Phase of the velocity modulation at t = 0, rad: v(0) is not at a turning point.
VELOCITY_PHASE = 0.3
#: Width of a speed step's tanh edge per period of the ``steps`` velocity form.
VELOCITY_STEP_EDGE = 0.01

#: Allowed range of each effect parameter: lower bound, upper bound (always excluded), and
#: whether the lower bound itself is allowed.
_RANGES: dict[str, tuple[float, float, bool]] = {
    "tau_leg": (0.0, np.inf, False),
    "tau_p": (0.0, np.inf, False),
    "kappa1": (0.0, np.inf, True),
    "kappa2": (0.0, np.inf, True),
    "wall_lag_s": (0.0, np.inf, False),
    "rho1": (0.0, np.inf, True),
    "rho2": (0.0, np.inf, True),
    "wall_c": (-KELVIN, np.inf, False),
    "m": (0.0, np.inf, True),
    "depth": (0.0, 1.0, True),
    "period_s": (0.0, np.inf, False),
    "delay_s": (0.0, np.inf, True),
    "gain": (0.0, np.inf, False),
    "offset_c": (-np.inf, np.inf, False),
    "sigma_ratio": (0.0, np.inf, False),
    "property_exponent": (-np.inf, np.inf, False),
    "interference_hz": (0.0, np.inf, False),
    "interference_c": (0.0, np.inf, True),
}
#: Relative amplitudes of the odd harmonics 1, 3, 5 of ``interference`` (a rectified pick-up).
INTERFERENCE_HARMONICS = ((1, 1.0), (3, 0.3), (5, 0.1))


@dataclass(frozen=True, kw_only=True)
class EffectRecord:
    """A simulated two-thermocouple record with one hidden effect.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times in seconds, starting at 0.
    gas : ndarray, shape (N,)
        True gas temperature at junction 1 at the sample instants, degrees C.
    tc1, tc2 : ndarray, shape (N,)
        Noisy thermocouple readings, degrees C.
    clean1, clean2 : ndarray, shape (N,)
        Noise-free readings, degrees C.
    tau1, tau2 : float
        True time constants in seconds: the convective ones for ``radiation``, the nominal
        τi0 (at v = v0) for ``velocity``.
    dt : float
        Sample interval in seconds.
    effect : str or None
        The hidden effect, one of :data:`EFFECT_NAMES`; None for plain first-order sensors.
    form : str
        The effect's form (:func:`effect_forms`; '' for an effect of one form or none).
    params : dict of str to float
        The effect's true parameters as used (defaults with the caller's overrides).
    sigma1, sigma2 : float
        Noise standard deviations, degrees C.
    kind : str
        Gas signal kind (see :func:`tcomp_core.simulate.gas_signal`).
    gas_held : ndarray, shape (N,)
        True gas temperature at junction 1 averaged over each interval [t_k, t_k+1) of the
        fine grid (trapezoid rule), what element k of a reconstruction estimates; the last
        element is the last instant's value. Sharp pulses make it differ from ``gas``.
    """

    time: NDArray[np.float64]
    gas: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    clean1: NDArray[np.float64]
    clean2: NDArray[np.float64]
    tau1: float
    tau2: float
    dt: float
    effect: str | None
    form: str
    params: dict[str, float]
    sigma1: float
    sigma2: float
    kind: str
    gas_held: NDArray[np.float64] | None = None


def _check_effect(effect: str | None) -> str | None:
    """Return the effect name, None for no effect (``None`` or ``"none"``)."""
    if effect is None or effect == "none":
        return None
    if effect not in EFFECT_NAMES:
        raise ValueError(
            f"unknown effect {effect!r}; choose one of {', '.join(EFFECT_NAMES)} or None"
        )
    return effect


def effect_forms(effect: str | None) -> tuple[str, ...]:
    """The forms the simulator gives ``effect`` in, the fit's first; ``("",)`` for one form.

    Raises
    ------
    ValueError
        On an unknown effect.
    """
    effect = _check_effect(effect)
    return ("",) if effect is None else EFFECTS[effect].simulation_forms


def _check_form(effect: str | None, form: str | None) -> str:
    """The form, the effect's first when None; raises ValueError naming the known forms."""
    forms = effect_forms(effect)
    if form is None:
        return forms[0]
    if form not in forms:
        known = ", ".join(repr(name) for name in forms)
        raise ValueError(f"unknown form {form!r} of effect {effect!r}; choose one of {known}")
    return form


def default_effect_params(
    effect: str | None, tau1: float, tau2: float, form: str | None = None
) -> dict[str, float]:
    """Default true parameters of an effect, strong enough to see in 10 s at K = 1–2 %.

    Each effect states its own (:meth:`~tcomp_core.effects.base.Effect.simulation_defaults`,
    which lists them with their units).

    Parameters
    ----------
    effect : str or None
        One of :data:`EFFECT_NAMES`; None (or ``"none"``) has no parameters.
    tau1, tau2 : float
        Time constants of the two sensors in seconds (``radiation`` and the ``lumped prong``
        conduction scale the thicker wire's parameter with them).
    form : str, optional
        One of :func:`effect_forms` (its first by default).

    Returns
    -------
    dict of str to float
    """
    effect = _check_effect(effect)
    tau1, tau2 = _check_tau(tau1, "tau1"), _check_tau(tau2, "tau2")
    form = _check_form(effect, form)
    if effect is None:
        return {}
    return EFFECTS[effect]().simulation_defaults(tau1, tau2, form)


def _check_tau(tau: float, name: str) -> float:
    tau = float(tau)
    if not (np.isfinite(tau) and tau > 0.0):
        raise ValueError(f"{name}={tau!r} s must be finite and > 0")
    return tau


def _effect_params(
    effect: str | None,
    tau1: float,
    tau2: float,
    overrides: Mapping[str, float] | None,
    form: str,
) -> dict[str, float]:
    """Defaults of ``effect`` with ``overrides`` applied, each checked against its range."""
    params = default_effect_params(effect, tau1, tau2, form)
    for key, value in (overrides or {}).items():
        if key not in params:
            allowed = ", ".join(params) or "none"
            in_form = f" in form {form!r}" if form else ""
            raise ValueError(
                f"unknown parameter {key!r} for effect {effect!r}{in_form}; allowed: {allowed}"
            )
        params[key] = float(value)
    for key, value in params.items():
        lower, upper, lower_allowed = _RANGES[key]
        above = value >= lower if lower_allowed else value > lower
        if not (np.isfinite(value) and above and value < upper):
            bracket = "[" if lower_allowed else "("
            raise ValueError(
                f"{effect} parameter {key}={value!r} outside {bracket}{lower}, {upper})"
            )
    return params


def _gas_params(effect: str | None, signal_params: Mapping[str, float] | None) -> dict[str, float]:
    """Gas signal parameters: the effect's own (hot gas for radiation) unless the caller's."""
    own = {} if effect is None else EFFECTS[effect].simulation_gas
    return {**own, **(signal_params or {})}


def _lti_response(
    numerator: list[float], denominator: NDArray[np.float64], gas: NDArray[np.float64], step: float
) -> NDArray[np.float64]:
    """Response of a unity-DC-gain G(s) to the linearly interpolated ``gas``, from equilibrium.

    Parameters
    ----------
    numerator, denominator : array_like
        Polynomial coefficients of G(s) in descending powers of s.
    gas : ndarray, shape (M,)
        Input on a uniform grid, degrees C.
    step : float
        Grid spacing in seconds.

    Returns
    -------
    ndarray, shape (M,)
        Output at the grid points, degrees C; equal to :func:`scipy.signal.lsim` on the
        deviation from ``gas[0]`` to rounding.
    """
    # The first-order hold is exact for an input linear between grid points; a zero state
    # and a zero initial deviation mean equilibrium with gas[0].
    # scipy-stubs 1.17 takes a 2-D numerator only; scipy takes the 1-D one of a SISO system.
    b, a, _ = signal.cont2discrete(  # type: ignore[call-overload]
        (numerator, denominator), step, method="foh"
    )
    return gas[0] + signal.lfilter(np.ravel(b), a, gas - gas[0])


def _first_order_tf(tau: float) -> tuple[list[float], NDArray[np.float64]]:
    """G(s) = 1 / (1 + τ s) as (numerator, denominator)."""
    return [1.0], np.array([tau, 1.0])


def _fin_response(
    gas: NDArray[np.float64], tau: float, tau_leg: float, tau_p: float, step: float
) -> NDArray[np.float64]:
    """A junction between two fin legs whose supports lag the gas, from equilibrium.

    The wire obeys τ ∂T/∂t = ∂²T/∂x²/m² + Tg − T with the supports at Tg/(1 + τp s); at the
    junction G(s) = (1 − S)/(1 + τ s) + S/(1 + τp s), S(s) = sech(mL √(1 + τ s)), mL =
    √(tau_leg/τ). S is simulated as the Weierstrass product of cosh, Π 1/((1 + a_n)(1 + τ_n s))
    with a_n = 4 (mL)²/((2n − 1)² π²) and τ_n = τ a_n/(1 + a_n): the first
    :data:`FIN_PRODUCT_TERMS` factors as lags in cascade, all with their DC gain sech(mL).
    """
    fin_ml = np.sqrt(tau_leg / tau)
    n = np.arange(1, FIN_PRODUCT_TERMS + 1)
    a = 4.0 * fin_ml**2 / ((2 * n - 1) ** 2 * np.pi**2)
    deviation = gas - gas[0]
    pulled = deviation / np.cosh(fin_ml)
    for lag in tau * a / (1.0 + a):
        pulled = _lti_response([1.0], np.array([lag, 1.0]), pulled, step)
    return (
        gas[0]
        + _lti_response([1.0], np.array([tau, 1.0]), deviation - pulled, step)
        + _lti_response([1.0], np.array([tau_p, 1.0]), pulled, step)
    )


def _prong_response(
    gas: NDArray[np.float64], tau: float, kappa: float, tau_p: float, step: float
) -> NDArray[np.float64]:
    """A junction coupled to a prong that lags the gas, from equilibrium.

    τ dT/dt = Tg − T + κ (Tp − T) and τp dTp/dt = Tg − Tp (the prong is heavy: the junction's
    heat does not move it), so G(s) = [1 + κ/(1 + τp s)]/(1 + κ + τ s) = (τp s + 1 + κ) /
    ((τ s + 1 + κ)(τp s + 1)), unity DC gain.
    """
    denominator = np.asarray(np.polymul([tau, 1.0 + kappa], [tau_p, 1.0]), dtype=np.float64)
    return _lti_response([tau_p, 1.0 + kappa], denominator, gas, step)


def _warming_wall(
    gas_k: NDArray[np.float64], wall_k: float, lag_s: float, step: float
) -> NDArray[np.float64]:
    """A wall starting at ``wall_k`` that follows the gas through a lag of ``lag_s`` (K, s).

    Linear: the lag's response from equilibrium with the first gas value, plus the initial
    difference decaying at the lag's rate. ``step`` is the grid spacing of ``gas_k``, s.
    """
    time = np.arange(gas_k.size) * step
    lagged = _lti_response(*_first_order_tf(lag_s), gas_k, step)
    return np.asarray(lagged + (wall_k - gas_k[0]) * np.exp(-time / lag_s))


def _radiation_equilibrium(gas_k: float, r: float, wall_k: float) -> float:
    """Sensor temperature in K with Tg − T − r (T⁴ − Tw⁴) = 0 for constant gas ``gas_k`` (K)."""
    low, high = sorted((gas_k, wall_k))
    if r == 0.0 or low == high:
        return gas_k
    # The balance falls monotonically in T and changes sign between the gas and the wall.
    return float(
        optimize.brentq(
            lambda temp: gas_k - temp - r * (temp**4 - wall_k**4), low, high, xtol=1e-12
        )
    )


def _radiation_response(
    gas_k: NDArray[np.float64],
    tau: float,
    r: float,
    wall_k: NDArray[np.float64],
    step: float,
    stride: int,
) -> NDArray[np.float64]:
    """RK4 solution of τ dT/dt = Tg − T − r (T⁴ − Tw⁴), temperatures in K, from equilibrium.

    Parameters
    ----------
    gas_k : ndarray, shape (M,)
        Gas temperature in K on a grid of spacing ``step / 2``; ``M - 1`` is a multiple of
        ``2 * stride``. Even points start the RK4 steps, odd points are their midpoints.
    tau : float
        Convective time constant in seconds.
    r : float
        Radiative coefficient in K⁻³.
    wall_k : ndarray, shape (M,)
        Wall temperature in K on the grid of ``gas_k``.
    step : float
        RK4 step in seconds.
    stride : int
        RK4 steps per output sample.

    Returns
    -------
    ndarray, shape ((M - 1) // (2 * stride) + 1,)
        Sensor temperature in K every ``stride`` steps.
    """
    # The gas less the wall's share of the loss, g + r Tw⁴: the balance is then g' − T − r T⁴.
    drive = (gas_k + r * wall_k**4).tolist()
    rate, half = 1.0 / tau, 0.5 * step
    temp = _radiation_equilibrium(float(gas_k[0]), r, float(wall_k[0]))
    out = [temp]
    i = 0
    # Inlined scalar RK4: a Python loop over floats is ~20x faster than numpy on 2 elements.
    for _ in range((gas_k.size - 1) // (2 * stride)):
        for _ in range(stride):
            g0, gm, g1 = drive[i], drive[i + 1], drive[i + 2]
            i += 2
            k1 = (g0 - temp - r * temp**4) * rate
            y = temp + half * k1
            k2 = (gm - y - r * y**4) * rate
            y = temp + half * k2
            k3 = (gm - y - r * y**4) * rate
            y = temp + step * k3
            k4 = (g1 - y - r * y**4) * rate
            temp += step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out.append(temp)
    return np.array(out)


def _level_response(
    gas_k: NDArray[np.float64], tau: float, exponent: float, ref_k: float, step: float, stride: int
) -> NDArray[np.float64]:
    """RK4 solution of τ (T_f/T_ref)^p dT/dt = Tg − T, temperatures in K, from equilibrium.

    T_f = (T + Tg)/2 is the film temperature at which the gas properties are taken.

    The grid is laid out as in :func:`_radiation_response`; returns the sensor temperature in
    K every ``stride`` steps.
    """
    gas = gas_k.tolist()
    half, film_ref = 0.5 * step, 2.0 * ref_k
    temp = gas[0]
    out = [temp]
    i = 0
    for _ in range((len(gas) - 1) // (2 * stride)):
        for _ in range(stride):
            g0, gm, g1 = gas[i], gas[i + 1], gas[i + 2]
            i += 2
            k1 = (g0 - temp) / (tau * ((temp + g0) / film_ref) ** exponent)
            y = temp + half * k1
            k2 = (gm - y) / (tau * ((y + gm) / film_ref) ** exponent)
            y = temp + half * k2
            k3 = (gm - y) / (tau * ((y + gm) / film_ref) ** exponent)
            y = temp + step * k3
            k4 = (g1 - y) / (tau * ((y + g1) / film_ref) ** exponent)
            temp += step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out.append(temp)
    return np.array(out)


def _velocity_factor(
    t: NDArray[np.float64], m: float, depth: float, period_s: float, form: str
) -> NDArray[np.float64]:
    """τ0/τ(t) = (v(t)/v0)^m.

    ``sine``: v(t)/v0 = 1 + depth sin(2π t / period_s + 0.3); ``steps``: 1 + depth times that
    sine's sign, through tanh edges :data:`VELOCITY_STEP_EDGE` of a period wide.
    """
    wave = np.sin(2.0 * np.pi * t / period_s + VELOCITY_PHASE)
    if form == "steps":
        wave = np.tanh(wave / (2.0 * np.pi * VELOCITY_STEP_EDGE))
    return (1.0 + depth * wave) ** m


def _linear_rk4_response(
    gas: NDArray[np.float64], factor: NDArray[np.float64], tau0: float, step: float, stride: int
) -> NDArray[np.float64]:
    """RK4 solution of τ0 dT/dt = f(t) (Tg − T), i.e. τ(t) = τ0 / f(t), from equilibrium.

    The equation is linear in T, so each RK4 step is T ← A T + B with A, B computed for all
    steps at once; only that recursion runs in Python.

    Parameters
    ----------
    gas, factor : ndarray, shape (M,)
        Gas temperature (degrees C) and f(t) on a grid of spacing ``step / 2``, laid out as in
        :func:`_radiation_response`.
    tau0 : float
        Time constant at f = 1, seconds.
    step : float
        RK4 step in seconds.
    stride : int
        RK4 steps per output sample.

    Returns
    -------
    ndarray, shape ((M - 1) // (2 * stride) + 1,)
        Sensor temperature in degrees C every ``stride`` steps.
    """
    # dT/dt = -p T + q; each RK4 slope k = alpha T + beta.
    p = factor / tau0
    q = p * gas
    p0, pm, p1 = p[:-1:2], p[1::2], p[2::2]
    q0, qm, q1 = q[:-1:2], q[1::2], q[2::2]
    half = 0.5 * step
    alpha1, beta1 = -p0, q0
    alpha2, beta2 = -pm * (1.0 + half * alpha1), qm - pm * half * beta1
    alpha3, beta3 = -pm * (1.0 + half * alpha2), qm - pm * half * beta2
    alpha4, beta4 = -p1 * (1.0 + step * alpha3), q1 - p1 * step * beta3
    gains = (1.0 + step / 6.0 * (alpha1 + 2.0 * alpha2 + 2.0 * alpha3 + alpha4)).tolist()
    drives = (step / 6.0 * (beta1 + 2.0 * beta2 + 2.0 * beta3 + beta4)).tolist()
    temp = float(gas[0])
    out = [temp]
    for k, (gain, drive) in enumerate(zip(gains, drives, strict=True), start=1):
        temp = gain * temp + drive
        if k % stride == 0:
            out.append(temp)
    return np.array(out)


def _fine_time(n: int, dt: float, points_per_sample: int) -> NDArray[np.float64]:
    """Uniform grid from 0 to the last sample instant with ``points_per_sample`` per interval."""
    count = (n - 1) * points_per_sample + 1
    return np.arange(count, dtype=np.float64) * (dt / points_per_sample)


def _interval_means(fine: NDArray[np.float64], per_sample: int) -> NDArray[np.float64]:
    """Trapezoid mean of a fine-grid series over each sample interval, shape (n,)."""
    edges = fine[::per_sample]
    inner = fine[:-1].reshape(-1, per_sample)
    means = (inner.sum(axis=1) - 0.5 * inner[:, 0] + 0.5 * edges[1:]) / per_sample
    return np.append(means, fine[-1])


def _delayed_gas(
    kind: SignalKind, t: NDArray[np.float64], delay: float, gas_params: Mapping[str, float]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gas at junction 1, g(t + δ), and at junction 2, g(t), from one generator call.

    Advancing junction 1 rather than delaying junction 2 keeps the times non-negative (the
    exhaust generator is not defined before 0), and one call keeps signals that depend on the
    whole time array (multisine normalisation, exhaust pulse heights) identical for both.
    """
    step = t[1] - t[0]
    shift = round(delay / step)
    if abs(delay - shift * step) <= 1e-9 * step:
        # δ is a whole number of grid steps: one grid longer by the shift serves both junctions.
        gas = gas_signal(kind, np.arange(t.size + shift) * step, **gas_params)
        return gas[shift:], gas[: t.size]
    gas = gas_signal(kind, np.concatenate((t + delay, t)), **gas_params)
    return gas[: t.size], gas[t.size :]


def _simulate_clean(
    effect: str | None,
    form: str,
    kind: SignalKind,
    taus: tuple[float, float],
    params: Mapping[str, float],
    gas_params: Mapping[str, float],
    n: int,
    dt: float,
    oversample: int,
) -> tuple[NDArray[np.float64], ...]:
    """Gas and both noise-free readings at the sample instants, and the held gas, shape (n,).

    The held gas is the gas averaged over each interval (:func:`_interval_means`); degrees C.
    """
    if effect in ("radiation", "velocity", "property"):
        stride = (oversample + 1) // 2
        t = _fine_time(n, dt, 2 * stride)
        gas = gas_signal(kind, t, **gas_params)
        step = dt / stride
        if effect == "radiation":
            wall_k = np.full(gas.size, params["wall_c"] + KELVIN)
            if form == "lagging wall":
                wall_k = _warming_wall(gas + KELVIN, wall_k[0], params["wall_lag_s"], step / 2)
            cube = 4.0 * (float(np.mean(gas)) + KELVIN) ** 3  # rho_i = 4 r_i T̄³
            clean = [
                _radiation_response(gas + KELVIN, tau, params[rho] / cube, wall_k, step, stride)
                - KELVIN
                for tau, rho in zip(taus, ("rho1", "rho2"), strict=True)
            ]
        elif effect == "property":
            ref_k = float(np.mean(gas)) + KELVIN
            clean = [
                _level_response(
                    gas + KELVIN, tau, params["property_exponent"], ref_k, step, stride
                )
                - KELVIN
                for tau in taus
            ]
        else:
            factor = _velocity_factor(t, params["m"], params["depth"], params["period_s"], form)
            clean = [_linear_rk4_response(gas, factor, tau, step, stride) for tau in taus]
        held = _interval_means(gas, 2 * stride)
        return gas[:: 2 * stride], clean[0], clean[1], held

    t = _fine_time(n, dt, oversample)
    step = dt / oversample
    if effect == "delay":
        gas, gas2 = _delayed_gas(kind, t, params["delay_s"], gas_params)
    else:
        gas = gas2 = gas_signal(kind, t, **gas_params)
    if effect == "conduction" and form == "lumped prong":
        clean1, clean2 = (
            _prong_response(series, tau, params[kappa], params["tau_p"], step)[::oversample]
            for series, tau, kappa in zip((gas, gas2), taus, ("kappa1", "kappa2"), strict=True)
        )
    elif effect == "conduction":
        clean1, clean2 = (
            _fin_response(series, tau, params["tau_leg"], params["tau_p"], step)[::oversample]
            for series, tau in zip((gas, gas2), taus, strict=True)
        )
    else:
        clean1 = _lti_response(*_first_order_tf(taus[0]), gas, step)[::oversample]
        clean2 = _lti_response(*_first_order_tf(taus[1]), gas2, step)[::oversample]
    if effect == "calibration":
        clean2 = params["gain"] * clean2 + params["offset_c"]
    if effect == "interference":
        time = np.arange(n) * dt
        for harmonic, share in INTERFERENCE_HARMONICS:
            phase = 2.0 * np.pi * harmonic * params["interference_hz"] * time
            clean2 = clean2 + params["interference_c"] * share * np.sin(phase)
    return gas[::oversample], clean1, clean2, _interval_means(gas, oversample)


def simulate_effect(
    effect: str | None,
    kind: SignalKind = "multisine",
    *,
    tau1: float = PAPER_TAU1,
    tau2: float = PAPER_TAU2,
    dt: float = PAPER_DT,
    duration: float = 10.0,
    noise_percent: float = 1.0,
    seed: int = 0,
    params: Mapping[str, float] | None = None,
    signal_params: Mapping[str, float] | None = None,
    oversample: int = 20,
    form: str | None = None,
) -> EffectRecord:
    """Simulate two thermocouples in one gas with a hidden effect, in continuous time.

    Parameters
    ----------
    effect : str or None
        One of :data:`EFFECT_NAMES`, or None (``"none"``) for plain first-order sensors.
    kind : {'sinusoid', 'ramp', 'multisine', 'exhaust'}
        Gas temperature signal (:func:`tcomp_core.simulate.gas_signal`). For ``radiation`` its
        ``mean`` and ``amplitude`` default to 700 and 250 degrees C.
    tau1, tau2 : float
        True time constants in seconds (τi0 for ``velocity``, convective for ``radiation``).
    dt : float
        Sample interval in seconds.
    duration : float
        Record length in seconds; ``round(duration / dt)`` samples.
    noise_percent : float
        Noise level K in percent of std(clean1) (Eq. 22), >= 0.
    seed : int
        Seed of the noise generator.
    params : mapping of str to float, optional
        Overrides of individual entries of :func:`default_effect_params`.
    signal_params : mapping of str to float, optional
        Keyword parameters of the gas signal generator.
    oversample : int
        Grid points per sample interval of the continuous simulation (rounded up to even for
        ``radiation`` and ``velocity``).
    form : str, optional
        The effect's form (:func:`effect_forms`): ``conduction`` as ``fin legs`` or a
        ``lumped prong``, ``radiation`` to a ``constant wall`` or a ``lagging wall``,
        ``velocity`` as a ``sine`` or ``steps``; the first, the form the fit assumes, by
        default.

    Returns
    -------
    EffectRecord

    Raises
    ------
    ValueError
        On an unknown effect, form or parameter, a parameter out of its range, or a non-positive
        ``dt``, ``duration``, ``tau1``, ``tau2`` or ``oversample``, or negative
        ``noise_percent``.
    """
    effect = _check_effect(effect)
    dt = check_sample_interval(dt)
    if not (np.isfinite(duration) and duration > 0.0):
        raise ValueError(f"{duration=} must be finite and > 0 s")
    if not noise_percent >= 0.0:
        raise ValueError(f"{noise_percent=} must be >= 0")
    if int(oversample) != oversample or oversample < 1:
        raise ValueError(f"{oversample=} must be a whole number >= 1")
    n = round(duration / dt)
    if n < 2:
        raise ValueError(f"{duration=} s holds fewer than 2 samples at {dt=} s")
    form = _check_form(effect, form)
    true_params = _effect_params(effect, tau1, tau2, params, form)
    taus = (float(tau1), float(tau2))
    gas, clean1, clean2, held = _simulate_clean(
        effect,
        form,
        kind,
        taus,
        true_params,
        _gas_params(effect, signal_params),
        n,
        dt,
        int(oversample),
    )
    phi = true_params["sigma_ratio"] ** -2 if effect == "noise_ratio" else 1.0
    rng = np.random.default_rng(seed)
    tc1, tc2, sigma1, sigma2 = add_noise(clean1, clean2, noise_percent, phi, rng)
    return EffectRecord(
        time=np.arange(n, dtype=np.float64) * dt,
        gas=gas,
        tc1=tc1,
        tc2=tc2,
        clean1=clean1,
        clean2=clean2,
        tau1=taus[0],
        tau2=taus[1],
        dt=dt,
        effect=effect,
        form=form,
        params=true_params,
        sigma1=sigma1,
        sigma2=sigma2,
        kind=kind,
        gas_held=held,
    )
