"""A calibration error: gain and offset of one sensor relative to the other.

Only the relative calibration is visible from two sensors: the fit says tc2 reads
``gain * T + offset_c`` where tc1 reads T. A gain or offset error of tc1 shows up as the
reciprocal gain and a scaled offset; the time constants are unaffected.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .base import Effect, FitContext, ParamSpec

__all__ = ["Calibration"]

#: Largest relative gain error of one sensor against the other that counts as calibration.
GAIN_LIMIT = 0.2


class Calibration(Effect):
    """Gain (dimensionless) and offset (degrees C) of tc2 relative to tc1.

    τ may move any distance from the first-order estimate (:attr:`max_tau_factor` infinite):
    the first-order model has no gain between the sensors and bends τ to explain one without
    limit (0.75 % of gain moved τ1 by +34 % on a slow drift).
    """

    name = "calibration"
    max_tau_factor = math.inf
    summary = "tc2 reads gain * T + offset relative to tc1 (gain, offset_c)"

    def specs(self, context: FitContext) -> tuple[ParamSpec, ...]:
        # Physical bounds: a thermocouple whose gain is off by more than GAIN_LIMIT is broken,
        # not miscalibrated; the offset may be whatever that gain leaves at the level.
        span = GAIN_LIMIT * abs(context.level_mean_c) + 10.0 * context.level_std_c + 10.0
        return (
            ParamSpec(
                name="gain",
                unit="1",
                lower=1.0 - GAIN_LIMIT,
                upper=1.0 + GAIN_LIMIT,
                description="gain of tc2 relative to tc1",
            ),
            ParamSpec(
                name="offset_c",
                unit="degC",
                lower=-span,
                upper=span,
                description="offset of tc2 relative to tc1",
            ),
        )

    def starts(
        self,
        context: FitContext,
        params: Mapping[str, float],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
    ) -> list[dict[str, float]]:
        return [{"gain": 1.0, "offset_c": 0.0}]

    def identifiability(self, params: Mapping[str, float]) -> str:
        return (
            "calibration: only the relative calibration is visible (tc2 reads "
            f"{params['gain']:.4g} T {params['offset_c']:+.3g} degC where tc1 reads T); which "
            "sensor is right cannot be told from two signals: the gas temperature is given on "
            "tc1's scale"
        )

    def calibration(self, sensor: int, params: Mapping[str, float]) -> tuple[float, float]:
        if sensor == 2:
            return params["gain"], params["offset_c"]
        return 1.0, 0.0
