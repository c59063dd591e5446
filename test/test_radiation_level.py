"""Radiation's level correction is applied only where the data fix it (issue 24, item 3).

The correction of the gas level is inferred from the level difference radiation puts between
the two readings; class-2 sensors differ by up to their tolerance by themselves, and a
calibration in the same model takes that difference outright.
"""

from __future__ import annotations

import math

import pytest

from tcomp_core.effects.base import KELVIN, OutputEvidence
from tcomp_core.effects.radiation import Radiation, sensor_level_difference_c
from tcomp_core.tolerance import class2_level_tolerance_c

#: A fit whose ratios are both told from 0.
INTERVALS = {"rho1": (0.03, 0.07), "rho2": (0.06, 0.12)}


def _fit(rho1, rho2, wall_c=200.0, effects=("radiation",), level_c=600.0):
    params = {"tau1": 0.02, "tau2": 0.08, "rho1": rho1, "rho2": rho2, "wall_c": wall_c}
    return OutputEvidence(
        intervals=INTERVALS, params=params, effects=effects, level_mean_c=level_c
    )


def test_the_level_difference_is_the_slower_wires_extra_steady_loss():
    fit = _fit(0.05, 0.09)
    mean_k, wall_k = 600.0 + KELVIN, 200.0 + KELVIN
    loss = (mean_k**4 - wall_k**4) / (4 * mean_k**3)
    assert sensor_level_difference_c(fit.params, 600.0) == pytest.approx(0.04 * loss)
    # Sensor 1 slower: its ratio is the slow one's.
    swapped = {**fit.params, "tau1": 0.08, "tau2": 0.02}
    assert sensor_level_difference_c(swapped, 600.0) == pytest.approx(-0.04 * loss)
    assert math.isnan(sensor_level_difference_c(fit.params, math.nan))


def test_a_level_difference_beyond_class_2_fixes_the_level():
    fit = _fit(0.05, 0.09)  # about 8.0 degC apart at 600 degC, class 2 allows 7
    assert sensor_level_difference_c(fit.params, 600.0) > class2_level_tolerance_c(600.0)
    assert Radiation().output_handling(fit)[0] == "compensated"


def test_a_level_difference_within_class_2_leaves_the_level_first_orders():
    fit = _fit(0.05, 0.07)  # about 4.0 degC apart, within class 2 (7 degC at 600 degC)
    handling, reason = Radiation().output_handling(fit)
    assert handling == "dynamics"
    assert "class 2" in reason and "600" in reason


def test_a_calibration_beside_it_leaves_the_level_first_orders():
    fit = _fit(0.05, 0.12, effects=("radiation", "calibration"))
    handling, reason = Radiation().output_handling(fit)
    assert handling == "dynamics" and "calibration" in reason


def test_ratios_not_told_from_zero_leave_the_level_first_orders():
    fit = OutputEvidence(
        intervals={"rho1": (0.0, 0.07), "rho2": (0.0, 0.2)},
        params=_fit(0.05, 0.15).params,
        effects=("radiation",),
        level_mean_c=600.0,
    )
    assert Radiation().output_handling(fit)[0] == "dynamics"


@pytest.mark.parametrize(
    ("rho1", "rho2", "gain", "handling"),
    [
        (0.0336, 0.0303, None, "first order"),  # +0.32 %: a clean pair, tc1 0.27 % high
        (0.0193, 0.0274, None, "first order"),  # -0.79 %: a clean pair, tc1 0.66 % high
        (0.0608, 0.1024, None, "dynamics"),  # -3.8 %: radiation to a lagging wall
        (0.0096, 0.0214, 0.9857, "dynamics"),  # -1.2 % by radiation, -2.6 % with the gain
        (0.0096, 0.0214, 1.0060, "first order"),  # the calibration takes the gain back
    ],
)
def test_radiation_within_class_2_in_level_and_gain_leaves_the_gas_first_orders(
    rho1, rho2, gain, handling
):
    """A relative gain within class 2 (with the fit's margin) is the sensors' own: radiation
    fitted to it undoes nothing (the ratios and gains of seen campaign draws)."""
    fit = _fit(rho1, rho2, wall_c=190.0, level_c=200.0)  # a wall near the gas: level not fixed
    if gain is not None:
        fit = OutputEvidence(
            intervals=fit.intervals,
            params={**fit.params, "gain": gain},
            effects=("radiation", "calibration"),
            level_mean_c=200.0,
        )
    got, reason = Radiation().output_handling(fit)
    assert got == handling, reason
    if handling == "first order":
        assert "class-2" in reason and "%" in reason
