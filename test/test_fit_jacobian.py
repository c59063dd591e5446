"""The effect fit's Jacobian (chain memo, s(t) shortcut) against scipy's finite differences."""

import numpy as np
import pytest
from scipy.optimize._numdiff import approx_derivative

from tcomp_core.effects import Model, make_context
from tcomp_core.effects.model import _LastResiduals
from tcomp_core.simulate_effects import simulate_effect

PARAMS = {
    "velocity": {"velocity_1": 0.2, "velocity_3": -0.3, "velocity_smoothness": 0.05},
    "radiation": {"rho1": 0.04, "rho2": 0.07, "wall_c": 150.0},
    "calibration": {"gain": 1.02, "offset_c": -0.5},
    "delay": {"delay_s": 0.003},
    "conduction": {"tau_leg": 0.3, "tau_p": 0.8, "mode1": 0.1, "mode2": -0.2},
}


@pytest.mark.parametrize(
    "effects",
    [("velocity",), ("velocity", "radiation"), ("calibration", "delay"), ("conduction",)],
)
def test_jacobian_equals_finite_differences(effects):
    sim = simulate_effect(effects[0], "multisine", duration=4.0, noise_percent=1.0, seed=4)
    context = make_context(sim.time, sim.tc1, sim.tc2, sim.dt, knot_spacing_s=0.5)
    params = {"tau1": 0.0238, "tau2": 0.1168}
    for name in effects:
        params.update(PARAMS[name])
    model = Model(effects, params)
    for spec in model.specs(context):  # every searched parameter set, velocity's included
        params.setdefault(spec.name, 0.05)
    problem = Model(effects, params).problem(sim.tc1, sim.tc2, context)
    x = np.array(
        [
            np.log(params[s.name]) if s.name.startswith("tau") else params[s.name]
            for s in problem.specs
        ]
    )
    margin = 1e-3 * (problem.upper - problem.lower)
    x = np.clip(x, problem.lower + margin, problem.upper - margin)
    got = problem.jacobian(x)
    bounds = (problem.lower, problem.upper)
    forward = approx_derivative(problem.residuals, x, method="2-point", bounds=bounds)
    central = approx_derivative(problem.residuals, x, method="3-point", bounds=bounds)
    assert got.shape == forward.shape
    through_s = np.array([s.name.startswith("velocity_") for s in problem.specs])
    # Differenced columns: scipy's own forward differences (the memo must change nothing).
    np.testing.assert_allclose(got[:, ~through_s], forward[:, ~through_s], rtol=1e-9, atol=1e-12)
    if through_s.any():
        # The s(t) shortcut against central differences: equal to the forward step's
        # truncation and rounding, ~1.5e-8 |r| (a wrong or missing term is far larger).
        scale = np.abs(central[:, through_s]).max(axis=0)
        rounding = 1e-7 * np.abs(problem.residuals(x)).max()
        error = np.abs(got[:, through_s] - central[:, through_s]).max(axis=0)
        assert np.all(error <= 1e-4 * scale + rounding)


def test_the_residuals_at_the_last_point_are_not_evaluated_again():
    calls = []

    def residuals(x, penalty_only=False):
        calls.append(penalty_only)
        return np.array([1.0]) if penalty_only else np.append(2.0 * x, 1.0)

    remembered = _LastResiduals(residuals)
    x = np.array([1.0, 2.0])
    first = remembered(x)
    assert remembered.at(x.copy()) is first and len(calls) == 1
    remembered(x + 1.0, penalty_only=True)  # the penalty rows alone are not remembered
    assert remembered.at(x) is first and len(calls) == 2
    np.testing.assert_array_equal(remembered.at(x + 1.0), [4.0, 6.0, 1.0])
    assert len(calls) == 3


def test_the_jacobian_where_scipy_just_evaluated_is_the_one_from_scratch():
    """scipy asks for the Jacobian where it has just had the residuals; taken from them, it is
    the same to the bit as with the residuals evaluated afresh."""
    sim = simulate_effect("conduction", "multisine", duration=4.0, noise_percent=1.0, seed=4)
    context = make_context(sim.time, sim.tc1, sim.tc2, sim.dt)
    params = {"tau1": 0.0238, "tau2": 0.1168, **PARAMS["conduction"]}
    problem = Model(("conduction",), params).problem(sim.tc1, sim.tc2, context)
    x = problem.pack(params)
    problem.residuals(x)
    reused = problem.jacobian(x)
    problem.residuals(x + 0.01)  # elsewhere: the Jacobian evaluates r(x) itself
    np.testing.assert_array_equal(reused, problem.jacobian(x))
