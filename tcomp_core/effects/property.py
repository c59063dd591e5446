"""Gas properties: the time constants follow the temperature level.

τ = ρc d/(4h) with h = Nu k/d, and the air's conductivity k, its viscosity (through Re in Nu)
and the wire's heat capacity ρc all change with temperature, so a real thermocouple's τ varies
with the level: τi(t) = τi0 (Tf(t)/T̄)^p, temperatures in kelvin, T̄ the record's mean level and
Tf = (Ti + Tg)/2 the film temperature between the junction and the gas, at which the gas
properties are taken (a fine wire lags a fast gas, so Tf follows the gas as much as the
reading). Both wires share the exponent p: they are of one alloy in one gas. For fine wires in
air p is a few tenths, of either sign: the air's conductivity and viscosity (through Re in the
Nusselt number), the temperature loading of Collis & Williams (1959) and the alloy's heat
capacity pull different ways. The search allows ±:data:`EXPONENT_LIMIT`, beyond what any gas
and wire give.

Which temperature sets τ, and whose τ follows it, are matters of form the two signals do not
settle. The gas properties are taken at the film temperature, the wire's heat capacity at the
junction's; Collis & Williams's temperature loading (Nu ∝ (Tf/Tg)^0.17) makes h depend on how
far the junction lags the gas; and Nu's sensitivity to Re, which carries the viscosity's
share, grows with Re, so the thicker wire's τ follows the level more than the thin one's
(one exponent for both is the fit's assumption, not physics). The data see only the ratio of
the two sensors' transfer functions, so a shared exponent turns a difference between the
wires into a correction common to both. On the detailed simulator's hot exhaust pulses
(Collis & Williams, Sutherland's air, c(Tj); campaign draw 2060), τ's own swing was ±0.4 and
±1 % on the two wires (film exponents 0.02 and 0.07), yet the film form fitted p = 0.27
(95 %: 0.17–0.37, block refits as tight) and made the gas 1.0 → 4.4 % off (3.2 % with the
level kept first order's). So the model is refitted in each other form
(:attr:`alternative_forms`: τ at the junction's temperature, τ by the lag alone, only the
slower wire's τ following the level) and a form the held-out blocks do not rule out adds what
it changes in the gas to the band, and must find the change itself
(:mod:`tcomp_core.diagnose.identification`): on 2060 the slower wire alone explained the
blocks as well and changed the gas by 0.6 °C rms where the shared exponent changed it by
6.2, so nothing is applied (1.0 %). The level a level-dependent τ corrects is applied only
where the data fix it (:meth:`Property.output_handling`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from .base import Effect, FitContext, OutputEvidence, ParamSpec, level_not_fixed

__all__ = ["EXPONENT_LIMIT", "FILM_WEIGHT", "Property", "tau_swing"]

#: Largest |p| of τ ∝ T^p that gas and wire properties can produce.
EXPONENT_LIMIT = 1.5
#: Share of the gas in the temperature that sets τ in the fit's own form (the film).
FILM_WEIGHT = 0.5
#: The simulator's exponent: strong (fine wires in air show a few tenths), so that 10 s of hot
#: gas show it beyond the ordinary gas-property physics at K = 1–2 %.
SIMULATED_EXPONENT = -0.8
#: The simulator's hot gas for it, degrees C (mean and amplitude).
SIMULATED_GAS_MEAN_C = 700.0
SIMULATED_GAS_AMPLITUDE_C = 250.0


class Property(Effect):
    """The exponent ``property_exponent`` (dimensionless) of τ ∝ T^p, both sensors.

    Output (:meth:`output_handling`): compensated in level only when the level difference
    the exponent puts between the two sensors (:attr:`~.base.OutputEvidence.level_split_c`)
    exceeds what two IEC 60584 class-2 sensors may differ by at the record's level, and no
    calibration in the model takes that difference; otherwise the dynamics only, the level
    staying first order's. The level a property correction makes rests on the form of the law
    (at the junction's temperature a periodic signal's mean is not moved at all) and on the
    sensors' offsets, which the data see only as that difference: on campaign draw 2076
    (a calibration beyond class 2 read with a property, τ ∝ T^0.14) the level-corrected gas
    was 8.2 % off and 6.2 % with the level kept (first order: 7.0 %).
    """

    name = "property"
    summary = "tau follows the temperature level through the gas properties (property_exponent)"
    output_error_params = ("property_exponent",)
    #: τ following the junction's own temperature (its heat capacity) instead of the film;
    #: τ following only how far the junction lags the gas (the temperature loading); only the
    #: slower (thicker) wire's τ following the level (Nu's sensitivity to Re grows with Re).
    alternative_forms = (
        {"property_film_weight": 0.0},
        {"property_level_weight": 0.0},
        {"property_fast_share": 0.0},
    )
    simulation_gas: ClassVar[Mapping[str, float]] = {
        "mean": SIMULATED_GAS_MEAN_C,
        "amplitude": SIMULATED_GAS_AMPLITUDE_C,
    }

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """property_exponent p of τ ∝ T^p (dimensionless, T in kelvin), in hot gas."""
        return {"property_exponent": SIMULATED_EXPONENT}

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        return (
            ParamSpec(
                name="property_exponent",
                unit="1",
                lower=-EXPONENT_LIMIT,
                upper=EXPONENT_LIMIT,
                description="exponent p of tau ~ (T / mean T)^p, T in kelvin",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        return [{"property_exponent": p} for p in (0.0, -0.5, 0.5)]

    def level_exponent(self, params: Mapping[str, float]) -> float | None:
        return params["property_exponent"]

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        why = level_not_fixed(fit, fit.level_split_c, "the level a level-dependent tau corrects")
        if why:
            return "dynamics", why
        return "compensated", "its stage of the sensor chain is inverted"

    def level_shares(self, params: Mapping[str, float]) -> tuple[float, float]:
        fast = float(params.get("property_fast_share", 1.0))
        return (fast, 1.0) if params["tau1"] <= params["tau2"] else (1.0, fast)

    def level_weights(self, params: Mapping[str, float]) -> tuple[float, float]:
        return (
            float(params.get("property_level_weight", 1.0)),
            float(params.get("property_film_weight", FILM_WEIGHT)),
        )


def tau_swing(exponent: float, film_k: NDArray[np.float64]) -> float:
    """Relative change of τ ∝ T^p between the 5th and 95th percentile of the film temperature.

    Parameters
    ----------
    exponent : float
        p.
    film_k : ndarray, shape (N,)
        Film (or sensor) temperatures over the record, K.

    Returns
    -------
    float
        The relative change; inf when the film temperatures reach 0 K (a fit's gas gone wild:
        the power law has no value there, and nothing ordinary does that).
    """
    low, high = np.percentile(film_k, (5.0, 95.0))
    mean = float(np.mean(film_k))
    if not low > 0.0:
        return math.inf
    return float(abs((high / mean) ** exponent - (low / mean) ** exponent))
