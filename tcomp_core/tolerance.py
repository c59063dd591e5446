"""Calibration tolerance of the thermocouples users own (IEC 60584, class 2).

Two class-2 sensors in the same gas may read up to about 2.5 °C or 0.75 % of the level apart
(issue 24: "±2.5 °C or 0.75 % between the two sensors"). Both the first-order estimator, which
fits a gain between the sensors with this tolerance as its prior, and the calibration effect,
which calls a difference within it the sensors' ordinary state, use these figures.
"""

from __future__ import annotations

__all__ = ["CLASS2_GAIN", "CLASS2_OFFSET_C", "class2_level_tolerance_c"]

#: Relative gain between two class-2 sensors, dimensionless.
CLASS2_GAIN = 0.0075
#: Offset between two class-2 sensors at the level, degrees C, to which CLASS2_GAIN of the
#: level is added.
CLASS2_OFFSET_C = 2.5


def class2_level_tolerance_c(level_c: float) -> float:
    """How far two class-2 sensors may differ in level at ``level_c`` (degrees C), degrees C."""
    return CLASS2_OFFSET_C + CLASS2_GAIN * abs(level_c)
