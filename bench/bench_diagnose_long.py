"""``tcomp diagnose`` on long bags: whole record against windows streamed from the file.

Generates (once, cached in ``--cache``, ``out/bench_diagnose_long/`` by default: the bags stay
out of the repository) a 10-minute and a one-hour 5 kHz two-sensor bag the way
``bench/bench_process.py`` writes its bag (the recorder's chunk writer, block by block: a
seeded 1 Hz + 10 Hz gas through the paper's two first-order lags, 0.3 °C noise). Then, in the
same run, each ``tcomp diagnose`` in a child process of its own, timed and with its peak
resident memory (``os.wait4``'s ``ru_maxrss`` of that child):

- ``whole``: ``--whole`` on the 10-minute bag, the baseline (what ``tcomp diagnose`` did
  before it streamed windows; not run on the one-hour bag, which would need ~28 GB);
- ``windows``: the default on the 10-minute bag (windows of 60 s, chosen automatically);
- ``windows``: the default on the one-hour bag;
- ``jobs N`` (with ``--jobs N``): the default windows diagnosed in N worker processes
  (``tcomp diagnose --jobs N``), on each bag, beside the one-process run of the same bag.

``peak MB`` is the child's own peak resident memory (``ru_maxrss``); ``tree MB`` the largest
proportional set size (PSS: each page shared between processes counted once, in shares)
summed over the child and its descendants, sampled every 0.2 s (psutil): with worker
processes forked from one fork server, a sum of their resident sizes would count the pages
they share with it (the imported core, about 85 MB) once per process.

It prints a table with the ratios against the baseline and whether the 10-minute bag's verdict
and τ agree between the whole record and its windows (the median over the windows giving the
verdict), and the resident memory per minute of record of each run.

Usage: ``python bench/bench_diagnose_long.py [--window-s 60] [--no-long] [--no-whole]
[--jobs 2]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import bench_process
import psutil  # a dependency of dask.distributed (tcomp campaign)

REPOSITORY = Path(__file__).resolve().parents[1]
MIB = 1024.0


@dataclass
class Run:
    """One child run of ``tcomp diagnose`` and what it found."""

    name: str
    minutes: float
    seconds: float
    peak_mib: float
    verdict: str
    tau1: float
    tau2: float
    tau1_95: tuple[float, float] | None = None
    tau2_95: tuple[float, float] | None = None
    windows: int = 1
    tree_mib: float = float("nan")


def cached_bag(cache: Path, minutes: float) -> Path:
    """The cached 5 kHz bag of ``minutes`` minutes, written on first use."""
    path = cache / f"sine_5khz_{minutes:g}min"
    if not path.exists():
        partial = cache / f".{path.name}.partial"
        if partial.exists():
            for child in sorted(partial.rglob("*"), reverse=True):
                child.unlink() if child.is_file() else child.rmdir()
            partial.rmdir()
        started = time.perf_counter()
        bench_process.make_bag(partial, minutes)
        partial.rename(path)
        print(f"wrote {path} in {time.perf_counter() - started:.1f} s", flush=True)
    return path


def _tree_pss_mib(root: int) -> float:
    """Proportional set size of process ``root`` and all its descendants, MiB (psutil)."""
    try:
        parent = psutil.Process(root)
        processes = [parent, *parent.children(recursive=True)]
    except psutil.Error:  # the child has ended
        return 0.0
    total = 0
    for process in processes:
        with contextlib.suppress(psutil.Error):  # a worker that ended meanwhile
            total += process.memory_full_info().pss
    return total / MIB / MIB


class _TreeSampler(threading.Thread):
    """Samples the largest proportional set size of a process tree every 0.2 s."""

    def __init__(self, root: int) -> None:
        super().__init__(daemon=True)
        self.root, self.peak_mib = root, 0.0
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.wait(0.2):
            self.peak_mib = max(self.peak_mib, _tree_pss_mib(self.root))


def diagnose_in_child(name: str, bag: Path, minutes: float, options: list[str]) -> Run:
    """Run ``tcomp diagnose`` in a child process; its wall time, peak RSS and result.

    The peak is the child's own (``ru_maxrss``), or the sampled peak of the child and its
    descendants when that is larger (worker processes).
    """
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "diagnosis.json"
        command = [sys.executable, "-m", "tcomp_core.cli", "diagnose", str(bag)]
        command += [*options, "--json", str(out)]
        environment = dict(os.environ)
        environment["PYTHONPATH"] = os.pathsep.join(
            [str(REPOSITORY), *filter(None, [environment.get("PYTHONPATH")])]
        )
        started = time.perf_counter()
        child = subprocess.Popen(command, env=environment, stdout=subprocess.PIPE, text=True)
        sampler = _TreeSampler(child.pid)
        sampler.start()
        assert child.stdout is not None
        printed = child.stdout.read()
        sampler.done.set()
        sampler.join()
        _, status, usage = os.wait4(child.pid, 0)
        child.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - started
        if child.returncode != 0:
            raise SystemExit(f"{' '.join(command)} failed ({child.returncode}):\n{printed}")
        document = json.loads(out.read_text())
    peak = usage.ru_maxrss / MIB  # kB on Linux
    if "windows" in document:  # the whole verdict and τ drawn from the windows
        taus = [document[name] for name in ("tau1", "tau2")]
        found = [tau["median"] for tau in taus]
        spreads = [(tau["min"], tau["max"]) for tau in taus]
        windows = len(document["windows"])
    else:
        final = document["final"]
        found = [final["tau1"], final["tau2"]]
        spreads = [tuple(final["intervals_95"].get(name, ())) or None for name in ("tau1", "tau2")]
        windows = 1
    return Run(
        name,
        minutes,
        seconds,
        peak,
        document["verdict"],
        *found,
        *spreads,
        windows=windows,
        tree_mib=sampler.peak_mib,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=Path("out/bench_diagnose_long"))
    parser.add_argument("--short-minutes", type=float, default=10.0)
    parser.add_argument("--long-minutes", type=float, default=60.0)
    parser.add_argument(
        "--window-s", type=float, help="window length (default: the automatic choice)"
    )
    parser.add_argument("--no-long", action="store_true", help="skip the one-hour bag")
    parser.add_argument("--no-whole", action="store_true", help="skip the whole-record baseline")
    parser.add_argument(
        "--jobs", type=int, default=1, help="also diagnose each bag's windows in N processes"
    )
    args = parser.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    short = cached_bag(args.cache, args.short_minutes)
    long = None if args.no_long else cached_bag(args.cache, args.long_minutes)
    windowed = [] if args.window_s is None else ["--window-s", f"{args.window_s:g}"]
    runs: list[Run] = []
    parallel = [] if args.jobs == 1 else ["--jobs", str(args.jobs)]
    plan = [
        *([] if args.no_whole else [("whole", short, args.short_minutes, ["--whole"])]),
        ("windows", short, args.short_minutes, windowed),
        *(
            [(f"jobs {args.jobs}", short, args.short_minutes, windowed + parallel)]
            if parallel
            else []
        ),
        *([] if long is None else [("windows", long, args.long_minutes, windowed)]),
        *(
            [(f"jobs {args.jobs}", long, args.long_minutes, windowed + parallel)]
            if parallel and long is not None
            else []
        ),
    ]
    for name, bag, minutes, options in plan:
        print(f"running {name} on {bag.name} ...", flush=True)
        runs.append(diagnose_in_child(name, bag, minutes, options))
    baseline = runs[0] if not args.no_whole else None
    print()
    print(
        f"{'run':<8} {'record':>7} {'windows':>7} {'wall s':>8} {'peak MB':>8} {'tree MB':>8} "
        f"{'MB/min':>7} {'x wall':>7} {'x peak':>7}  {'verdict':<10} {'tau1 s':>9} {'tau2 s':>9}"
    )
    for run in runs:
        ratios = (
            f"{run.seconds / baseline.seconds:>7.2f} {run.peak_mib / baseline.peak_mib:>7.2f}"
            if baseline is not None
            else f"{'-':>7} {'-':>7}"
        )
        print(
            f"{run.name:<8} {run.minutes:>5g} m {run.windows:>7} {run.seconds:>8.1f} "
            f"{run.peak_mib:>8.0f} {run.tree_mib:>8.0f} {run.peak_mib / run.minutes:>7.1f} "
            f"{ratios}  "
            f"{run.verdict:<10} {run.tau1:>9.5g} {run.tau2:>9.5g}"
        )
    for run in runs:
        if not run.name.startswith("jobs"):
            continue
        alone = next(r for r in runs if r.name == "windows" and r.minutes == run.minutes)
        same = (run.verdict, run.tau1, run.tau2) == (alone.verdict, alone.tau1, alone.tau2)
        print(
            f"{run.minutes:g}-minute bag in {args.jobs} processes against one: "
            f"{alone.seconds / run.seconds:.2f}x faster, {run.tree_mib:.0f} MB over all its "
            f"processes against {alone.tree_mib:.0f} ({run.tree_mib / alone.tree_mib:.2f}x), "
            f"verdict and tau {'identical' if same else 'DIFFERENT'}"
        )
    if baseline is not None:
        same = next(run for run in runs[1:] if run.minutes == baseline.minutes)
        print()
        print(f"{args.short_minutes:g}-minute bag, whole record against its windows:")
        print(f"  verdict: {baseline.verdict} / {same.verdict}: ", end="")
        print("same" if baseline.verdict == same.verdict else "DIFFERENT")
        for name, whole, median, interval, spread in (
            ("tau1", baseline.tau1, same.tau1, baseline.tau1_95, same.tau1_95),
            ("tau2", baseline.tau2, same.tau2, baseline.tau2_95, same.tau2_95),
        ):
            inside = "inside" if interval and interval[0] <= median <= interval[1] else "outside"
            print(
                f"  {name}: whole {whole:.6g} s (95 % {interval[0]:.6g} .. {interval[1]:.6g}), "
                if interval
                else f"  {name}: whole {whole:.6g} s, ",
                end="",
            )
            print(
                f"windows' median {median:.6g} s (windows {spread[0]:.6g} .. {spread[1]:.6g}): "
                if spread
                else f"windows' median {median:.6g} s: ",
                end="",
            )
            print(f"{100 * (median / whole - 1):+.3f} %, {inside} the whole record's interval")


if __name__ == "__main__":
    main()
