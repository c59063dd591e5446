"""The gas a user takes home by default, against the best reconstruction offered for its context.

For each record whose true gas is known, e_Tg (% of the reference's spread, against the gas held
over each interval) of:

- offline: ``tcomp reconstruct`` with no option (the default), the Kalman smoother, the causal
  filter fitted on the whole record, and the paper's Eq. (7);
- streaming: ``tcomp process`` with no option (the node's engine and defaults, fits inline),
  against the offline causal filter (the best causal reconstruction: its model fitted on the
  whole record) and Eq. (7).

Records: the bundled ``bags/rig_sine_5khz`` (10 Hz sine, 5 kHz) and the independent detailed
simulator's engine pulses (``test/detailed_physics.py``) at 0.5, 2, 5 and 20 kHz. Ratios are
default / best, measured in the same run. The node itself is measured by
``test/ros/test_end_to_end.py`` (the shipped YAML, a bag replayed over DDS) and
``bench_realtime.py``.

Run::

    .venv/bin/python bench/bench_default_gas.py            # all records
    .venv/bin/python bench/bench_default_gas.py --quick    # the bag and 5 kHz pulses
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "test"))

from detailed_physics import Rig, simulate_rig  # noqa: E402

from tcomp_core.cli import main as tcomp  # noqa: E402
from tcomp_core.estimators import estimate  # noqa: E402
from tcomp_core.fusion import fuse  # noqa: E402
from tcomp_core.io import read_bag, write_csv  # noqa: E402
from tcomp_core.metrics import reconstruction_error_percent  # noqa: E402
from tcomp_core.reconstruct import reconstruct  # noqa: E402


def records(quick: bool):
    """(name, time, tc1, tc2, gas held over each interval, dt)."""
    bag = read_bag(HERE.parent / "bags" / "rig_sine_5khz")
    held = bag.ref[:-1]  # simulated with the gas held over each interval (bags/README.md)
    time_s = (bag.stamps_ns - bag.stamps_ns[0]) * 1e-9  # from the stamps: no epoch rounding
    yield "bags/rig_sine_5khz (sine, 5 kHz)", time_s, bag.tc1, bag.tc2, held
    for rate in (5000,) if quick else (500, 2000, 5000, 20000):
        rig = Rig(
            signal="engine_pulses",
            rate_hz=float(rate),
            duration_s=6.0,
            seed=3,
            noise_c=(0.25, 0.25),
        )
        sim = simulate_rig(rig)
        held = 0.5 * (sim.gas[:-1] + sim.gas[1:])  # a smooth gas: its mean over the interval
        yield f"detailed engine pulses, {rate / 1000:g} kHz", sim.time, sim.tc1, sim.tc2, held


def error(truth: np.ndarray, gas: np.ndarray) -> float:
    count = min(truth.size, gas.size)
    keep = np.isfinite(gas[:count])
    return reconstruction_error_percent(truth[:count][keep], gas[:count][keep])


def run_verb(arguments: list[str]) -> float:
    started = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        status = tcomp(arguments)
    if status != 0:
        raise RuntimeError(f"tcomp {' '.join(arguments)} failed")
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        work = Path(directory)
        for name, time_s, tc1, tc2, held in records(args.quick):
            dt = float(np.median(np.diff(time_s)))
            data = write_csv(work / "in.csv", time_s, tc1, tc2, overwrite=True)
            found = estimate(tc1, tc2, dt)
            smoother = fuse(tc1, tc2, dt, found.tau1, found.tau2).gas
            causal = fuse(tc1, tc2, dt, found.tau1, found.tau2, causal=True).gas
            eq7 = reconstruct(tc1, tc2, dt, found.tau1, found.tau2).gas
            offline_s = run_verb(
                ["reconstruct", str(data), "-o", str(work / "off.csv"), "--force"]
            )
            stream_s = run_verb(
                ["process", str(data), "-o", str(work / "on.csv"), "--force", "--no-diagnose"]
            )
            offline = np.genfromtxt(work / "off.csv", delimiter=",", names=True)["gas"]
            stream = np.genfromtxt(work / "on.csv", delimiter=",", names=True)["gas"]
            e = {
                "reconstruct": error(held, offline),
                "smoother": error(held, smoother),
                "process": error(held, stream),
                "causal": error(held, causal),
                "eq7": error(held, eq7),
            }
            rows.append((name, e, offline_s, stream_s))
    header = (
        f"{'record':<36} {'reconstruct':>11} {'smoother':>9} {'ratio':>6}  {'process':>8} "
        f"{'causal':>7} {'ratio':>6}  {'Eq. 7':>7}  {'s off/on':>9}"
    )
    print("e_Tg, % of the reference's spread (default / best offered for the context)")
    print(header)
    print("-" * len(header))
    for name, e, offline_s, stream_s in rows:
        print(
            f"{name:<36} {e['reconstruct']:>11.3f} {e['smoother']:>9.3f} "
            f"{e['reconstruct'] / e['smoother']:>5.2f}x  {e['process']:>8.3f} "
            f"{e['causal']:>7.3f} {e['process'] / e['causal']:>5.2f}x  {e['eq7']:>7.2f}  "
            f"{offline_s:>4.1f}/{stream_s:<4.1f}"
        )
    worst = max(
        max(e["reconstruct"] / e["smoother"], e["process"] / e["causal"]) for _, e, _, _ in rows
    )
    print(f"worst default / best: {worst:.2f}x (goal: offline <= 1.1x, streaming <= 1.5x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
