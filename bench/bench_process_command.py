"""``tcomp process BAG -o OUT --no-diagnose`` as a whole command, on a recorder-layout bag.

Issue 25 asks each campaign worker to run ``tcomp process`` at >= 1 M pairs/s as a whole command
(start-up, imports, reading, pairing, estimation with the default ml-eiv and φ measured in
every window, Kalman reconstruction, writing) on a 10-minute 5 kHz bag written the way a
recorder writes one (:mod:`recorder_bag`: messages interleaved one by one, 1 MB uncompressed
chunks, 3 M pairs). This benchmark generates that bag once (cached in ``--cache``), then runs
the command as a subprocess, ``--repeat`` times, and prints its wall time and pairs/s.

With ``--baseline-tree DIR`` (a checkout of another commit, e.g. a ``git worktree`` of main)
the command runs alternately from that tree and from this one (``PYTHONPATH``), so both see the
same load on a shared machine, and the table gives each one's best and median with the ratio
of this tree's pairs/s to the baseline's (wall and CPU time). ``--compare`` then runs each tree
once more and prints how far this tree's gas and ``/diagnostics`` (the τ history: each
re-estimation's τ, intervals, fit error, condition, as the node publishes them, 6 significant
digits) are from the baseline's: a speed-up must not move them beyond the estimator's noise.
``--profile FILE`` runs this tree's command once under :mod:`cProfile` and prints the functions
with the most cumulative and own time. ``--split`` runs this tree's command alternately with the
node's re-estimation period (``update_period_s``, 0.5 s) and with one of ``--sparse-period-s``
(10 s: 20 times fewer re-estimations), and prints what one re-estimation costs (the difference
over the difference in their number), what the rest of the command costs (reading, pairing,
Kalman filtering, writing, start-up), the pairs/s the command would reach were the
re-estimations free, and the time one re-estimation may take for 1 M pairs/s.

Usage: ``python bench/bench_process_command.py [--minutes 10] [--rate-hz 5000]
[--baseline-tree /work/wt-base] [--compare] [--profile out/process.prof] [--split]``.
"""

from __future__ import annotations

import argparse
import math
import os
import pstats
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from recorder_bag import recorder_bag

HERE = Path(__file__).resolve().parents[1]


def run_command(
    tree: Path, bag: Path, output: Path, extra: list[str], profile: Path | None = None
) -> tuple[float, float]:
    """Wall and CPU time (user + system) of one ``tcomp process`` run from ``tree``, seconds.

    The CPU time is the child's own: on a machine shared with other jobs it varies less
    than the wall time, which also counts the time the child waited for a core.
    """
    env = {**os.environ, "PYTHONPATH": str(tree)}
    # ``python -m`` puts the working directory first on sys.path: run from the tree itself.
    cwd = str(tree)
    prefix = [sys.executable]
    if profile is not None:
        prefix += ["-m", "cProfile", "-o", str(profile)]
    command = [*prefix, "-m", "tcomp_core.cli", "process", str(bag), "-o", str(output)]
    command += ["--no-diagnose", *extra]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def read_output(bag: Path) -> tuple[np.ndarray, list[dict[str, str]]]:
    """The gas temperatures (degrees C) and the /diagnostics key-values of an output bag."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from tcomp_core.io import GAS_TOPIC, read_topics

    batches, *_ = read_topics(bag, [GAS_TOPIC])
    typestore = get_typestore(Stores.ROS2_JAZZY)
    statuses = []
    with Reader(bag) as reader:
        wanted = [c for c in reader.connections if c.topic == "/diagnostics"]
        for connection, _, raw in reader.messages(wanted):
            array = typestore.deserialize_cdr(raw, connection.msgtype)
            statuses.append({kv.key: kv.value for kv in array.status[0].values})
    return np.asarray(batches[GAS_TOPIC].temperature), statuses


def compare(
    baseline: tuple[np.ndarray, list[dict[str, str]]],
    current: tuple[np.ndarray, list[dict[str, str]]],
) -> None:
    """Print how far this tree's gas and /diagnostics (the τ history) are from the baseline's."""
    print("outputs (bags, same input), this tree against the baseline:")
    old, new = baseline[0], current[0]
    relative = np.abs(new - old) / np.abs(old) if old.size == new.size else np.array([np.inf])
    print(f"  gas: {old.size} / {new.size} samples, max rel diff {relative.max():.3g}")
    statuses = list(zip(baseline[1], current[1], strict=False))
    print(f"  /diagnostics: {len(baseline[1])} / {len(current[1])} statuses")
    worst: dict[str, float] = {}
    unequal = 0
    for before, after in statuses:
        for key, value in before.items():
            if after.get(key) == value or key.startswith("latency"):
                continue
            unequal += 1
            try:
                a, b = float(value), float(after.get(key, "nan"))
            except ValueError:
                worst[key] = math.inf
                continue
            worst[key] = max(worst.get(key, 0.0), abs(b - a) / max(abs(a), 1e-300))
    print(f"  values printed differently: {unequal} of {sum(len(s) for s, _ in statuses)}")
    for key, value in sorted(worst.items(), key=lambda item: -item[1])[:12]:
        print(f"    {key}: max rel diff {value:.3g}")


def print_profile(path: Path, count: int = 30) -> None:
    """The functions with the most cumulative and own time of a cProfile dump."""
    stats = pstats.Stats(str(path))
    stats.sort_stats("cumulative").print_stats(count)
    stats.sort_stats("tottime").print_stats(count)


def timed_runs(
    bag: Path, cases: dict[str, tuple[Path, list[str]]], repeat: int
) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    """Wall and CPU seconds of ``repeat`` rounds of the command, the cases alternating.

    ``cases`` maps a name (printed) to (tree, extra options); each run's output is removed.
    """
    walls: dict[str, list[float]] = {name: [] for name in cases}
    cpus: dict[str, list[float]] = {name: [] for name in cases}
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(repeat):
            for number, (name, (tree, extra)) in enumerate(cases.items()):
                output = Path(tmp) / f"out_{run}_{number}"
                wall, cpu = run_command(tree, bag, output, extra)
                walls[name].append(wall)
                cpus[name].append(cpu)
                shutil.rmtree(output, ignore_errors=True)
                print(f"  run {run + 1} {name}: {wall:.2f} s wall, {cpu:.2f} s CPU", flush=True)
    return walls, cpus


def split_estimation(
    bag: Path, pairs: int, seconds: float, repeat: int, sparse_s: float, extra: list[str]
) -> None:
    """Print the command's cost split into its re-estimations and the rest (``--split``).

    Runs this tree's command ``repeat`` times at the node's re-estimation period and at
    ``sparse_s``, alternately; the medians of the two give the cost of one re-estimation
    (their difference over the difference in the number of re-estimations) and that of the
    rest, in wall and CPU seconds.
    """
    from tcomp_core.online import OnlineConfig

    period = OnlineConfig().update_period_s
    counts = {period: seconds / period, sparse_s: seconds / sparse_s}
    labels = {every: f"re-estimation every {every:g} s" for every in counts}
    cases = {labels[every]: (HERE, [*extra, f"--update-period-s={every}"]) for every in counts}
    walls, cpus = timed_runs(bag, cases, repeat)
    wall = {every: statistics.median(walls[label]) for every, label in labels.items()}
    cpu = {every: statistics.median(cpus[label]) for every, label in labels.items()}
    extra_count = counts[period] - counts[sparse_s]
    per_wall = (wall[period] - wall[sparse_s]) / extra_count
    per_cpu = (cpu[period] - cpu[sparse_s]) / extra_count
    rest_wall = wall[sparse_s] - counts[sparse_s] * per_wall
    rest_cpu = cpu[sparse_s] - counts[sparse_s] * per_cpu
    budget = (pairs / 1e6 - rest_wall) / counts[period]
    print(f"split of this tree's command (medians of {repeat}):")
    for every, count in counts.items():
        print(
            f"  re-estimation every {every:g} s ({count:.0f} of them): {wall[every]:.2f} s wall "
            f"({pairs / wall[every]:.3g} pairs/s), {cpu[every]:.2f} s CPU"
        )
    print(f"  one re-estimation: {1e3 * per_wall:.2f} ms wall, {1e3 * per_cpu:.2f} ms CPU")
    print(
        f"  the rest (start-up, reading, pairing, filtering, writing): {rest_wall:.2f} s wall, "
        f"{rest_cpu:.2f} s CPU: {pairs / rest_wall:.3g} pairs/s were re-estimation free"
    )
    if budget > 0:
        print(
            f"  1 M pairs/s leaves {1e3 * budget:.3f} ms per re-estimation "
            f"({per_wall / budget:.1f}x less than it takes)"
        )
    else:
        print(
            "  1 M pairs/s is out of reach even with free re-estimations: the rest alone "
            f"takes {rest_wall:.2f} s for {pairs} pairs"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--rate-hz", type=int, default=5000)
    parser.add_argument("--cache", type=Path, default=Path("out/bench_process"))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline-tree", type=Path, default=None)
    parser.add_argument("--compare", action="store_true", help="compare the output bags")
    parser.add_argument("--profile", type=Path, default=None, help="cProfile dump to write")
    parser.add_argument(
        "--skip-timing",
        action="store_true",
        help="skip timing the trees against each other (--compare, --profile, --split still run)",
    )
    parser.add_argument(
        "--split", action="store_true", help="split this tree's time: re-estimations, the rest"
    )
    parser.add_argument(
        "--sparse-period-s", type=float, default=10.0, help="--split's sparse re-estimation period"
    )
    parser.add_argument("extra", nargs="*", help="further tcomp process options (after --)")
    args = parser.parse_args(argv)
    bag = (args.cache / f"recorder_{args.rate_hz}hz_{args.minutes:g}min").resolve()
    if not (bag / "metadata.yaml").is_file():
        shutil.rmtree(bag, ignore_errors=True)
        bag.parent.mkdir(parents=True, exist_ok=True)
        started = time.perf_counter()
        recorder_bag(bag, args.minutes, args.rate_hz)
        print(f"generated {bag} in {time.perf_counter() - started:.1f} s")
    pairs = round(args.minutes * 60 * args.rate_hz)
    size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    trees = [("this tree", HERE)]
    if args.baseline_tree is not None:
        trees.insert(0, ("baseline", args.baseline_tree.resolve()))
    print(f"bag: {bag} ({size_mb:.0f} MB, recorder layout), {pairs} pairs")
    cases = {name: (tree, args.extra) for name, tree in trees}
    walls, cpus = timed_runs(bag, cases, 0 if args.skip_timing else args.repeat)
    with tempfile.TemporaryDirectory() as tmp:
        if not args.skip_timing:
            print(f"tcomp process BAG -o OUT --no-diagnose {' '.join(args.extra)}")
            print(
                f"{'tree':<12} {'best s':>8} {'median s':>9} {'pairs/s':>10} {'median':>10} "
                f"{'CPU s':>8} {'pairs/CPU s':>12}"
            )
            rates, cpu_rates = {}, {}
            for name, _ in trees:
                best, median = min(walls[name]), statistics.median(walls[name])
                cpu = statistics.median(cpus[name])
                rates[name], cpu_rates[name] = pairs / median, pairs / cpu
                print(
                    f"{name:<12} {best:>8.2f} {median:>9.2f} {pairs / best:>10.4g} "
                    f"{pairs / median:>10.4g} {cpu:>8.2f} {pairs / cpu:>12.4g}"
                )
            if "baseline" in rates:
                print(
                    "this tree / baseline: "
                    f"{rates['this tree'] / rates['baseline']:.2f}x (median wall pairs/s), "
                    f"{cpu_rates['this tree'] / cpu_rates['baseline']:.2f}x (median CPU)"
                )
        if args.compare and args.baseline_tree is not None:
            outputs = {}
            for name, tree in trees:
                output = Path(tmp) / f"compared_{name.replace(' ', '_')}"
                run_command(tree, bag, output, args.extra)
                outputs[name] = read_output(output)
                shutil.rmtree(output, ignore_errors=True)
            compare(outputs["baseline"], outputs["this tree"])
        if args.profile is not None:
            args.profile = args.profile.resolve()
            output = Path(tmp) / "profiled"
            wall, _ = run_command(HERE, bag, output, args.extra, profile=args.profile)
            print(f"profiled run (this tree): {wall:.2f} s under cProfile")
            print_profile(args.profile)
    if args.split:
        split_estimation(
            bag, pairs, args.minutes * 60.0, args.repeat, args.sparse_period_s, args.extra
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
