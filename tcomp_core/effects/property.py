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
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from .base import Effect, FitContext, ParamSpec

__all__ = ["EXPONENT_LIMIT", "Property", "tau_swing"]

#: Largest |p| of τ ∝ T^p that gas and wire properties can produce.
EXPONENT_LIMIT = 1.5
#: The simulator's exponent: strong (fine wires in air show a few tenths), so that 10 s of hot
#: gas show it beyond the ordinary gas-property physics at K = 1–2 %.
SIMULATED_EXPONENT = -0.8
#: The simulator's hot gas for it, degrees C (mean and amplitude).
SIMULATED_GAS_MEAN_C = 700.0
SIMULATED_GAS_AMPLITUDE_C = 250.0


class Property(Effect):
    """The exponent ``property_exponent`` (dimensionless) of τ ∝ T^p, both sensors."""

    name = "property"
    summary = "tau follows the temperature level through the gas properties (property_exponent)"
    output_error_params = ("property_exponent",)
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
