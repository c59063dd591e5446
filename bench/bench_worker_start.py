"""A job worker's first job: the CPU it spends before its work, with the fork server's preload.

The node's signal-model fits and diagnoses run in worker processes forked from a fork server
(:mod:`tcomp_core.workers`), which imports :data:`~tcomp_core.workers.WORKER_PRELOAD` before it
forks. Whatever the server has not done, each worker does on its first job: before
:mod:`tcomp_core.worker_preload`, every worker imported numba and built its typing and target
contexts on its first compiled loop, and imported ``tcomp_core.online`` to unpickle a job.

This benchmark runs, in a fresh process per configuration, ``--workers`` workers one after
another (a fresh :class:`~tcomp_core.workers.ProcessRunner` each, as a node restarting a dead
worker gets). Each worker runs the same signal-model fit twice on a fixed simulated pair and
reports its own CPU time: before the job (since its fork: its start-up job and the imports the
job's arguments needed), and for each fit. Configurations: the project's preload, and the baseline
``("__main__", "tcomp_core.diagnose", "tcomp_core.fusion")`` (the preload before
:mod:`tcomp_core.worker_preload`). They alternate ``--repeats`` times, so a busy moment of the
machine hits both. Per configuration it prints the medians of the fork server's own CPU (its
preload, once per process that starts workers), the worker's start-up, the first and the second
fit, and the overhead: what a fresh worker spends that a warm one does not (start-up plus the
first fit's excess over the second). Last, how much less overhead this preload leaves each
worker than the baseline, and after how many workers the server's extra start-up is paid back.

Usage: ``python bench/bench_worker_start.py [--workers 4] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from typing import TYPE_CHECKING

from tcomp_core import workers as job_workers

if TYPE_CHECKING:
    from tcomp_core.simulate import SimulatedPair

#: The fork server's preload before :mod:`tcomp_core.worker_preload` existed.
BASELINE_PRELOAD = ("__main__", "tcomp_core.diagnose", "tcomp_core.fusion")
#: The environment variable that selects the baseline. It is read where this module is
#: imported: in the measuring process (its fork server's preload), in the fork server (which
#: imports this script as the caller's main module) and so in every worker it forks (whose
#: start-up job imports the preload's modules).
BASELINE_VARIABLE = "BENCH_WORKER_PRELOAD_BASELINE"
if os.environ.get(BASELINE_VARIABLE):
    job_workers.WORKER_PRELOAD = BASELINE_PRELOAD
#: The simulated pair: 2 s at 1 kHz of the paper's sinusoid, K = 1 %, the paper's τ.
DT, DURATION_S, NOISE_PERCENT = 1e-3, 2.0, 1.0


def _pair() -> SimulatedPair:
    # Imported here: the fork server imports this script, and its own CPU is one of the figures.
    from tcomp_core.simulate import simulate_pair

    return simulate_pair("sinusoid", dt=DT, duration=DURATION_S, noise_percent=NOISE_PERCENT)


def _two_fits(pair: SimulatedPair) -> tuple[float, float, float]:
    """The job: the worker's CPU before it (since its fork: its start-up job, the imports its
    arguments needed), then for a first and a second identical signal-model fit, s."""
    times = [time.process_time()]
    from tcomp_core.fusion import fit_signal_models

    for _ in range(2):
        started = time.process_time()
        fit_signal_models(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
        times.append(time.process_time() - started)
    return times[0], times[1], times[2]


def _process_cpu_s(pid: int) -> float:
    """User plus system CPU of process ``pid`` so far, s (Linux ``/proc``)."""
    with open(f"/proc/{pid}/stat") as handle:
        fields = handle.read().rpartition(")")[2].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _child(workers: int) -> dict:
    """Run ``workers`` fresh workers, one after another; their CPU and the fork server's."""
    import multiprocessing.forkserver

    pair = _pair()
    fits = []
    for _ in range(workers):
        runner = job_workers.ProcessRunner()
        try:
            if not runner.submit(_two_fits, pair):
                raise RuntimeError("the runner refused the job")
            outcome = None
            while outcome is None:
                time.sleep(0.005)
                outcome = runner.poll()
            if outcome.error:
                raise RuntimeError(outcome.error)
            fits.append(outcome.value)
        finally:
            runner.close()
    server = multiprocessing.forkserver._forkserver._forkserver_pid  # type: ignore[attr-defined]
    return {"server_cpu_s": _process_cpu_s(server), "fits": fits}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--workers", type=int, default=4, help="fresh workers per process")
    parser.add_argument("--repeats", type=int, default=3, help="processes per configuration")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(_child(args.workers)))
        return
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    env.pop(BASELINE_VARIABLE, None)
    configurations = {"project": env, "baseline": {**env, BASELINE_VARIABLE: "1"}}
    runs: dict[str, list[dict]] = {name: [] for name in configurations}
    command = [sys.executable, __file__, "--child", "--workers", str(args.workers)]
    for _ in range(args.repeats):
        for name, child_env in configurations.items():
            output = subprocess.run(
                command, env=child_env, check=True, capture_output=True, text=True
            )
            runs[name].append(json.loads(output.stdout.strip().splitlines()[-1]))
    print(
        f"{args.workers} fresh workers per process, {args.repeats} processes per preload; "
        "CPU seconds, medians"
    )
    print(
        f"{'preload':<10} {'server':>8} {'start-up':>9} {'1st fit':>8} {'2nd fit':>8} "
        f"{'overhead':>9}"
    )
    summary = {}
    for name, results in runs.items():
        server = statistics.median(r["server_cpu_s"] for r in results)
        start, first, second = (
            statistics.median(f[i] for r in results for f in r["fits"]) for i in range(3)
        )
        # What a fresh worker spends that a warm one does not: its start-up and its first
        # fit's excess over the second.
        overhead = statistics.median(f[0] + f[1] - f[2] for r in results for f in r["fits"])
        summary[name] = (server, overhead)
        print(f"{name:<10} {server:8.3f} {start:9.3f} {first:8.3f} {second:8.3f} {overhead:9.3f}")
    (server, excess), (base_server, base_excess) = summary["project"], summary["baseline"]
    saved = base_excess - excess
    print(f"each fresh worker: {saved:.3f} s of CPU less overhead than with the baseline")
    extra = server - base_server
    if saved > 0:
        print(
            f"the server's preload costs {extra:+.3f} s once per process: repaid after "
            f"{max(0.0, extra) / saved:.1f} workers (the node starts two)"
        )


if __name__ == "__main__":
    main()
