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

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .base import KELVIN, Effect, FitContext, ParamSpec

__all__ = ["Radiation"]

#: Weight of the ρ2/ρ1 = (τ2/τ1)^⅓ prior, in units of the criterion per unit ρ.
PRIOR_WEIGHT = 30.0


class Radiation(Effect):
    """ρ1, ρ2 (dimensionless) and the wall temperature (degrees C)."""

    name = "radiation"
    summary = (
        "radiation to the wall lowers the reading with the temperature level (rho1, rho2, wall)"
    )

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        return (
            ParamSpec(
                name="rho1",
                unit="1",
                lower=0.0,
                upper=1.0,
                description="radiative/convective conductance 4 r1 T^3 of tc1 at the mean",
            ),
            ParamSpec(
                name="rho2",
                unit="1",
                lower=0.0,
                upper=1.0,
                description="radiative/convective conductance 4 r2 T^3 of tc2 at the mean",
            ),
            ParamSpec(
                name="wall_c",
                unit="degC",
                lower=-KELVIN + 1.0,
                upper=context.level_mean_c,
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
        walls = (max(0.5 * (mean - KELVIN), -KELVIN + 2.0), mean - 2.0 * context.level_std_c)
        return [
            {"rho1": r1, "rho2": r2, "wall_c": min(wall, mean - 1.0)}
            for wall in walls
            for r1, r2 in ((0.03, 0.08), (0.08, 0.03))
        ]

    def radiation(
        self, sensor: int, params: Mapping[str, float], context: FitContext
    ) -> tuple[float, float]:
        mean_k = context.level_mean_c + KELVIN
        r = params[f"rho{sensor}"] / (4.0 * mean_k**3)
        return r, params["wall_c"] + KELVIN

    def penalty(self, params: Mapping[str, float], n_rows: int) -> NDArray[np.float64]:
        ratio = (params["tau2"] / params["tau1"]) ** (1.0 / 3.0)
        return np.array([PRIOR_WEIGHT * (params["rho2"] - ratio * params["rho1"])])
