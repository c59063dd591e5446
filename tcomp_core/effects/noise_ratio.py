"""Unequal noise on the two sensors: φ = σ1²/σ2² ≠ 1 in C0(φ) (Eq. 19).

β-GTLS with φ = 1 is consistent only when both sensors are equally noisy; otherwise it weights
the two equations wrongly and biases τ. The ratio is not fitted by the criterion (a larger
assumed noise always "explains" more); it is measured from the spectra above both sensors'
bandwidth (:mod:`tcomp_core.noise`) and then used in the fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from .base import Effect, FitContext, OutputEvidence

if TYPE_CHECKING:
    from ..lines import ForeignLine

__all__ = ["NOISE_RATIO_FACTOR", "NoiseRatio", "noise_ratio_beyond_chance"]

#: Noise variance ratio φ̂ beyond which (or below its inverse) unequal noise is a finding by
#: itself: the spectral estimate of φ is good to ~10 % on clean records, but a fast sensor whose
#: signal reaches the top of the band (sharp exhaust pulses) reads up to ~1.7 with equal noise.
#: On 241 stored campaign draws φ̂ lay beyond it on all 24 whose sensors' noise differed (σ
#: ratios 2-3.5: φ̂ 4.37 or more either way) and within 1.32 of 1 on the 217 others.
NOISE_RATIO_FACTOR = 2.0


def noise_ratio_beyond_chance(phi_hat: float) -> bool:
    """Whether a measured φ̂ lies beyond :data:`NOISE_RATIO_FACTOR` (or below its inverse)."""
    return abs(math.log(phi_hat)) > math.log(NOISE_RATIO_FACTOR)


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

    def found_by_default_path(self, lines: Sequence[ForeignLine], phi_hat: float) -> str:
        """Noise variances that differ beyond :data:`NOISE_RATIO_FACTOR`, measured.

        The default path measures φ itself and weighs the sensors by it (ml-eiv, the
        smoother), so a model may need no piece for it: the refit with φ measured can even
        score worse on the held-out blocks than φ = 1 (campaign draw 3454, φ̂ = 6.5: raw error
        1.57 → 2.03 %), and the draw read ``none``.
        """
        if not noise_ratio_beyond_chance(phi_hat):
            return ""
        return (
            f"the sensors' noise variances differ (phi = sigma1^2/sigma2^2 = {phi_hat:.3g} "
            "from the spectra); the default path measures phi itself and weighs the sensors "
            "by it, so the model needs no piece for it"
        )

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
