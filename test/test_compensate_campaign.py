"""A fast subset of ``bench/bench_compensate.py --campaign`` (issue 24).

The campaign's draws are a pure function of their index (``bench/campaign_draws.py``); these
are three of the cheapest (0.5 kHz): a clean pair within IEC 60584 class 2, a calibration
beyond it, and a delay with radiation to a constant wall. Each is diagnosed as a user runs it
and compensated with the output model; the gas is scored against the simulator's truth.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import bench_compensate
import campaign_draws

from tcomp_core import estimate

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("index", [41, 38, 68])
def test_a_campaign_draw_is_never_compensated_materially_worse(index):
    row = bench_compensate.campaign_row(index)
    assert "error" not in row, row.get("error")
    first, final = row["smoother_first"], row["smoother_final"]
    assert not campaign_draws.materially_worse(first, final), (row["label"], first, final)
    first, final = row["smoother_first_full"], row["smoother_final_full"]
    assert not campaign_draws.materially_worse(first, final), (row["label"], first, final)
    if not row["truth"]:
        assert row["found"] == [], (row["label"], row["found"])
    # Whatever is applied is pinned down and physical: a refused piece says why.
    for piece in row["pieces"]:
        assert piece["reason"], piece


@pytest.mark.parametrize("index", [3865, 3967])
def test_a_calibration_whose_free_gain_runs_to_its_bound_is_named_with_the_gain_held(index):
    """Rotating disks at 0.5 kHz with one sensor 2-4 % low in gain and 6-9 degC off: the free
    gain trades with tau2 along the disk's tone and runs to its bound (0.8), where its fit,
    though best on the held-out blocks, is refused as no physical explanation; the choice
    with the gain held at 1 is then the calibration's fit, not the record left unexplained
    (340 and 188 % held-out error before)."""
    from tcomp_core.diagnose import diagnose
    from tcomp_core.effects.calibration import GAIN_HELD

    item = campaign_draws.draw(index)
    assert item.effects == ("calibration",), item.label
    record, _ = campaign_draws.simulate(item)
    found = diagnose(record)
    assert found.verdict == "calibration", [(s.effect, s.refusal) for s in found.suspects[:3]]
    assert found.final.params[GAIN_HELD] == 1.0
    assert not found.final.at_bound
    assert found.final.error_pct < 0.01 * found.base.error_pct


def test_campaign_draws_are_a_function_of_their_index():
    first, again = campaign_draws.draw(7), campaign_draws.draw(7)
    assert first.label == again.label and first.rig == again.rig
    labels = {campaign_draws.draw(i).label for i in range(40)}
    assert len(labels) == 40
    effects = {e for i in range(40) for e in campaign_draws.draw(i).effects}
    assert effects == set(campaign_draws.CAMPAIGN_EFFECTS)
    # Every draw carries a sensor difference; within class 2 unless calibration is drawn.
    for i in range(40):
        item = campaign_draws.draw(i)
        _, gain, offset = item.rig.calibration
        inside = abs(gain - 1) <= campaign_draws.CLASS2_GAIN and abs(offset) <= 2.5
        assert inside != ("calibration" in item.effects), item.label


def test_materially_worse_needs_both_the_ratio_and_the_points():
    assert campaign_draws.materially_worse(1.0, 1.2)
    assert not campaign_draws.materially_worse(1.0, 1.09)  # within 1.1x
    assert not campaign_draws.materially_worse(0.5, 0.59)  # 1.18x but 0.09 point
    assert campaign_draws.materially_worse(1.0, float("nan"))


def test_a_record_whose_flow_speed_drifts_gets_a_first_order_estimate():
    # Draw 357: a flow speed drifting through a 10 kHz step/ramp record, so τ drifts too. The
    # first-order search crosses a long flat valley (about 670 evaluations at φ = 1, more than
    # least_squares' default budget of 300); it was refused as "did not converge", leaving the
    # default path with no gas at all.
    item = campaign_draws.draw(357)
    assert "velocity" in item.effects
    record, truth = campaign_draws.simulate(item)
    result = estimate(record.tc1, record.tc2, record.dt, "ml-eiv", phi=1.0)
    assert result.params["evaluations"] > 300
    assert 0.0 < result.tau1 < result.tau2 < 10 * truth["tau2"]


def test_a_grid_start_below_a_sample_does_not_stall_the_default_estimate():
    # Draw 480: steps and ramps at 10 kHz, tc1 three times noisier than tc2, a delay. β-GTLS
    # gives no start, and the τ grid's best cell had τ1 a tenth of a sample, where the residual
    # does not depend on τ1: the search stalled there and the default path refused the record
    # ("condition inf"). From the grid's best cell with both τ at least a sample it finds τ.
    from tcomp_core.estimators import mleiv

    item = campaign_draws.draw(480)
    record, truth = campaign_draws.simulate(item)
    result = estimate(record.tc1, record.tc2, record.dt, "ml-eiv", phi=None)
    assert result.params["start_beta_gtls"] == 0.0
    assert result.tau1 == pytest.approx(truth["tau1"], rel=0.05)
    assert result.tau2 == pytest.approx(truth["tau2"], rel=0.05)
    problem = mleiv._CrossRelation.from_signals(
        record.tc1, record.tc2, record.dt, result.phi, mleiv._gain_weight(record.tc2)
    )
    starts = mleiv._grid_starts(problem)
    assert len(starts) == 2 and min(starts[1][:2]) >= math.log(record.dt)


def test_a_fit_whose_wide_parameters_move_the_gas_more_than_it_corrects_is_not_applied():
    # Draw 408: a radiating exhaust at 2 kHz (both wires read about 17 degC low) read as
    # conduction. The supports' temperatures span three quarters of their range, and across
    # them the gas moves by several times the correction: applied, the gas went 12.5 degC
    # further from the truth (13.5 -> 22.0 % against the default path's).
    row = bench_compensate.campaign_row(408)
    assert "error" not in row, row.get("error")
    assert "radiation" in row["truth"]
    default, final = row["smoother_default"], row["smoother_final"]
    assert not campaign_draws.materially_worse(default, final), (default, final)
    for piece in row["pieces"]:
        assert piece["handling"] == "first order" or piece["effect"] != "conduction", piece


def test_a_radiation_kept_at_first_orders_level_is_judged_on_what_it_changes():
    # Draw 422: tc1 3.2 % and 8.9 degC off (beyond class 2) on engine pulses, read as
    # radiation whose ratios are both within reach of 0: undone for the dynamics only, the
    # level first order's. Its change was measured with the level it does not apply (18 degC
    # rms, against a band of 2), so it passed, and its τ 7-10 % off made the gas 7.5 -> 12.2 %.
    # Measured as published, the change is 0.5 degC rms, inside its band: not applied.
    row = bench_compensate.campaign_row(422)
    assert "error" not in row, row.get("error")
    default, final = row["smoother_default"], row["smoother_final"]
    assert not campaign_draws.materially_worse(default, final), (default, final)
    for piece in row["pieces"]:
        assert piece["handling"] != "dynamics" or piece["effect"] != "radiation", piece
