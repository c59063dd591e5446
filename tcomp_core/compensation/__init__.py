"""Compensation with the diagnosed physics: the gas temperature of an extended model.

:mod:`.plan` decides how each effect of a fitted model is treated (:class:`OutputModel`, the
"never worse" rules); :mod:`.offline` reconstructs a whole record with it (Kalman smoother or
causal filter); :mod:`.stream` turns a stream of readings into first-order ones sample by
sample, for the compensator node and ``tcomp process``.
"""

from __future__ import annotations

from .offline import (
    Compensated,
    compensate,
    default_path_gas,
    equivalent_readings,
    level_shift_c,
)
from .plan import (
    FIRST_ORDER,
    OutputModel,
    Piece,
    default_estimate,
    default_first_order_failure,
    default_taus,
    fit_output_model,
    output_model_from_diagnosis,
    output_model_with_fallback,
    parse_compensate_effects,
    swapped_sensors,
)

__all__ = [
    "FIRST_ORDER",
    "Compensated",
    "OutputModel",
    "Piece",
    "compensate",
    "default_estimate",
    "default_first_order_failure",
    "default_path_gas",
    "default_taus",
    "equivalent_readings",
    "fit_output_model",
    "level_shift_c",
    "output_model_from_diagnosis",
    "output_model_with_fallback",
    "parse_compensate_effects",
    "swapped_sensors",
]
