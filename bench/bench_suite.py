"""Where the test suite's time goes: CPU or waiting, and which files.

Runs the tests as ``make test`` does (``make pytest``: the real-time tests one at a time beside
the rest on every core at a lower priority, one BLAS thread per process; pytest arguments after
``--`` instead run one pytest, ``-n WORKERS --dist worksteal``, on what they select) with a plugin
(:mod:`suite_cpu_plugin`) that records each test's wall time and the CPU time of its worker
process and of the processes it started and reaped (node processes, CLI children, Dask
workers), and samples the machine's busy share from ``/proc/stat`` over the run. It prints
the run's wall time, the machine's busy share, the workers' idle seconds (wall minus the CPU of
the test and its children, summed over tests: what more workers than cores could fill) and
the files that take the most worker time. The node's fitting and diagnosis workers are forked
by a fork server (:mod:`tcomp_core.workers`), whose children a test never reaps: their CPU
shows as idle time of the tests that ran them, not as children.

Run::

    .venv/bin/python bench/bench_suite.py                      # the whole suite, as make test
    .venv/bin/python bench/bench_suite.py -- -m "not slow"     # as make test-fast
    .venv/bin/python bench/bench_suite.py --workers 3          # more workers than cores
    .venv/bin/python bench/bench_suite.py -- test              # all in one pytest, as before
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_compensate import BLAS_THREADS
from bench_realtime import machine_ticks

ROOT = Path(__file__).resolve().parent.parent


def run_suite(workers: str, pytest_args: list[str], record: Path) -> tuple[float, float, int]:
    """Run pytest; returns (wall s, machine busy share, exit code)."""
    env = {
        **os.environ,
        **dict.fromkeys(BLAS_THREADS, "1"),  # make test's: the workers already fill the cores
        "SUITE_CPU_RECORD": str(record),
        "PYTHONPATH": os.pathsep.join(
            filter(None, (str(Path(__file__).parent), os.environ.get("PYTHONPATH")))
        ),
    }
    if pytest_args:
        command = [sys.executable, "-m", "pytest", "-q", "-p", "suite_cpu_plugin"]
        command += ["-n", workers, "--dist", "worksteal", *pytest_args]
    else:
        command = ["make", "--no-print-directory", "pytest", f"PY={sys.executable}"]
        command += [f"PYTEST_WORKERS={workers}", "PYTEST_FLAGS=-q -p suite_cpu_plugin"]
    busy0, total0 = machine_ticks()
    start = time.perf_counter()
    code = subprocess.call(command, cwd=ROOT, env=env)
    wall = time.perf_counter() - start
    busy1, total1 = machine_ticks()
    return wall, (busy1 - busy0) / max(1, total1 - total0), code


def summary(rows: list[dict], wall: float, busy: float, top: int) -> str:
    """The report's text: totals, then the files by worker time."""
    files: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0, 0.0, 0.0])
    for row in rows:
        totals = files[row["id"].split("::")[0]]
        totals[0] += row["wall"]
        totals[1] += row["self"]
        totals[2] += row["children"]
        totals[3] += _idle_s(row["wall"], row["self"], row["children"])
    columns = zip(*files.values(), strict=True)
    worker_s, own_s, children_s, idle_s = (sum(column) for column in columns)
    cpu_s = own_s + children_s
    lines = [
        f"tests {len(rows)}, wall {wall:.1f} s, machine busy {100 * busy:.0f} %",
        f"worker time {worker_s:.0f} s: CPU of the tests and their children {cpu_s:.0f} s, "
        f"workers idle {idle_s:.0f} s (per test, wall less that CPU where it is more)",
        f"{'file':48} {'worker s':>9} {'CPU s':>8} {'children s':>11} {'idle s':>7}",
    ]
    ordered = sorted(files.items(), key=lambda item: -item[1][0])
    for name, (spent, own, children, idle) in ordered[:top]:
        lines.append(f"{name:48} {spent:9.1f} {own:8.1f} {children:11.1f} {idle:7.1f}")
    return "\n".join(lines)


def _idle_s(wall: float, own: float, children: float) -> float:
    """A test's idle worker time: its wall time less the CPU it and its children used."""
    return max(0.0, wall - own - children)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--workers", default="auto", help="pytest-xdist workers (-n)")
    parser.add_argument("--top", type=int, default=20, help="files listed")
    parser.add_argument("--json", type=Path, help="also write every test's figures here")
    parser.add_argument("pytest_args", nargs="*", help="pytest arguments (after --)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        record = Path(work) / "tests.jsonl"
        wall, busy, code = run_suite(args.workers, args.pytest_args, record)
        text = record.read_text() if record.exists() else ""
    rows = [json.loads(line) for line in text.splitlines() if line]
    if not rows:
        print(f"bench_suite: no test ran (pytest exit code {code})", file=sys.stderr)
        return 1
    print(summary(rows, wall, busy, args.top))
    if args.json:
        args.json.write_text(json.dumps({"wall_s": wall, "busy": busy, "tests": rows}))
    return code


if __name__ == "__main__":
    sys.exit(main())
