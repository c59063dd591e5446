"""How long the Kalman signal-model fit takes, against a baseline commit measured in the same run.

Every gas the tools publish by default comes through a signal model fitted by maximum likelihood
(:func:`tcomp_core.fusion.fitting.fit_signal_models`: all five models, a few hundred
evaluations of the innovation likelihood): ``tcomp reconstruct``'s smoother on the whole
record, ``tcomp process`` and the node's causal filter on 4096 pairs of the stream. This bench
fits them on records simulated by each code alike (the paper's τ1 = 23.8 ms, τ2 = 116.8 ms;
sinusoid, ramp, multisine and exhaust pulses at 500, 2 000 and 5 000 Hz, K = 0.5 and 2 %, 4096
samples each) and runs :func:`tcomp_core.fusion.fuse` on the paper's 10 s records, in a child
process per code (the baseline's ``git archive`` first on ``PYTHONPATH``, as
``bench/bench_diagnose_speed.py`` does), alternating which code goes first.

It prints per group of records the CPU seconds of each code and their ratio (baseline /
current: above 1 the current code is faster), whether both ranked the same models in the same
order, the largest relative difference of any hyper-parameter and log-likelihood, and the
smoother's gas error e_Tg (%) against the true gas for both. A child's first fit (imports,
numba loading or compiling its kernels) is timed apart as ``start``.

Usage::

    PYTHONPATH=. .venv/bin/python bench/bench_signal_model_fit.py [--baseline REF] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench_diagnose_speed import child_environment, differences, merge_base, unpack_baseline

REPOSITORY = Path(__file__).resolve().parents[1]
KINDS = ("sinusoid", "ramp", "multisine", "exhaust")
RATES_HZ = (500.0, 2000.0, 5000.0)
NOISE_PERCENT = (0.5, 2.0)
SAMPLES = 4096


def child(out: str) -> None:
    """Fit every record with whichever ``tcomp_core`` is first on the path; write to ``out``."""
    started = time.process_time()
    from tcomp_core.fusion import fuse
    from tcomp_core.fusion.fitting import fit_signal_models
    from tcomp_core.metrics import reconstruction_error_percent
    from tcomp_core.simulate import simulate_pair

    tau1, tau2 = 0.0238, 0.1168
    warm = simulate_pair("multisine", tau1=tau1, tau2=tau2, duration=1.0, noise_percent=1.0)
    fit_signal_models(warm.tc1, warm.tc2, warm.dt, tau1, tau2)
    document: dict[str, Any] = {"start_s": time.process_time() - started, "fits": {}, "fuse": {}}
    for kind in KINDS:
        for rate in RATES_HZ:
            for noise in NOISE_PERCENT:
                pair = simulate_pair(
                    kind,
                    tau1=tau1,
                    tau2=tau2,
                    dt=1.0 / rate,
                    duration=SAMPLES / rate,
                    noise_percent=noise,
                    seed=7,
                    warmup=0.5,
                )
                begin = time.process_time()
                fits = fit_signal_models(pair.tc1, pair.tc2, pair.dt, tau1, tau2)
                document["fits"][f"{kind} {rate:g} Hz K={noise:g}"] = {
                    "cpu_s": time.process_time() - begin,
                    "ranked": [
                        [m.kind, ll, m.q, m.freq_hz, m.level_q, m.order, list(m.ar)]
                        for m, ll in fits.ranked
                    ],
                }
    for kind in KINDS:
        pair = simulate_pair(kind, tau1=tau1, tau2=tau2, noise_percent=2.0, seed=7)
        begin = time.process_time()
        result = fuse(pair.tc1, pair.tc2, pair.dt, tau1, tau2)
        truth = pair.gas[: result.gas.size]
        document["fuse"][kind] = {
            "cpu_s": time.process_time() - begin,
            "model": result.kind,
            "error_pct": reconstruction_error_percent(truth, result.gas),
        }
    Path(out).write_text(json.dumps(document, default=float))


def run_child(root: Path, scratch: Path) -> dict[str, Any]:
    """The child with ``root``'s code first on the path."""
    out = scratch / "fits.json"
    environment = child_environment(root)
    for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        environment.setdefault(name, "1")
    command = [sys.executable, str(Path(__file__).resolve()), "--child", str(out)]
    subprocess.run(command, env=environment, check=True, cwd=REPOSITORY)
    return json.loads(out.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", help="commit to compare with (default: merge base)")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each code (default 2)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    baseline = args.baseline or merge_base()
    with tempfile.TemporaryDirectory() as directory:
        scratch = Path(directory)
        codes = {"baseline": unpack_baseline(baseline, scratch), "current": REPOSITORY}
        runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "current": []}
        for repeat in range(args.repeats):
            order = ["baseline", "current"] if repeat % 2 == 0 else ["current", "baseline"]
            for name in order:
                runs[name].append(run_child(codes[name], scratch))
    print(f"baseline {baseline}; current {REPOSITORY}; median of {args.repeats} runs each")
    old, new = runs["baseline"][0], runs["current"][0]
    start = [statistics.median(run["start_s"] for run in runs[name]) for name in runs]
    print(f"start (imports, first fit): {start[0]:.2f} s baseline, {start[1]:.2f} s current")
    print(f"{'signal':10s} {'baseline s':>10s} {'current s':>10s} {'ratio':>6s}  same  largest")
    totals = [0.0, 0.0]
    for kind in KINDS:
        keys = [key for key in old["fits"] if key.startswith(kind + " ")]
        seconds = [
            statistics.median(sum(run["fits"][key]["cpu_s"] for key in keys) for run in runs[n])
            for n in runs
        ]
        totals = [total + value for total, value in zip(totals, seconds, strict=True)]
        same = all(
            [row[0] for row in old["fits"][key]["ranked"]]
            == [row[0] for row in new["fits"][key]["ranked"]]
            for key in keys
        )
        largest = max(
            differences(old["fits"][key]["ranked"], new["fits"][key]["ranked"])[0] for key in keys
        )
        print(
            f"{kind:10s} {seconds[0]:10.2f} {seconds[1]:10.2f} {seconds[0] / seconds[1]:6.2f}"
            f"  {'yes' if same else 'NO ':4s} {largest:.1e}"
        )
    print(f"{'all':10s} {totals[0]:10.2f} {totals[1]:10.2f} {totals[0] / totals[1]:6.2f}")
    print(
        f"\n{'fuse, 10 s':10s} {'baseline s':>10s} {'current s':>10s} {'ratio':>6s}  e_Tg % (b/c)"
    )
    for kind in KINDS:
        seconds = [statistics.median(run["fuse"][kind]["cpu_s"] for run in runs[n]) for n in runs]
        errors = (old["fuse"][kind]["error_pct"], new["fuse"][kind]["error_pct"])
        models = (old["fuse"][kind]["model"], new["fuse"][kind]["model"])
        print(
            f"{kind:10s} {seconds[0]:10.2f} {seconds[1]:10.2f} {seconds[0] / seconds[1]:6.2f}"
            f"  {errors[0]:.4f} / {errors[1]:.4f}"
            + ("" if models[0] == models[1] else f"  models {models[0]} / {models[1]}")
        )


if __name__ == "__main__":
    main()
