"""Unequal noise on the two sensors: φ = σ1²/σ2² ≠ 1 in C0(φ) (Eq. 19).

β-GTLS with φ = 1 is consistent only when both sensors are equally noisy; otherwise it weights
the two equations wrongly and biases τ. The ratio is not fitted by the criterion (a larger
assumed noise always "explains" more); it is measured from the spectra above both sensors'
bandwidth (:mod:`tcomp_core.noise`) and then used in the fit.
"""

from __future__ import annotations

from collections.abc import Mapping

from .base import Effect, FitContext

__all__ = ["NoiseRatio"]


class NoiseRatio(Effect):
    """φ = σ1²/σ2², measured from the spectra by the model."""

    name = "noise_ratio"
    summary = "the sensors' noise variances differ (phi from the spectra)"

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """sigma_ratio = σ2/σ1 (dimensionless): φ = σ1²/σ2² = 0.16."""
        return {"sigma_ratio": 2.5}

    def output_handling(self, intervals: Mapping[str, tuple[float, float]]) -> tuple[str, str]:
        return "compensated", "the noise levels are measured from the readings"

    def fixed(self, context: FitContext) -> dict[str, float]:
        return {"phi": context.phi_hat}

    def noise_ratio(self, params: Mapping[str, float]) -> float:
        return params["phi"]
