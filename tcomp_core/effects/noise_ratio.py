"""Unequal noise on the two sensors: φ = σ1²/σ2² ≠ 1 in C0(φ) (Eq. 19).

β-GTLS with φ = 1 is consistent only when both sensors are equally noisy; otherwise it weights
the two equations wrongly and biases τ. The ratio is not fitted by the criterion (a larger
assumed noise always "explains" more); it is measured from the spectra above both sensors'
bandwidth (:mod:`tcomp_core.noise`) and then used in the fit.
"""

from __future__ import annotations

from collections.abc import Mapping

from .base import Effect, FitContext, OutputEvidence

__all__ = ["NoiseRatio"]


class NoiseRatio(Effect):
    """φ = σ1²/σ2², measured from the spectra by the model.

    Output (:meth:`output_handling`): first order. The ratio weights the two sensors, it
    changes nothing a reconstruction undoes, and the default path measures it itself; applied,
    the model only swapped ml-eiv's τ for the diagnosis's, and on every unseen campaign draw
    where it did (2101–2160) the gas was worse than the default path's: 3.51 → 4.20 % (2104,
    beside a radiation to a lagging wall), 4.58 → 6.21 % (2120, beside a calibration).
    """

    name = "noise_ratio"
    summary = "the sensors' noise variances differ (phi from the spectra)"
    keeps_first_order_scale = True
    default_path_covers = True

    def simulation_defaults(self, tau1: float, tau2: float, form: str) -> dict[str, float]:
        """sigma_ratio = σ2/σ1 (dimensionless): φ = σ1²/σ2² = 0.16."""
        return {"sigma_ratio": 2.5}

    def output_handling(self, fit: OutputEvidence) -> tuple[str, str]:
        return (
            "first order",
            "nothing in the sensor chain to undo: the default path measures the noise ratio "
            "itself (ml-eiv's phi from the spectra, the smoother's noise model), and ml-eiv's "
            "tau is at the Cramer-Rao bound",
        )

    def fixed(self, context: FitContext) -> dict[str, float]:
        return {"phi": context.phi_hat}

    def noise_ratio(self, params: Mapping[str, float]) -> float:
        return params["phi"]
