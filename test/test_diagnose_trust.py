"""Issue 15: physical bounds, confidence intervals, absolute significance, the property effect
and the unexplained verdict, checked on our effect simulator and on the independent detailed
physics simulator (test/detailed_physics.py)."""

import dataclasses
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from detailed_physics import Rig, Wire, simulate_rig
from scipy import signal
from sim_records import record_of

from tcomp_core.diagnose import diagnose, fit_effects
from tcomp_core.diagnose.quantisation import detect_quantisation, in_band_variance
from tcomp_core.diagnose.ranking import MIN_FALL_PER_FLOOR, is_significant
from tcomp_core.diagnose.result import ModelFit
from tcomp_core.effects import EFFECT_NAMES, make_context
from tcomp_core.effects.calibration import GAIN_HELD
from tcomp_core.effects.model import Model
from tcomp_core.effects.radiation import (
    SIMULATED_GAS_MEAN_C,
    SIMULATED_RHO1,
    Radiation,
    max_radiation_ratio,
)
from tcomp_core.io import Record
from tcomp_core.simulate_effects import simulate_effect


def _record(sim, name="x"):
    return record_of(sim, name)


def test_radiation_bound_follows_emissivity_one_and_the_weakest_convection():
    # A 50 degC rig cannot radiate like a 700 degC exhaust: the bound grows as T^3 / h_min.
    cold = max_radiation_ratio(0.1168, 50.0)
    hot = max_radiation_ratio(0.0238, SIMULATED_GAS_MEAN_C)
    assert cold < 0.05 < SIMULATED_RHO1 < hot
    # h_min ~ tau^-1/2, so the bound grows as sqrt(tau).
    assert max_radiation_ratio(0.4, 300.0) / max_radiation_ratio(0.1, 300.0) == pytest.approx(2.0)
    time = np.arange(1000) * 0.002
    context = make_context(
        time, 50.0 + np.sin(time), 50.0 + np.sin(time), 0.002, base_taus_s=(0.0238, 0.1168)
    )
    specs = {spec.name: spec for spec in Radiation().specs(context)}
    assert specs["rho1"].upper == pytest.approx(max_radiation_ratio(0.0238, context.level_mean_c))
    assert specs["rho2"].upper == pytest.approx(max_radiation_ratio(0.1168, context.level_mean_c))
    assert specs["wall_c"].lower == pytest.approx(200.0 - 273.15)


def _fit(error, raw, floor, blocks, params, at_bound=()):
    return ModelFit(
        effects=(),
        params=params,
        tau1=0.02,
        tau2=0.1,
        error_pct=error,
        raw_error_pct=raw,
        noise_floor_pct=floor,
        train_error_pct=error,
        block_errors_pct=np.asarray(blocks, dtype=float),
        predicted=np.zeros(3),
        gas1=np.zeros(3),
        gas2=np.zeros(3),
        n_params=len(params),
        at_bound=at_bound,
    )


def test_significance_needs_a_fall_above_the_floor_inside_the_physical_range():
    taus = {"tau1": 0.02, "tau2": 0.1}
    current = _fit(5.0, 5.2, 1.0, [5.0, 5.5, 4.8, 5.2, 5.1], taus)
    better = dict(error=1.0, raw=1.4, floor=1.0, blocks=[1.2, 1.5, 1.1, 1.3, 1.4])
    with_gain = {**taus, "gain": 1.02, "offset_c": 0.1}
    assert is_significant(current, _fit(**better, params=with_gain))
    # The same fall with the new gain on its bound: physics does not allow it.
    assert not is_significant(current, _fit(**better, params=with_gain, at_bound=("gain",)))
    # A τ the candidate drives onto its bound is a degenerate fit; one already there before,
    # or already collapsed near it (a missing delay does that to τ1), does not count against
    # the new effect.
    driven = {**with_gain, "tau1": 4e-5}
    degenerate = _fit(**better, params=driven, at_bound=("tau1",))
    assert not is_significant(current, degenerate)
    assert is_significant(dataclasses.replace(current, at_bound=("tau1",)), degenerate)
    collapsed = dataclasses.replace(current, params={**taus, "tau1": 8e-5})
    assert is_significant(collapsed, degenerate)
    # A raw fall of 45 %, every block better, but the model error falls by 0.35 % against a
    # 2 % noise floor: not a clear part of the error above the floor.
    small = _fit(0.6, 2.0, 2.0, [1.9, 2.1, 1.8, 2.0, 2.05], taus)
    smaller = _fit(0.25, 1.1, 2.0, [1.0, 1.2, 1.1, 1.0, 1.1], with_gain)
    assert MIN_FALL_PER_FLOOR * 2.0 > 0.6 - 0.25
    assert not is_significant(small, smaller)
    assert is_significant(dataclasses.replace(small, noise_floor_pct=0.5), smaller)


def test_each_refusal_names_the_rule_that_failed_with_its_figures():
    from tcomp_core.diagnose.ranking import significance_refusal

    taus = {"tau1": 0.02, "tau2": 0.1}
    with_gain = {**taus, "gain": 0.8, "offset_c": 3.7}
    current = _fit(5.0, 5.2, 1.0, [5.0, 5.5, 4.8, 5.2, 5.1], taus)
    better = dict(error=1.0, raw=1.4, floor=1.0, blocks=[1.2, 1.5, 1.1, 1.3, 1.4])
    assert significance_refusal(current, _fit(**better, params=with_gain)) == ""
    on_bound = significance_refusal(current, _fit(**better, params=with_gain, at_bound=("gain",)))
    assert "gain = 0.8" in on_bound and "edge of its physical range" in on_bound
    small = significance_refusal(current, _fit(4.6, 4.8, 1.0, [4.6] * 5, with_gain))
    assert "falls 7.69 % (5.2 -> 4.8 %), 20 % asked" in small
    patchy = significance_refusal(current, _fit(1.0, 1.4, 1.0, [1.0, 6.0, 6.0, 1.0, 1.0], taus))
    assert "in 60 % of the validation blocks, 70 % asked" in patchy
    # A current model with no raw error left: nothing can fall (no division by it).
    perfect = dataclasses.replace(current, raw_error_pct=0.0)
    assert "falls -inf %" in significance_refusal(perfect, _fit(**better, params=with_gain))
    # Every refusal is a verdict of is_significant and the other way round.
    for fit in (_fit(**better, params=with_gain), _fit(4.6, 4.8, 1.0, [4.6] * 5, with_gain)):
        assert is_significant(current, fit) == (significance_refusal(current, fit) == "")


def test_the_refused_suspects_above_the_taken_one_are_said_with_their_reason():
    from tcomp_core.cli.diagnosis import _refused_ahead
    from tcomp_core.diagnose.result import Suspect

    def suspect(name, evidence, significant, refusal=""):
        return Suspect(
            effect=name,
            error_pct=1.0,
            evidence=evidence,
            signature="",
            significant=significant,
            refusal=refusal,
        )

    ranked = [
        suspect("calibration", 0.9, False, "its fit puts gain = 0.8 on the edge"),
        suspect("delay", 0.1, False, "the raw held-out error falls 5 %"),
        suspect("velocity", -0.2, False, "the raw held-out error falls -20 %"),
        suspect("conduction", 0.5, True),
        suspect("radiation", 0.05, False, "below materiality"),
    ]
    assert [s.effect for s in _refused_ahead(ranked)] == ["calibration", "delay"]
    assert Suspect.summary(ranked[0])["refusal"] == "its fit puts gain = 0.8 on the edge"
    assert Suspect.summary(ranked[3])["refusal"] == ""


def test_a_suspect_that_clearly_beats_a_significant_one_is_significant_too():
    from tcomp_core.diagnose.ranking import _dominant
    from tcomp_core.diagnose.result import Suspect

    taus = {"tau1": 0.02, "tau2": 0.1}
    current = _fit(2.5, 2.6, 0.5, [2.5, 2.6, 2.4, 2.7, 2.5], taus)
    weaker = _fit(1.0, 1.1, 0.5, [1.0, 1.2, 1.1, 1.0, 1.1], {**taus, "tau_leg": 0.01})
    stronger = _fit(0.08, 0.5, 0.5, [0.5, 0.6, 0.4, 0.5, 0.5], {**taus, "delay_s": 5e-4})

    def suspect(name, fit, significant):
        return Suspect(
            effect=name,
            error_pct=fit.error_pct,
            evidence=0.5,
            signature="",
            significant=significant,
            fit=fit,
        )

    marked = _dominant(
        [suspect("delay", stronger, False), suspect("conduction", weaker, True)], current
    )
    assert [s.significant for s in marked] == [True, True]
    # Not when it is degenerate (a parameter it adds on its bound) ...
    bound = dataclasses.replace(stronger, at_bound=("delay_s",))
    marked = _dominant(
        [suspect("delay", bound, False), suspect("conduction", weaker, True)], current
    )
    assert not marked[0].significant
    # ... nor when it beats the accepted one in too few blocks, nor when nothing was accepted.
    patchy = dataclasses.replace(stronger, block_errors_pct=np.array([0.5, 1.3, 1.4, 1.2, 0.5]))
    marked = _dominant(
        [suspect("delay", patchy, False), suspect("conduction", weaker, True)], current
    )
    assert not marked[0].significant
    alone = _dominant([suspect("delay", stronger, False)], current)
    assert not alone[0].significant
    # ... nor when it does not beat the current model itself: an accepted suspect may stand
    # above it (a noise ratio is accepted by its measured φ when its refit does no harm).
    measured = _fit(3.0, 3.1, 0.5, [3.0, 3.1, 2.9, 3.2, 3.0], taus)
    level = _fit(2.45, 2.55, 0.5, [2.45, 2.55, 2.35, 2.65, 2.45], {**taus, "delay_s": 1e-6})
    marked = _dominant(
        [suspect("delay", level, False), suspect("noise_ratio", measured, True)], current
    )
    assert not marked[0].significant


def test_a_runner_up_staircase_is_abandoned_only_where_it_cannot_win():
    from tcomp_core.diagnose.pipeline import _cannot_end_better, _clearly_better

    taus = {"tau1": 0.02, "tau2": 0.1}
    blocks = [0.3, 0.25, 0.3, 0.2, 0.3]

    def fit(error, effects, scale=1.0):
        raw = 1.0 + error
        made = _fit(error, raw, 1.0, [b * scale for b in blocks], taus)
        return dataclasses.replace(made, effects=effects)

    explained = fit(0.3, ("delay",))  # below half a noise floor: nothing longer is significant
    # Even a perfect model with more effects is not significant against it ...
    perfect = dataclasses.replace(fit(0.0, ("property", "delay"), 0.0), raw_error_pct=1.0)
    assert not _clearly_better(perfect, explained, 1.0)
    assert _cannot_end_better(fit(5.0, ("property", "delay")), explained, 1.0)
    # ... so a staircase as long as it is left only if its step is not clearly better ...
    assert _cannot_end_better(fit(10.8, ("property",), 20.0), explained, 1.0)
    clearly = fit(0.1, ("property",), 0.5)
    assert _clearly_better(clearly, explained, 1.0)
    assert not _cannot_end_better(clearly, explained, 1.0)
    # ... and a shorter one, or one against a model not explained to its noise, is followed.
    assert not _cannot_end_better(fit(10.8, ()), fit(0.3, ("delay", "property")), 1.0)
    assert not _cannot_end_better(fit(5.0, ("property", "delay")), fit(0.6, ("delay",)), 1.0)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kind", "dt", "delay_s", "seed"),
    [("multisine", 2e-4, 4e-4, 41), ("exhaust", 2e-4, 6e-4, 42), ("ramp", 1e-4, 3e-4, 43)],
)
def test_a_delay_of_a_few_samples_at_a_high_rate_is_the_verdict(kind, dt, delay_s, seed):
    # The diagnosis works decimated; a delay of 2-3 raw samples is a fraction of a working
    # sample, and was ruled immaterial while a weaker conduction was taken.
    sim = simulate_effect(
        "delay",
        kind,
        tau1=0.0165,
        tau2=0.08,
        dt=dt,
        duration=5.0,
        noise_percent=1.0,
        seed=seed,
        params={"delay_s": delay_s},
    )
    found = diagnose(_record(sim))
    assert found.verdict == "delay"
    assert found.final.params["delay_s"] == pytest.approx(delay_s, rel=0.25)


@pytest.mark.slow
def test_a_level_difference_one_tone_cannot_tell_from_a_gain_is_named_calibration():
    """On a rotating disk (nearly one tone) a gain trades with τ along the tone's amplitude
    ratio: fitted free it went to its bound and the fit was refused, leaving the record
    unexplained. The gain held at 1, the level difference beyond class 2 is the verdict."""
    rig = _rig(calibration=(1, 0.958, 8.9), noise_c=(0.2, 0.2), seed=11)
    rec = simulate_rig(rig)
    found = diagnose(_record(rec))
    assert found.verdict == "calibration", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    params = found.final.params
    assert params[GAIN_HELD] == 1.0 and params["gain"] == 1.0
    assert "gain held at 1" in " ".join(found.identifiability)
    # tc2 against tc1 at the mean level: tc1 reads 0.958 T + 8.9 where tc2 reads T.
    level = float(np.mean(rec.tc1))
    truth = (level - 8.9) / 0.958 - level
    assert params["offset_c"] == pytest.approx(truth, abs=0.5)
    # The 4.4 % gain the tone does not show is taken into τ2 (about 6 % short here).
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.08)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.08)


def _delayed_pulses(seed):
    """Exhaust pulses at 2 kHz, tc2 1.5 ms downstream (3 samples), tc2's gain 0.72 % low.

    The gain lies within IEC 60584 class 2; the cross-relation's τ are noise-biased here, the
    default path's ml-eiv's are not (fresh campaign draw 3747, other seeds).
    """
    rig = Rig(
        signal="engine_pulses",
        duration_s=4.0,
        rate_hz=2000.0,
        seed=seed,
        wires=(Wire(diameter_m=69e-6), Wire(diameter_m=178e-6)),
        speed_m_s=6.4,
        spacing_m=0.0099,
        calibration=(2, 0.9928, -0.7),
        noise_c=(0.32, 0.32),
    )
    return simulate_rig(rig)


@pytest.mark.slow
def test_a_delay_is_judged_at_the_default_paths_scale_of_tau():
    """The base model takes the default path's τ where they simulate the slow sensor better;
    a delay, which keeps first order's scale, is offered that scale too, or it carries the
    cross-relation's bias the base was spared: judged with its own fit's τ the delay was
    refused and the record left unexplained, τ1 9 % short."""
    rec = _delayed_pulses(seed=1)
    found = diagnose(_record(rec, "delayed pulses"))
    assert found.verdict == "delay", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert found.final.params["delay_s"] == pytest.approx(rec.truth["delay_s"], rel=0.1)
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.03)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.03)


def test_a_whole_record_refit_that_simulates_worse_is_not_taken(monkeypatch):
    """Held-out blocks choose the model; its refit on the whole record is kept only where it
    simulates the slow sensor at least as well (the cross-relation behind it is biased)."""
    from tcomp_core.diagnose.heldout import Evaluator
    from tcomp_core.diagnose.pipeline import _base_fit

    sim = simulate_effect("delay", "exhaust", noise_percent=1.0, seed=5, params={"delay_s": 0.004})
    evaluator, start, _, _ = _base_fit(_record(sim, "delay"))
    chosen = evaluator.fit(start.with_effect("delay"))
    fit = evaluator.evaluate(chosen)
    honest = Evaluator.refit_model

    def biased(self, model, hold=frozenset()):
        refit = honest(self, model, hold)
        return Model(refit.effects, {**refit.params, "tau1": 0.7 * refit.params["tau1"]})

    kept = evaluator.refit_whole(fit)
    assert kept.tau1 != pytest.approx(chosen.tau1, rel=1e-9)  # an honest refit is taken
    monkeypatch.setattr(Evaluator, "refit_model", biased)
    kept = evaluator.refit_whole(fit)
    assert kept.tau1 == pytest.approx(chosen.tau1, rel=1e-9)
    assert kept.tau2 == pytest.approx(chosen.tau2, rel=1e-9)


def test_a_setting_that_holds_a_parameter_holds_it_in_every_fit():
    sim = simulate_effect("calibration", "multisine", noise_percent=1.0, seed=2)
    context = make_context(sim.time, sim.tc1, sim.tc2, sim.dt)
    start = {"tau1": sim.tau1, "tau2": sim.tau2}
    held = Model(("calibration",), {**start, GAIN_HELD: 1.0})
    assert "gain" not in {spec.name for spec in held.problem(sim.tc1, sim.tc2, context).specs}
    fitted = held.fit(sim.tc1, sim.tc2, context)
    assert fitted.params["gain"] == 1.0 and fitted.params[GAIN_HELD] == 1.0
    free = Model(("calibration",), {**start, GAIN_HELD: 0.0}).fit(sim.tc1, sim.tc2, context)
    assert free.params["gain"] == pytest.approx(sim.params["gain"], rel=0.005)


@pytest.mark.slow
def test_calibration_intervals_cover_the_truth_and_are_tight():
    covered, widths = {"tau1": 0, "tau2": 0, "gain": 0, "offset_c": 0}, []
    seeds = range(6)
    for seed in seeds:
        sim = simulate_effect("calibration", "multisine", noise_percent=1.0, seed=seed)
        found = fit_effects(_record(sim), ["calibration"])
        final = found.final
        # Said aloud: two signals see only the relative calibration.
        assert any("tc1's scale" in text for text in found.identifiability)
        truth = {"tau1": sim.tau1, "tau2": sim.tau2, **sim.params}
        for name in covered:
            low, high = final.intervals[name]
            covered[name] += low <= truth[name] <= high
        widths.append(final.intervals["gain"][1] - final.intervals["gain"][0])
        assert final.params["gain"] == pytest.approx(sim.params["gain"], rel=0.005)
    assert all(count >= len(seeds) - 1 for count in covered.values()), covered
    assert max(widths) < 0.02  # +-1 %: an interval, not a shrug


def _rig(**overrides):
    base = Rig(duration_s=10.0, rate_hz=2000.0, noise_c=(0.05, 0.05), adc_bits=16)
    return dataclasses.replace(base, **overrides)


@pytest.mark.slow
@pytest.mark.parametrize("channel", [2, 1])
def test_mains_on_one_channel_is_found_as_interference(channel):
    rig = _rig(seed=3, mains_hz=50.0, mains_amplitude_c=0.5, mains_channel=channel)
    rec = simulate_rig(rig)
    found = diagnose(_record(rec, "mains"))
    assert found.verdict == "interference", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert found.final.params["interference_hz"] == pytest.approx(50.0, abs=0.01)
    assert found.final.params["interference_channel"] == channel
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.02)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.02)
    assert not found.unexplained


@pytest.mark.slow
def test_mains_the_default_path_takes_off_is_named_though_the_model_needs_no_piece():
    """Lines one channel carries alone are notched by the default path before it estimates
    τ; the base model at its τ then leaves them no error, yet they are the record's physics."""
    from tcomp_core.diagnose.result import diagnosis_to_dict

    rig = _rig(
        signal="step_ramp",
        duration_s=6.0,
        seed=8,
        wires=(Wire(40e-6), Wire(90e-6)),
        speed_m_s=6.0,
        mains_hz=50.0,
        mains_amplitude_c=1.5,
        mains_channel=2,
        noise_c=(1.0, 1.0),
        adc_bits=None,
    )
    found = diagnose(_record(simulate_rig(rig), "mains"))
    assert found.default_path_findings == ["interference"], found.final.effects
    assert found.verdict == "interference"
    assert "interference" not in found.final.effects  # the exercised path: no piece for it
    assert any(re.search(r"tc2 carries a (49\.9|50)[.\d]* Hz line", n) for n in found.notes)
    assert diagnosis_to_dict(found)["default_path_findings"] == ["interference"]
    clean = diagnose(_record(simulate_rig(dataclasses.replace(rig, mains_hz=None)), "clean"))
    assert clean.default_path_findings == [] and clean.verdict != "interference"


@pytest.mark.slow
def test_without_the_interference_effect_mains_is_unexplained_and_named():
    rig = _rig(seed=3, mains_hz=50.0, mains_amplitude_c=0.5, mains_channel=2)
    others = [name for name in EFFECT_NAMES if name != "interference"]
    found = diagnose(_record(simulate_rig(rig), "mains"), candidates=others)
    assert found.verdict == "unexplained"
    text = found.unexplained
    assert re.search(r"spectral line at (49\.9|50)[.\d]* Hz on tc2", text), text


@pytest.mark.slow
def test_interference_on_the_effect_simulator_recovers_the_line():
    sim = simulate_effect("interference", "multisine", noise_percent=1.0, seed=1)
    found = diagnose(_record(sim))
    p = found.final.params
    assert found.verdict == "interference"
    assert p["interference_hz"] == pytest.approx(sim.params["interference_hz"], abs=0.01)
    amplitude = np.hypot(p["interference_a1"], p["interference_b1"])
    assert amplitude == pytest.approx(sim.params["interference_c"], rel=0.05)
    assert found.final.tau1 == pytest.approx(sim.tau1, rel=0.02)


@pytest.mark.slow
def test_clean_detailed_records_with_frozen_properties_give_none():
    for seed in range(2):
        record = _record(simulate_rig(_rig(seed=seed, frozen_gas_properties=True)))
        found = diagnose(record)
        assert found.verdict == "none", [(s.effect, s.error_pct) for s in found.suspects[:3]]
        assert not found.unexplained


@pytest.mark.slow
def test_clean_detailed_rig_with_realistic_gas_properties_gives_none():
    # τ follows the film temperature (Collis & Williams at the film temperature): the clean
    # 20–80 degC rig used to read calibration or radiation. The property fit explained it as
    # the wires' ordinary physics; since the base model fits the sensors' level difference
    # (level_c) no effect is needed at all, and the time constants come out right.
    for seed in range(2):
        rec = simulate_rig(_rig(seed=seed))
        found = diagnose(_record(rec))
        assert found.verdict == "none", [(s.effect, s.error_pct) for s in found.suspects[:3]]
        assert set(found.expected_physics) <= {"property"}
        assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.02)
        assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize(("rate_hz", "noise_c"), [(5000.0, 0.05), (2000.0, 0.1)])
def test_clean_engine_pulses_give_none_with_the_ordinary_physics_named(rate_hz, noise_c):
    # 100-700 degC pulses: Collis & Williams' loading makes heating slower than cooling, which
    # rectifies the pulses and leaves the sensors' means a few hundredths of a degree apart.
    # A calibration or radiation that small fitted best; conduction or property, which explain
    # the residual less well, were called (5 kHz: property, 2 kHz: conduction). The base
    # model's level difference (level_c) now takes those hundredths: it is at the floor.
    rec = simulate_rig(
        _rig(signal="engine_pulses", rate_hz=rate_hz, noise_c=(noise_c, noise_c), seed=7)
    )
    found = diagnose(_record(rec))
    assert found.verdict == "none", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert set(found.expected_physics) <= {"calibration", "radiation", "property"}
    assert found.final.error_pct <= found.base.error_pct < 0.3
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.02)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.02)


@pytest.mark.slow
def test_a_noisy_clean_record_is_judged_against_the_first_order_that_simulates_it_best():
    # Campaign draw 2873 (clean engine pulses, 2 kHz, K = 3.3 %, a class-2 pair): the
    # cross-relation's noise bias put the base model's tau 10-12 % short, its held-out error
    # at 2.2 % against 0.09 % at ml-eiv's tau, and a speed varying over the record took the
    # verdict. The default path's tau simulate the slow sensor better: they are the base.
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    import campaign_draws

    item = campaign_draws.draw(2873)
    assert not item.effects and item.noise_percent > 3.0
    record, truth = campaign_draws.simulate(item)
    found = diagnose(record)
    assert found.verdict == "none", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert found.base.error_pct < 0.2
    assert found.base.tau1 == pytest.approx(truth["tau1"], rel=0.02)
    assert found.base.tau2 == pytest.approx(truth["tau2"], rel=0.02)


@pytest.mark.slow
def test_a_line_the_default_path_notches_is_said_when_the_base_takes_its_tau():
    # Campaign draw 3276: 60 Hz mains on tc2 of 5 kHz steps. The cross-relation base put τ1 on
    # its 6 s bound; ml-eiv, its lines notched, is within 1 % and leaves the line no error to
    # explain, so interference is no verdict: the diagnosis still names the line.
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    import campaign_draws

    from tcomp_core.diagnose.pipeline import _base_fit, _notes

    item = campaign_draws.draw(3276)
    assert item.effects == ("interference",)
    record, truth = campaign_draws.simulate(item)
    evaluator, _, base, _ = _base_fit(record)
    assert evaluator.base_taus_published
    assert base.tau1 == pytest.approx(truth["tau1"], rel=0.02)
    lines = [note for note in _notes(evaluator.data, evaluator) if "Hz line" in note]
    assert any(note.startswith("tc2 carries a 60") for note in lines), lines


@pytest.mark.slow
def test_a_delay_on_engine_pulses_is_not_taken_for_its_alias_one_period_away():
    # 9 ms between the junctions on 40 Hz pulses (25 ms period): the delay less one period
    # fits the cross-relation about as well with tau 50 % long; a coarse scan of trial delays
    # (5 ms apart) missed the true one and the diagnosis read conduction.
    delay = 0.009
    rig = _rig(
        signal="engine_pulses",
        rate_hz=5000.0,
        noise_c=(0.1, 0.1),
        seed=5,
        spacing_m=delay * Rig.speed_m_s,
    )
    rec = simulate_rig(rig)
    found = diagnose(_record(rec))
    assert found.verdict == "delay", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert found.final.params["delay_s"] == pytest.approx(delay, abs=5e-4)
    # The alias would put τ 50 % long. (The final τ are the estimation blocks' fit when its
    # whole-record refit simulates worse: 2.2 % here against the refit's 2.0 %.)
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.03)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.03)


@pytest.mark.slow
def test_a_delay_the_first_order_start_hides_is_applied():
    """2 ms between the junctions of a 56/100 µm pair on engine pulses at 1 kHz (two samples):
    the closed-form first-order start absorbs the delay by bending τ2 − τ1, and the two
    readings agree there (about 3 °C rms) because the delay is hidden. Taken as the evidence,
    that made the delay's change of 17 °C a correction six times its evidence, refused; at the
    default path's τ and the fit's own the readings disagree by 22 and 35 °C, and the delay,
    pinned at 2.05 ms, makes the gas nearer the truth than the default path's."""
    from tcomp_core.compensation import (
        compensate,
        default_estimate,
        default_first_order_failure,
        output_model_from_diagnosis,
    )
    from tcomp_core.effects.chain import fractional_shift
    from tcomp_core.fusion import fuse
    from tcomp_core.lines import line_free_pair
    from tcomp_core.metrics import reconstruction_error_percent

    delay, speed = 0.002, 5.0
    rig = Rig(
        signal="engine_pulses",
        duration_s=4.0,
        rate_hz=1000.0,
        seed=21,
        wires=(Wire(56e-6), Wire(100e-6)),
        speed_m_s=speed,
        spacing_m=delay * speed,
        noise_c=(0.5, 0.5),
    )
    sim = simulate_rig(rig)
    record = _record(sim)
    plain = default_estimate(record)
    taus = (float(plain.tau1), float(plain.tau2))
    fitted = fit_effects(record, ["delay"], published_taus=taus, published_lines=plain.lines)
    found = fitted.final.identification
    assert fitted.final.params["delay_s"] == pytest.approx(delay, abs=2e-4)
    assert found is not None and not found.extrapolates, (found.change_c, found.evidence_c)
    model = output_model_from_diagnosis(
        fitted,
        first_order_taus=taus,
        first_order_lines=plain.lines,
        first_order_failure=default_first_order_failure(record, plain),
    )
    assert model.applied() == ("delay",), model.describe()
    default = fuse(*line_free_pair(sim.tc1, sim.tc2, sim.dt, plain.lines, taus), sim.dt, *taus)
    gas = compensate(model, sim.time, sim.tc1, sim.tc2, sim.dt).gas
    # Against the truth read half a sample on (element k stands for [t_k, t_k+1)), both
    # low-passed at 30 Hz as the issue scores them, the edges left out.
    shifted = fractional_shift(sim.gas, 0.5)[0]
    truth = np.where(np.isfinite(shifted), shifted, sim.gas)
    sos = signal.butter(4, 30.0, output="sos", fs=rig.rate_hz)
    edge = slice(200, -200)
    errors = [
        reconstruction_error_percent(
            signal.sosfiltfilt(sos, truth)[edge], signal.sosfiltfilt(sos, g)[edge]
        )
        for g in (default.gas, gas)
    ]
    assert errors[1] < 0.5 * errors[0], errors


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "offset_c"), [(3, -2.0), (11, 1.5)])
def test_a_delay_behind_a_class_2_offset_is_not_imitated_by_conduction(seed, offset_c):
    # Four samples between the junctions at 5 kHz and a sensor offset every real pair may
    # have: a conduction fit absorbs the two together better than the delay alone, so the
    # greedy staircase took it (tau a third of the truth) and refused the delay after it.
    rate, speed = 5000.0, 5.0
    rig = Rig(
        signal="engine_pulses",
        duration_s=4.0,
        rate_hz=rate,
        seed=seed,
        wires=(Wire(40e-6), Wire(90e-6)),
        speed_m_s=speed,
        spacing_m=4.0 / rate * speed,
        calibration=(1, 1.0, offset_c),
    )
    rec = simulate_rig(rig)
    sigma = 0.02 * float(np.std(rec.tc1))
    rng = np.random.default_rng(seed)
    record = Record(
        time=rec.time,
        tc1=rec.tc1 + sigma * rng.standard_normal(rec.time.size),
        tc2=rec.tc2 + sigma * rng.standard_normal(rec.time.size),
        ref=rec.gas,
        source="delay+offset",
        dt=rec.dt,
    )
    found = diagnose(record)
    assert "delay" in found.final.effects, found.notes
    assert "conduction" not in found.final.effects, found.notes
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.03)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.03)


@pytest.mark.slow
def test_a_phase_no_first_order_pair_has_makes_the_delay_significant():
    """Exhaust pulses at 0.5 kHz, tc2 read 3.6 samples (7 ms) late: at the 40 Hz firing the
    readings' ratio has a phase of about -100°, which no two first-order lags give. The
    delay's refit lowered the held-out error but failed the block rules, and conduction took
    the verdict with τ 3.8 times too long; the measured phase makes the delay significant."""
    rate, speed = 500.0, 7.0
    rig = Rig(
        signal="engine_pulses",
        duration_s=4.0,
        rate_hz=rate,
        seed=34,
        wires=(Wire(50e-6), Wire(150e-6)),
        speed_m_s=speed,
        spacing_m=3.6 / rate * speed,
        noise_c=(0.4, 0.4),
        calibration=(1, 1.004, 1.2),  # within IEC 60584 class 2
    )
    rec = simulate_rig(rig)
    record = Record(
        time=rec.time, tc1=rec.tc1, tc2=rec.tc2, ref=rec.gas, source="late tc2", dt=rec.dt
    )
    found = diagnose(record)
    assert found.verdict == "delay", [
        (s.effect, s.error_pct, s.significant) for s in found.suspects
    ]
    assert found.final.params["delay_s"] == pytest.approx(rec.truth["delay_s"], rel=0.1)
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.6)


@pytest.mark.slow
def test_a_strong_property_effect_is_found_with_its_exponent():
    # Part of the property effect's signature is a level difference between the sensors
    # (heating and cooling at different τ rectify the signal), which the base model's level
    # difference (level_c) now takes: the exponent comes out -0.45 for -0.8, which reads as
    # the wires' ordinary physics. It is still the one significant suspect, with τ right.
    sim = simulate_effect("property", "multisine", noise_percent=1.0, seed=1)
    found = diagnose(_record(sim))
    top = found.suspects[0]
    assert top.effect == "property" and top.significant, [
        (s.effect, s.error_pct) for s in found.suspects[:3]
    ]
    assert found.verdict in ("property", "none")
    assert found.final.effects == ("property",)
    exponent = found.final.params["property_exponent"]
    assert sim.params["property_exponent"] - 0.1 <= exponent < -0.3
    assert found.final.tau1 == pytest.approx(sim.tau1, rel=0.02)
    assert found.final.tau2 == pytest.approx(sim.tau2, rel=0.02)
    assert found.base.error_pct >= 2.0 * found.final.error_pct


@pytest.mark.parametrize(
    ("level_c", "gain", "offset_c", "material"),
    [
        (500.0, 0.9999, -0.046, False),  # below the fit's resolution
        (50.0, 1.0075, -2.5, False),  # the edge of IEC 60584 class 2: the sensors users own
        (700.0, 0.9925, 2.5, False),  # class 2 at an exhaust level: 0.75 % of 700 degC added
        (50.0, 1.0, -6.5, True),  # beyond class 2 in offset, with the fit's resolution
        (50.0, 1.02, 0.0, True),  # beyond class 2 in gain
        (50.0, 1.012, 0.0, False),  # beyond class 2 in gain, but within the fit's resolution
        (700.0, 1.0, 18.0, True),  # beyond 2.5 degC + 0.75 % of the level, with the margin
    ],
)
def test_a_calibration_within_class_2_is_not_material(level_c, gain, offset_c, material):
    from tcomp_core.effects.base import Evidence
    from tcomp_core.effects.calibration import Calibration

    evidence = Evidence(
        level_mean_c=level_c,
        record_dt=1e-3,
        dt=1e-3,
        readings=(np.zeros(4), np.zeros(4)),
        base_taus=(0.05, 0.2),
    )
    params = {"tau1": 0.05, "tau2": 0.2, "gain": gain, "offset_c": offset_c}
    assert Calibration().material(params, evidence) is material


def test_quantisation_is_recognised_from_the_steps():
    rng = np.random.default_rng(5)
    slow = 50.0 + 10.0 * np.sin(np.arange(20000) * 2e-4)  # moves << one code per sample
    step = 1642.0 / 4096  # 12-bit over the type-K range
    coded = np.round((slow + 0.05 * rng.standard_normal(slow.size)) / step) * step
    found = detect_quantisation(coded)
    assert found is not None and found.step_c == pytest.approx(step, rel=1e-9)
    assert found.in_band and in_band_variance(found) == pytest.approx(step**2 / 12.0)
    fast = np.round((50.0 + 30.0 * rng.standard_normal(20000)) / step) * step
    assert not detect_quantisation(fast).in_band  # many codes per sample: white, not counted
    assert detect_quantisation(slow + 1e-3 * rng.standard_normal(slow.size)) is None


@pytest.mark.slow
def test_a_coarse_adc_is_counted_in_the_noise_floor_not_called_an_effect():
    rec = simulate_rig(_rig(seed=0, rate_hz=5000.0, adc_bits=12))
    found = diagnose(_record(rec, "12-bit"))
    assert found.verdict == "none", [(s.effect, s.error_pct) for s in found.suspects[:3]]
    assert any("quantised in steps of 0.4" in note for note in found.notes)


def test_a_support_transient_beyond_what_the_legs_let_through_is_no_conduction():
    """Campaign draw 662 (tc2 three times noisier, no conduction) was read as conduction with
    legs so long that wire 1's supports pass sech(9.8) = 1e-4 of their excess, and a start-up
    transient of 103 degC on its reading: supports a million degrees off. Compensated with it,
    the gas went 1.3 -> 9.3 % off."""
    from tcomp_core.effects import Model
    from tcomp_core.effects.conduction import MAX_SUPPORT_EXCESS_C, fin_sech

    base = (0.0585, 0.27)
    fitted = {"tau1": 0.0585, "tau2": 0.27, "tau_leg": 5.67, "tau_p": 0.393}
    reason = Model(("conduction",), {**fitted, "mode1": 103.0, "mode2": 0.0}).implausible(base)
    assert "wire 1's reading starts 103 degC off" in reason and "at most 2273 degC" in reason
    # Wire 2's legs pass sech(4.6) = 2 %: 288 degC on its reading is 14 000 degC at the supports.
    reason = Model(("conduction",), {**fitted, "mode1": 0.0, "mode2": 288.0}).implausible(base)
    assert "wire 2's reading" in reason
    # What the legs can pass from supports within any thermocouple's range is plausible, and
    # so is any start on short legs (a window cut from a running record).
    limit = fin_sech(math.sqrt(5.67 / 0.27)) * MAX_SUPPORT_EXCESS_C
    within = {**fitted, "mode1": 0.0, "mode2": 0.9 * limit}
    assert Model(("conduction",), within).implausible(base) == ""
    short = {"tau1": 0.0303, "tau2": 0.1606, "tau_leg": 0.271, "tau_p": 2.46}
    assert (
        Model(("conduction",), {**short, "mode1": 120.0, "mode2": -80.0}).implausible(
            (7.2 * 0.0303, 4.7 * 0.1606)
        )
        == ""
    )


def test_each_effect_bounds_how_far_tau_moves_and_conduction_its_conductance_ratio():
    from tcomp_core.effects import Model
    from tcomp_core.effects.conduction import MAX_KAPPA, fin_kappa

    base = (0.0165, 0.08)
    # The worst case: conduction with tau1 27x the first-order estimate.
    far = Model(("conduction",), {"tau1": 0.45, "tau2": 1.2, "tau_leg": 0.5, "tau_p": 2.0})
    assert "tau1 = 0.45 s is 27.3x" in far.implausible(base)
    # Lagging supports make the first-order tau many times the wire's own: a conduction fit
    # may bring tau down from it without limit (a fit at a seventh of it was refused before).
    slowed = (7.2 * 0.0303, 4.7 * 0.1606)
    near = {"tau1": 0.0303, "tau2": 0.1606, "tau_leg": 0.271, "tau_p": 2.46}
    assert Model(("conduction",), near).implausible(slowed) == ""
    assert "at most 13.3x" in Model(("conduction",), near).implausible((0.0303 / 14, 0.1606))
    assert "at least 1/5" in Model(
        ("property",), {"tau1": 0.0303, "tau2": 0.1606, "property_exponent": 0.5}
    ).implausible(slowed)
    # Short legs at the fit's own tau: the supports' conductance dominates the junction's.
    legs = {"tau1": 0.0165, "tau2": 0.08, "tau_leg": 0.02 * 0.08, "tau_p": 1.0}
    assert fin_kappa(math.sqrt(0.02)) > MAX_KAPPA
    assert "conductance to its supports" in Model(("conduction",), legs).implausible(base)
    fine = {**legs, "tau_leg": 1.7**2 * 0.08}
    assert Model(("conduction",), fine).implausible(base) == ""
    # A delay may bring back a tau1 the first-order fit collapsed to a tenth; with a delay in
    # the model the loosest factor of its effects applies.
    collapsed = (0.0017, 0.08)
    delay = {"tau1": 0.0165, "tau2": 0.08, "delay_s": 5e-4}
    assert Model(("delay",), delay).implausible(collapsed) == ""
    assert Model(("delay",), delay).implausible((0.0165 / 25, 0.08)) == ""  # 9 ms, pulses
    prop = {"tau1": 0.0165, "tau2": 0.08, "property_exponent": 0.5}
    assert "at most 5x with property" in Model(("property",), prop).implausible(collapsed)
    both = Model(("property", "delay"), {**prop, "delay_s": 5e-4})
    assert both.implausible(collapsed) == ""
    assert Model(("delay",), delay).implausible(None) == ""
    # A gain between the sensors (calibration, radiation) or a line on one of them
    # (interference) bends the first-order tau without limit.
    for effect, params in [
        ("calibration", {"gain": 1.0, "offset_c": 0.0}),
        ("radiation", {"rho1": 0.1, "rho2": 0.15, "wall_c": 300.0}),
    ]:
        assert Model((effect,), {**prop, **params}).implausible((0.25, 1.1)) == ""
    # A first-order tau below a sample gives no scale (the fit found no lag to measure).
    assert Model(("property",), prop).implausible(collapsed, collapsed_below_s=0.002) == ""


def test_an_implausible_fit_is_never_compensated():
    from tcomp_core.compensation import output_model_from_diagnosis

    sim = simulate_effect("delay", "multisine", duration=4.0, noise_percent=1.0, seed=44)
    fitted = fit_effects(_record(sim), ("delay",))
    model = output_model_from_diagnosis(fitted)
    assert model.applied() == ("delay",)
    # Legs so short at the fit's tau that the supports carry 50x the junction's convection.
    params = {"tau1": fitted.final.tau1, "tau2": fitted.final.tau2, "tau_p": 1.0}
    params["tau_leg"] = fitted.final.tau2 * 0.2**2
    far = dataclasses.replace(fitted.final, effects=("conduction",), params=params)
    refused = output_model_from_diagnosis(dataclasses.replace(fitted, final=far))
    assert refused.applied() == () and refused.name() == "first-order"
    assert all("no physical sensor" in piece.reason for piece in refused.pieces)


@pytest.mark.slow
@pytest.mark.parametrize("noise_c", [(1.0, 3.0), (3.0, 1.0)])
def test_unequal_noise_is_named_and_every_effect_is_judged_against_the_fitted_first_order_tau(
    noise_c,
):
    """Steps and ramps at 10 kHz, one sensor three times noisier than the other. β-GTLS with
    φ = 1, the diagnosis's closed-form start, puts τ far off (or fails and falls back to its
    grid), and every effect's plausibility bounds were taken from that start: on a campaign
    draw the start's τ1 was 17 times the truth, so the noise ratio's refit, with τ right, was
    called implausible and the verdict was none. The bounds come from the base model's fit."""
    rig = _rig(signal="step_ramp", rate_hz=10_000.0, duration_s=6.0, seed=21, noise_c=noise_c)
    rec = simulate_rig(rig)
    found = diagnose(_record(rec, "unequal noise"))
    assert not any("of the first-order" in s.signature for s in found.suspects), [
        s.signature for s in found.suspects
    ]
    assert found.verdict == "noise_ratio", [
        (s.effect, s.error_pct, s.significant) for s in found.suspects
    ]
    assert found.final.tau1 == pytest.approx(rec.truth["tau1"], rel=0.05)
    assert found.final.tau2 == pytest.approx(rec.truth["tau2"], rel=0.05)


def test_no_verdict_rests_on_a_tau_of_more_than_half_the_record():
    # Conduction to cold supports put a base fit's τ at the end of the fits' search (one record)
    # and a calibration with τ as long was named: whatever the first-order τ, a τ the record
    # cannot tell from a gain is implausible; one well inside the record is not.
    from tcomp_core.diagnose.pipeline import _base_fit
    from tcomp_core.diagnose.ranking import MAX_TAU_PER_RECORD, implausibility

    sim = simulate_effect(None, "multisine", tau1=0.03, tau2=0.2, dt=0.002, duration=4.0, seed=3)
    record = Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=None, source="x", dt=sim.dt)
    evaluator, _, base, _ = _base_fit(record)
    long_tau = 1.01 * MAX_TAU_PER_RECORD * evaluator.context.duration_s
    context = dataclasses.replace(evaluator.context, base_taus_s=(0.5 * long_tau, long_tau))
    evaluator = dataclasses.replace(evaluator, context=context)
    assert implausibility(base, evaluator) == ""
    slow = dataclasses.replace(base, tau2=long_tau, params={**base.params, "tau2": long_tau})
    assert "record" in implausibility(slow, evaluator)


@pytest.mark.slow
def test_no_verdict_swaps_which_sensor_is_the_slower_against_the_published_taus():
    """A fit whose τ make the other sensor the slower than the default path's τ do is no
    physical sensor in the diagnosis too, not only in the output: the delay that the record
    holds is the verdict judged against τ of its own order and refused against them swapped
    (the campaign's spurious delays with τ1 and τ2 swapped became verdicts)."""
    from tcomp_core.effects import Model

    sim = simulate_effect(
        "delay", "multisine", duration=4.0, noise_percent=1.0, seed=3, params={"delay_s": 0.004}
    )
    record = Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=sim.gas, source="x", dt=sim.dt)
    own = diagnose(record, candidates=("delay",), max_effects=1)
    assert own.verdict == "delay", own.suspects
    taus = (float(own.final.tau1), float(own.final.tau2))
    model = Model(own.final.effects, own.final.params)
    assert model.implausible(taus, 0.0, taus) == ""
    # A delay may not lower τ by half either; an effect that may move τ anywhere (a
    # calibration) is held by the sensors' order alone.
    assert "1/4.9 of the default path's" in model.implausible(taus, 0.0, taus[::-1])
    calibrated = Model(("calibration",), {"tau1": taus[0], "tau2": taus[1], "gain": 1.0})
    assert calibrated.implausible(taus, 0.0, taus) == ""
    assert "which wire is the slower" in calibrated.implausible(taus, 0.0, taus[::-1])
    swapped = diagnose(record, candidates=("delay",), max_effects=1, published_taus=taus[::-1])
    assert swapped.verdict != "delay"
    assert "implausible: " in swapped.suspects[0].signature
    assert not swapped.suspects[0].significant


def test_wires_whose_radiation_needs_emissivities_far_apart_are_no_physical_sensor():
    """ρ_slow/ρ_fast = (ε_s/ε_f) (τ_s/τ_f)^(1/3): campaign draw 2842 (a calibration beyond class
    2 on a cool step record, no radiation) was fitted with the thicker wire radiating 0.23 of
    what one emissivity gives, and its dynamics made the gas worse; the radiation draws' fits
    came within 0.94-1.62 of it."""
    from tcomp_core.effects import Model
    from tcomp_core.effects.radiation import EMISSIVITY_RATIO_MAX

    taus = {"tau1": 0.0647, "tau2": 0.3217}
    one = (taus["tau2"] / taus["tau1"]) ** (1.0 / 3.0)
    spurious = {**taus, "rho1": 0.0161, "rho2": 0.0062, "wall_c": 38.9}
    reason = Model(("radiation",), spurious).implausible(None)
    assert "emissivities would differ" in reason and "0.226 times" in reason, reason
    for rel in (1.0, 0.6, 1.62, 1.9):
        fit = {**taus, "rho1": 0.07, "rho2": 0.07 * one * rel, "wall_c": 300.0}
        assert Model(("radiation",), fit).implausible(None) == ""
    beyond = {
        **taus,
        "rho1": 0.07,
        "rho2": 0.07 * one * 1.05 * EMISSIVITY_RATIO_MAX,
        "wall_c": 0.0,
    }
    assert "emissivities would differ" in Model(("radiation",), beyond).implausible(None)
    faint = {**taus, "rho1": 0.008, "rho2": 0.001, "wall_c": 0.0}  # no material radiation
    assert Model(("radiation",), faint).implausible(None) == ""
    swapped = {"tau1": taus["tau2"], "tau2": taus["tau1"], "rho1": 0.0062, "rho2": 0.0161}
    assert "rho1/rho2" in Model(("radiation",), {**swapped, "wall_c": 38.9}).implausible(None)
