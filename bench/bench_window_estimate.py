"""The cost of one re-estimation of the node's window, this tree against a baseline checkout.

``tcomp process`` on issue 25's recorder bag spends most of its time re-estimating τ1, τ2 on
the node's sliding window (2 s at 5 kHz, every 0.5 s: 1 200 times in 10 minutes). This benchmark
runs that sequence alone: ``--windows`` windows of 10 000 samples, 2 500 apart, of
:mod:`bench_process`'s signal (10 Hz and 1 Hz about 300 °C through the paper's lags, 0.3 °C of
noise), each estimated with the default estimator as the node's window estimator calls it (φ
measured, the previous window's τ, gain and φ as the start). Each run is a fresh process; with
``--baseline-tree DIR`` runs alternate between that tree and this one (``PYTHONPATH``) so both
see the same load, and the table gives each one's best and median milliseconds per window,
their ratio, and how far this tree's τ1, τ2 and intervals are from the baseline's.

Usage: ``python bench/bench_window_estimate.py [--windows 200] [--repeat 5]
[--baseline-tree /tmp/base]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
RATE_HZ = 5000
WINDOW = 2 * RATE_HZ
STEP = WINDOW // 4

#: The child: estimates the windows and prints its seconds per window and the results.
CHILD = """
import json, sys, time
sys.path.insert(0, {bench!r})
import numpy as np
from bench_process import sensor_blocks
from tcomp_core.estimators import estimate, warm_start
windows = {windows}
minutes = ((windows - 1) * {step} + {window}) / {rate} / 60.0
blocks = list(sensor_blocks(minutes, {rate}, seed=11))
tc1 = np.concatenate([b[1][0] for b in blocks])
tc2 = np.concatenate([b[1][1] for b in blocks])
start, phi, found = None, None, []
begun = time.perf_counter()
for i in range(windows):
    part = slice(i * {step}, i * {step} + {window})
    result = estimate(tc1[part], tc2[part], 1.0 / {rate}, phi=None, start=start, phi_start=phi)
    start, phi = warm_start(result), result.phi
    params = result.params
    found.append([result.tau1, result.tau2, params["tau1_ci_low"], params["tau1_ci_high"]])
seconds = (time.perf_counter() - begun) / windows
print(json.dumps({{"seconds": seconds, "found": found}}))
"""


def run(tree: Path, windows: int) -> dict:
    """One child process from ``tree``: its seconds per window and its estimates."""
    code = CHILD.format(bench=str(HERE), windows=windows, step=STEP, window=WINDOW, rate=RATE_HZ)
    env = {**os.environ, "PYTHONPATH": str(tree)}
    with tempfile.TemporaryDirectory() as scratch:
        done = subprocess.run(
            [sys.executable, "-c", code],
            cwd=scratch,
            env=env,
            check=True,
            capture_output=True,
            text=True,
        )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=200, help="windows per run")
    parser.add_argument("--repeat", type=int, default=5, help="runs per tree")
    parser.add_argument("--baseline-tree", type=Path, help="a checkout to compare against")
    args = parser.parse_args(argv)
    trees = {"this tree": HERE.parent}
    if args.baseline_tree is not None:
        trees = {"baseline": args.baseline_tree.resolve(), **trees}
    times: dict[str, list[float]] = {name: [] for name in trees}
    results: dict[str, list] = {}
    run(HERE.parent, 2)  # compile or load the compiled loops before any timing
    for _ in range(args.repeat):
        for name, tree in trees.items():
            outcome = run(tree, args.windows)
            times[name].append(1e3 * outcome["seconds"])
            results[name] = outcome["found"]
    print(f"{args.windows} windows of {WINDOW} samples at {RATE_HZ} Hz, {args.repeat} runs each")
    print(f"{'tree':<12}{'best ms':>10}{'median ms':>11}")
    for name, values in times.items():
        print(f"{name:<12}{min(values):>10.3f}{statistics.median(values):>11.3f}")
    if "baseline" in times:
        ratio = statistics.median(times["baseline"]) / statistics.median(times["this tree"])
        print(f"this tree / baseline: {ratio:.2f}x faster (median)")
        apart = max(
            abs(mine / theirs - 1.0)
            for row_mine, row_theirs in zip(results["this tree"], results["baseline"], strict=True)
            for mine, theirs in zip(row_mine, row_theirs, strict=True)
        )
        print(f"tau1, tau2 and tau1's interval: largest relative difference {apart:.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
