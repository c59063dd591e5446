"""A transport delay: the second junction sees the gas δ seconds later than the first.

Junctions a few millimetres apart in a flow of a few metres per second, or different wire
lengths in the flow, see the same gas at different times. A delay looks like extra lag at low
frequencies, so the base model absorbs it into τ2 − τ1 and then fails at high frequencies.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from ..errors import TcompError
from ..estimators.beta import beta_gtls
from .base import Effect, FitContext, ParamSpec
from .chain import fractional_shift

__all__ = ["Delay"]

#: Trial delays of the closed-form scan, and how many of the best start the search. The GTLS
#: criterion is sharp around the true delay: a 9 ms delay on 40 Hz engine pulses stood out 5×
#: against its aliases one pulse period away with trials 1.3 ms apart, and was missed 4 ms
#: away (41 trials), where the search then ended on the alias with τ 50 % long.
_TRIALS = 161
_STARTS = 3


class Delay(Effect):
    """δ (s), positive when tc2 sees the gas later."""

    name = "delay"
    summary = "tc2 sees the gas later than tc1 (delay_s)"

    def _bound(self, context: FitContext) -> float:
        return float(min(max(context.tau_scale_s, 20.0 * context.dt), context.duration_s / 10.0))

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        bound = self._bound(context)
        return (
            ParamSpec(
                name="delay_s",
                unit="s",
                lower=-bound,
                upper=bound,
                description="how much later tc2 sees the gas than tc1",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        # A strong delay drives the base model's τ far off. β-GTLS on tc2 advanced by a trial
        # delay is closed-form, so a fine grid of trials finds the few delays (and τ) to start
        # from: those whose GTLS criterion (smallest generalised eigenvalue) is lowest.
        bound = self._bound(context)
        trials = []
        for delay in np.linspace(-0.9 * bound, 0.9 * bound, _TRIALS):
            shifted, _ = fractional_shift(tc2, delay / context.dt)
            inside = np.isfinite(shifted)
            try:
                found = beta_gtls(tc1[inside], shifted[inside], context.dt, context.phi_hat)
            except TcompError:
                continue
            criterion = found.params["noise_eigenvalue"] / inside.sum()
            trials.append(
                (criterion, {"delay_s": float(delay), "tau1": found.tau1, "tau2": found.tau2})
            )
        trials.sort(key=lambda trial: trial[0])
        return [{"delay_s": 0.0}] + [start for _, start in trials[:_STARTS]]

    def identifiability(self, params: Mapping[str, float]) -> str:
        return (
            "delay: only the relative delay is visible (tc2 sees the gas after tc1); the gas "
            "temperature is given at tc1's position"
        )

    def delay_s(self, params: Mapping[str, float]) -> float:
        return params["delay_s"]
