"""Conduction to the supports: a slow second mode (prong conduction).

Heat conducted along the wire to its cooler supports adds a slow mode with time constant τp;
the sensor's transfer function becomes

    G(s) = [1 + κ / (1 + τp s)] / (1 + κ + τ s),

unity DC gain, with κ the ratio of conductive to convective conductance, fitted per sensor
with one τp. With equal κ the effect cancels in the relation of the two sensors and only
rescales τ.

Two sensors cannot identify all five parameters: the ratio G2/G1 has two zeros and two poles,
so a one-parameter family (τp, κ1, κ2, τ1, τ2 scaled together, τ1/τ2 fixed) explains the data
equally well. The family is resolved by physics: for wires of one material and exposed length
in forced convection (Nu ∝ Re^½), both κ and τ grow as d^1.5, so κ1/κ2 = τ1/τ2. A penalty
holds the fit to that member only where the data are silent (it costs a fraction of one
unit of the criterion per 0.1 of κ); data that do tell κ1 from κ2 override it.

The slow mode remembers for several τp: a record that does not start at rest starts with the
mode charged. Its initial excess is fitted per sensor (``mode1``, ``mode2``, degrees C), so a
window cut from a running record fits as well as one that starts at rest.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .base import Effect, FitContext, ParamSpec

__all__ = ["Conduction"]

#: Weight of the κ1/κ2 = τ1/τ2 prior, in units of the criterion per unit κ.
PRIOR_WEIGHT = 3.0


class Conduction(Effect):
    """κ1, κ2 (dimensionless) and τp (s)."""

    name = "conduction"
    summary = "conduction to the supports adds a slow mode (kappa1, kappa2, tau_p)"

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        slowest = max(context.duration_s / 3.0, 4.0 * context.tau_scale_s)
        span = 10.0 * context.level_std_c + 10.0
        return (
            ParamSpec(
                name="kappa1",
                unit="1",
                lower=0.0,
                upper=3.0,
                description="conductive/convective conductance of tc1",
            ),
            ParamSpec(
                name="kappa2",
                unit="1",
                lower=0.0,
                upper=3.0,
                description="conductive/convective conductance of tc2",
            ),
            ParamSpec(
                name="tau_p",
                unit="s",
                lower=1.5 * context.tau_scale_s,
                upper=slowest,
                description="time constant of the slow (support) mode",
            ),
            ParamSpec(
                name="mode1",
                unit="degC",
                lower=-span,
                upper=span,
                description="initial excess of tc1's slow mode",
            ),
            ParamSpec(
                name="mode2",
                unit="degC",
                lower=-span,
                upper=span,
                description="initial excess of tc2's slow mode",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        spec = self.specs(context)[2]
        return [
            {"kappa1": k1, "kappa2": k2, "tau_p": float(tau_p), "mode1": 0.0, "mode2": 0.0}
            for tau_p in np.geomspace(spec.lower * 1.5, spec.upper / 1.5, 4)
            for k1, k2 in ((0.02, 0.1), (0.1, 0.02))
        ]

    def identifiability(self, params: Mapping[str, float]) -> str:
        ratio = params["tau1"] / params["tau2"]
        return (
            "conduction: the two signals fix only G2/G1, so the mode common to both sensors "
            "(kappa1, kappa2, tau_p and the tau scaled together) is set by the prior "
            f"kappa1/kappa2 = tau1/tau2 = {ratio:.3g} (wires of one material and length); the "
            f"fit gives kappa1/kappa2 = {params['kappa1'] / max(params['kappa2'], 1e-12):.3g}"
        )

    def conduction(self, sensor: int, params: Mapping[str, float]) -> tuple[float, float, float]:
        return params[f"kappa{sensor}"], params["tau_p"], params[f"mode{sensor}"]

    def penalty(self, params: Mapping[str, float], n_rows: int) -> NDArray[np.float64]:
        ratio = params["tau1"] / params["tau2"]
        return np.array([PRIOR_WEIGHT * (params["kappa1"] - ratio * params["kappa2"])])
