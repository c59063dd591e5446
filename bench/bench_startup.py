"""Start-up time of the ``tcomp`` command line against a bare interpreter, in the same run.

Each command runs ``--repeats`` times in a fresh process (alternating between commands, so
a busy moment of the machine hits all of them alike); the table gives the median and the
fastest wall time and the median minus that of ``python -c pass``, the interpreter's own
start-up. ``--ref REV`` also times the ``tcomp_core`` of a git revision (extracted with ``git
archive`` into a temporary directory, e.g. ``--ref HEAD`` before a change is committed) so a
before/after comparison comes from one run on one machine. Goal: ``tcomp --help`` and
``tcomp VERB --help`` in <= 0.3 s.

Usage: ``python bench/bench_startup.py [--repeats 15] [--ref REV]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GOAL_S = 0.3
#: ``tcomp ARGS`` run the way the console script runs it.
TCOMP = "import sys; from tcomp_core.cli import main; sys.argv[0] = 'tcomp'; sys.exit(main())"


def _time_once(command: list[str], env: dict[str, str], cwd: Path) -> float:
    started = time.perf_counter()
    subprocess.run(command, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def _extract(rev: str, into: Path) -> Path:
    """Extract ``tcomp_core`` of git revision ``rev`` under ``into``; returns ``into``."""
    archive = subprocess.run(
        ["git", "archive", "--format=tar", rev, "tcomp_core"],
        cwd=ROOT,
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into


def _cases(ref_path: Path | None, ref: str) -> list[tuple[str, list[str], dict[str, str]]]:
    """(label, command, environment) of each timed command; the baseline first."""
    python = sys.executable
    here = {**os.environ, "PYTHONPATH": str(ROOT)}
    cases = [
        ("python -c pass (baseline)", [python, "-c", "pass"], here),
        ("python -c 'import numpy' (for scale)", [python, "-c", "import numpy"], here),
        ("tcomp --help", [python, "-c", TCOMP, "--help"], here),
        ("tcomp estimate --help", [python, "-c", TCOMP, "estimate", "--help"], here),
        ("tcomp process --help", [python, "-c", TCOMP, "process", "--help"], here),
        ("tcomp --version", [python, "-c", TCOMP, "--version"], here),
    ]
    script = Path(python).with_name("tcomp")  # the console script, if installed
    if script.is_file():
        cases.append(("tcomp --help (console script)", [str(script), "--help"], here))
    if ref_path is not None:
        old = {**os.environ, "PYTHONPATH": str(ref_path)}
        cases += [
            (f"tcomp --help ({ref})", [python, "-c", TCOMP, "--help"], old),
            (f"tcomp estimate --help ({ref})", [python, "-c", TCOMP, "estimate", "--help"], old),
        ]
    return cases


def _check_source(env: dict[str, str], expected: Path, cwd: Path) -> None:
    """Make sure ``env`` imports ``tcomp_core`` from ``expected`` (not another copy)."""
    where = subprocess.run(
        [sys.executable, "-c", "import tcomp_core; print(tcomp_core.__file__)"],
        env=env,
        cwd=cwd,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    if not Path(where).is_relative_to(expected):
        raise SystemExit(f"tcomp_core came from {where}, not from {expected}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15, help="runs per command (default 15)")
    parser.add_argument("--ref", help="also time tcomp_core of this git revision, e.g. HEAD")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_startup_") as scratch:
        # Run from an empty directory: ``python -c`` puts the working directory first on
        # sys.path, where a tcomp_core would shadow the one PYTHONPATH names.
        cwd = Path(scratch) / "cwd"
        cwd.mkdir()
        ref_path = _extract(args.ref, Path(scratch) / "ref") if args.ref else None
        cases = _cases(ref_path, args.ref or "")
        for _, _, env in cases:
            _check_source(env, Path(env["PYTHONPATH"]), cwd)
        times: list[list[float]] = [[] for _ in cases]
        for _ in range(args.repeats):
            for index, (_, command, env) in enumerate(cases):
                times[index].append(_time_once(command, env, cwd))
    base = statistics.median(times[0])
    load = os.getloadavg()[0]
    print(f"{args.repeats} runs each, {sys.executable}, load average {load:.1f}")
    print(f"{'command':<44} {'median s':>9} {'min s':>8} {'- baseline s':>13}")
    for (label, _, _), samples in zip(cases, times, strict=True):
        median = statistics.median(samples)
        print(f"{label:<44} {median:>9.3f} {min(samples):>8.3f} {median - base:>13.3f}")
    ref = args.ref or ""
    worst = max(
        statistics.median(samples)
        for (label, _, _), samples in zip(cases, times, strict=True)
        if label.startswith("tcomp") and (ref == "" or not label.endswith(f"({ref})"))
    )
    verdict = "PASS" if worst <= GOAL_S else "MISS"
    print(f"{verdict}: slowest tcomp start-up {worst:.3f} s (goal <= {GOAL_S:g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
