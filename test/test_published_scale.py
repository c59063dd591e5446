"""A fitted model's τ take the default path's common scale where the fit cannot pin it.

The cross-relation fit of a model with effects pins the ratio τ2/τ1 far better than the
scale both share; the default path (ml-eiv) knows the scale better. Only effects that move the
sensors apart (a shift, a gain, a line, a noise) leave first order's scale unbiased.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from detailed_physics import Rig, Wire, simulate_rig
from sim_records import record_of

from tcomp_core.diagnose.pipeline import _base_fit
from tcomp_core.diagnose.ranking import fit_with_effect
from tcomp_core.effects import EFFECTS, Model
from tcomp_core.estimators.default import default_estimate

#: Each test fits a delay on a 3 s, 5 kHz detailed-physics record first.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def delayed():
    """Evaluator and delay fit of 5 kHz engine pulses with a 0.4 ms delay (2 samples)."""
    delay, speed = 0.0004, 5.0
    rig = Rig(
        signal="engine_pulses",
        duration_s=3.0,
        rate_hz=5000.0,
        seed=5,
        wires=(Wire(56e-6), Wire(100e-6)),
        speed_m_s=speed,
        spacing_m=delay * speed,
        noise_c=(1.0, 1.0),
    )
    sim = simulate_rig(rig)
    record = record_of(sim, "d")
    plain = default_estimate(record)
    taus = (float(plain.tau1), float(plain.tau2))
    evaluator, start, _, _ = _base_fit(record, taus, plain.lines)
    model, _ = fit_with_effect(evaluator, start, "delay")
    return evaluator, evaluator.refit_model(model)


def test_the_default_paths_scale_is_taken_along_the_fits_loose_direction_only(delayed):
    evaluator, model = delayed
    ratio = model.tau2 / model.tau1
    for factor in (0.97, 1.04):
        scaled = replace(evaluator, published_taus_s=(factor * model.tau1, factor * model.tau2))
        kept = scaled.with_published_scale(model, frozenset())
        assert kept is not None, factor
        assert kept.tau1 == pytest.approx(factor * model.tau1, rel=0.01)
        assert kept.tau2 / kept.tau1 == pytest.approx(ratio, rel=0.005)
        # The delay is refitted at the held τ, not left as it was.
        assert kept.params["delay_s"] == pytest.approx(model.params["delay_s"], rel=0.5)
    # A default path whose ratio differs moves only the scale: the ratio stays the fit's.
    tilted = replace(evaluator, published_taus_s=(model.tau1, 1.03 * model.tau2))
    kept = tilted.with_published_scale(model, frozenset())
    assert kept is not None and kept.tau2 / kept.tau1 == pytest.approx(ratio, rel=0.005)


def test_a_scale_the_fit_rules_out_or_held_taus_are_not_taken(delayed):
    evaluator, model = delayed
    far = replace(evaluator, published_taus_s=(3.0 * model.tau1, 3.0 * model.tau2))
    assert far.with_published_scale(model, frozenset()) is None
    near = replace(evaluator, published_taus_s=(1.02 * model.tau1, 1.02 * model.tau2))
    assert near.with_published_scale(model, frozenset({"tau1", "tau2"})) is None
    assert replace(near, published_taus_s=None).with_published_scale(model, frozenset()) is None


def test_an_effect_on_the_lag_keeps_its_own_scale(delayed):
    evaluator, model = delayed
    near = replace(evaluator, published_taus_s=(1.02 * model.tau1, 1.02 * model.tau2))
    on_lag = [name for name, effect in EFFECTS.items() if not effect.keeps_first_order_scale]
    assert {"velocity", "conduction", "radiation", "property"} <= set(on_lag)
    conduction, _ = fit_with_effect(evaluator, model, "conduction")
    assert near.with_published_scale(conduction, frozenset()) is None


def test_a_fit_with_one_free_parameter_runs(delayed):
    """τ held leaves a delay fit one unknown (SciPy's LSMR trust-region step needs two)."""
    evaluator, model = delayed
    hold = frozenset(model.params) - {"delay_s"}
    fitted = model.params["delay_s"]
    for delay_s in (0.0, 0.3 * fitted, 3.0 * fitted):  # off the fit: trust-region steps
        start = Model(model.effects, {**model.params, "delay_s": delay_s})
        refit = evaluator.refit_model(start, hold)
        assert refit.params["delay_s"] == pytest.approx(fitted, rel=0.05), delay_s
        assert (refit.tau1, refit.tau2) == (model.tau1, model.tau2)


def test_the_output_error_grid_ranks_with_loose_fits_and_searches_from_a_converged_one(
    delayed, monkeypatch
):
    """Conduction's legs (an output-error parameter): the grid's fits only rank its points, at
    GRID_TOLERANCE; the best point's fit is converged at the fit's own tolerance before the
    search starts from it, and what the search returns is a converged fit."""
    from tcomp_core.diagnose import ranking
    from tcomp_core.diagnose.heldout import Evaluator
    from tcomp_core.effects.model import FIT_TOLERANCE

    evaluator, model = delayed
    calls = []
    fit = Evaluator.fit

    def recording(self, start, hold=frozenset(), tolerance=FIT_TOLERANCE):
        fitted = fit(self, start, hold, tolerance)
        calls.append((tolerance, start, fitted))
        return fitted

    monkeypatch.setattr(Evaluator, "fit", recording)
    start = model.with_effect("conduction")
    found = ranking._output_error_fit(evaluator, start, ("tau_leg",), coupled=True)
    grid = calls[: ranking.OUTPUT_ERROR_GRID]
    assert all(tolerance == ranking.GRID_TOLERANCE for tolerance, _, _ in grid)
    assert all(tolerance == FIT_TOLERANCE for tolerance, _, _ in calls[len(grid) :])
    errors = [evaluator.training_error(fitted) for _, _, fitted in grid]
    assert calls[len(grid)][1] is grid[errors.index(min(errors))][2]  # the best, converged
    assert any(found is fitted for _, _, fitted in calls[len(grid) :])
