"""Does the way a node spins its executor grow its memory? Bare rclpy processes side by side.

Each variant is a process of its own holding a bare node with the compensator's timers (5 ms,
0.5 s, 1 s; the 1 s one publishes a DiagnosticArray of 40 values, as the node's report does),
spun by :func:`tcomp_ros.spin.make_executor`'s executor (the EventsExecutor) in one of these
ways:

``slices:S``      ``spin_until_future_complete`` on a future never done, S seconds a slice
                  (:func:`tcomp_ros.spin.spin_until_shutdown`'s loop)
``slices-pub:S``  the same, also publishing 25 Temperature messages per 5 ms tick (5 kHz)
``once``          ``spin_once(timeout_sec=0.05)`` (the bench's bare subscriber)

Every variant runs at once on a private domain, samples its own resident memory every
``--interval`` s, and the bench prints each one's growth as the least-squares slope after
``--warmup`` s (MiB per hour) with its standard error, the first and last RSS and the timer
ticks (equal ticks: the variants ran alike). A variant that grows by more than another does so
in the way it spins: nothing else differs.

Run::

    .venv/bin/python bench/bench_spin_growth.py                        # 10 min, four variants
    .venv/bin/python bench/bench_spin_growth.py --duration 900 --variants slices:0.05 once
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
VARIANTS = ("slices:0.05", "slices:1.0", "slices-pub:0.05", "once")


def child(variant: str, duration: float, interval: float, out: Path) -> None:
    """One variant: spin the bare node for ``duration`` s, write its RSS samples to ``out``."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.task import Future
    from sensor_msgs.msg import Temperature

    from tcomp_ros.spin import make_executor

    kind, _, slice_text = variant.partition(":")
    rclpy.init()
    node = rclpy.create_node("spin_growth_" + kind.replace("-", "_"))
    gas = node.create_publisher(Temperature, "gas_temperature", 1000)
    diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
    ticks = [0]

    def drain() -> None:
        ticks[0] += 1
        if kind == "slices-pub":
            for k in range(25):
                message = Temperature()
                message.header.stamp.sec = ticks[0]
                message.temperature = float(k)
                gas.publish(message)

    def report() -> None:
        status = DiagnosticStatus(name="spin growth", message="ok")
        status.values = [KeyValue(key=f"key{i}", value=str(i)) for i in range(40)]
        diagnostics.publish(DiagnosticArray(status=[status]))

    node.create_timer(0.005, drain)
    node.create_timer(0.5, lambda: None)
    node.create_timer(1.0, report)
    executor = make_executor(node.context)
    executor.add_node(node)
    never = Future()
    slice_s = float(slice_text or 0.05)
    samples = []
    start = time.monotonic()
    next_sample = 0.0
    while (now := time.monotonic() - start) < duration:
        if kind == "once":
            executor.spin_once(timeout_sec=0.05)
        else:
            executor.spin_until_future_complete(never, timeout_sec=slice_s)
        if now >= next_sample:
            samples.append((now, _rss_kib()))
            next_sample += interval
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
    out.write_text(json.dumps({"variant": variant, "samples": samples, "ticks": ticks[0]}))


def _rss_kib() -> int:
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))


def growth(samples: list[list[float]], warmup: float) -> tuple[float, float, float, float]:
    """Slope and its standard error (MiB/h), first and last RSS (MiB) after ``warmup`` s."""
    data = np.asarray(samples, dtype=float)
    data = data[data[:, 0] >= warmup]
    if len(data) < 3:
        return math.nan, math.nan, math.nan, math.nan
    hours, mib = data[:, 0] / 3600.0, data[:, 1] / 1024.0
    centred = hours - hours.mean()
    slope = float(centred @ (mib - mib.mean()) / (centred @ centred))
    residual = mib - mib.mean() - slope * centred
    stderr = math.sqrt(float(residual @ residual) / (len(data) - 2) / float(centred @ centred))
    return slope, stderr, float(mib[0]), float(mib[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--duration", type=float, default=600.0, help="seconds")
    parser.add_argument("--warmup", type=float, default=180.0, help="left out of the slope, s")
    parser.add_argument("--interval", type=float, default=5.0, help="RSS sampling period, s")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument("--child", nargs=2, metavar=("VARIANT", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child[0], args.duration, args.interval, Path(args.child[1]))
        return 0
    env = {**os.environ, "ROS_DOMAIN_ID": str(1 + (os.getpid() * 11) % 100)}
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE.parent), env.get("PYTHONPATH")]))
    print(
        f"bench_spin_growth: {len(args.variants)} variants side by side, {args.duration:g} s, "
        f"slope after {args.warmup:g} s, ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="bench_spin_growth_") as workdir:
        outs = {variant: Path(workdir) / f"{i}.json" for i, variant in enumerate(args.variants)}
        options = ["--duration", str(args.duration), "--interval", str(args.interval)]
        children = [
            subprocess.Popen(
                [sys.executable, __file__, *options, "--child", variant, str(out)], env=env
            )
            for variant, out in outs.items()
        ]
        for process in children:
            process.wait()
        print(f"{'variant':<18} {'growth':>22}   {'RSS':>18}   ticks")
        for variant, out in outs.items():
            if not out.exists():
                print(f"{variant:<18} failed (no samples)")
                continue
            found = json.loads(out.read_text())
            slope, stderr, first, last = growth(found["samples"], args.warmup)
            print(
                f"{variant:<18} {slope:+8.2f} ± {stderr:.2f} MiB/h   "
                f"{first:7.1f} -> {last:7.1f} MiB   {found['ticks']}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
