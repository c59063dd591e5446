"""A long-running engine keeps a bounded state: nothing it holds grows with the pairs it took.

The node runs for weeks (issue 27): once the engine's window and its newest pairs
(``RECENT_S``) are full, feeding it more must not keep more Python memory. The soak bench
(``bench/bench_soak.py``) measures the process's RSS; this test checks the engine itself,
with tracemalloc, at a low rate so that a minute of pairs is quick to fill.
"""

from __future__ import annotations

import gc
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from tcomp_core.memory import heap_info
from tcomp_core.online import DIAGNOSTICS_PERIOD_S, Engine, OnlineConfig
from tcomp_core.online.compensator import LANDED_KEPT, RECENT_S
from tcomp_core.simulate import simulate_pair
from tcomp_core.workers import InlineRunner

RATE = 100  # pairs a second: RECENT_S of them fill in a few thousand pairs
BATCH = 5  # samples of each input per drain


def _drive(engine: Engine, pair, start: int, drains: int) -> None:
    """Feed ``drains`` drains of ``pair`` (repeated) from drain ``start``, as the node does."""
    update_every = round(engine.config.update_period_s * RATE / BATCH)
    report_every = round(DIAGNOSTICS_PERIOD_S * RATE / BATCH)
    for drain in range(start, start + drains):
        index = np.arange(drain * BATCH, (drain + 1) * BATCH)
        stamps = 10**18 + index * (1_000_000_000 // RATE)
        k = index % pair.tc1.size
        now = (drain + 1) * BATCH / RATE
        engine.add_samples(0, stamps, pair.tc1[k], now)
        engine.add_samples(1, stamps, pair.tc2[k], now)
        engine.reconstruct()
        if (drain + 1) % update_every == 0:
            engine.update_estimate(now)
        if (drain + 1) % report_every == 0:
            engine.poll_diagnosis(now)
            engine.diagnosis.log = []  # the node logs and empties it at each report
            engine.report(now, new_period=True)


@pytest.mark.slow
def test_the_engine_holds_no_more_after_its_buffers_are_full():
    # 10 s of a 1 Hz sinusoid (a whole number of periods: repeated seamlessly), seeded noise.
    pair = simulate_pair(
        "sinusoid",
        tau1=0.05,
        tau2=0.25,
        dt=1.0 / RATE,
        duration=10.0,
        noise_percent=1.0,
        seed=27,
        signal_params={"freq_hz": 1.0},
    )
    config = OnlineConfig(window_s=2.0, update_period_s=0.5, reconstruction="difference")
    engine = Engine(config, diagnosis_runner=InlineRunner())
    warm = round(1.5 * RECENT_S * RATE / BATCH)  # the newest pairs full, and turned over
    _drive(engine, pair, 0, warm)
    assert engine.compensator.tau is not None
    drains = round(RECENT_S * RATE / BATCH)
    tracemalloc.start()
    try:
        # Only blocks allocated while tracing count: the newest pairs turn over once first.
        _drive(engine, pair, warm, drains)
        gc.collect()
        before = tracemalloc.get_traced_memory()[0]
        _drive(engine, pair, warm + drains, drains)
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    # 1200 drains: a single small object kept per drain would be > 60 KiB.
    assert grown < 48 * 1024, f"{grown} bytes kept over {drains} drains"
    recent = engine.compensator.recent
    assert recent.size <= recent.capacity + BATCH
    assert len(recent.parts) <= recent.capacity // BATCH + 1
    assert len(engine.compensator._landed) <= LANDED_KEPT
    assert not engine.compensator._backlog


#: Run in a child process: a pinned threshold would stay for the rest of the test session.
_PINNED_CHECK = f"""
import sys
sys.path.insert(0, {str(Path(__file__).parent)!r})
from tcomp_core.memory import pin_mmap_threshold
from test_online_soak import _mapped_blocks_after_a_freed_large_array
assert pin_mmap_threshold()
print(_mapped_blocks_after_a_freed_large_array())
"""


@pytest.mark.slow
@pytest.mark.skipif(heap_info() is None, reason="glibc's mallinfo2 is needed")
def test_a_pinned_mmap_threshold_keeps_freed_large_arrays_out_of_the_heap():
    # Unpinned, glibc raises its threshold to 16 MiB when the 16 MiB array is freed, and the
    # next 8 MiB array comes from a heap (to stay there once freed); pinned, it has a mapping
    # of its own, returned when freed.
    done = subprocess.run(
        [sys.executable, "-c", _PINNED_CHECK], capture_output=True, text=True, check=True
    )
    assert done.stdout.split() == ["1"], done.stdout + done.stderr


def _mapped_blocks_after_a_freed_large_array() -> int:
    """Mappings an 8 MiB array takes after a 16 MiB one was freed (run in a child process or a
    worker; module level, so that it pickles by reference)."""
    big = np.ones(16 << 20, np.uint8)
    del big
    before = heap_info()
    array = np.ones((8 << 20) + 4096, np.uint8)
    after = heap_info()
    assert before is not None and after is not None and array.size
    return after.mapped_blocks - before.mapped_blocks


@pytest.mark.slow
@pytest.mark.skipif(heap_info() is None, reason="glibc's mallinfo2 is needed")
def test_the_worker_processes_pin_the_mmap_threshold_as_the_node_does():
    # The fitting and diagnosis workers free window-sized arrays job after job too: pinned (the
    # default) the second array has a mapping of its own; left to glibc it comes from a heap.
    from tcomp_core.workers import ProcessRunner

    found = {}
    for pin in (True, False):
        runner = ProcessRunner(pin_heap=pin)
        try:
            assert runner.start(wait_s=60.0)
            assert runner.submit(_mapped_blocks_after_a_freed_large_array)
            outcome = None
            for _ in range(600):
                outcome = runner.poll()
                if outcome is not None:
                    break
                time.sleep(0.05)
        finally:
            runner.close()
        assert outcome is not None and not outcome.error, outcome
        found[pin] = outcome.value
    assert found == {True: 1, False: 0}
