"""The online compensator publishing an extended model's gas: chunking, switching, gaps."""

from __future__ import annotations

import numpy as np
import pytest
from output_models import STREAM_MODELS, model_with

from tcomp_core.compensation import equivalent_readings
from tcomp_core.compensation.stream import EquivalentStream
from tcomp_core.online import OnlineCompensator, OnlineConfig
from tcomp_core.reconstruct import reconstruct
from tcomp_core.simulate_effects import simulate_effect

ORIGIN_NS = 1_700_000_000 * 10**9


def _record(effect: str | None = "delay"):
    sim = simulate_effect(effect, "multisine", duration=6.0, noise_percent=1.0, seed=11)
    stamps = ORIGIN_NS + np.round(sim.time * 1e9).astype(np.int64)
    return sim, stamps


def _run(compensator: OnlineCompensator, stamps, tc1, tc2, sizes):
    """Feed pairs in batches of the given sizes (cycled); the concatenated output."""
    outs, start, i = [], 0, 0
    while start < stamps.size:
        stop = min(stamps.size, start + sizes[i % len(sizes)])
        outs.append(compensator.add_pairs(stamps[start:stop], tc1[start:stop], tc2[start:stop]))
        start, i = stop, i + 1
    return (np.concatenate([getattr(o, name) for o in outs]) for name in ("stamps_ns", "gas"))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["delay", "conduction", "calibration+delay"])
def test_the_published_extended_gas_does_not_depend_on_the_batches(name):
    sim, stamps = _record()
    effects, params = STREAM_MODELS[name]
    model = model_with(effects, params, n=sim.tc1.size)
    runs = []
    for sizes in ([1], [7, 50, 3], [500]):
        compensator = OnlineCompensator(
            OnlineConfig(reconstruction="difference"), initial_tau=(0.0238, 0.1168)
        )
        compensator.use_output_model(model, ORIGIN_NS, (stamps, sim.tc1, sim.tc2))
        runs.append(tuple(_run(compensator, stamps, sim.tc1, sim.tc2, sizes)))
        assert compensator.output is not None and compensator.output.since_ns == stamps[0]
    for out_stamps, gas in runs[1:]:
        np.testing.assert_array_equal(out_stamps, runs[0][0])
        np.testing.assert_allclose(gas, runs[0][1], rtol=0, atol=1e-9)
    out_stamps, gas = runs[0]
    latency = compensator.output.latency
    assert out_stamps.size == stamps.size - 1 - latency
    # Eq. (7) on the equivalent readings, as the offline path computes them.
    tc1, tc2 = equivalent_readings(model, sim.time, sim.tc1, sim.tc2, sim.dt)
    offline = reconstruct(tc1, tc2, sim.dt, model.tau1, model.tau2, phi=1.0).gas
    inner = slice(100, out_stamps.size)
    np.testing.assert_allclose(
        gas[inner] - compensator.output.level_shift_c,
        offline[: out_stamps.size][inner],
        atol=1e-6,
    )


@pytest.mark.slow
def test_switching_models_mid_stream_skips_and_repeats_no_stamp():
    sim, stamps = _record()
    compensator = OnlineCompensator(
        OnlineConfig(reconstruction="kalman"), initial_tau=(0.0238, 0.1168)
    )
    delay = model_with(*STREAM_MODELS["delay"], n=sim.tc1.size)
    third = stamps.size // 3
    parts = []
    parts.append(compensator.add_pairs(stamps[:third], sim.tc1[:third], sim.tc2[:third]))
    # Built (inline here) and primed on the newest pairs, it takes over with the next pairs.
    compensator.use_output_model(delay, ORIGIN_NS, (stamps, sim.tc1, sim.tc2))
    assert compensator.output_model is delay and compensator.output is None
    middle = slice(third, 2 * third)
    parts.append(compensator.add_pairs(stamps[middle], sim.tc1[middle], sim.tc2[middle]))
    assert compensator.output is not None and compensator.output.model is delay
    assert compensator.published_tau == (delay.tau1, delay.tau2)
    compensator.use_output_model(None)
    assert compensator.output_model is None
    rest = slice(2 * third, None)
    parts.append(compensator.add_pairs(stamps[rest], sim.tc1[rest], sim.tc2[rest]))
    published = np.concatenate([part.stamps_ns for part in parts])
    assert np.all(np.diff(published) > 0)
    # First order up to the switch, the delay model (6.55 + 16 taps: 22 samples behind) until
    # the switch back, whose 22 pending pairs are not published: every other stamp but the
    # last is.
    latency = EquivalentStream(delay, sim.dt, ORIGIN_NS).latency
    assert latency == 22
    assert published.size == stamps.size - 1 - latency
    assert np.all(np.isfinite(np.concatenate([part.gas for part in parts])))


def test_a_gap_restarts_the_extended_stream_and_counts_what_it_drops():
    sim, stamps = _record()
    stamps = stamps.copy()
    stamps[1500:] += 10**9  # one second missing
    compensator = OnlineCompensator(
        OnlineConfig(reconstruction="difference"), initial_tau=(0.0238, 0.1168)
    )
    compensator.use_output_model(
        model_with(*STREAM_MODELS["delay"], n=sim.tc1.size), ORIGIN_NS, (stamps, sim.tc1, sim.tc2)
    )
    out_stamps, gas = _run(compensator, stamps, sim.tc1, sim.tc2, [64])
    assert np.all(np.diff(out_stamps) > 0)
    assert np.all(np.isfinite(gas))
    # Each stretch loses its last pair (no successor) and the 22 the delay had not emitted;
    # the last stretch's are still pending.
    assert out_stamps.size == stamps.size - 2 * (1 + 22)
    assert compensator.counters["unreconstructed"] == 1 + 22
    assert compensator.output.lost == 22


def test_a_refit_of_the_same_physics_keeps_since_and_another_model_restarts_it():
    sim, stamps = _record()
    compensator = OnlineCompensator(
        OnlineConfig(reconstruction="difference"), initial_tau=(0.0238, 0.1168)
    )
    record = (stamps, sim.tc1, sim.tc2)
    delay = model_with(*STREAM_MODELS["delay"], n=sim.tc1.size)
    compensator.use_output_model(delay, ORIGIN_NS, record)
    compensator.add_pairs(stamps[:1000], sim.tc1[:1000], sim.tc2[:1000])
    since = compensator.output.since_ns
    assert since == stamps[0]
    compensator.use_output_model(delay, ORIGIN_NS, record)  # refitted: same effects
    compensator.add_pairs(stamps[1000:2000], sim.tc1[1000:2000], sim.tc2[1000:2000])
    assert compensator.output.since_ns == since
    other = model_with(*STREAM_MODELS["conduction"], n=sim.tc1.size)
    compensator.use_output_model(other, ORIGIN_NS, record)
    compensator.add_pairs(stamps[2000:], sim.tc1[2000:], sim.tc2[2000:])
    assert compensator.output.since_ns > stamps[1000]


@pytest.mark.slow
def test_a_discontinuity_or_a_new_reconstruction_keeps_the_output_model():
    from dataclasses import replace

    sim, stamps = _record()
    compensator = OnlineCompensator(
        OnlineConfig(reconstruction="difference"), initial_tau=(0.0238, 0.1168)
    )
    model = model_with(*STREAM_MODELS["conduction"], n=sim.tc1.size)
    compensator.use_output_model(model, ORIGIN_NS, (stamps, sim.tc1, sim.tc2))
    first = compensator.add_pairs(stamps[:1000], sim.tc1[:1000], sim.tc2[:1000])
    compensator.restart()  # the stamps start over (a bag played again)
    again = compensator.add_pairs(stamps[:1000], sim.tc1[:1000], sim.tc2[:1000])
    np.testing.assert_array_equal(again.stamps_ns, first.stamps_ns)
    np.testing.assert_allclose(again.gas, first.gas)
    compensator.reconfigure(replace(compensator.config, reconstruction="kalman"))
    assert compensator.output_model is model
    later = compensator.add_pairs(stamps[1000:], sim.tc1[1000:], sim.tc2[1000:])
    assert later.stamps_ns[0] == stamps[999] and np.all(later.variance > 0)  # Kalman now


# -- the engine's rules for output models (tcomp_core.online.diagnosis) --------------------------
@pytest.mark.slow
def test_an_output_model_is_taken_only_when_it_passes_and_dropped_when_stale():
    from tcomp_core.online import Engine
    from tcomp_core.online.diagnosis import OUTPUT_STALE_PERIODS

    sim, stamps = _record()
    engine = Engine(OnlineConfig(compensate_effects=True, diagnosis_period_s=1.0))
    engine.add_samples(0, stamps[:2000], sim.tc1[:2000], 0.0)
    engine.add_samples(1, stamps[:2000], sim.tc2[:2000], 0.0)
    engine.reconstruct()
    compensator, policy = engine.compensator, engine.diagnosis
    record = (stamps[:2000], sim.tc1[:2000], sim.tc2[:2000])
    delay = STREAM_MODELS["delay"]
    good = model_with(*delay, n=2000, error_pct=1.0, base_error_pct=10.0)
    cases = [
        (model_with(*delay, n=2000, error_pct=9.0, base_error_pct=10.0), "less than 20 %"),
        (
            model_with(*delay, n=2000, error_pct=1.0, base_error_pct=10.0, at_bound=("delay_s",)),
            "bound (delay_s)",
        ),
        (model_with((), {}, n=2000, error_pct=1.0, base_error_pct=10.0), "no effect"),
    ]
    for refused, why in cases:
        assert policy.take(compensator, good, int(stamps[0]), record, 5.0)
        assert compensator.output_model is good
        assert not policy.take(compensator, refused, int(stamps[0]), record, 5.0)
        assert compensator.output_model is None and why in compensator.output_note
    assert policy.take(compensator, good, int(stamps[0]), record, 5.0)
    engine.periodic_diagnosis(5.0 + OUTPUT_STALE_PERIODS * 1.0 - 0.1)
    assert compensator.output_model is good  # fresh still
    engine.periodic_diagnosis(5.0 + OUTPUT_STALE_PERIODS * 1.0 + 0.1)
    assert compensator.output_model is None
    assert compensator.output_note.startswith("stale")
    values = engine.report(9.0).values
    assert values["output_model"] == "first-order" and values["output_model_note"].startswith(
        "stale"
    )


class _SlowDiagnosis:
    """A diagnosis runner whose job lands, with a given result, when :meth:`finish` is called."""

    def __init__(self, result: dict) -> None:
        self.result, self.running, self.outcome = result, False, None

    @property
    def busy(self) -> bool:
        return self.running

    def submit(self, function, *args) -> bool:
        if self.running:
            return False
        self.running = True
        return True

    def finish(self) -> None:
        from tcomp_core.workers import Outcome

        self.running, self.outcome = False, Outcome(dict(self.result))

    def poll(self):
        outcome, self.outcome = self.outcome, None
        return outcome

    def close(self) -> None:
        pass


@pytest.mark.slow
def test_a_fit_that_took_long_to_land_is_stale_only_that_much_later():
    from tcomp_core.online import Engine
    from tcomp_core.online.diagnosis import OUTPUT_STALE_PERIODS

    sim, stamps = _record()
    good = model_with(*STREAM_MODELS["delay"], n=2000, error_pct=1.0, base_error_pct=10.0)
    result = {
        "effects": ["delay"],
        "base_error_pct": 10.0,
        "error_pct": 1.0,
        "tau1": 0.0238,
        "tau2": 0.1168,
        "at_bound": [],
        "top_suspect": "delay",
        "top_suspect_error_pct": 1.0,
        "samples": 2000,
        "seconds": 6.0,
        "output_model": good,
    }
    runner = _SlowDiagnosis(result)
    engine = Engine(
        OnlineConfig(compensate_effects=True, diagnosis_period_s=1.0), diagnosis_runner=runner
    )
    engine.add_samples(0, stamps[:2000], sim.tc1[:2000], 0.0)
    engine.add_samples(1, stamps[:2000], sim.tc2[:2000], 0.0)
    engine.reconstruct()
    compensator, policy = engine.compensator, engine.diagnosis
    assert policy.start(5.0, compensator)  # the data are taken at 5 s ...
    runner.finish()
    policy.poll(11.0, compensator)  # ... and the fit lands 6 s later
    assert compensator.output_model is good
    limit = 5.0 + OUTPUT_STALE_PERIODS * 1.0 + 6.0
    engine.periodic_diagnosis(limit - 0.1)
    assert compensator.output_model is good  # a period-sized age would have dropped it at 8 s
    engine.periodic_diagnosis(limit + 0.1)
    assert compensator.output_model is None and compensator.output_note.startswith("stale")


def test_recent_pairs_give_the_newest_and_those_since_a_stamp_from_their_newest_batches():
    from tcomp_core.online.extended import RecentPairs

    recent = RecentPairs(100)
    stamps = np.arange(250, dtype=np.int64) * 10
    for start in range(0, 250, 7):  # batches of 7, the oldest dropped beyond 100
        part = slice(start, start + 7)
        recent.add(stamps[part], stamps[part] * 0.5)
    kept = recent.columns()[0]
    assert kept.size == 100 and kept[-1] == stamps[-1]
    np.testing.assert_array_equal(recent.tail(13)[0], stamps[-13:])
    np.testing.assert_array_equal(recent.tail(1000)[0], kept)
    np.testing.assert_array_equal(recent.since(2005)[0], stamps[stamps >= 2005])
    np.testing.assert_array_equal(recent.since(2000)[1], stamps[stamps >= 2000] * 0.5)
    np.testing.assert_array_equal(recent.since(0)[0], kept)
