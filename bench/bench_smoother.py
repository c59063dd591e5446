"""The offline Kalman gas (``fuse``: signal-model fit and smoother), against a baseline commit.

``tcomp reconstruct``'s default path on records whose length grows with the rate: the
detailed simulator's engine pulses (``test/detailed_physics.py``, 4 s, noise 0.25 °C) at 5 and
20 kHz and the bundled ``bags/rig_sine_5khz``. τ1, τ2 come from this checkout's default
estimate, once, and both codes get the same arrays. Each record runs in a child process of each
code (the baseline's a ``git archive`` of ``--baseline``, first on the child's ``PYTHONPATH``),
alternating which goes first, ``--repeats`` times; a child times ``fuse`` after one call that
warms its compiled loops.

Prints per record the fewest CPU seconds of each code, their ratio (baseline / current: above 1
the current code is faster) and how far the current gas and its standard deviation are from the
baseline's (largest relative difference).

Usage::

    .venv/bin/python bench/bench_smoother.py --baseline 13e6b8a --repeats 3
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_diagnose_speed import REPOSITORY, child_environment, unpack_baseline

RATES_HZ = (5000.0, 20000.0)


def child(source: str, out: str) -> None:
    """Time ``fuse`` on the record in ``source`` (npz); its CPU time, gas and std to ``out``."""
    from tcomp_core.fusion import fuse

    data = np.load(source)
    pair = (data["tc1"], data["tc2"], float(data["dt"]), float(data["tau1"]), float(data["tau2"]))
    fuse(*pair)  # compiles or loads the numba loops
    start = time.process_time()
    result = fuse(*pair)
    cpu = time.process_time() - start
    np.savez(out, cpu=cpu, gas=result.gas, std=result.std)


def records(directory: Path) -> dict[str, Path]:
    """The records as npz files (tc1, tc2, dt, tau1, tau2) in ``directory``."""
    sys.path.insert(0, str(REPOSITORY / "test"))
    from detailed_physics import Rig, simulate_rig

    from tcomp_core.estimators import estimate
    from tcomp_core.io import read_record

    pairs = {}
    for rate in RATES_HZ:
        rig = Rig(
            signal="engine_pulses", rate_hz=rate, duration_s=4.0, seed=3, noise_c=(0.25, 0.25)
        )
        simulated = simulate_rig(rig)
        pairs[f"engine pulses {rate / 1000:g} kHz"] = (simulated.tc1, simulated.tc2, simulated.dt)
    bag = read_record(REPOSITORY / "bags" / "rig_sine_5khz")
    pairs["bags/rig_sine_5khz"] = (bag.tc1, bag.tc2, bag.dt)
    paths = {}
    for index, (name, (tc1, tc2, dt)) in enumerate(pairs.items()):
        found = estimate(tc1, tc2, dt)
        paths[name] = directory / f"record{index}.npz"
        np.savez(paths[name], tc1=tc1, tc2=tc2, dt=dt, tau1=found.tau1, tau2=found.tau2)
    return paths


def run_child(tree: Path, source: Path, out: Path) -> dict[str, np.ndarray]:
    """One child of the code in ``tree``; its results."""
    environment = child_environment(tree)
    environment.setdefault("OPENBLAS_NUM_THREADS", "1")
    command = [sys.executable, str(Path(__file__).resolve()), "--child", str(source), str(out)]
    subprocess.run(command, env=environment, check=True, cwd=tree)
    with np.load(out) as saved:
        return {key: saved[key] for key in saved.files}


def largest_relative(old: np.ndarray, new: np.ndarray) -> float:
    """Largest |new - old| / |old| where old is finite and nonzero."""
    keep = np.isfinite(old) & (old != 0.0)
    return float(np.max(np.abs(new[keep] - old[keep]) / np.abs(old[keep])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default="main", help="commit to compare with")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs=2, metavar=("SOURCE", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        trees = {"baseline": unpack_baseline(args.baseline, work), "current": REPOSITORY}
        print(f"fuse() CPU seconds, fewest of {args.repeats}; baseline {args.baseline}")
        print(f"{'record':24s} {'baseline':>9s} {'current':>9s} {'ratio':>6s}  gas / std rel diff")
        for name, source in records(work).items():
            cpu: dict[str, list[float]] = {key: [] for key in trees}
            last: dict[str, dict[str, np.ndarray]] = {}
            for repeat in range(args.repeats):
                order = list(trees) if repeat % 2 == 0 else list(reversed(trees))
                for key in order:
                    last[key] = run_child(trees[key], source, work / f"{key}.npz")
                    cpu[key].append(float(last[key]["cpu"]))
            old, new = min(cpu["baseline"]), min(cpu["current"])
            gas = largest_relative(last["baseline"]["gas"], last["current"]["gas"])
            std = largest_relative(last["baseline"]["std"], last["current"]["std"])
            print(f"{name:24s} {old:9.3f} {new:9.3f} {old / new:6.2f}  {gas:.2g} / {std:.2g}")


if __name__ == "__main__":
    main()
