"""Radiation exchange with the duct wall.

A hot junction radiates to a cooler wall: τ dTm/dt = Tg − Tm − r (Tm⁴ − Tw⁴), temperatures in
kelvin. It lowers the reading in proportion to Tm⁴ − Tw⁴ and so depends on the temperature level,
which the linear base model cannot follow. ``r`` is fitted as the dimensionless radiative to
convective conductance ρ = 4 r T̄³ at the record's mean temperature T̄, one per sensor; the wall
temperature Tw is fitted too (it is identified only when ρ1 ≠ ρ2).

At moderate noise the two sensors' relation leaves a valley: τ, ρ1, ρ2 and Tw trade against
each other with almost no change of the criterion. Physics picks the member: r = εσ/h with
h ∝ d^-½ (Nu ∝ Re^½) and τ ∝ d^1.5, so r ∝ d^½ ∝ τ^⅓ for wires of one emissivity, and
ρ2/ρ1 = (τ2/τ1)^⅓. A penalty holds the fit to that ratio where the data are silent; it costs
about one unit of the criterion for 0.03 of ρ, which informative data outweigh.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ..tolerance import CLASS2_GAIN, CLASS2_MARGIN
from .base import KELVIN, Effect, Evidence, FitContext, OutputEvidence, ParamSpec, level_not_fixed

__all__ = [
    "EMISSIVITY_RATIO_MAX",
    "MIN_RHO",
    "Radiation",
    "air_conductivity",
    "gain_within_class2",
    "max_radiation_ratio",
    "one_emissivity_ratio",
    "sensor_level_difference_c",
]

#: Least radiative/convective conductance of the wire that radiates more that counts as
#: radiation (a loss below is too small to matter).
MIN_RHO = 0.01

#: Weight of the ρ2/ρ1 = (τ2/τ1)^⅓ prior, in units of the criterion per unit ρ.
PRIOR_WEIGHT = 30.0
#: Most the two wires' emissivities differ by (a factor): two wires of one alloy in one gas
#: oxidise alike, type K between about 0.6 and 0.9, so the slower wire's ρ over the faster's
#: stays within this factor of the one-emissivity ratio (τs/τf)^⅓.
EMISSIVITY_RATIO_MAX = 2.0
#: Stefan–Boltzmann constant, W m⁻² K⁻⁴.
STEFAN_BOLTZMANN = 5.670374419e-8
#: Least volumetric heat capacity ρc of thermocouple wire, J m⁻³ K⁻¹: platinum (types R, S,
#: B: 21 450 kg m⁻³ × 133 J kg⁻¹ K⁻¹ = 2.85e6) is the lowest of the usual alloys (type K
#: ≈ 8 700 × 450 = 3.9e6). The lower ρc, the weaker the convection a given τ implies.
WIRE_RHO_C_MIN = 2.8e6
#: Least Nusselt number of a wire in cross flow: Collis & Williams (1959) give
#: Nu = 0.24 + 0.56 Re^0.45 down to Re = 0.02, where Nu = 0.34; natural convection of a
#: fine wire in still gas is of the same order.
NUSSELT_MIN = 0.3
#: Least wall temperature, K: no duct or test cell wall is colder than 200 K.
WALL_MIN_K = 200.0
#: The simulator's radiation: the fast wire's ρ, the wall (constant, or its temperature at the
#: start when it warms with the gas, degrees C), the warming wall's lag (s), and the hot gas.
SIMULATED_RHO1 = 0.08
SIMULATED_WALL_C = 300.0
SIMULATED_WALL_LAG_S = 20.0
SIMULATED_GAS_MEAN_C = 700.0
SIMULATED_GAS_AMPLITUDE_C = 250.0


def air_conductivity(temperature_k: float) -> float:
    """Thermal conductivity of air at ``temperature_k`` (K), W m⁻¹ K⁻¹.

    0.0241 (T/273.15)^0.81: within 4 % of Incropera & DeWitt (2007, Table A.4), 250–1 000 K.
    """
    return 0.0241 * (temperature_k / KELVIN) ** 0.81


def sensor_level_difference_c(params: Mapping[str, float], level_mean_c: float) -> float:
    """The level difference radiation puts between the two readings at ``level_mean_c``, °C.

    The slower (thicker) wire's steady loss less the faster one's, ``(ρs − ρf) (T̄⁴ − Tw⁴) /
    (4 T̄³)`` with T̄ the mean level in kelvin (``params``: ``rho1``, ``rho2``, ``wall_c``,
    ``tau1``, ``tau2``). Everything radiation corrects in level is inferred from this
    difference: the correction is about it over ρs/ρf − 1. Two sensors of one tolerance class
    differ in level by up to :func:`~tcomp_core.tolerance.class2_level_tolerance_c` by
    themselves, so a difference within that does not fix the correction (it moves by as much
    as it is across the tolerance). NaN when the level is unknown.
    """
    if not math.isfinite(level_mean_c):
        return math.nan
    slow, fast = (2, 1) if params["tau2"] >= params["tau1"] else (1, 2)
    mean_k = level_mean_c + KELVIN
    wall_k = params["wall_c"] + KELVIN
    loss = (mean_k**4 - wall_k**4) / (4.0 * mean_k**3)
    return float((params[f"rho{slow}"] - params[f"rho{fast}"]) * loss)


def gain_within_class2(params: Mapping[str, float]) -> str:
    """Why radiation's dynamics rest on the sensors' calibration, or '' when they do not.

    Linearised, radiation makes each wire read the gas's swing times 1/(1 + ρi): tc2 reads
    (1 + ρ1)/(1 + ρ2) of tc1's swing, times a calibration's ``gain`` in the same model. The
    correction of the swing (about ρ̄ of it) is inferred from that relative gain, and two
    IEC 60584 class-2 sensors differ in gain by up to :data:`~tcomp_core.tolerance.CLASS2_GAIN`
    by themselves; within :data:`~tcomp_core.tolerance.CLASS2_MARGIN` times that (the fit's
    resolution of a gain, as a calibration is judged) the gain is the sensors' own and nothing
    radiates that the data show. Two clean step records whose tc1 read 0.27 % and 0.66 % high
    were called radiation at 0.32 % and 0.79 % and compensated, their gas 0.61 → 3.18 % and
    1.19 → 2.79 % off; the five radiating draws compensated better than first order lay at
    2.6-4.9 %.
    """
    ratio = (1.0 + params["rho1"]) / (1.0 + params["rho2"]) * params.get("gain", 1.0)
    limit = CLASS2_MARGIN * CLASS2_GAIN
    if abs(ratio - 1.0) > limit:
        return ""
    return (
        f"the relative gain of the sensors that radiation implies, {100.0 * (ratio - 1.0):+.3g} "
        f"%, is within what two IEC 60584 class-2 sensors may differ by ({100.0 * limit:.3g} "
        "% with the fit's margin): the correction of the swing would rest on their "
        "calibration, not on the data, and the gas is first order's"
    )


def max_radiation_ratio(tau_s: float, mean_c: float) -> float:
    """Largest radiative/convective conductance ratio ρ = 4 ε σ T̄³/h physics allows.

    For a wire of time constant ``tau_s`` (s) at the mean temperature ``mean_c`` (degrees C).
    A cylinder in cross flow has τ = ρc d/(4h) and h = Nu k/d, so h = √(Nu k ρc/(4τ)): the
    least h comes from the least Nu (:data:`NUSSELT_MIN`) and ρc (:data:`WIRE_RHO_C_MIN`),
    with k of air at the mean temperature; ε ≤ 1 then bounds ρ.
    """
    mean_k = mean_c + KELVIN
    h_min = math.sqrt(NUSSELT_MIN * air_conductivity(mean_k) * WIRE_RHO_C_MIN / (4.0 * tau_s))
    return 4.0 * STEFAN_BOLTZMANN * mean_k**3 / h_min


def one_emissivity_ratio(params: Mapping[str, float]) -> float:
    """ρ2/ρ1 of two wires of one emissivity, (τ2/τ1)^⅓ (module notes; ``tau1``, ``tau2`` in s)."""
    return float((params["tau2"] / params["tau1"]) ** (1.0 / 3.0))


class Radiation(Effect):
    """ρ1, ρ2 (dimensionless) and the wall temperature (degrees C).

    τ may move any distance from the first-order estimate (:attr:`max_tau_factor` infinite):
    linearised, radiation is a relative gain and offset of the two sensors, which the
    first-order model explains by bending τ without limit (on hot engine pulses of the
    detailed simulator the first-order τ came out 5× the radiation fit's).

    Material (:meth:`material`) from a radiative/convective conductance of
    :data:`MIN_RHO` on the wire that radiates more. Output (:meth:`output_handling`): the
    steady radiation error of each wire is removed, in level, only where the data fix that
    level; otherwise only the dynamics, the level staying first order's: when neither ρ is
    told from 0 (both 95 % intervals reach it), when a calibration shares the model (its
    offset and gain trade with the wall and the ratios), and when radiation's part of the
    sensors' level difference (:func:`sensor_level_difference_c`) is within what two class-2
    sensors may differ by anyway. The level correction is that difference over ρs/ρf − 1, so
    within the tolerance it rests on the sensors' calibration, not on the data (a hot record
    with a lagging wall, compensated as radiation beside a calibration, had its gas moved
    6 °C off: 5.5 → 6.4 %). Where the level is not fixed and the relative gain radiation
    implies between the sensors is within class 2 as well (:func:`gain_within_class2`),
    nothing is undone: ``first order``.
    """

    name = "radiation"
    max_tau_factor = math.inf
    summary = (
        "radiation to the wall lowers the reading with the temperature level (rho1, rho2, wall)"
    )

    simulation_forms = ("constant wall", "lagging wall")
    simulation_gas: ClassVar[Mapping[str, float]] = {
        "mean": SIMULATED_GAS_MEAN_C,
        "amplitude": SIMULATED_GAS_AMPLITUDE_C,
    }

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """rho1, rho2 (4 ri T̄³ at the gas mean), wall_c (degrees C); ``lagging wall``: wall_lag_s.

        ρ2 = ρ1 (τ2/τ1)^⅓, a thicker wire radiating relatively more (Nu ∝ Re^½). The lagging
        wall starts at wall_c and follows the gas through a first-order lag of wall_lag_s (a
        duct warming up), so the radiation error drifts over the record.
        """
        params = {
            "rho1": SIMULATED_RHO1,
            "rho2": SIMULATED_RHO1 * (tau2 / tau1) ** (1.0 / 3.0),
            "wall_c": SIMULATED_WALL_C,
        }
        if form == "lagging wall":
            params["wall_lag_s"] = SIMULATED_WALL_LAG_S
        return params

    def material(self, params: Mapping[str, float], evidence: Evidence) -> bool:
        return bool(max(params["rho1"], params["rho2"]) >= MIN_RHO)

    def implausible(self, params: Mapping[str, float]) -> str:
        """Two wires whose ρ ratio needs emissivities more than a factor apart.

        ρ = 4 ε σ T̄³/h with h ∝ d^-½ and τ ∝ d^1.5 gives ρs/ρf = (εs/εf) (τs/τf)^⅓ for the
        slower and the faster wire; beyond :data:`EMISSIVITY_RATIO_MAX` either way (with the
        wire that radiates more material, :data:`MIN_RHO`) the fit has found something else
        that grows with the level. On the campaign's radiation draws the fitted ratio came
        within 0.94–1.62 of (τs/τf)^⅓; a calibration beyond class 2 on a cool step record
        (draw 2842, no radiation) was fitted with the thicker wire radiating 0.23 of it, and
        its dynamics made the gas 14.3 → 16.0 % off.
        """
        tau1, tau2 = params.get("tau1", math.nan), params.get("tau2", math.nan)
        if not (tau1 > 0.0 and tau2 > 0.0) or max(params["rho1"], params["rho2"]) < MIN_RHO:
            return ""
        slow, fast = (2, 1) if tau2 >= tau1 else (1, 2)
        one_emissivity = one_emissivity_ratio(params) ** (1 if slow == 2 else -1)
        ratio = params[f"rho{slow}"] / max(params[f"rho{fast}"], 1e-12)
        if 1.0 / EMISSIVITY_RATIO_MAX <= ratio / one_emissivity <= EMISSIVITY_RATIO_MAX:
            return ""
        return (
            f"rho{slow}/rho{fast} = {params[f'rho{slow}']:.3g}/{params[f'rho{fast}']:.3g} of "
            f"the slower over the faster wire is {ratio / one_emissivity:.3g} times the "
            f"(tau{slow}/tau{fast})^(1/3) = {one_emissivity:.3g} of one emissivity: the wires' "
            f"emissivities would differ by more than {EMISSIVITY_RATIO_MAX:g}x"
        )

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        lows = [fit.intervals.get(f"rho{i}", (math.inf, math.inf))[0] for i in (1, 2)]
        if max(lows) <= 0.0:
            why = (
                "neither wire's radiative ratio rho is told from 0 (95 % intervals reach 0): "
                "the data do not fix the radiation level, which stays first order's"
            )
        else:
            share = sensor_level_difference_c(fit.params, fit.level_mean_c)
            why = level_not_fixed(fit, share, "the radiation level")
            if not why:
                return "compensated", "the steady radiation error of each wire is removed"
        within = gain_within_class2(fit.params)
        if within:
            return "first order", within
        return "dynamics", why

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        # Physical bounds: emissivity <= 1 with the weakest convection the base τ allows, and
        # a wall between WALL_MIN_K and the gas's mean temperature.
        mean = context.level_mean_c
        taus = context.base_taus_s
        uppers = (1.0, 1.0) if taus is None else [max_radiation_ratio(t, mean) for t in taus]
        return (
            *(
                ParamSpec(
                    name=f"rho{i}",
                    unit="1",
                    lower=0.0,
                    upper=min(uppers[i - 1], 1.0),
                    description=f"radiative/convective conductance 4 r{i} T^3 of tc{i} at the "
                    "mean",
                )
                for i in (1, 2)
            ),
            ParamSpec(
                name="wall_c",
                unit="degC",
                lower=WALL_MIN_K - KELVIN,
                upper=max(mean, WALL_MIN_K - KELVIN + 1.0),
                description="wall temperature",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        mean = context.level_mean_c
        lowest = WALL_MIN_K - KELVIN + 1.0
        walls = (max(0.5 * (mean - KELVIN), lowest), max(mean - 2.0 * context.level_std_c, lowest))
        return [
            {"rho1": r1, "rho2": r2, "wall_c": min(wall, mean - 1.0)}
            for wall in walls
            for r1, r2 in ((0.03, 0.08), (0.08, 0.03))
        ]

    def identifiability(self, params: Mapping[str, float]) -> str:
        ratio = one_emissivity_ratio(params)
        return (
            "radiation: tau, rho1, rho2 and the wall trade along a shallow valley; the prior "
            f"rho2/rho1 = (tau2/tau1)^(1/3) = {ratio:.3g} (one emissivity, Nu ~ Re^1/2) picks "
            f"the member where the data are silent; the fit gives "
            f"{params['rho2'] / max(params['rho1'], 1e-12):.3g}"
        )

    def radiation(
        self, sensor: int, params: Mapping[str, float], context: FitContext
    ) -> tuple[float, float]:
        mean_k = context.level_mean_c + KELVIN
        r = params[f"rho{sensor}"] / (4.0 * mean_k**3)
        return r, params["wall_c"] + KELVIN

    def penalty(self, params: Mapping[str, float], n_rows: int) -> NDArray[np.float64]:
        ratio = one_emissivity_ratio(params)
        return np.array([PRIOR_WEIGHT * (params["rho2"] - ratio * params["rho1"])])
