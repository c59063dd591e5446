"""A change of the inputs' rate is noticed (issue 26, item 4).

Sensors switching from 500 Hz to 5 kHz kept the learnt period of 2 ms: τ came out ten times
too long and thousands of gas values outside -273.15..2000 °C were published with status OK.
Now the period, the window, τ and the reconstruction restart, the status says why, and τ at the
new rate is the sensors' again.
"""

from __future__ import annotations

import numpy as np
import pytest

from tcomp_core.online import OnlineCompensator, OnlineConfig
from tcomp_core.online.compensator import RATE_CHANGE_STEPS
from tcomp_core.online.health import HealthMonitor
from tcomp_core.online.pairing import PairCounters
from tcomp_core.simulate import simulate_pair

TAUS = (0.0238, 0.1168)


def _segment(rate, duration, start_ns, seed):
    pair = simulate_pair(
        "multisine", dt=1.0 / rate, duration=duration, noise_percent=1.0, seed=seed, warmup=1.0
    )
    stamps = start_ns + np.round(pair.time * 1e9).astype(np.int64)
    return stamps, pair.tc1, pair.tc2


def _feed(engine, stamps, tc1, tc2, batch):
    gas, notes = [], []
    for number, start in enumerate(range(0, stamps.size, batch)):
        part = slice(start, start + batch)
        gas.append(engine.add_pairs(stamps[part], tc1[part], tc2[part]).gas)
        if number % 5 == 0:
            engine.update_estimate()
        notes.append(engine.rate_note)
    return np.concatenate(gas), notes


@pytest.mark.slow
@pytest.mark.parametrize("reconstruction", ["difference", "kalman"])
def test_a_rate_change_restarts_the_period_and_tau(reconstruction):
    engine = OnlineCompensator(OnlineConfig(window_s=2.0, reconstruction=reconstruction))
    slow = _segment(500, 6.0, 10**18, seed=1)
    gas_slow, _ = _feed(engine, *slow, batch=50)
    assert engine.period_s == pytest.approx(2e-3)
    assert engine.tau == pytest.approx(TAUS, rel=0.05)
    fast = _segment(5000, 6.0, int(slow[0][-1]) + 200_000, seed=2)
    gas_fast, notes = _feed(engine, *fast, batch=500)
    assert engine.rate_changes == 1
    assert engine.period_s == pytest.approx(2e-4)
    assert engine.tau == pytest.approx(TAUS, rel=0.05)
    # Said while it mattered, cleared once an estimate at the new rate was accepted.
    assert any("inputs changed rate" in note for note in notes) and notes[-1] == ""
    published = np.concatenate((gas_slow, gas_fast))
    assert np.all((published > -273.15) & (published < 2000.0))


def test_the_status_warns_until_the_new_rate_is_estimated():
    engine = OnlineCompensator(OnlineConfig(window_s=2.0, reconstruction="difference"))
    slow = _segment(500, 6.0, 10**18, seed=1)
    _feed(engine, *slow, batch=50)
    fast = _segment(5000, 0.05, int(slow[0][-1]) + 200_000, seed=2)
    engine.add_pairs(*fast)  # no re-estimation yet
    assert engine.tau is None
    assert engine.rate_note.startswith("inputs changed rate (sample period 0.002 s -> about")
    monitor = HealthMonitor(silence_timeout_s=1e9, stale_after_s=1e9)
    health = monitor.report(
        0.0, engine=engine, counters=PairCounters(), published=0, max_model_error_pct=10.0
    )
    assert health.level >= 1 and "inputs changed rate" in health.message


def test_a_steady_rate_with_jitter_and_gaps_is_not_a_change():
    engine = OnlineCompensator(OnlineConfig(window_s=2.0, reconstruction="difference"))
    stamps, tc1, tc2 = _segment(500, 6.0, 10**18, seed=3)
    rng = np.random.default_rng(4)
    jittered = stamps + rng.integers(-100_000, 100_000, stamps.size)  # ±5 % of the period
    keep = np.ones(stamps.size, dtype=bool)
    keep[1000 : 1000 + 2 * RATE_CHANGE_STEPS : 3] = False  # dropped pairs: gaps
    _feed(engine, jittered[keep], tc1[keep], tc2[keep], batch=50)
    assert engine.rate_changes == 0 and engine.rate_note == ""
    assert engine.tau == pytest.approx(TAUS, rel=0.05)


@pytest.mark.slow
def test_a_change_inside_one_batch_is_counted_once_and_learns_the_new_period():
    """``tcomp process`` hands the engine a second of pairs at a time: a batch of 400 pairs
    at 500 Hz then 100 at 2 kHz used to learn the new period from all of them (2 ms, the
    median), and the change was noticed again a batch later ("changed 2 time(s)")."""
    engine = OnlineCompensator(OnlineConfig(window_s=2.0))
    slow = _segment(500, 4.8, 10**18, seed=3)
    fast = _segment(2000, 4.0, int(slow[0][-1]) + 500_000, seed=4)
    stamps, tc1, tc2 = (np.concatenate(parts) for parts in zip(slow, fast, strict=True))
    out, notes = [], []
    for start in range(0, stamps.size, 500):  # the change falls 400 pairs into a batch
        part = slice(start, start + 500)
        out.append(engine.add_pairs(stamps[part], tc1[part], tc2[part]).stamps_ns)
        notes.append(engine.rate_note)
        engine.update_estimate()
    assert engine.rate_changes == 1
    assert engine.period_s == pytest.approx(5e-4)
    # Named at the last pair of the old rate, not at the batch's first.
    assert "at stamp 1000000004.798000 s" in next(filter(None, notes))
    # The old rate's pairs of that batch were reconstructed before the restart.
    published = np.concatenate(out)
    change = int(fast[0][0])
    assert np.count_nonzero((published > change - 10**9) & (published < change)) > 400
