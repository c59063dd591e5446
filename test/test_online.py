"""The online engine: first output, backlog, gaps, reconstructors, health rules, schedule."""

from __future__ import annotations

import numpy as np
import pytest

from tcomp_core.metrics import reconstruction_error_percent
from tcomp_core.online import (
    FIRST_ESTIMATE_ROWS,
    Engine,
    Level,
    OnlineCompensator,
    OnlineConfig,
    ScheduledEngine,
)
from tcomp_core.online.health import LIVE_ONLY_KEYS, NO_DIAGNOSIS, NO_LATENCY
from tcomp_core.reconstruct import reconstruct
from tcomp_core.tracking import varying_lag_response


def _feed(engine, pair, batch=50):
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    out_stamps, out_gas = [], []
    for start in range(0, stamps.size, batch):
        part = slice(start, start + batch)
        s, g, _ = engine.add_pairs(stamps[part], pair.tc1[part], pair.tc2[part])
        out_stamps.append(s)
        out_gas.append(g)
    return stamps, np.concatenate(out_stamps), np.concatenate(out_gas)


def test_every_pair_is_reconstructed_once_the_first_estimate_lands(pair_factory):
    pair = pair_factory("multisine", noise_percent=1.0, seed=2, duration=2.0)
    engine = OnlineCompensator(OnlineConfig(window_s=1.0, reconstruction="difference"))
    stamps, out_stamps, gas = _feed(engine, pair)
    # One output per pair but the last (each output is stamped with the pair it starts).
    np.testing.assert_array_equal(out_stamps, stamps[:-1])
    assert engine.counters["unreconstructed"] == 0
    assert engine.tau is not None
    assert engine.tau[0] == pytest.approx(pair.tau1, rel=0.05)
    # The backlog was reconstructed with the first accepted τ, like everything after it, the
    # two sensors fused with the noise ratio measured with it (phi 0, the default).
    phi = engine.last_status.estimate.phi
    assert phi is not None and phi != 1.0
    batch = reconstruct(pair.tc1, pair.tc2, pair.dt, *engine.tau, phi=phi)
    np.testing.assert_allclose(gas, batch.gas[: gas.size], rtol=1e-9)


def test_the_first_estimate_comes_after_first_estimate_rows(pair_factory):
    # Eq. (7) publishes from the first τ on (the Kalman filter waits for a window's fit too:
    # test_online_kalman.py).
    pair = pair_factory("multisine", noise_percent=1.0, seed=2, duration=2.0)
    engine = OnlineCompensator(OnlineConfig(window_s=1.0, reconstruction="difference"))
    stamps = np.round(pair.time * 1e9).astype(np.int64)
    n = FIRST_ESTIMATE_ROWS - 10
    out, _, _ = engine.add_pairs(stamps[:n], pair.tc1[:n], pair.tc2[:n])
    assert out.size == 0 and engine.tau is None
    out, _, _ = engine.add_pairs(stamps[n : n + 40], pair.tc1[n : n + 40], pair.tc2[n : n + 40])
    assert engine.tau is not None
    assert out.size == n + 40 - 1


def test_the_backlog_keeps_at_most_one_window(pair_factory):
    # A constant signal never gives an estimate: the engine holds one window, counts the rest.
    n = 3000
    stamps = np.arange(n, dtype=np.int64) * 2_000_000
    engine = OnlineCompensator(OnlineConfig(window_s=1.0))
    for start in range(0, n, 100):
        part = slice(start, start + 100)
        out, _, _ = engine.add_pairs(stamps[part], np.full(100, 50.0), np.full(100, 50.0))
        assert out.size == 0
    assert engine.tau is None
    held = engine.held_pairs
    assert 500 <= held <= 600
    assert engine.counters["unreconstructed"] + held == n - 1


def test_reconstruction_matches_the_batch_reconstruction_with_the_same_tau(pair_factory):
    pair = pair_factory("ramp", noise_percent=0.5, seed=3, duration=1.0)
    config = OnlineConfig(window_s=0.5, reconstruction="difference")
    engine = OnlineCompensator(config, initial_tau=(pair.tau1, pair.tau2))
    _, _, gas = _feed(engine, pair)
    batch = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    np.testing.assert_allclose(gas, batch.gas[: gas.size], rtol=1e-9)


def _feed_and_estimate(engine, pair, batch=100, every=5):
    """Feed in batches, re-estimating after every ``every``-th batch (a timer's stand-in)."""
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    out_stamps, out_gas, out_variance = [], [], []
    for number, start in enumerate(range(0, stamps.size, batch)):
        part = slice(start, start + batch)
        s, g, v = engine.add_pairs(stamps[part], pair.tc1[part], pair.tc2[part])
        out_stamps.append(s)
        out_gas.append(g)
        out_variance.append(v)
        if number % every == 0:
            engine.update_estimate()
    return (
        stamps,
        np.concatenate(out_stamps),
        np.concatenate(out_gas),
        np.concatenate(out_variance),
    )


def _second_half_error(pair, stamps, out_stamps, gas):
    index = np.searchsorted(stamps, out_stamps)
    late = index > stamps.size // 2
    return reconstruction_error_percent(pair.gas[index[late]], gas[late])


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kind", "signal_model", "most"),
    [
        ("sinusoid", "periodic", 0.1),
        ("sinusoid", "random-walk", 0.8),
        ("ramp", "random-walk", 1.0),
    ],
)
def test_kalman_reconstruction_beats_the_difference_equation(
    pair_factory, kind, signal_model, most
):
    pair = pair_factory(kind, noise_percent=2.0, seed=3, duration=10.0)
    errors, outputs = {}, {}
    for reconstruction in ("difference", "kalman"):
        config = OnlineConfig(
            window_s=4.0, reconstruction=reconstruction, signal_model=signal_model
        )
        engine = OnlineCompensator(config)
        stamps, out_stamps, gas, variance = _feed_and_estimate(engine, pair)
        errors[reconstruction] = _second_half_error(pair, stamps, out_stamps, gas)
        outputs[reconstruction] = out_stamps
        if reconstruction == "kalman":
            assert engine.fusion_model is not None
            assert engine.fusion_model.kind == signal_model
            assert engine.fusion_note == ""
            assert engine.published_tau == (engine.fusion_model.tau1, engine.fusion_model.tau2)
            assert variance.shape == gas.shape and np.all(variance > 0.0)
        else:
            assert np.all(variance == 0.0)
    # The same samples come out, stamped alike; only their values differ.
    np.testing.assert_array_equal(outputs["kalman"], outputs["difference"])
    assert errors["kalman"] < most * errors["difference"]


def _feed_kept(engine, pair, keep):
    """Feed the pairs where ``keep`` holds, estimating after every batch."""
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    out_stamps, gas = [], []
    for start in range(0, stamps.size, 100):
        part = np.flatnonzero(keep[start : start + 100]) + start
        s, g, _ = engine.add_pairs(stamps[part], pair.tc1[part], pair.tc2[part])
        out_stamps.append(s)
        gas.append(g)
        engine.update_estimate()
    return stamps, np.concatenate(out_stamps), np.concatenate(gas)


@pytest.mark.slow
def test_kalman_filter_restarts_after_a_gap_and_loses_no_sample(pair_factory):
    pair = pair_factory("multisine", noise_percent=1.0, seed=4, duration=6.0)
    everything = np.ones(pair.time.size, dtype=bool)
    keep = everything.copy()
    keep[1500:1600] = False  # 0.2 s of both sensors lost
    config = OnlineConfig(window_s=2.0, reconstruction="kalman")
    stamps, out_stamps, gas = _feed_kept(OnlineCompensator(config), pair, keep)
    kept = stamps[keep]
    # Every kept pair but the last, and the one before the gap (no successor), comes out.
    np.testing.assert_array_equal(out_stamps, np.setdiff1d(kept[:-1], [stamps[1499]]))
    _, whole_stamps, whole_gas = _feed_kept(OnlineCompensator(config), pair, everything)

    def error_after_restart(at, values):
        after = at > stamps[1700]
        return reconstruction_error_percent(
            pair.gas[np.searchsorted(stamps, at[after])], values[after]
        )

    # 0.2 s after the restart the filter is as good as one that never stopped.
    restarted = error_after_restart(out_stamps, gas)
    assert restarted < 1.1 * error_after_restart(whole_stamps, whole_gas)


@pytest.mark.slow
def test_switching_to_kalman_at_run_time_fits_the_signal_model_at_once(pair_factory):
    pair = pair_factory("ramp", noise_percent=1.0, seed=5, duration=4.0)
    engine = OnlineCompensator(OnlineConfig(window_s=2.0, reconstruction="difference"))
    _feed_and_estimate(engine, pair)
    assert engine.fusion_model is None and engine.reconstruction == "difference"
    engine.reconfigure(OnlineConfig(window_s=2.0, reconstruction="kalman"))
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18 + 10**10
    engine.add_pairs(stamps[:10], pair.tc1[:10], pair.tc2[:10])  # the build is taken over
    assert engine.fusion_model is not None and engine.reconstruction == "kalman"
    assert (engine.fusion_model.tau1, engine.fusion_model.tau2) == engine.tau
    with pytest.raises(ValueError, match="reconstruction='wiener'"):
        OnlineConfig(reconstruction="wiener")
    with pytest.raises(ValueError, match="signal_model='pink'"):
        OnlineConfig(signal_model="pink")


def _velocity_pair(seed):
    """Three tones through sensors whose τ follow 1 + 0.3 sin(2π t / 8 s), 1 % noise."""
    dt, count = 0.002, 8000
    time = np.arange(count) * dt
    gas = (
        100.0
        + 20.0 * np.sin(2 * np.pi * 3 * time)
        + 10.0 * np.sin(2 * np.pi * 11 * time + 1.0)
        + 5.0 * np.sin(2 * np.pi * 23 * time)
    )
    scale = 1.0 + 0.3 * np.sin(2 * np.pi * time / 8.0)
    rng = np.random.default_rng(seed)
    tc1 = varying_lag_response(gas, 0.0238 * scale, dt) + rng.normal(0.0, 0.05, count)
    tc2 = varying_lag_response(gas, 0.1168 * scale, dt) + rng.normal(0.0, 0.05, count)
    return time, tc1, tc2, 0.0238 * scale


@pytest.mark.slow
def test_tracking_memory_follows_a_tau_that_changes_with_the_flow():
    time, tc1, tc2, tau1 = _velocity_pair(seed=6)
    stamps = np.round(time * 1e9).astype(np.int64) + 1
    errors = {}
    for memory in (0.0, 0.5):
        engine = OnlineCompensator(OnlineConfig(window_s=2.0, tracking_memory_s=memory))
        relative = []
        for start in range(0, stamps.size, 100):
            part = slice(start, start + 100)
            engine.add_pairs(stamps[part], tc1[part], tc2[part])
            engine.update_estimate()
            if start >= 2000:
                relative.append(engine.tau[0] / tau1[start + 99] - 1.0)
        errors[memory] = float(np.sqrt(np.mean(np.square(relative))))
        if memory:
            assert engine.last_status.estimate.method == "beta-gtls-forgetting"
            ratio = engine.tau[0] / engine.tau[1]
            assert ratio == pytest.approx(0.0238 / 0.1168, rel=0.03)
    # The 2 s window lags the change by ~1 s; a 0.5 s memory by ~0.5 s.
    assert errors[0.5] < 0.7 * errors[0.0]
    assert errors[0.5] < 0.12


@pytest.mark.slow
def test_stamps_of_the_first_pairs_keep_every_nanosecond(pair_factory):
    # Stamps of today's wall clock (~1.8e18 ns) need 61 bits: as float64 they would round.
    pair = pair_factory("multisine", noise_percent=1.0, seed=2, duration=1.0)
    stamps = 1_795_000_000_123_456_789 + np.round(pair.time * 1e9).astype(np.int64) + 7
    engine = OnlineCompensator(OnlineConfig(window_s=1.0))
    out = [
        engine.add_pairs(stamps[k : k + 10], pair.tc1[k : k + 10], pair.tc2[k : k + 10])[0]
        for k in range(0, stamps.size, 10)
    ]
    np.testing.assert_array_equal(np.concatenate(out), stamps[:-1])


# -- health --------------------------------------------------------------------------------------
def _engine_with(pair, seconds, update_period_s=0.5, silence_timeout_s=1.0):
    """An engine fed ``seconds`` of the pair in 0.1 s drains (now = newest stamp, s)."""
    engine = Engine(
        OnlineConfig(update_period_s=update_period_s, silence_timeout_s=silence_timeout_s)
    )
    stamps = np.round(pair.time * 1e9).astype(np.int64)
    step = round(0.1 / pair.dt)
    for start in range(0, round(seconds / pair.dt), step):
        part = slice(start, start + step)
        now = stamps[part][-1] * 1e-9
        engine.add_samples(0, stamps[part], pair.tc1[part], now)
        engine.add_samples(1, stamps[part], pair.tc2[part], now)
        engine.reconstruct()
    return engine, now


def test_health_is_stale_before_an_estimate_then_ok(pair_factory):
    pair = pair_factory()
    engine, now = _engine_with(pair, 1.0, silence_timeout_s=60.0)
    health = engine.report(now)
    assert health.level == Level.STALE and health.message.startswith("no estimate yet")
    engine.update_estimate(now)
    health = engine.report(now)
    assert (health.level, health.message) == (Level.OK, "estimating")
    assert health.values["matched"] == health.values["received_tc1"] == str(round(1.0 / pair.dt))
    # The estimate ages on the caller's clock, nothing else: 3 updates and a report later, stale.
    assert engine.report(now + 2.4).level == Level.OK
    assert engine.report(now + 2.6).level == Level.STALE


def test_health_errors_name_the_silent_or_invalid_sensor(pair_factory):
    pair = pair_factory()
    engine, now = _engine_with(pair, 1.0)
    engine.update_estimate(now)
    silent = engine.report(now + 1.5)
    assert silent.level == Level.ERROR
    assert silent.message == "tc1 silent for 1.5 s; tc2 silent for 1.5 s"
    engine.add_samples(0, [10**18], [float("nan")], now + 1.6)
    engine.add_samples(1, [10**18], [20.0], now + 1.6)
    invalid = engine.report(now + 1.7)
    assert invalid.level == Level.ERROR and "tc1 sent 1 invalid value(s)" in invalid.message
    assert invalid.values["invalid_tc1"] == "1"
    assert engine.report(now + 1.8).level == Level.OK  # the report period moved on


def test_health_warns_on_a_refused_estimate():
    engine = Engine(OnlineConfig())
    stamps = 10**18 + np.arange(600, dtype=np.int64) * 1_000_000
    flat = np.full(600, 50.0)  # no excitation: nothing to estimate
    engine.add_samples(0, stamps, flat, 1.0)
    engine.add_samples(1, stamps, flat, 1.0)
    engine.reconstruct()
    status = engine.update_estimate(1.0)
    assert not status.accepted
    health = engine.report(1.0)
    assert health.level == Level.STALE and status.reason in health.message
    keys = list(health.values)
    assert keys[-len(NO_DIAGNOSIS) - len(LIVE_ONLY_KEYS) :] == [*NO_DIAGNOSIS, *LIVE_ONLY_KEYS]
    assert all(health.values[key] == NO_LATENCY[key] for key in LIVE_ONLY_KEYS)


# -- schedule ------------------------------------------------------------------------------------
@pytest.mark.slow
def test_schedule_does_not_depend_on_the_reading_chunks(pair_factory):
    pair = pair_factory()
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18

    def run(chunk):
        scheduled = ScheduledEngine(Engine(OnlineConfig()), update_period_s=0.5, batch_s=0.1)
        steps = []
        for start in range(0, stamps.size, chunk):
            part = slice(start, start + chunk)
            steps += scheduled.feed(
                {0: (stamps[part], pair.tc1[part]), 1: (stamps[part], pair.tc2[part])}
            )
        steps += scheduled.finish()
        gas = np.concatenate([step.gas.gas for step in steps])
        reports = [step.health.values for step in steps if step.health is not None]
        return gas, reports

    gas, reports = run(977)
    for chunk in (64, 5000, stamps.size):
        other_gas, other_reports = run(chunk)
        np.testing.assert_array_equal(other_gas, gas)
        assert other_reports == reports
    assert len(reports) == int(pair.time[-1] - pair.time[0])


# -- guards against hostile input (issue 13) -----------------------------------------------------
@pytest.mark.slow
def test_values_outside_the_physical_range_are_invalid_in_tcomp_process(tmp_path, pair_factory):
    from tcomp_core.io import write_csv
    from tcomp_core.process import ProcessConfig, process

    pair = pair_factory()
    tc1 = pair.tc1.copy()
    tc1[[300, 301]] = [1e308, -300.0]  # finite, but no thermocouple reads them
    source = tmp_path / "in.csv"
    write_csv(source, pair.time, tc1, pair.tc2)
    result = process(source, tmp_path / "out.csv", ProcessConfig(diagnose=False))
    table = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    gas = table["gas"][~np.isnan(table["gas"])]  # empty cells: pairs not reconstructed
    assert gas.size > pair.tc1.size - 10
    assert np.abs(gas).max() < 1e4  # finite and bounded
    assert result.counters["invalid_tc1"] == 2
    assert any("outside the physical range" in warning for warning in result.warnings)


def test_configured_range_applies_and_is_checked():
    engine = Engine(OnlineConfig(min_temperature_c=0.0, max_temperature_c=100.0))
    stamps = 10**18 + np.arange(4, dtype=np.int64)
    engine.add_samples(0, stamps, [50.0, -1.0, 101.0, np.inf], 0.0)
    assert engine.counters.invalid == [3, 0]
    with pytest.raises(ValueError, match="min_temperature_c"):
        OnlineConfig(min_temperature_c=-300.0)
    with pytest.raises(ValueError, match="max_temperature_c"):
        OnlineConfig(max_temperature_c=np.inf)


@pytest.mark.slow
def test_stamps_jumping_back_restart_the_engine_and_resume(pair_factory):
    pair = pair_factory()
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    engine = Engine(OnlineConfig())
    half = stamps.size // 2
    for index, values in ((0, pair.tc1), (1, pair.tc2)):
        engine.add_samples(index, stamps[:half], values[:half], 1.0)
    first = engine.reconstruct()
    engine.update_estimate(1.0)
    # A clock reset: the second half arrives stamped an hour earlier.
    back = stamps[half:] - 3600 * 10**9
    for index, values in ((0, pair.tc1), (1, pair.tc2)):
        engine.add_samples(index, back, values[half:], 2.0)
    second = engine.reconstruct()
    assert engine.counters.discontinuities == 1
    assert engine.counters.last_discontinuity_ns == int(back[0])
    assert second.stamps_ns.size >= stamps.size - half - 5  # not a silent outage
    assert engine.counters.out_of_order == 0  # the run that made the jump was not lost
    assert first.stamps_ns.size > 0 and engine.compensator.tau is not None
    health = engine.report(2.0)
    assert "stamps jumped back" in health.message and health.level >= Level.WARN
    assert health.values["discontinuities"] == "1"


def test_one_late_message_is_out_of_order_not_a_discontinuity(pair_factory):
    pair = pair_factory()
    stamps = np.round(pair.time * 1e9).astype(np.int64) + 10**18
    engine = Engine(OnlineConfig())
    for index, values in ((0, pair.tc1), (1, pair.tc2)):
        engine.add_samples(index, stamps, values, 1.0)
    engine.add_samples(0, stamps[:1] - 3600 * 10**9, pair.tc1[:1], 1.0)
    assert engine.counters.discontinuities == 0 and engine.counters.out_of_order == 1


def test_window_is_bounded_in_samples_whatever_the_period():
    with pytest.raises(ValueError, match="max_window_samples"):
        OnlineConfig(window_s=2.0, sample_period_s=1e-9)
    engine = Engine(OnlineConfig(max_window_samples=1000))
    stamps = 10**18 + np.arange(5000, dtype=np.int64)  # 1 ns apart: a 2e9-sample window
    rng = np.random.default_rng(3)
    engine.add_samples(0, stamps, 20 + rng.standard_normal(5000), 0.0)
    engine.add_samples(1, stamps, 20 + rng.standard_normal(5000), 0.0)
    engine.reconstruct()
    assert engine.compensator.window_samples <= 1000


@pytest.mark.slow
def test_health_warns_while_the_readings_disagree_with_the_signal_model():
    """A Kalman filter fitted on tones that meet 500 °C steps: its std widens (counted in
    ``widened``) and the status says so, at least WARN, while the steps last."""
    from scipy import signal

    dt, taus = 0.002, (0.02, 0.1)
    time = np.arange(round(8.0 / dt)) * dt
    tones = 300 + 50 * np.sin(2 * np.pi * 3 * time) + 20 * np.sin(2 * np.pi * 11 * time)
    gas = np.where(time < 6.0, tones, np.where(time % 1.0 < 0.5, 300.0, 800.0))
    rng = np.random.default_rng(41)
    readings = []
    for tau in taus:
        pole = np.exp(-dt / tau)
        lagged = signal.lfilter([1 - pole], [1, -pole], gas, zi=[pole * gas[0]])[0]
        readings.append(lagged + rng.normal(0.0, 0.3, gas.size))
    engine = Engine(OnlineConfig(reconstruction="kalman", window_s=3.0, update_period_s=0.5))
    stamps = np.round(time * 1e9).astype(np.int64) + 10**18
    levels, widened = {}, {}
    for start in range(0, stamps.size, 50):
        part = slice(start, start + 50)
        now = stamps[part][-1] * 1e-9
        engine.add_samples(0, stamps[part], readings[0][part], now)
        engine.add_samples(1, stamps[part], readings[1][part], now)
        engine.reconstruct()
        if (start + 50) % 250 == 0:  # every half second
            engine.update_estimate(now)
            health = engine.report(now)
            second = round(time[part][-1] - 1e-9, 1)
            levels[second], widened[second] = health, int(health.values["widened"])
    tones_end = levels[5.5]
    assert tones_end.level == Level.OK and widened[5.5] < 0.01 * 5.5 / dt
    for second in (7.0, 7.5, 8.0):  # 500 °C steps: the gas rings far beyond the model's std
        health = levels[second]
        assert health.level >= Level.WARN, health.message
        assert "disagree with the filter's model" in health.message
    assert widened[8.0] - widened[6.5] > 0.5 * 1.5 / dt
