"""Soak bench: does the compensator's resident memory grow while it runs, and by how much an hour?

A node meant to run for weeks must not grow: 6.6 MB an hour is a gigabyte a week. This bench
samples the resident set size (``VmRSS`` of ``/proc/<pid>/status``) every ``--interval``
seconds and reports its growth as the least-squares slope of RSS against time over the samples
after ``--warmup`` seconds (start-up, the first window, the first fits and the allocator's
first arenas are not growth), with the first and last RSS after the warm-up and the number of
samples. The slope's standard error is printed too: a slope within two of them is noise. The
slope over the last two thirds of those samples is printed as well: the node settles for some
twenty minutes (+5.5 MiB/h over the first third of an hour), so an hour's whole slope is mostly
that settling and the late one is what it keeps growing by (run an hour to measure a week).

``--mode node`` (the default) – the real node
    ``python -m tcomp_ros.compensator`` (bench_realtime.py's ``NODE_PARAMETERS``: window 2 s,
    update 0.5 s; the default Kalman reconstruction unless ``-p reconstruction:=difference``)
    is fed at ``--rate`` per sensor by bench_realtime.py's *publisher* role, whose signal
    repeats every ``--loop-s`` seconds so that an hour's run does not hold an hour of samples.
    Beside it, subscribed to the same topics, runs bench_realtime.py's *counter* role: a bare
    rclpy subscriber spinning as the node does (EventsExecutor) that only counts; its growth,
    measured over the same seconds, is the baseline of rclpy and DDS at this rate, and the
    node's growth is also printed against it. The node's fitting and diagnosis worker
    processes are sampled too (their sum is printed, they are separate processes), and so is
    the publisher: a bare rclpy publisher of both inputs, keeping no per-batch records here,
    the baseline for the node's own publishing (the node publishes the gas at the pair rate).
    CPU % of the node and the machine is from bench_realtime.py's sampler. ``--node-env
    NAME=VALUE`` sets an environment variable of the node's process alone (its worker
    processes inherit it), e.g. ``PYTHONMALLOC=malloc`` to take Python's own allocator out.
    A run cut short (Ctrl-C, SIGTERM) prints the slopes of the samples it has.

``--mode engine`` – the node's engine alone, in this process
    :class:`tcomp_core.online.Engine` (the pair matcher, :class:`~tcomp_core.online.
    OnlineCompensator`, health and diagnosis the node holds) is driven as the node's timers
    drive it, on a simulated clock: every 5 ms of stream time the 25 new samples of each input
    (at 5 kHz) are added and reconstructed, τ is re-estimated every 0.5 s, a report is made every
    second (with the diagnosis' poll) and the periodic diagnosis ticks at its period. The
    runners are the node's (fits and diagnoses in a worker process, estimates on a thread)
    unless ``--inline``. By default the samples come as fast as the stream would deliver them
    (one drain per 5 ms of wall time); ``--unpaced`` drains as fast as the CPU allows, so a run
    covers more stream time than wall time (growth is then given per hour of stream too). No
    rclpy, no DDS: what grows here is the engine's. Beside RSS it prints the heap that glibc's
    malloc has in use (``mallinfo2``: ``uordblks`` + ``hblkhd``), which does not count freed
    memory kept by the allocator, so RSS growing while the heap in use does not is allocator
    retention (fragmentation, arenas), not a leak; the count of Python's own blocks
    (``sys.getallocatedblocks``) is printed as well. glibc's mmap threshold is pinned as the
    node's ``main()`` pins it (:mod:`tcomp_core.memory`), and so is the worker processes'
    (their RSS, summed, is sampled as well); ``--glibc-dynamic`` leaves it to glibc in all of
    them, as before, and ``--trim S`` calls ``malloc_trim(0)`` every S s of stream (to tell
    retention from use). ``--tracemalloc N`` starts tracing after the warm-up, takes a
    snapshot after another warm-up and one at the end, and prints the N biggest differences
    grouped by traceback (tracing slows the engine tenfold: use it to hunt, not to measure).
    In node mode ``--tracemalloc N`` runs the node through ``rt_node_trace.py``: its traced
    Python memory (every object and numpy buffer it holds) and tracemalloc's own tables (native
    memory, part of the RSS) are sampled beside its RSS and given slopes after twice the
    warm-up, with the N biggest differences; RSS that grows by more than those tables while
    the traced memory does not grows in native code (rclpy, the middleware, the C allocator).
    Tracing slows the node: give it a rate it keeps up with.

Run::

    cd /work/main && .venv/bin/python bench/bench_soak.py                  # node, 120 s
    .venv/bin/python bench/bench_soak.py --duration 3600                   # node, an hour
    .venv/bin/python bench/bench_soak.py --duration 3600 --node-env PYTHONMALLOC=malloc
    .venv/bin/python bench/bench_soak.py --mode engine                     # engine, 120 s
    .venv/bin/python bench/bench_soak.py --mode engine --unpaced --duration 240
    .venv/bin/python bench/bench_soak.py --mode engine --unpaced --duration 240 --glibc-dynamic
    .venv/bin/python bench/bench_soak.py --mode engine --unpaced --duration 300 --tracemalloc 12
    .venv/bin/python bench/bench_soak.py --rate 2000 --duration 1200 --tracemalloc 8
    MALLOC_ARENA_MAX=2 .venv/bin/python bench/bench_soak.py --mode engine --glibc-dynamic

The script exits 0 whatever the outcome; with ``--json PATH`` it also writes its figures there.
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import json
import math
import os
import shutil
import signal
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import bench_realtime as rt
import numpy as np

#: Default warm-up, s: the newest pairs the engine keeps (RECENT_S of them) fill over a minute.
WARMUP_S = 70.0
#: Drain period of the node (``tcomp_ros.compensator.PROCESS_PERIOD_S``), seconds.
DRAIN_S = 0.005
MIB = 1024.0 * 1024.0


def rss_bytes(pid: int | str = "self") -> int | None:
    """Resident set size of a process, bytes (VmRSS); None once it is gone."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return None


@dataclass
class Series:
    """Samples (wall time s, value bytes) of one measured quantity."""

    label: str
    times: list[float] = field(default_factory=list)
    values: list[float] = field(default_factory=list)

    def add(self, t: float, value: float | None) -> None:
        if value is not None:
            self.times.append(t)
            self.values.append(float(value))

    def growth(self, start: float, per: float = 3600.0) -> dict:
        """Least-squares slope (MiB per ``per`` s) over the samples at ``start`` or later.

        Also the slope over the last two thirds of those samples' span (``late_slope``,
        ``late_stderr``, from ``late_from_s``): a process that settles for tens of minutes
        (its heaps and rclpy's pools reaching their working size) has a whole-run slope that
        is mostly the settling; the late one is what it keeps growing by.
        """
        t = np.asarray(self.times)
        v = np.asarray(self.values) / MIB
        keep = t >= start
        t, v = t[keep], v[keep]
        result = {"label": self.label, "samples": int(t.size), "series": self}
        if t.size < 3 or np.ptp(t) <= 0.0:
            return {**result, "slope": math.nan, "stderr": math.nan, "first": math.nan,
                    "last": math.nan, "span_s": 0.0, "late_slope": math.nan,
                    "late_stderr": math.nan, "late_from_s": math.nan}  # fmt: skip
        slope, stderr = _slope(t, v)
        late_from = float(t[0] + (t[-1] - t[0]) / 3.0)
        late = t >= late_from
        late_slope, late_stderr = _slope(t[late], v[late]) if late.sum() >= 3 else (math.nan,) * 2
        return {
            **result,
            "slope": slope * per,
            "stderr": stderr * per,
            "first": float(v[0]),
            "last": float(v[-1]),
            "span_s": float(t[-1] - t[0]),
            "late_slope": late_slope * per,
            "late_stderr": late_stderr * per,
            "late_from_s": late_from,
        }


def _slope(t: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of ``v`` against ``t`` and its standard error (≥ 3 samples)."""
    tc = t - t.mean()
    slope = float(tc @ (v - v.mean()) / (tc @ tc))
    residual = v - v.mean() - slope * tc
    return slope, math.sqrt(float(residual @ residual) / (t.size - 2) / float(tc @ tc))


# ------------------------------------------------------------------------------------------------
# Engine mode
# ------------------------------------------------------------------------------------------------
def run_engine(args: argparse.Namespace) -> dict:
    """Drive the node's engine on a simulated clock; sample this process's memory."""
    import tracemalloc

    from tcomp_core.memory import heap_info, pin_mmap_threshold
    from tcomp_core.online import DIAGNOSTICS_PERIOD_S, Engine, OnlineConfig
    from tcomp_core.parameters import PARAMETERS
    from tcomp_core.simulate import simulate_pair
    from tcomp_core.workers import InlineRunner, ProcessRunner, ThreadRunner

    if not args.glibc_dynamic:
        pin_mmap_threshold()  # as the node's main() does
    values = {spec.name: spec.default for spec in PARAMETERS}
    values.update({name: _typed(values[name], v) for name, v in parameters(args).items()})
    config = OnlineConfig.from_parameters(values)
    workers: tuple[ProcessRunner, ...] = ()
    if args.inline:
        engine = Engine(config, diagnosis_runner=InlineRunner())
    else:
        fits = ProcessRunner(pin_heap=not args.glibc_dynamic)
        diagnoses = ProcessRunner(pin_heap=not args.glibc_dynamic)
        engine = Engine(
            config,
            runner=fits,
            diagnosis_runner=diagnoses,
            estimate_runner=ThreadRunner("tcomp-estimate"),
        )
        fits.start(wait_s=30.0)
        diagnoses.start(wait_s=30.0)
        workers = (fits, diagnoses)
    rate = round(args.rate)
    per_drain = round(rate * DRAIN_S)
    loop = round(args.loop_s * rate) // per_drain * per_drain
    sim = simulate_pair(
        "sinusoid",
        tau1=rt.SIGNAL["tau1"],
        tau2=rt.SIGNAL["tau2"],
        dt=1.0 / rate,
        duration=loop / rate,
        noise_percent=rt.SIGNAL["noise_percent"],
        signal_params={"freq_hz": rt.SIGNAL["freq_hz"]},
        seed=args.seed,
    )
    tc = (sim.tc1[:loop], sim.tc2[:loop])
    giga = 1_000_000_000
    t0_ns = 1_700_000_000 * giga
    update_s = float(values["update_period_s"])
    diagnosis_s = float(values["diagnosis_period_s"])
    libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    series = {
        "rss": Series("RSS"),
        "heap": Series("malloc heap in use"),
        "held": Series("malloc heap held"),
        "blocks": Series("Python blocks (x 64 B)"),
    }
    stream = Series("stream time")  # (wall, stream seconds): stream hours per wall hour
    if args.tracemalloc:
        series["traced"] = Series("tracemalloc traced")
    if not args.inline:
        series["workers"] = Series("worker processes' RSS")
    snapshots = []

    def sample(t: float, stream_s: float) -> None:
        series["rss"].add(t, rss_bytes())
        info = heap_info()
        if info is not None:
            series["heap"].add(t, info.in_use)
            series["held"].add(t, info.held)
        # Objects of pymalloc's own arenas (mmap, not malloc): a count, scaled to a typical
        # small object so that its slope reads next to the others.
        series["blocks"].add(t, 64 * sys.getallocatedblocks())
        if tracemalloc.is_tracing():
            series["traced"].add(t, tracemalloc.get_traced_memory()[0])
        if "workers" in series:
            sizes = [rss_bytes(pid) for runner in workers for pid in runner.worker_pids]
            if sizes and None not in sizes:  # a worker restarting is left out
                series["workers"].add(t, sum(size for size in sizes if size is not None))
        stream.add(t, stream_s)

    start = time.monotonic()
    next_sample = 0.0
    next_update, next_report = update_s, DIAGNOSTICS_PERIOD_S
    next_diagnosis = diagnosis_s if diagnosis_s > 0 else math.inf
    drains = published = 0
    next_trim = args.trim if args.trim > 0 else math.inf
    trim = libc.malloc_trim
    while True:
        wall = time.monotonic() - start
        if wall >= args.duration:
            break
        if not args.unpaced and drains * DRAIN_S > wall:
            time.sleep(drains * DRAIN_S - wall)
        k = (drains * per_drain) % loop
        stamps = t0_ns + (np.arange(per_drain) + drains * per_drain) * giga // rate
        now = (drains + 1) * DRAIN_S
        engine.add_samples(0, stamps, tc[0][k : k + per_drain], now)
        engine.add_samples(1, stamps, tc[1][k : k + per_drain], now)
        published += int(engine.reconstruct().stamps_ns.size)
        drains += 1
        if now >= next_update:
            engine.update_estimate(now)
            next_update += update_s
        if now >= next_report:
            engine.poll_diagnosis(now)
            engine.diagnosis.log = []  # the node logs and empties it at each report
            engine.report(now, new_period=True)
            next_report += DIAGNOSTICS_PERIOD_S
        if now >= next_diagnosis:
            engine.periodic_diagnosis(now)
            next_diagnosis += diagnosis_s
        if now >= next_trim:
            trim()
            next_trim += args.trim
        wall = time.monotonic() - start
        if wall >= next_sample:
            sample(wall, now)
            next_sample += args.interval
            # Tracing starts after the warm-up (it slows the engine tenfold); the reference
            # snapshot is taken once the traced blocks have turned over a warm-up more.
            if args.tracemalloc and not tracemalloc.is_tracing() and now >= args.warmup:
                tracemalloc.start(args.frames)
            if args.tracemalloc and not snapshots and now >= 2 * args.warmup:
                snapshots.append(tracemalloc.take_snapshot())
    sample(time.monotonic() - start, drains * DRAIN_S)
    # The warm-up is stream time: RecentPairs fills over RECENT_S of it, however fast it comes.
    reached = [t for t, s in zip(stream.times, stream.values, strict=True) if s >= args.warmup]
    warm_wall = reached[0] if reached else math.inf
    if args.tracemalloc and snapshots:
        top = tracemalloc.take_snapshot().compare_to(snapshots[0], "traceback")
        print(f"tracemalloc: the {args.tracemalloc} biggest differences since twice the warm-up")
        for stat in top[: args.tracemalloc]:
            print(f"  {stat.size_diff / 1024:+9.1f} KiB {stat.count_diff:+7d} blocks")
            for line in stat.traceback.format(limit=args.frames):
                print("     ", line)
    compensator = engine.compensator
    stream_s = drains * DRAIN_S
    wall_s = time.monotonic() - start
    engine.close()
    growths = [s.growth(warm_wall) for s in series.values()]
    speed = stream_s / wall_s
    return {
        "mode": "engine",
        "growth": growths,
        "stream_s": stream_s,
        "wall_s": wall_s,
        "stream_per_wall": speed,
        "published": published,
        "matched": engine.counters.matched,
        "tau": compensator.tau,
        "reconstruction": compensator.reconstruction,
        "runners": "inline" if args.inline else "node (worker process, thread)",
        "mmap_threshold": "dynamic (glibc)" if args.glibc_dynamic else "pinned",
    }


# ------------------------------------------------------------------------------------------------
# Node mode
# ------------------------------------------------------------------------------------------------
def run_node(args: argparse.Namespace) -> dict:
    """The node and a bare counter fed by one publisher; sample their memory."""
    workdir = Path(tempfile.mkdtemp(prefix="bench_soak_"))
    domain, env = rt.child_environment()
    children = rt.Children(workdir, env)
    sampler = rt.CpuSampler()
    print(f"bench_soak: ROS_DOMAIN_ID={domain}, work dir {workdir}", flush=True)
    node_args = argparse.Namespace(node_probe=False, node_profile=False)
    command = rt.node_command(node_args, workdir, parameters(args))
    trace = workdir / "node_trace.jsonl"
    if args.tracemalloc:  # the same node, its Python allocations traced (rt_node_trace.py)
        tracer = [sys.executable, str(Path(__file__).with_name("rt_node_trace.py"))]
        tracer += ["--out", str(trace), "--start", str(args.warmup)]
        tracer += ["--top", str(args.tracemalloc), "--frames", str(args.frames)]
        command = tracer + command[command.index("--ros-args") :]
    if args.node_env:  # the node's process alone (env execs it: the same pid)
        command = ["env", *args.node_env, *command]
    try:
        node = children.start("compensator", command)
        sampler.watch("compensator", node.pid)
        stop = workdir / "counter.stop"
        ready = workdir / "counter.ready"
        counter_out = workdir / "counter.json"
        counter = children.start_child(
            "counter", "counter", out=counter_out, stop=stop, ready=ready, timeline_s=3600.0
        )
        rt.wait_for_file(ready, children, ("compensator", "counter"), 60.0)
        out = workdir / "publisher.json"
        pub = children.start_child(
            "publisher",
            "publisher",
            out=out,
            rate=args.rate,
            duration=args.duration,
            pub_period_ms=1.0,
            loop_s=args.loop_s,
            batch_log=0,  # its per-batch records grew ~0.5 GB an hour: no baseline then
        )
        series = {"node": Series("node RSS"), "counter": Series("bare subscriber RSS")}
        series["workers"] = Series("node's worker processes RSS")
        series["publisher"] = Series("bare publisher RSS")
        start = time.monotonic()
        deadline = start + args.duration + 90.0
        next_sample = 0.0
        try:
            while pub.poll() is None:
                wall = time.monotonic() - start
                if wall >= next_sample:
                    series["node"].add(wall, rss_bytes(node.pid))
                    series["counter"].add(wall, rss_bytes(counter.pid))
                    workers = [rss_bytes(pid) for pid in _descendants(node.pid)]
                    series["workers"].add(wall, sum(w for w in workers if w is not None))
                    series["publisher"].add(wall, rss_bytes(pub.pid))
                    sampler.sample()
                    next_sample += args.interval
                children.check_alive("compensator", "counter")
                if time.monotonic() > deadline:
                    raise RuntimeError(
                        f"the publisher did not finish:\n{children.tail('publisher')}"
                    )
                time.sleep(0.05)
        except KeyboardInterrupt:  # a soak cut short still has its slopes so far
            print(f"interrupted after {time.monotonic() - start:.0f} s", file=sys.stderr)
            return {
                "mode": "node",
                "interrupted": True,
                "growth": [item.growth(args.warmup) for item in series.values()],
            }
        sampler.sample()
        if pub.returncode != 0 or not out.exists():
            raise RuntimeError(f"publisher failed:\n{children.tail('publisher')}")
        published = json.loads(out.read_text())
        time.sleep(rt.SETTLE_S)
        stop.write_text("stop")
        time.sleep(1.0)
        children.stop("counter")
        children.stop("compensator", signal.SIGINT, timeout=10.0)
        counted = json.loads(counter_out.read_text()) if counter_out.exists() else {}
        t0, t1 = published["t0_ns"], published["t_end_ns"]
        growth = [s.growth(args.warmup) for s in series.values()]
        top: list[dict] = []
        if args.tracemalloc and trace.exists():
            traced = Series("node: Python's traced memory")
            own = Series("node: tracemalloc's own tables")
            for line in trace.read_text().splitlines():
                entry = json.loads(line)
                if "t" in entry:  # the tracer's monotonic clock is this process's
                    traced.add(entry["t"] - start, entry["traced"])
                    own.add(entry["t"] - start, entry.get("own"))
                top = entry.get("top", top)
            # Tracing sees only blocks allocated after it starts: buffers made before are
            # counted as they are reallocated, so its first warm-up is left out as well.
            growth += [traced.growth(2 * args.warmup), own.growth(2 * args.warmup)]
        return {
            "mode": "node",
            "growth": growth,
            "traced_top": top,
            "pairs_sent": published["n"],
            "achieved_pairs_per_s": published["achieved_pairs_per_s"],
            "counter_received": counted.get("received"),
            "cpu_node_pct": sampler.percent("compensator", t0, t1),
            "machine_pct": sampler.machine_percent(t0, t1),
            "node_log_tail": children.tail("compensator", 5),
        }
    finally:
        children.stop_all()
        if args.keep:
            print(f"kept {workdir}")
        else:
            shutil.rmtree(workdir, ignore_errors=True)


def _typed(default: object, text: str) -> object:
    """``text`` (a ``-p`` value) as the type of the parameter's default."""
    if isinstance(default, bool):
        return text.strip().lower() == "true"
    return type(default)(text)


def _descendants(pid: int) -> list[int]:
    """Process ids of the live descendants of ``pid``."""
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            children = [int(child) for child in task.read_text().split()]
        except OSError:
            continue
        for child in children:
            found += [child, *_descendants(child)]
    return found


# ------------------------------------------------------------------------------------------------
def parameters(args: argparse.Namespace) -> dict[str, str]:
    """The node's parameters: bench_realtime.py's, then the ``-p`` ones."""
    return {**rt.NODE_PARAMETERS, **rt.node_parameters(args.node_param)}


def print_report(args: argparse.Namespace, result: dict) -> None:
    print("-" * 96)
    for g in result["growth"]:
        print(
            f"{g['label']:<32} {g['slope']:+8.2f} ± {g['stderr']:.2f} MiB/h   "
            f"{g['first']:8.1f} -> {g['last']:8.1f} MiB over {g['span_s']:.0f} s, "
            f"{g['samples']} samples"
        )
    late = result["growth"][0].get("late_from_s", math.nan)
    print(f"the last two thirds (from {late:.0f} s), when the settling is over:")
    for g in result["growth"]:
        print(f"  {g['label']:<30} {g['late_slope']:+8.2f} ± {g['late_stderr']:.2f} MiB/h")
    first = result["growth"][0]
    if result["mode"] == "node":
        base = result["growth"][1]
        ratio = first["slope"] / base["slope"] if base["slope"] else math.nan
        print(f"node against the bare subscriber, same run: {ratio:.2f} x its growth")
        if result.get("interrupted"):
            print("interrupted: the slopes of the samples so far; no CPU or message counts")
        elif result.get("traced_top"):
            print(
                f"node: the {len(result['traced_top'])} biggest traced differences since "
                "twice the warm-up"
            )
            for stat in result["traced_top"]:
                print(f"  {stat['size_diff'] / 1024:+9.1f} KiB {stat['count_diff']:+7d} blocks")
                print("\n".join(f"      {line}" for line in stat["traceback"][-4:]))
        if not result.get("interrupted"):
            print(
                f"pairs sent {result['pairs_sent']} at {result['achieved_pairs_per_s']:.0f}/s; "
                f"counter received {result['counter_received']} messages; node CPU "
                f"{result['cpu_node_pct']:.0f} %, machine {result['machine_pct']:.0f} %"
            )
    else:
        speed = result["stream_per_wall"]
        print(
            f"stream {result['stream_s']:.0f} s in {result['wall_s']:.0f} s of wall time "
            f"({speed:.2f} x real time), runners {result['runners']}, mmap threshold "
            f"{result['mmap_threshold']}; "
            f"{result['matched']} pairs matched, {result['published']} published, "
            f"τ {result['tau']}, {result['reconstruction']}"
        )
        if abs(speed - 1.0) > 0.05:
            print(f"  RSS per hour of stream: {first['slope'] / speed:+.2f} MiB")
    # A week of the stream (not of this run's wall time, when unpaced).
    per_week = 24 * 7 / result.get("stream_per_wall", 1.0)
    print(
        f"{first['label']} over a week of the stream: {first['slope'] * per_week:+.0f} MiB at "
        f"the whole run's slope, {first['late_slope'] * per_week:+.0f} MiB at its last two "
        "thirds'"
    )
    print(f"MALLOC_ARENA_MAX={os.environ.get('MALLOC_ARENA_MAX', '(unset)')}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--mode", choices=("node", "engine"), default="node")
    parser.add_argument("--duration", type=float, default=120.0, help="seconds")
    parser.add_argument("--warmup", type=float, default=WARMUP_S, help="left out of the slope, s")
    parser.add_argument("--interval", type=float, default=1.0, help="RSS sampling period, s")
    parser.add_argument("--rate", type=float, default=5000.0, help="samples/s per sensor")
    parser.add_argument("--loop-s", type=float, default=20.0, help="the signal repeats after, s")
    parser.add_argument(
        "-p",
        "--node-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="a node parameter beside bench_realtime.py's (repeatable)",
    )
    parser.add_argument(
        "--node-env",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="node: an environment variable of the node's process alone, e.g. "
        "PYTHONMALLOC=malloc (repeatable)",
    )
    parser.add_argument("--inline", action="store_true", help="engine: inline runners")
    parser.add_argument("--unpaced", action="store_true", help="engine: as fast as possible")
    parser.add_argument(
        "--glibc-dynamic",
        action="store_true",
        help="engine: leave glibc's mmap threshold dynamic (as before the node pinned it)",
    )
    parser.add_argument("--trim", type=float, default=0.0, help="engine: malloc_trim every, s")
    parser.add_argument("--seed", type=int, default=0, help="engine: the signal's noise seed")
    parser.add_argument(
        "--tracemalloc",
        type=int,
        default=0,
        metavar="N",
        help="trace Python's allocations (the node's, or the engine's); top N differences",
    )
    parser.add_argument("--frames", type=int, default=6, help="tracemalloc traceback depth")
    parser.add_argument("--keep", action="store_true", help="node: keep the work directory")
    parser.add_argument("--json", default="", help="also write the figures to this file")
    args = parser.parse_args(argv)

    rt.interrupt_on_sigterm()
    print(
        f"bench_soak: mode {args.mode}, {args.duration:g} s, warm-up {args.warmup:g} s, "
        f"{args.rate:g} Hz per sensor, parameters {parameters(args)}"
        + (f", node environment {' '.join(args.node_env)}" if args.node_env else ""),
        flush=True,
    )
    try:
        result = run_engine(args) if args.mode == "engine" else run_node(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 0
    except Exception as exc:
        print(f"bench failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 0
    print_report(args, result)
    if args.json:
        Path(args.json).write_text(json.dumps(result, default=vars))
    return 0


if __name__ == "__main__":
    sys.exit(main())
