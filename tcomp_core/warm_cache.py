"""Compile the numba loops into their disk cache once: ``python -m tcomp_core.warm_cache``.

numba compiles a loop on its first call in a process and caches the machine code beside its
module (:mod:`.compiled`); a process that finds it there loads it in milliseconds. On a fresh
install nothing is cached, and every process that starts before the cache is written compiles
each loop it needs itself: both test workers and the real-time tests of ``make test``, and every
node and ``tcomp process`` worker they start, about 5 s of CPU each (a fresh clone's ``make
pytest`` took 304 s where the same clone took 273 s once its cache was warm). This runs every
loop once, on a short simulated record, through the code that calls it in use (the ml-eiv
criterion, the Kalman smoother and causal filter, the node's engine, the lag of a radiating and
of a level-dependent sensor), so that later processes load what it compiled. Without numba it
runs the same code as Python and compiles nothing.
"""

from __future__ import annotations

import sys
import time

import numpy as np

__all__ = ["main", "warm_cache"]

#: The record the loops are run on: short, but long enough for every path to run in full.
_SECONDS = 4.0
_DT = 0.002


def warm_cache() -> float:
    """Run every compiled loop once; returns the seconds it took.

    Raises
    ------
    TcompError
        If an estimate or a reconstruction of the simulated record fails (a broken install).
    """
    from .effects.chain import SensorChain, reading_from_gas
    from .estimators import estimate
    from .fusion import fuse
    from .online import OnlineCompensator, OnlineConfig
    from .simulate import simulate_pair

    started = time.perf_counter()
    pair = simulate_pair("multisine", dt=_DT, duration=_SECONDS, noise_percent=2.0, seed=1)
    tc1, tc2 = pair.tc1, pair.tc2
    found = estimate(tc1, tc2, _DT)  # ml-eiv: the whitened cross-relation residual
    smoothed = fuse(tc1, tc2, _DT, found.tau1, found.tau2)  # the smoother's Riccati and modes
    fuse(tc1, tc2, _DT, found.tau1, found.tau2, model=smoothed.model, causal=True)
    engine = OnlineCompensator(OnlineConfig(window_s=1.0, update_period_s=0.5))
    stamps = np.arange(tc1.size, dtype=np.int64) * round(_DT * 1e9)
    engine.add_pairs(stamps, tc1, tc2)  # the node's causal filter and its widening
    gas = pair.gas[:-1] + 300.0
    hot = SensorChain(tau=found.tau1, r=1e-12, wall_k=500.0)  # a radiating sensor's lag
    reading_from_gas(hot, gas, _DT, float(gas[0]))
    level = SensorChain(tau=found.tau1, level_exponent=0.5, level_ref_k=600.0)
    reading_from_gas(level, gas, _DT, float(gas[0]))  # τ at the film temperature
    return time.perf_counter() - started


def main() -> int:
    """Warm the cache and say how long it took."""
    seconds = warm_cache()
    print(f"numba loops compiled or loaded from their cache in {seconds:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
