"""What a physical effect is: named parameters and hooks into the two-sensor chain.

The base model (Eq. 2) says each thermocouple is a first-order lag of the same gas temperature.
An effect extends it with parameters of its own and changes one stage of how a measurement maps
to the gas temperature (see :mod:`tcomp_core.effects.chain`):

    measured -> [calibration] -> [conduction pre-filter] -> first-order inverse
             (with [velocity]-scaled τ and the [radiation] loss) -> [delay] -> gas temperature

Every hook has a neutral default, so an effect overrides only its own stage and any set of
effects composes. Sensor numbers are 1 and 2 (thin and thick wire in the paper's notation).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from numpy.typing import NDArray

from ..tolerance import class2_level_tolerance_c

if TYPE_CHECKING:
    from ..lines import ForeignLine

__all__ = [
    "KELVIN",
    "Effect",
    "Evidence",
    "FitContext",
    "OutputEvidence",
    "ParamSpec",
    "level_not_fixed",
]

#: Offset between degrees Celsius and kelvin.
KELVIN = 273.15


@dataclass(frozen=True, kw_only=True)
class ParamSpec:
    """One fitted parameter of an effect.

    Attributes
    ----------
    name : str
        Key in the model's parameter dict (unique across effects).
    unit : str
        Unit for reports (``"s"``, ``"1"``, ``"degC"``...).
    lower, upper : float
        Bounds of the search.
    description : str
        One line for reports.
    physical : bool
        Whether the bounds are the parameter's physical range (a fit that ends on one wanted
        more than physics allows, :mod:`tcomp_core.diagnose.uncertainty`) rather than only
        the reach of the record (a time constant longer than the record can show).
    """

    name: str
    unit: str
    lower: float
    upper: float
    description: str
    physical: bool = True

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise ValueError(f"{self.name}: bounds {self.lower} .. {self.upper} are empty")


@dataclass(frozen=True, kw_only=True)
class FitContext:
    """Facts of one record that effects need for their parameters and shapes.

    Attributes
    ----------
    dt : float
        Sample interval, s.
    time : ndarray, shape (N,)
        Sample times from 0, s.
    level_mean_c, level_std_c : float
        Mean and standard deviation of the measured temperatures, degrees C.
    knot_spacing_s : float
        Spacing of the spline knots of slowly varying quantities (velocity), s.
    phi_hat : float
        Noise variance ratio σ1²/σ2² estimated from the spectra by the model.
    tau_scale_s : float
        A rough time constant of the slower sensor, s, to scale delays and slow modes.
    sigma2 : float
        Noise standard deviation of thermocouple 2, degrees C: the unit of the fit's residuals,
        so that penalties weigh against residuals of order one.
    noise_kernel : ndarray or None
        Impulse response of the low-pass the readings were given through before the fit
        (None: raw readings); the fit's residual normalisation counts the noise it removes.
    base_taus_s : tuple of float or None
        τ1, τ2 of the first-order model, s: effects derive physical bounds from them (None:
        unknown, the bounds are the widest).
    film_cutoff_hz : float or None
        Band edge of the gas signal, Hz, where the gas setting a film temperature is low-passed.
    """

    dt: float
    time: NDArray[np.float64]
    level_mean_c: float
    level_std_c: float
    knot_spacing_s: float
    phi_hat: float
    tau_scale_s: float
    sigma2: float = 1.0
    noise_kernel: NDArray[np.float64] | None = None
    base_taus_s: tuple[float, float] | None = None
    film_cutoff_hz: float | None = None

    @property
    def duration_s(self) -> float:
        """Record length, s."""
        return float(self.time[-1] - self.time[0]) + self.dt


@dataclass(frozen=True, kw_only=True)
class Evidence:
    """What an effect's materiality is judged on besides its parameters.

    Attributes
    ----------
    level_mean_c : float
        Mean temperature of the record, degrees C.
    record_dt : float
        The record's own sample interval, s (before the diagnosis decimates it).
    dt : float
        Sample interval of ``readings``, s.
    readings : (ndarray, ndarray)
        tc1, tc2 at ``dt``, degrees C, shape (N,) each.
    base_taus : (float, float)
        τ1, τ2 of the first-order model of the record, s.
    """

    level_mean_c: float
    record_dt: float
    dt: float
    readings: tuple[NDArray[np.float64], NDArray[np.float64]]
    base_taus: tuple[float, float]


@dataclass(frozen=True, kw_only=True)
class OutputEvidence:
    """What a compensated gas's treatment of an effect is decided on: the final fit.

    Attributes
    ----------
    intervals : mapping of str to (float, float)
        The fit's 95 % intervals by parameter name.
    params : mapping of str to float
        The fit's parameters (``tau1``, ``tau2`` in s and the effects' own).
    effects : tuple of str
        Every effect of the fitted model, this one included.
    level_mean_c : float
        Mean temperature of the record's readings, degrees C (NaN when unknown).
    ordinary : tuple of str
        Effects of the model that are the sensors' ordinary physics
        (:attr:`tcomp_core.diagnose.Diagnosis.expected_physics`) or that the default path
        covers (:attr:`Effect.default_path_covers`), left first order.
    level_split_c : float
        The level difference the model's effects put between the two sensors' gas, degrees C
        (:func:`tcomp_core.diagnose.identification.level_split_c`; NaN when unknown): all the
        data say of the level the effects correct.
    """

    intervals: Mapping[str, tuple[float, float]]
    params: Mapping[str, float]
    effects: tuple[str, ...] = ()
    level_mean_c: float = float("nan")
    ordinary: tuple[str, ...] = ()
    level_split_c: float = float("nan")


def level_not_fixed(fit: OutputEvidence, split_c: float, what: str) -> str:
    """Why the level ``what`` corrects stays first order's, or '' when the data fix it.

    The only thing that fixes such a level is the level difference the effect puts between the
    two sensors (``split_c``, degrees C; NaN when unknown): not when a calibration in the same
    model takes that difference, nor when it is within what two IEC 60584 class-2 sensors may
    differ by at the record's level anyway.
    """
    if "calibration" in fit.effects:
        return (
            "a calibration in the same model takes the sensors' level difference, the only "
            f"thing that fixes {what}: it stays first order's"
        )
    tolerance = class2_level_tolerance_c(fit.level_mean_c)
    if not abs(split_c) > tolerance:
        return (
            f"the part of the sensors' level difference that fixes {what}, {split_c:+.3g} degC "
            f"at {fit.level_mean_c:.4g} degC, is within what IEC 60584 class 2 alone allows "
            f"there ({tolerance:.2g} degC): the correction would rest on the sensors' "
            "tolerance, not on the data, and the level stays first order's"
        )
    return ""


class Effect:
    """Base class of the effects; the hooks return the neutral value (no change)."""

    #: Name used in the API, CLI, JSON and diagnostics.
    name: ClassVar[str] = ""
    #: One line: what is physically missing from the base model.
    summary: ClassVar[str] = ""
    #: Whether the default first-order path already accounts for the effect by itself, with
    #: nothing in the sensor chain to undo (the noise ratio: ml-eiv and the smoother measure
    #: the noise). A compensated gas leaves it first order, and it counts as the sensors'
    #: ordinary physics beside other effects (:attr:`OutputEvidence.ordinary`); a model of
    #: such effects is judged at both of that path's τ
    #: (:func:`tcomp_core.diagnose.ranking._at_published_scale`).
    default_path_covers: ClassVar[bool] = False
    #: Other forms of the same physics, as settings carried in the parameters (one dict per
    #: form): the fit's own form is one reading of the literature, and the data cannot always
    #: tell them apart. The model is refitted in each (:mod:`tcomp_core.diagnose.
    #: identification`) and what the form changes in the gas joins the gas's band: a
    #: correction that rests on the form, not on the data, is not applied.
    alternative_forms: ClassVar[tuple[dict[str, float], ...]] = ()
    #: Settings of the fit (neither searched nor measured) to choose between on held-out data:
    #: one dict of values per choice, carried in the parameters (see
    #: :func:`tcomp_core.diagnose.ranking.fit_with_effect`); the first is the default.
    setting_choices: ClassVar[tuple[dict[str, float], ...]] = ()
    #: Parameters the cross-relation criterion hardly sees through the noise it amplifies, and
    #: which it biases (a noisy pole reweights its own residuals): chosen instead by the
    #: free-run (output) error of the slow sensor on the estimation blocks, a bounded 1-D search
    #: each, the other parameters fitted by the cross-relation in between (see
    #: :func:`tcomp_core.diagnose.ranking.fit_with_effect`).
    output_error_params: ClassVar[tuple[str, ...]] = ()
    #: The setting (0 or 1, carried in the parameters among :attr:`setting_choices`' settings,
    #: which give it 0) that marks the effect's parameters as refined with τ on the free-run
    #: (output) error of the slow sensor on the estimation blocks, the error the held-out test
    #: scores (:meth:`tcomp_core.diagnose.heldout.Evaluator.polish`); such parameters are then
    #: held as output-error parameters are. "" for an effect never refined. For a τ that moves
    #: through the record the cross-relation is biased by the noise its derivatives amplify: it
    #: lowers its own residual by shrinking τ where the readings are noisiest, so that on noisy
    #: engine pulses its velocity fit simulated the slow sensor worse than constant τ did
    #: (held-out error 2.5 → 3.9 %) where the same spline refined on the free-run error fell to
    #: 0.8 %. Where the cross-relation's fit does simulate better, the refined one is no better
    #: (held-out 1.3 → 3.6 % on a rotating disk), so it is offered only where the fit
    #: simulates worse than the model without the effect, and kept when the held-out blocks
    #: prefer it (:func:`tcomp_core.diagnose.ranking.fit_with_effect`).
    free_run_setting: ClassVar[str] = ""
    #: Whether the other parameters move with an output-error parameter, so that the search
    #: refits them at each of its trials (costly) instead of once at the end.
    output_error_coupled: ClassVar[bool] = False
    #: Whether the effect's chain depends on the sample times (``FitContext.time``), so that it
    #: cannot be fitted on a stretch of the record alone.
    uses_sample_times: ClassVar[bool] = False
    #: Whether each parameter is decided by one stretch of the record only (a spline's
    #: coefficients). A refit without that stretch interpolates them, and a delete-a-block
    #: jackknife would count that interpolation as the fit's uncertainty, n - 1 times over
    #: (:func:`tcomp_core.diagnose.identification.identify` propagates their covariance
    #: instead).
    local_parameters: ClassVar[bool] = False
    #: Whether the sensors' disagreement at the closed-form first-order start counts as
    #: evidence for the effect's correction (:func:`tcomp_core.diagnose.identification.
    #: identify`). An effect that such a start absorbs by bending τ (a delay) sets it False and
    #: says why: the disagreement there hides what the effect corrects.
    evidence_at_start: ClassVar[bool] = True
    #: Whether the default first-order path's τ keep their common scale under this effect
    #: when the effect is small: it moves the two sensors apart (a shift, a gain, a line, a
    #: noise), not the lag both see. A model of such effects only takes the default path's
    #: scale where its fit cannot tell it from its own
    #: (:meth:`tcomp_core.diagnose.heldout.Evaluator.with_published_scale`); an effect on the
    #: lag itself (a varying speed, a conduction, a radiation, a level-dependent τ) biases that
    #: scale (a speed swinging ±30 % put the default path's τ 6–8 % high where the velocity fit
    #: was within 4 %, campaign draw 3008) and keeps the fit's own.
    keeps_first_order_scale: ClassVar[bool] = False
    #: How far a fit with this effect may move either τ from the first-order estimate (a factor,
    #: either way). The first-order τ absorbs what the effect does, so it is biased, but by a
    #: bounded amount for each effect; a fit beyond found no physical explanation and is
    #: degenerate (:meth:`tcomp_core.effects.Model.implausible`). Effects that bias the
    #: first-order τ strongly raise it and say why in their class docstring.
    max_tau_factor: ClassVar[float] = 5.0
    #: How far τ may fall below the first-order estimate when that differs (a factor; None:
    #: :attr:`max_tau_factor`), for an effect that biases the first-order τ one way only.
    max_tau_fall: ClassVar[float | None] = None
    #: Whether the effect fits the level difference between the two sensors itself (a
    #: calibration's offset). Without such an effect the model fits it as the base parameter
    #: ``level_c`` (:attr:`tcomp_core.effects.Model.has_level`): two sensors of one class
    #: differ in level by up to their tolerance, which no dynamics explains.
    fits_level: ClassVar[bool] = False
    #: Forms the lumped simulator (:mod:`tcomp_core.simulate_effects`) gives this effect in.
    #: The first is the form the fit assumes; the others are forms the literature also uses
    #: (conduction through a lumped prong as well as fin legs, a wall that warms with the gas,
    #: flow speed steps), so a record made with one and compensated with the fit's tests the
    #: compensation against the form of the physics. ``("",)``: one form.
    simulation_forms: ClassVar[tuple[str, ...]] = ("",)
    #: Gas signal parameters the simulator uses unless the caller chooses them (hot gas for
    #: effects that need it), as keywords of :func:`tcomp_core.simulate.gas_signal`.
    simulation_gas: ClassVar[Mapping[str, float]] = {}

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """True parameters of the simulator's records of this effect in ``form``, by name.

        Strong enough to see in 10 s at K = 1–2 %. Parameters the fit also has carry its names,
        so a record's truth compares with a fit by name; a form's own keep their own.

        Parameters
        ----------
        tau1, tau2 : float
            Time constants of the two sensors, s (> 0).
        form : str
            One of :attr:`simulation_forms`.
        """
        return {}

    def found_by_default_path(self, lines: Sequence[ForeignLine], phi_hat: float) -> str:
        """Why the default path found this effect and accounts for it itself ('' if it did not).

        ``lines`` are the lines that path found on one channel alone
        (:attr:`tcomp_core.estimators.Estimate.lines`), ``phi_hat`` the noise variance ratio
        σ1²/σ2² measured from the spectra. Such an effect may leave the base model at that
        path's τ no error, so that no round adds it: it is named from this instead
        (:attr:`tcomp_core.diagnose.result.Diagnosis.default_path_findings`). '' by default.
        """
        return ""

    def material(self, params: Mapping[str, float], evidence: Evidence) -> bool:
        """Whether a fit of this size is a finding rather than the sensors' ordinary state.

        True by default; an effect with an ordinary size (a calibration within the sensors'
        tolerance class, a radiative loss too small to matter, a delay under a sample) says
        where it ends in its docstring.
        """
        return True

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        """How a compensated gas treats this effect, and why (``compensated`` by default).

        One of ``compensated``, ``prior`` (a stated convention fixes what the two signals
        cannot), ``dynamics`` (undone for the dynamics, the level kept first order's), judged
        on the final fit (:mod:`tcomp_core.compensation.plan`).
        """
        return "compensated", "its stage of the sensor chain is inverted"

    def implausible(self, params: Mapping[str, float]) -> str:
        """Why these parameters are no physical sensor, by this effect's own bounds ('' if none).

        Parameters beyond the search range cannot occur (the fit is bounded); these are bounds
        that involve several parameters, e.g. conduction's conductance ratio at the fit's τ.
        """
        return ""

    def unseen_parameters(self, context: FitContext, samples: NDArray[np.bool_]) -> frozenset[str]:
        """Parameters that act mostly outside ``samples`` (shape (N,)); none by default.

        A criterion scored on those samples alone cannot decide them.
        """
        return frozenset()

    def refined_on_free_run(self, params: Mapping[str, float]) -> bool:
        """Whether ``params`` mark this effect as refined on the free-run error."""
        return bool(self.free_run_setting) and params.get(self.free_run_setting, 0.0) == 1.0

    def held_by_setting(self, params: Mapping[str, float]) -> dict[str, float]:
        """Parameters a setting in ``params`` holds, with the values they are held at.

        A setting choice (:attr:`setting_choices`) may leave out a parameter that a record
        cannot pin, holding it at the value that means "no such term"; every fit of the
        model then holds it there (:meth:`tcomp_core.effects.model.Model.problem`), and the
        held-out error chooses between the choices as it does for any setting.
        """
        return {}

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        """The effect's fitted parameters and their bounds for this record."""
        return ()

    def identifiability(self, params: Mapping[str, float]) -> str:
        """What two signals cannot fix about this effect and what decided it ("" if nothing)."""
        return ""

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        """Initial values, one dict per start of the search.

        A dict holds the effect's own parameters and may also restart ``tau1``/``tau2``
        (for effects that shift the time constants far from the base model's). An empty list
        says the data hold nothing for the effect to fit (the fit then raises).
        """
        return [{}]

    def fixed(self, context: FitContext) -> dict[str, float]:
        """Parameters set from the data outside the fit (not searched), by name."""
        return {}

    def penalty(self, params: Mapping[str, float], n_rows: int) -> NDArray[np.float64]:
        """Extra least-squares residuals regularising the parameters (none by default)."""
        return np.empty(0)

    # Hooks into the sensor chain (see tcomp_core.effects.chain), neutral by default.

    def calibration(self, sensor: int, params: Mapping[str, float]) -> tuple[float, float]:
        """``(gain, offset_c)``: the sensor reads ``gain * T + offset_c``."""
        return 1.0, 0.0

    def additive(
        self, sensor: int, params: Mapping[str, float], context: FitContext
    ) -> NDArray[np.float64] | None:
        """A signal added to the sensor's readings, shape (N,), degrees C, or None."""
        return None

    def conduction(
        self, sensor: int, params: Mapping[str, float]
    ) -> tuple[float, float, float] | None:
        """``(fin_ml, tau_p_s, mode0_c)`` of conduction to the supports, or None."""
        return None

    def tau_factor(
        self, context: FitContext, params: Mapping[str, float]
    ) -> NDArray[np.float64] | None:
        """Per-sample factor s(t) on both time constants, shape (N,), or None."""
        return None

    def log_factor_jacobian(self, context: FitContext) -> dict[str, NDArray[np.float64]]:
        """``∂ log s(t)/∂θ``, shape (N,), of parameters acting only through :meth:`tau_factor`.

        By name; none by default. The fit's Jacobian needs no evaluation for them.
        """
        return {}

    def level_exponent(self, params: Mapping[str, float]) -> float | None:
        """Exponent p of τ ∝ (T/T̄)^p with the sensor's temperature T in kelvin, or None."""
        return None

    def level_weights(self, params: Mapping[str, float]) -> tuple[float, float]:
        """``(a, w)`` of the temperature T = T̄ + a (Tj − T̄) + w (Tg − Tj) that sets τ.

        (1, 0.5): the film temperature (:class:`~tcomp_core.effects.chain.SensorChain`).
        """
        return 1.0, 0.5

    def level_shares(self, params: Mapping[str, float]) -> tuple[float, float]:
        """Factors on the exponent of :meth:`level_exponent` for sensors 1 and 2 (1: shared)."""
        return 1.0, 1.0

    def radiation(
        self, sensor: int, params: Mapping[str, float], context: FitContext
    ) -> tuple[float, float] | None:
        """``(r, wall_k)``: loss ``r (T⁴ - T_w⁴)`` in kelvin with r in K⁻³, or None."""
        return None

    def delay_s(self, params: Mapping[str, float]) -> float:
        """How much later sensor 2 sees the gas than sensor 1, s."""
        return 0.0

    def noise_ratio(self, params: Mapping[str, float]) -> float | None:
        """Noise variance ratio φ = σ1²/σ2² the fit assumes, or None for the default 1."""
        return None
