"""A two-thermocouple model: the first-order base plus any set of effects, and its fit.

The fit minimises the cross-relation criterion

    J(θ) = Σ_k (u1[k] − u2[k])² / (φ g1[k] + g2[k]),

where u_i is the gas temperature reconstructed from sensor i through its chain
(:mod:`tcomp_core.effects.chain`) and g_i the white-noise variance gain of that
reconstruction, so the denominator is the noise variance of the difference in units of σ2².
For the base model this is exactly the generalised total least squares criterion of β-GTLS
(Eqs. 18–21): both divide the squared equation error by its own noise variance. The same
criterion for every model makes their held-out errors comparable, and φ enters it as it enters
C0(φ).
"""

from __future__ import annotations

import functools
import itertools
import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.optimize import least_squares

from ..errors import EstimationError
from ..tolerance import class2_level_tolerance_c
from .base import KELVIN, Effect, FitContext, ParamSpec
from .chain import (
    SHIFT_HALF_TAPS,
    Aligned,
    SensorChain,
    aligned_reading,
    gas_and_noise_gain,
    gas_from_reading,
    reading_from_gas,
)
from .registry import EFFECTS, check_effect_names

__all__ = [
    "LEVEL",
    "ORDER_RATIO",
    "LeastSquaresProblem",
    "Model",
    "make_context",
    "swapped_sensors",
]

#: The base model's level difference between the sensors: tc2 reads T + level_c where tc1
#: reads T, degrees C (see :attr:`Model.has_level`).
LEVEL = "level_c"

#: Time constants closer than this factor leave undecided which sensor is the slower.
ORDER_RATIO = 1.5

#: Evaluations allowed to each start of a multi-start search before the best is polished.
_SCOUT_EVALUATIONS = 30
#: Relative tolerances (cost and step) of the cross-relation fit, its scouts' and its polish's.
#: Its residuals are in units of their noise, so at the noise floor the cost is about N/2 and
#: a change of 0.5 is one standard deviation of one parameter; 1e-6 of the cost is 0.03 or less
#: up to N = 60 000 (6 s at 10 kHz). At scipy's 1e-8 the fits crept on along valleys the data
#: do not resolve: on the conduction bag the conduction fit ended 0.0004 lower in cost and the
#: delay fit 0.008 lower, for half again the time (a support mode moved 55 % between the two,
#: the held-out error 0.05 %), and 33 diagnoses took 1.47x as long in all (0.8-3x each, README).
#: The scouts stop there too: at 1e-4 (they only choose the polish's basin) 33 diagnoses were
#: 1.15x faster with the same results, but on a fresh draw a lagging wall's radiation scout
#: stopped in a worse basin, calibration took its place and the final τ came out 10-14 % short.
FIT_TOLERANCE = 1e-6
#: Samples of the stretch (mid-record) the starts are scouted on when the record is longer:
#: the scouts only choose the basin; the polish runs on every sample.
_SCOUT_SAMPLES = 10_000


def swapped_sensors(taus: tuple[float, float], published_taus: tuple[float, float]) -> str:
    """Why ``taus`` make the other sensor the slower one than ``published_taus`` do ('' if not).

    Which sensor is the slower is its wire's (diameter, junction), and no effect swaps it; the
    default path's τ (ml-eiv with the sensors' gain) tell it where they differ by more than
    :data:`ORDER_RATIO`. A fit that puts it the other way round by as much has traded the lag
    for something else. The final fits of 10 of 640 campaign draws did, every one on steps with
    a mains line or strong conduction and none to the gas's good: on four a delay (0.27 and
    0.54 s on the two looked at) with τ1 and τ2 swapped around it (2513, 2691, 2753, 2758),
    which applied made the gas 7.6 → 29.7 % and 1.6 → 30.3 % off; the other six had a τ on a
    bound and were refused anyway.
    """
    fitted, published = taus[0] / taus[1], published_taus[0] / published_taus[1]
    if not (0.0 < fitted < math.inf and 0.0 < published < math.inf):
        return ""
    # log > 0: tc1 the slower; each order decided only beyond ORDER_RATIO.
    orders = (math.log(fitted), math.log(published))
    if min(abs(order) for order in orders) < math.log(ORDER_RATIO) or orders[0] * orders[1] > 0:
        return ""
    return (
        f"tau1/tau2 = {taus[0]:.3g}/{taus[1]:.3g} s make tc{1 if fitted > 1.0 else 2} the "
        f"slower sensor, where the default path's {published_taus[0]:.3g}/"
        f"{published_taus[1]:.3g} s make it tc{1 if published > 1.0 else 2}: which wire is "
        "the slower no effect changes"
    )


def make_context(
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    *,
    phi_hat: float = 1.0,
    knot_spacing_s: float | None = None,
    tau_scale_s: float | None = None,
    sigma2: float = 1.0,
    base_taus_s: tuple[float, float] | None = None,
    film_cutoff_hz: float | None = None,
) -> FitContext:
    """Build the :class:`FitContext` of a record.

    Parameters
    ----------
    time : ndarray, shape (N,)
        Sample times, s (shifted to start at 0).
    tc1, tc2 : ndarray, shape (N,)
        Readings, degrees C.
    dt : float
        Sample interval, s.
    phi_hat : float
        Noise variance ratio σ1²/σ2² measured from the spectra by the model
        (:func:`tcomp_core.noise.model_noise`).
    knot_spacing_s : float, optional
        Knot spacing of slowly varying quantities; default a tenth of the record.
    tau_scale_s : float, optional
        A rough time constant of the slower sensor; default 20 samples.
    sigma2 : float
        Noise standard deviation of thermocouple 2 at this sample rate, degrees C.
    base_taus_s : tuple of float, optional
        τ1, τ2 of the first-order model, s (for the effects' physical bounds).
    film_cutoff_hz : float, optional
        Band edge of the gas signal, Hz: the gas that sets the film temperature of a
        level-dependent τ is low-passed there (default: not low-passed).
    """
    time = np.asarray(time, dtype=np.float64) - float(time[0])
    both = np.concatenate((tc1, tc2))
    duration = float(time[-1]) + dt
    return FitContext(
        dt=dt,
        time=time,
        level_mean_c=float(both.mean()),
        level_std_c=float(both.std()),
        knot_spacing_s=knot_spacing_s or duration / 10.0,
        phi_hat=phi_hat,
        tau_scale_s=tau_scale_s or 20.0 * dt,
        sigma2=sigma2,
        base_taus_s=base_taus_s,
        film_cutoff_hz=film_cutoff_hz,
    )


#: The hooks of :class:`~.base.Effect` that set fields of a sensor chain.
_CHAIN_HOOKS = (
    "additive",
    "calibration",
    "conduction",
    "tau_factor",
    "level_exponent",
    "radiation",
    "delay_s",
)
#: Every field of a sensor chain, in order (the memo's key), and where its arrays are.
_CHAIN_FIELDS = operator.attrgetter(*(f.name for f in fields(SensorChain)))
_ARRAY_FIELDS = tuple(
    i for i, f in enumerate(fields(SensorChain)) if f.name in ("factor", "film_sos", "additive")
)


class _ChainMemo:
    """The last few inverse-chain results of each sensor, within one fit.

    A finite-difference Jacobian moves one parameter at a time and most parameters belong to
    one sensor's chain (τ1 to sensor 1, a calibration or delay to sensor 2), so the other
    sensor's gas is the one just computed: it is looked up instead of filtered again. Chains
    match when every scalar field is equal and they hold the very same ``factor`` array (the
    velocity effect returns one array per set of coefficients); the memo keeps the chains it
    stores alive, so an identity cannot be reused by another array while it is compared.
    """

    SIZE = 3

    def __init__(self) -> None:
        self._entries: dict[int, list[tuple[tuple, SensorChain, tuple]]] = {1: [], 2: []}
        # Per sensor: the last readings aligned (line off, delay undone), which most columns
        # of a Jacobian share, with the key and the line array it was computed for.
        self._aligned: dict[int, tuple[tuple, SensorChain, Aligned]] = {}

    @staticmethod
    def _key(chain: SensorChain) -> tuple:
        """Every field: scalars by value, arrays (factor, film filter, line) by identity."""
        key = list(_CHAIN_FIELDS(chain))
        for i in _ARRAY_FIELDS:
            if key[i] is not None:
                key[i] = ("array", id(key[i]))
        return tuple(key)

    def gas(
        self,
        sensor: int,
        chain: SensorChain,
        reading: NDArray[np.float64],
        context: FitContext,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
        """:func:`~.chain.gas_and_noise_gain` of ``chain``, from the memo when just computed."""
        entries = self._entries[sensor]
        key = self._key(chain)
        for stored, _, value in entries:
            if stored == key:
                return value
        aligned = None
        if chain.additive is not None or chain.delay_s:
            line = None if chain.additive is None else id(chain.additive)
            stage = (line, chain.delay_s)
            found = self._aligned.get(sensor)
            if found is None or found[0] != stage:
                # The chain is kept with it: the line's identity stays its own.
                found = (stage, chain, aligned_reading(chain, reading, context.dt))
                self._aligned[sensor] = found
            aligned = found[2]
        value = gas_and_noise_gain(chain, reading, context.dt, context.noise_kernel, aligned)
        entries.insert(0, (key, chain, value))
        del entries[self.SIZE :]
        return value


@dataclass(frozen=True, kw_only=True)
class LeastSquaresProblem:
    """A model's fit criterion for :func:`scipy.optimize.least_squares`.

    Attributes
    ----------
    specs : tuple of ParamSpec
        The searched parameters, in the order of the search vector x.
    lower, upper : ndarray, shape (P,)
        Bounds of x (log of the bound for the time constants).
    n_rows : int
        Number of data residuals; penalty residuals follow them.
    unpack : callable
        x → parameter dict (fixed and setting values included).
    residuals : callable
        x → residual vector, shape (n_rows + penalties,).
    jacobian : callable
        x → its Jacobian, shape (n_rows + penalties, P) (see :class:`_Jacobian`).
    """

    specs: tuple[ParamSpec, ...]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    n_rows: int
    unpack: Callable[[NDArray[np.float64]], dict[str, float]]
    residuals: Callable[..., NDArray[np.float64]]
    jacobian: Callable[[NDArray[np.float64]], NDArray[np.float64]]

    def pack(self, params: Mapping[str, float]) -> NDArray[np.float64]:
        """Parameter dict → search vector x (the inverse of ``unpack``), shape (P,)."""
        return np.array(
            [
                math.log(params[s.name])
                if s.name.startswith("tau")
                else params.get(s.name, 0.0)
                if s.name == LEVEL
                else params[s.name]
                for s in self.specs
            ]
        )


class _Jacobian:
    """Forward-difference Jacobian of the fit's residuals, with a shortcut for s(t).

    Each column is (r(x + h e_i) − r(x))/h with scipy's 2-point step h = ±√ε max(1, |x_i|);
    the chain memo makes a column that moves one sensor's parameter cost one chain.
    Parameters that act only through the time-constant factor s(t) (velocity) need no
    evaluation: s(t_k) enters residual k only through both poles of interval k, exactly as
    log τ1 and log τ2 do together, so ∂r_k/∂log s_k is the sum of the log τ1 and log τ2
    columns, and the chain rule gives ∂r_k/∂θ = (∂r_k/∂log s_k)(∂log s_k/∂θ).
    Penalty rows (after the first ``n_rows``) are differenced in the usual way. r(x) itself
    is the residuals' last value when they were last evaluated at x (:class:`_LastResiduals`):
    scipy asks for the Jacobian where it has just evaluated them.
    """

    def __init__(
        self,
        residuals: _LastResiduals,
        lower: NDArray[np.float64],
        upper: NDArray[np.float64],
        n_rows: int,
        names: Sequence[str],
        log_factor_columns: Mapping[int, NDArray[np.float64]],
    ) -> None:
        self.residuals = residuals
        self.lower, self.upper = lower, upper
        self.n_rows = n_rows
        self.local = dict(log_factor_columns) if {"tau1", "tau2"} <= set(names) else {}
        self.taus: tuple[int, int] = (
            (list(names).index("tau1"), list(names).index("tau2")) if self.local else (0, 1)
        )

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        base = self.residuals.at(x)
        jac = np.empty((base.size, x.size))
        differenced = [i for i in range(x.size) if i not in self.local]
        for i in differenced:
            jac[:, i] = self._column(x, i, base)
        if self.local:
            per_sample = jac[: self.n_rows, self.taus[0]] + jac[: self.n_rows, self.taus[1]]
            for i, column in self.local.items():
                jac[: self.n_rows, i] = per_sample * column
                if base.size > self.n_rows:
                    jac[self.n_rows :, i] = self._column(x, i, base, penalty_only=True)
        return jac

    def _column(
        self, x: NDArray[np.float64], i: int, base: NDArray[np.float64], penalty_only=False
    ) -> NDArray[np.float64]:
        # scipy's 2-point step: towards the sign of x_i, turned back at a bound.
        step = _EPS_SQRT * (1.0 if x[i] >= 0 else -1.0) * max(1.0, abs(float(x[i])))
        if not self.lower[i] <= x[i] + step <= self.upper[i]:
            step = -step
        moved = x.copy()
        moved[i] += step
        step = float(moved[i] - x[i])  # the step x actually took, in floating point
        if penalty_only:
            return (self.residuals(moved, penalty_only=True) - base[self.n_rows :]) / step
        return (self.residuals(moved) - base) / step


_EPS_SQRT = math.sqrt(np.finfo(float).eps)


class _LastResiduals:
    """A fit's residual function that keeps its last value (all rows, not the penalties alone).

    :meth:`at` gives the residuals at x from that value when x is the point they were last
    evaluated at (the same numbers: the residuals are a function of x alone).
    """

    def __init__(self, residuals: Callable[..., NDArray[np.float64]]) -> None:
        self._residuals = residuals
        self._last: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def __call__(self, x: NDArray[np.float64], penalty_only: bool = False) -> NDArray[np.float64]:
        values = self._residuals(x, penalty_only)
        if not penalty_only:
            # Kept and handed out: read-only, so that a caller writing into it (scipy's robust
            # losses scale f in place; the fits use the linear one) fails instead of changing
            # the value a later Jacobian takes.
            values.flags.writeable = False
            self._last = (np.array(x, dtype=np.float64), values)
        return values

    def at(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The residuals at x, evaluated again only when x is not where they last were."""
        if self._last is not None and np.array_equal(self._last[0], x):
            return self._last[1]
        return self(x)


def _level_prior_sd(context: FitContext) -> float:
    """Standard deviation of the Gaussian prior on ``level_c``, degrees C.

    Class 2's tolerance between the sensors at the record's level is its 95 % bound. The data
    fix a level difference far better than that (a constant seen on every sample), so the
    prior decides only what they cannot: how much of a level difference an effect that also
    shifts the level (a radiative loss) takes, which is then as much as it can explain.
    """
    return class2_level_tolerance_c(context.level_mean_c) / 1.959963984540054


@functools.lru_cache(maxsize=16)
def _film_filter(dt: float, cutoff_hz: float | None) -> NDArray[np.float64] | None:
    """Second-order Butterworth low-pass for the film temperature's gas (cached: one array)."""
    if cutoff_hz is None or not 0.0 < cutoff_hz < 0.45 / dt:
        return None
    return signal.butter(2, cutoff_hz, output="sos", fs=1.0 / dt)  # shared: do not modify


def _effect(name: str) -> Effect:
    """A new instance of a checked effect name."""
    return EFFECTS[name]()


@dataclass(frozen=True)
class Model:
    """The first-order two-thermocouple model with zero or more effects.

    Parameters
    ----------
    effects : sequence of str
        Effect names (see :data:`tcomp_core.choices.EFFECT_NAMES`), in the order added.
    params : mapping of str to float
        Parameter values: ``tau1``, ``tau2`` (s) and the effects' own; empty before a fit.
    """

    effects: tuple[str, ...] = ()
    params: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        names = check_effect_names(self.effects)
        object.__setattr__(self, "effects", names)
        instances = tuple(_effect(name) for name in names)
        object.__setattr__(self, "_instances", instances)
        object.__setattr__(self, "params", dict(self.params))
        # Per chain hook, the effects that override it (the others return the neutral value):
        # a fit builds the chains for every residual.
        hooked = {
            hook: tuple(
                e for e in instances if getattr(type(e), hook) is not getattr(Effect, hook)
            )
            for hook in _CHAIN_HOOKS
        }
        object.__setattr__(self, "_hooked", hooked)

    @property
    def instances(self) -> tuple[Effect, ...]:
        """The effect objects."""
        return self._instances  # type: ignore[attr-defined]

    def implausible(
        self,
        base_taus_s: tuple[float, float] | None,
        collapsed_below_s: float = 0.0,
        published_taus_s: tuple[float, float] | None = None,
    ) -> str:
        """Why this model's parameters are no physical sensor ('' when they are plausible).

        A τ moved from a first-order estimate by more than the loosest
        :attr:`~.base.Effect.max_tau_factor` of the model's effects (down:
        :attr:`~.base.Effect.max_tau_fall` where an effect sets it), or an effect's own bound
        (:meth:`~.base.Effect.implausible`). The first-order estimates are the fit's base
        ``base_taus_s`` and, with effects, the default path's ``published_taus_s`` (None: not
        checked): the two first orders take different things into τ (the default path fits the
        sensors' gain and notches a line one channel carries; a line left on bent the base's
        τ1 to 1/40 of the truth, where the default path had it within 1 %), and an effect moves
        τ only so far from either. A first-order τ below ``collapsed_below_s`` (s; the sample
        interval) gives no scale: that first order found no lag to measure there (a missing
        delay collapses τ1 so), and that τ is not compared. τ that make the other sensor the
        slower one than the default path's do are none either (:func:`swapped_sensors`).
        """
        references = [("first-order", base_taus_s)]
        if published_taus_s is not None:
            references.append(("default path's", published_taus_s))
        for name, taus in references:
            reason = self._moved_too_far(name, taus, collapsed_below_s)
            if reason:
                return reason
        for effect in self.instances:
            reason = effect.implausible(self.params)
            if reason:
                return reason
        if published_taus_s is not None and self.instances:
            return swapped_sensors((self.tau1, self.tau2), published_taus_s)
        return ""

    def _moved_too_far(
        self, name: str, first_order_s: tuple[float, float] | None, collapsed_below_s: float
    ) -> str:
        """Why a τ lies beyond the effects' reach of the ``name`` first order ('' if none)."""
        if first_order_s is None or not self.instances:
            return ""
        rise = max(effect.max_tau_factor for effect in self.instances)
        fall = max(
            effect.max_tau_factor if effect.max_tau_fall is None else effect.max_tau_fall
            for effect in self.instances
        )
        for index, base in enumerate(first_order_s, start=1):
            tau = self.params.get(f"tau{index}", math.nan)
            if not (base > collapsed_below_s and base > 0.0 and tau > 0.0):
                continue
            if tau / base > rise:
                return (
                    f"tau{index} = {tau:.3g} s is {tau / base:.3g}x the {name} {base:.3g} s "
                    f"(at most {rise:.3g}x with {'+'.join(self.effects)})"
                )
            if base / tau > fall:
                return (
                    f"tau{index} = {tau:.3g} s is 1/{base / tau:.3g} of the {name} {base:.3g} s "
                    f"(at least 1/{fall:.3g} with {'+'.join(self.effects)})"
                )
        return ""

    def without_level(self) -> Model:
        """The model with the sensors' level difference left in the readings (``level_c`` 0).

        The fit needs the level difference; a gas temperature does not take it: which sensor's
        level is right two signals cannot tell, so each sensor's gas stays on its own scale
        and the reconstruction mixes them as the first-order one does.
        """
        return Model(self.effects, {k: v for k, v in self.params.items() if k != LEVEL})

    def with_effect(self, name: str) -> Model:
        """A new model with one more effect; the fitted parameters so far are kept."""
        if name in self.effects:
            raise ValueError(f"the model already has the effect {name!r}")
        return Model((*self.effects, name), self.params)

    @property
    def tau1(self) -> float:
        """Time constant of thermocouple 1, s."""
        return self.params["tau1"]

    @property
    def tau2(self) -> float:
        """Time constant of thermocouple 2, s."""
        return self.params["tau2"]

    @property
    def phi(self) -> float:
        """Noise variance ratio assumed by the fit."""
        return self._phi(self.params)

    def _phi(self, params: Mapping[str, float]) -> float:
        """The noise variance ratio these parameters give the model's effects."""
        for effect in self.instances:
            value = effect.noise_ratio(params)
            if value is not None:
                return value
        return 1.0

    @property
    def has_level(self) -> bool:
        """Whether the model fits the sensors' level difference ``level_c`` as a base parameter.

        True unless an effect fits the level itself (:attr:`~.base.Effect.fits_level`, a
        calibration's offset). Two sensors of one tolerance class differ in level by up to a
        few degrees, which no dynamics explains: left out, it bends τ on a drifting record (as
        ml-eiv's offset b would, :mod:`tcomp_core.estimators.mleiv`) and is taken up by
        whatever effect can shift a level (conduction, radiation).
        """
        return not any(effect.fits_level for effect in self.instances)

    def specs(self, context: FitContext) -> list[ParamSpec]:
        """Every searched parameter: τ1, τ2, ``level_c`` (:attr:`has_level`), the effects' own."""
        upper = max(context.duration_s, 100.0 * context.dt)
        taus = [
            ParamSpec(
                name=f"tau{i}",
                unit="s",
                lower=context.dt / 50.0,
                upper=upper,
                description=f"time constant of tc{i}",
            )
            for i in (1, 2)
        ]
        if self.has_level:
            span = 0.2 * abs(context.level_mean_c) + 10.0 * context.level_std_c + 10.0
            taus.append(
                ParamSpec(
                    name=LEVEL,
                    unit="degC",
                    lower=-span,
                    upper=span,
                    description="level of tc2 relative to tc1 (the sensors' calibrations)",
                )
            )
        return taus + [spec for effect in self.instances for spec in effect.specs(context)]

    def n_params(self, context: FitContext) -> int:
        """Number of parameters taken from the data (searched and fixed)."""
        fixed = sum(len(effect.fixed(context)) for effect in self.instances)
        return len(self.specs(context)) + fixed

    # -- the two sensor chains ------------------------------------------------------------

    def chains(self, context: FitContext, params: Mapping[str, float] | None = None):
        """The resolved :class:`SensorChain` of sensors 1 and 2."""
        params = self.params if params is None else params
        hooked: dict[str, tuple[Effect, ...]] = self._hooked  # type: ignore[attr-defined]
        has_level = self.has_level
        shares = (1.0, 1.0)
        # The hooks that do not depend on the sensor, once for both.
        common: dict[str, Any] = {}
        for effect in hooked["tau_factor"]:
            factor = effect.tau_factor(context, params)
            if factor is not None:
                common["factor"] = factor
        for effect in hooked["level_exponent"]:
            exponent = effect.level_exponent(params)
            if exponent is not None:
                common["level_exponent"] = exponent
                common["level_ref_k"] = context.level_mean_c + KELVIN
                common["level_weight"], common["film_weight"] = effect.level_weights(params)
                shares = effect.level_shares(params)
                common["film_sos"] = _film_filter(context.dt, context.film_cutoff_hz)
        chains = []
        for sensor in (1, 2):
            # The fields each effect sets, later effects over earlier ones. Each field has one
            # hook (the level's offset is set before any), so hook by hook is effect by effect.
            values: dict[str, Any] = {"tau": params[f"tau{sensor}"]}
            if sensor == 2 and has_level and params.get(LEVEL, 0.0):
                values["offset"] = params[LEVEL]
            for effect in hooked["additive"]:
                additive = effect.additive(sensor, params, context)
                if additive is not None:
                    values["additive"] = additive
            for effect in hooked["calibration"]:
                gain, offset = effect.calibration(sensor, params)
                if (gain, offset) != (1.0, 0.0):
                    values["gain"], values["offset"] = gain, offset
            for effect in hooked["conduction"]:
                conduction = effect.conduction(sensor, params)
                if conduction is not None:
                    values["fin_ml"], values["tau_p"], values["mode0"] = conduction
            values.update(common)
            if shares[sensor - 1] != 1.0:
                values["level_exponent"] = values["level_exponent"] * shares[sensor - 1]
            for effect in hooked["radiation"]:
                radiation = effect.radiation(sensor, params, context)
                if radiation is not None:
                    values["r"], values["wall_k"] = radiation
            for effect in hooked["delay_s"] if sensor == 2 else ():
                delay_s = effect.delay_s(params)
                if delay_s:
                    values["delay_s"] = delay_s
            chains.append(SensorChain(**values))
        return chains[0], chains[1]

    def reconstruct(
        self, tc1: NDArray[np.float64], tc2: NDArray[np.float64], context: FitContext
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Gas temperature from each sensor on the common time base, shape (N - 1,) each."""
        first, second = self.chains(context)
        return (
            gas_from_reading(first, tc1, context.dt)[0],
            gas_from_reading(second, tc2, context.dt)[0],
        )

    def cross_residual(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        context: FitContext,
        params: Mapping[str, float] | None = None,
        memo: _ChainMemo | None = None,
    ) -> NDArray[np.float64]:
        """Normalised cross-relation residual (u1 − u2)/(σ2 sqrt(φ g1 + g2)), shape (N - 1,).

        ``memo`` (inside a fit, for fixed readings) reuses a chain's gas computed just before.
        """
        params = self.params if params is None else params
        first, second = self.chains(context, params)
        memo = _ChainMemo() if memo is None else memo
        gas1, gain1 = memo.gas(1, first, tc1, context)
        gas2, gain2 = memo.gas(2, second, tc2, context)
        phi = self._phi(params)
        return (gas1 - gas2) / (context.sigma2 * np.sqrt(phi * gain1 + gain2))

    def simulate(
        self,
        reading: NDArray[np.float64],
        source: int,
        initial_reading: float,
        context: FitContext,
    ) -> NDArray[np.float64]:
        """Free-run simulation of the other sensor from sensor ``source``'s readings.

        Parameters
        ----------
        reading : ndarray, shape (N,)
            Readings of sensor ``source`` (1 or 2), degrees C.
        source : int
            The sensor whose readings drive the simulation.
        initial_reading : float
            The other sensor's reading at sample 0, degrees C.
        context : FitContext

        Returns
        -------
        ndarray, shape (N,)
            The other sensor's simulated readings, degrees C.
        """
        return self.simulator(reading, source, context)(initial_reading)

    def simulator(
        self, reading: NDArray[np.float64], source: int, context: FitContext
    ) -> Callable[[float], NDArray[np.float64]]:
        """:meth:`simulate` as a function of the initial reading (the gas computed once).

        A free run that restarts from several initial readings (:mod:`tcomp_core.diagnose.
        heldout`) inverts the source sensor's chain once.
        """
        chains = self.chains(context)
        gas, _ = gas_from_reading(chains[source - 1], reading, context.dt)
        other = chains[2 - source]
        return lambda initial_reading: reading_from_gas(other, gas, context.dt, initial_reading)

    # -- fitting ----------------------------------------------------------------------------

    def fit(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        context: FitContext,
        rows: NDArray[np.bool_] | None = None,
        hold: frozenset[str] = frozenset(),
        tolerance: float = FIT_TOLERANCE,
    ) -> Model:
        """Fit every parameter by the cross-relation criterion; returns the fitted model.

        Parameters without a value yet start from each effect's starting points (a short
        search from each, then the best is polished); those with one start there.

        Parameters
        ----------
        tc1, tc2 : ndarray, shape (N,)
            Readings, degrees C.
        context : FitContext
        rows : ndarray of bool, shape (N - 1,), optional
            Intervals the criterion uses (default all).
        hold : frozenset of str
            Parameters held at their current values (not searched).
        tolerance : float
            Relative tolerance of the search's cost and step, its scouts' too (default
            :data:`FIT_TOLERANCE`; looser only where a fit only ranks and the one chosen is
            then converged).

        Raises
        ------
        EstimationError
            If τ1 and τ2 have no values and no start can be made, or the search fails.
        """
        if "tau1" not in self.params or "tau2" not in self.params:
            raise EstimationError("the model needs starting values of tau1 and tau2")
        problem = self.problem(tc1, tc2, context, rows, hold)
        lower, upper = problem.lower, problem.upper
        residuals, jacobian, unpack = problem.residuals, problem.jacobian, problem.unpack
        starts = self._starts(context, problem, tc1, tc2)
        if not starts:
            raise EstimationError(
                f"{', '.join(self.effects)}: nothing in these data for the fit to start from "
                "(e.g. no line on one channel that the other does not share)"
            )
        # tr_solver="lsmr": the exact trust-region solver takes an SVD of the whole N × P
        # Jacobian every step (N ~ 20 000 rows: 40 % of a diagnosis); with P ≲ 20 LSMR solves
        # the same subproblem in a few products with J. SciPy's LSMR step needs two unknowns
        # (its two-dimensional subspace indexes a second one); one is solved exactly.
        solver: Literal["exact", "lsmr"] = "lsmr" if problem.lower.size > 1 else "exact"
        if len(starts) > 1:
            scout = self._scout_problem(tc1, tc2, context, rows, hold, problem)
            scouted = [
                least_squares(
                    scout.residuals,
                    x0,
                    jac=scout.jacobian,
                    bounds=(lower, upper),
                    max_nfev=_SCOUT_EVALUATIONS,
                    tr_solver=solver,
                    ftol=tolerance,
                    xtol=tolerance,
                )
                for x0 in starts
            ]
            x0 = min(scouted, key=lambda result: result.cost).x
        else:
            x0 = starts[0]
        result = least_squares(
            residuals,
            x0,
            jac=jacobian,
            bounds=(lower, upper),
            x_scale="jac",
            tr_solver=solver,
            ftol=tolerance,
            xtol=tolerance,
        )
        if not np.isfinite(result.cost):
            raise EstimationError(f"the fit of {self.effects or 'the base model'} diverged")
        return Model(self.effects, unpack(result.x))

    def _scout_problem(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        context: FitContext,
        rows: NDArray[np.bool_] | None,
        hold: frozenset[str],
        whole: LeastSquaresProblem,
    ) -> LeastSquaresProblem:
        """The criterion on a mid-record stretch of :data:`_SCOUT_SAMPLES` samples for scouting.

        ``whole`` itself when the record is short, when an effect's chain depends on the
        sample times (:attr:`~tcomp_core.effects.base.Effect.uses_sample_times`), or when the
        stretch cannot pose the same problem.
        """
        n = tc1.size
        if n <= 2 * _SCOUT_SAMPLES or any(e.uses_sample_times for e in self.instances):
            return whole
        start = (n - _SCOUT_SAMPLES) // 2
        stop = start + _SCOUT_SAMPLES
        part_rows = None if rows is None else rows[start : stop - 1]
        try:
            part = self.problem(tc1[start:stop], tc2[start:stop], context, part_rows, hold)
        except EstimationError:
            return whole
        return part if part.specs == whole.specs else whole

    def problem(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        context: FitContext,
        rows: NDArray[np.bool_] | None = None,
        hold: frozenset[str] = frozenset(),
    ) -> LeastSquaresProblem:
        """The fit's criterion as a least-squares problem in the search coordinates.

        Parameters are as :meth:`fit`'s; the time constants (every ``tau*``) are searched as
        their logarithms.

        Raises
        ------
        EstimationError
            If too few rows are usable for the parameters.
        """
        held = {
            k: v
            for effect in self.instances
            for k, v in effect.held_by_setting(self.params).items()
        }
        specs = [spec for spec in self.specs(context) if spec.name not in hold | held.keys()]
        rows = np.ones(tc1.size - 1, dtype=bool) if rows is None else rows
        rows = rows & self._valid_rows(tc1.size, context)
        n_rows = int(rows.sum())
        if n_rows <= len(specs) + 2:
            raise EstimationError(
                f"{n_rows} usable samples are too few for {len(specs)} parameters"
            )
        fixed = {k: v for effect in self.instances for k, v in effect.fixed(context).items()}
        # Settings (Effect.setting_choices, alternative_forms) are neither searched nor
        # measured: carried over.
        settings = [c for e in self.instances for c in (*e.setting_choices, *e.alternative_forms)]
        setting_names = {name for choice in settings for name in choice}
        carried = (setting_names | hold) & self.params.keys()
        fixed = {**{n: self.params[n] for n in carried}, **held, **fixed}

        def unpack(x: NDArray[np.float64]) -> dict[str, float]:
            values = dict(fixed)
            for spec, value in zip(specs, x, strict=True):
                values[spec.name] = math.exp(value) if spec.name.startswith("tau") else value
            return values

        memo = _ChainMemo()
        level_sd = _level_prior_sd(context) if any(s.name == LEVEL for s in specs) else None

        # The effects with a penalty (the others add no rows).
        penalising = [e for e in self.instances if type(e).penalty is not Effect.penalty]

        def penalties(values: Mapping[str, float]) -> list[NDArray[np.float64]]:
            extra = [effect.penalty(values, n_rows) for effect in penalising]
            if level_sd is not None:
                extra.append(np.array([values[LEVEL] / level_sd]))
            return extra

        def residuals(x: NDArray[np.float64], penalty_only: bool = False) -> NDArray[np.float64]:
            values = unpack(x)
            if penalty_only:
                extra = penalties(values)
                return np.concatenate(extra) if extra else np.empty(0)
            r = self.cross_residual(tc1, tc2, context, values, memo)[rows]
            finite = np.isfinite(r)
            if not finite.all():
                r = np.where(finite, r, 1e6)
            extra = penalties(values)
            return np.concatenate([r, *extra]) if extra else r

        lower = np.array(
            [math.log(s.lower) if s.name.startswith("tau") else s.lower for s in specs]
        )
        upper = np.array(
            [math.log(s.upper) if s.name.startswith("tau") else s.upper for s in specs]
        )
        remembered = _LastResiduals(residuals)
        jacobian = _Jacobian(
            remembered,
            lower,
            upper,
            n_rows,
            [spec.name for spec in specs],
            self._log_factor_columns(context, specs, rows),
        )
        return LeastSquaresProblem(
            specs=tuple(specs),
            lower=lower,
            upper=upper,
            n_rows=n_rows,
            unpack=unpack,
            residuals=remembered,
            jacobian=jacobian,
        )

    def _log_factor_columns(
        self, context: FitContext, specs: Sequence[ParamSpec], rows: NDArray[np.bool_]
    ) -> dict[int, NDArray[np.float64]]:
        """∂ log s/∂θ on the fitted rows for parameters that act only through s(t), by index.

        None with a level-dependent τ: its film temperature comes from the low-passed gas, so
        residual k then depends on s at neighbouring samples too and the shortcut of
        :class:`_Jacobian` would not hold (those columns are differenced instead).
        """
        if any(type(e).level_exponent is not Effect.level_exponent for e in self.instances):
            return {}
        columns: dict[int, NDArray[np.float64]] = {}
        index = {spec.name: i for i, spec in enumerate(specs)}
        for effect in self.instances:
            for name, column in effect.log_factor_jacobian(context).items():
                if name in index:  # a held parameter has no column
                    columns[index[name]] = column[:-1][rows]  # interval k uses s(t_k)
        return columns

    def _valid_rows(self, n: int, context: FitContext) -> NDArray[np.bool_]:
        """Intervals every parameter value can use (delays shift data off the ends)."""
        valid = np.ones(n - 1, dtype=bool)
        margin = 0
        for effect in self.instances:
            for spec in effect.specs(context):
                if spec.name == "delay_s":
                    bound = max(-spec.lower, spec.upper)
                    margin = max(margin, math.ceil(bound / context.dt) + SHIFT_HALF_TAPS + 1)
        if margin:
            valid[:margin] = False
            valid[-margin:] = False
        return valid

    def _starts(
        self,
        context: FitContext,
        problem: LeastSquaresProblem,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[NDArray[np.float64]]:
        """Start vectors: every combination of the new effects' starts."""
        options = [
            effect.starts(context, self.params, tc1, tc2)
            for effect in self.instances
            if any(spec.name not in self.params for spec in effect.specs(context))
        ]
        starts = []
        level = float(np.mean(tc2) - np.mean(tc1)) if tc1.size else 0.0
        for combination in itertools.product(*options) if options else [()]:
            values = dict(self.params)
            if self.has_level:
                values.setdefault(LEVEL, level if math.isfinite(level) else 0.0)
            for part in combination:
                values.update(part)
            x = problem.pack(values)
            lower, upper = problem.lower, problem.upper
            starts.append(
                np.clip(x, lower + 1e-9 * (upper - lower), upper - 1e-9 * (upper - lower))
            )
        return starts
