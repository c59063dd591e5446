"""The background diagnoser: a job in a spawned worker process, polled without blocking."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from tcomp_core.diagnose.background import BackgroundDiagnoser, parse_effects
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.simulate import simulate_pair

# Jobs in a worker process, and their waits and latencies on the wall clock.
pytestmark = pytest.mark.realtime

KEYS = {
    "effects",
    "base_error_pct",
    "error_pct",
    "tau1",
    "tau2",
    "at_bound",
    "top_suspect",
    "top_suspect_error_pct",
    "samples",
    "seconds",
}


def wait_for_result(diagnoser, timeout_s=120.0):  # generous: the worker runs niced
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = diagnoser.poll()
        if result is not None:
            return result
        time.sleep(0.05)
    raise AssertionError(f"no result within {timeout_s} s")


@pytest.fixture
def diagnoser():
    made = BackgroundDiagnoser()
    yield made
    made.close()


@pytest.mark.slow
def test_job_runs_in_the_background_and_reports_once(diagnoser):
    data = simulate_pair("multisine", noise_percent=1, duration=4, seed=1)
    assert not diagnoser.busy and diagnoser.latest is None
    started = time.monotonic()
    assert diagnoser.submit(data.time, data.tc1, data.tc2, data.dt, effects=(), find_suspect=True)
    assert time.monotonic() - started < 1.0  # submit does not wait for the worker
    assert diagnoser.busy
    assert not diagnoser.submit(
        data.time, data.tc1, data.tc2, data.dt, effects=("delay",), find_suspect=False
    )
    result = wait_for_result(diagnoser)
    assert set(result) == KEYS, result
    assert result["effects"] == []
    assert result["samples"] == data.tc1.size
    assert result["tau1"] == pytest.approx(data.tau1, rel=0.05)
    assert result["tau2"] == pytest.approx(data.tau2, rel=0.05)
    assert result["error_pct"] == result["base_error_pct"]
    assert result["top_suspect"] == "none"  # first-order sensors: nothing is missing
    assert np.isnan(result["top_suspect_error_pct"])
    assert 0.0 < result["seconds"] < time.monotonic() - started
    assert not diagnoser.busy
    assert diagnoser.poll() is None  # once only
    assert diagnoser.latest is result

    # A failure inside the worker comes back as a result; the worker lives on.
    short = slice(0, 100)
    assert diagnoser.submit(
        data.time[short], data.tc1[short], data.tc2[short], data.dt, effects=(), find_suspect=False
    )
    failed = wait_for_result(diagnoser)
    assert set(failed) == {"error"}
    assert "too few to diagnose" in failed["error"]


def test_bad_input_is_refused_at_submit(diagnoser):
    data = simulate_pair("multisine", duration=1, seed=1)
    with pytest.raises(ValueError, match="unknown effect 'smoke'"):
        diagnoser.submit(
            data.time, data.tc1, data.tc2, data.dt, effects=("smoke",), find_suspect=False
        )
    with pytest.raises(ValueError, match="shape"):
        diagnoser.submit(
            data.time, data.tc1[:-1], data.tc2, data.dt, effects=(), find_suspect=False
        )
    assert not diagnoser.busy and diagnoser.poll() is None


def test_close_is_idempotent_and_final():
    diagnoser = BackgroundDiagnoser()
    diagnoser.close()  # never started: nothing to stop
    diagnoser.close()
    with pytest.raises(RuntimeError, match="closed"):
        diagnoser.submit(
            np.arange(3.0), np.zeros(3), np.zeros(3), 1.0, effects=(), find_suspect=False
        )


def test_close_ends_a_running_job_at_once():
    data = simulate_pair("multisine", noise_percent=1, duration=4, seed=2)
    diagnoser = BackgroundDiagnoser()
    assert diagnoser.submit(
        data.time, data.tc1, data.tc2, data.dt, effects=("conduction",), find_suspect=True
    )
    started = time.monotonic()
    diagnoser.close()
    diagnoser.close()
    assert time.monotonic() - started < 1.0
    assert not diagnoser.busy and diagnoser.poll() is None


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ("", ()),
        ("none", ()),
        ("conduction", ("conduction",)),
        (" delay , calibration", ("delay", "calibration")),
        (list(EFFECT_NAMES), EFFECT_NAMES),
    ],
)
def test_parse_effects(text, names):
    assert parse_effects(text) == names


@pytest.mark.parametrize(
    ("text", "message"),
    [("smoke", "unknown"), ("delay,delay", "repeat"), ("delay,", "empty effect name")],
)
def test_parse_effects_refuses_bad_names(text, message):
    with pytest.raises(ValueError, match=message):
        parse_effects(text)


@pytest.mark.slow
def test_a_dead_worker_is_reported_and_replaced(diagnoser):
    data = simulate_pair("multisine", noise_percent=1, duration=4, seed=3)
    args = (data.time, data.tc1, data.tc2, data.dt)
    assert diagnoser.submit(*args, effects=("conduction",), find_suspect=True)
    (pid,) = diagnoser.runner.worker_pids
    os.kill(pid, signal.SIGKILL)
    failed = wait_for_result(diagnoser)
    assert "the diagnosis worker died" in failed["error"]
    assert diagnoser.submit(*args, effects=(), find_suspect=False)
    assert wait_for_result(diagnoser)["tau1"] == pytest.approx(data.tau1, rel=0.05)


@pytest.mark.slow
def test_an_auto_job_returns_the_diagnosis_final_model_as_an_output_model(diagnoser):
    from tcomp_core.simulate_effects import simulate_effect

    data = simulate_effect("delay", "multisine", duration=4.0, noise_percent=1.0, seed=4)
    assert diagnoser.submit(
        data.time, data.tc1, data.tc2, data.dt, effects=None, find_suspect=True, output=True
    )
    result = wait_for_result(diagnoser)
    assert set(result) == KEYS | {"output_model"}, result
    model = result["output_model"]
    assert result["effects"] == ["delay"] == list(model.effects)
    assert model.name(causal_stream=True) == "first-order+delay"
    assert model.params["delay_s"] == pytest.approx(data.params["delay_s"], rel=0.1)
    assert result["top_suspect"] == "delay"
