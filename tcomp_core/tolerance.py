"""Calibration tolerance of the thermocouples users own (IEC 60584, class 2).

Two class-2 sensors in the same gas may read up to about 2.5 °C or 0.75 % of the level apart
(issue 24: "±2.5 °C or 0.75 % between the two sensors"). Both the first-order estimator, which
fits a gain between the sensors with this tolerance as its prior, and the calibration effect,
which calls a difference within it the sensors' ordinary state, use these figures; beyond
them by :data:`CLASS2_MARGIN`, :func:`class2_disagreement` says so (the CLI's warning, the node's
``sensor_disagreement``).
"""

from __future__ import annotations

__all__ = [
    "CLASS2_GAIN",
    "CLASS2_MARGIN",
    "CLASS2_OFFSET_C",
    "beyond_class2",
    "class2_disagreement",
    "class2_level_tolerance_c",
]

#: Relative gain between two class-2 sensors, dimensionless.
CLASS2_GAIN = 0.0075
#: Offset between two class-2 sensors at the level, degrees C, to which CLASS2_GAIN of the
#: level is added.
CLASS2_OFFSET_C = 2.5
#: A calibration difference within class 2 is the state of the sensors users own: fitted when
#: it helps (it moves τ) but no finding. It counts beyond class 2 by this factor: the fit
#: resolves a gain to about ±1 % (95 % intervals on the effect simulator at K = 1 %,
#: ``test_calibration_intervals_cover_the_truth_and_are_tight``) and more at higher noise, so
#: a pair at the edge of the class is not called miscalibrated by its fit's error. (It was
#: 1.25 until the first campaign draws: three clean pairs within class 2 were called
#: miscalibrated.)
CLASS2_MARGIN = 2.0


def class2_level_tolerance_c(level_c: float) -> float:
    """How far two class-2 sensors may differ in level at ``level_c`` (degrees C), degrees C."""
    return CLASS2_OFFSET_C + CLASS2_GAIN * abs(level_c)


def beyond_class2(gain: float, offset_c: float, level_c: float) -> bool:
    """Whether two sensors differ beyond class 2 by :data:`CLASS2_MARGIN`.

    A gain off by more than the margin times :data:`CLASS2_GAIN`, or a difference at the level
    ``offset_c`` (degrees C) beyond the margin times :func:`class2_level_tolerance_c` at
    ``level_c`` (degrees C).
    """
    return bool(
        abs(gain - 1.0) > CLASS2_MARGIN * CLASS2_GAIN
        or abs(offset_c) > CLASS2_MARGIN * class2_level_tolerance_c(level_c)
    )


def class2_disagreement(gain: float, offset_c: float, level_c: float) -> str:
    """How two sensors' fitted disagreement lies beyond class 2, or '' when it does not.

    Beyond as :func:`beyond_class2` judges it.

    Parameters
    ----------
    gain : float
        tc1's reading per degree of tc2's, dimensionless (ml-eiv's ``gain``).
    offset_c : float
        tc1's reading minus ``gain`` times tc2's at tc2's mean, degrees C (``offset_c``).
    level_c : float
        Mean temperature of the readings, degrees C.

    Returns
    -------
    str
        E.g. ``"the two readings differ by +4.05 % in gain and +2.12 °C in level, beyond IEC
        60584 class 2 (0.75 % in gain, 3.7 °C in level at 163 °C)"``.
    """
    if not beyond_class2(gain, offset_c, level_c):
        return ""
    tolerance = class2_level_tolerance_c(level_c)
    return (
        f"the two readings differ by {100.0 * (gain - 1.0):+.3g} % in gain and "
        f"{offset_c:+.3g} °C in level, beyond IEC 60584 class 2 ({100 * CLASS2_GAIN:g} % in "
        f"gain, {tolerance:.2g} °C in level at {level_c:.4g} °C)"
    )
