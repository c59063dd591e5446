"""Does the way a node spins its executor grow its memory? Bare rclpy processes side by side.

Each variant is a process of its own holding a bare node with the compensator's timers (5 ms,
0.5 s, 1 s; the 1 s one publishes a DiagnosticArray of 40 values, as the node's report does),
spun by :func:`tcomp_ros.spin.make_executor`'s executor (the EventsExecutor) in one of these
ways:

``slices:S``      :func:`tcomp_ros.spin.spin_until_shutdown` itself, S seconds a slice
                  (``spin_until_future_complete`` on a future never done)
``slices-pub:S``  the same, also publishing 25 Temperature messages per 5 ms tick (5 kHz)
``once``          ``spin_once(timeout_sec=0.05)`` (the bench's bare subscriber)

Every variant runs at once on a private domain, samples its own resident memory every
``--interval`` s, and the bench prints each one's growth as the least-squares slope after
``--warmup`` s (MiB per hour, ``bench_soak.py``'s ``Series``) with its standard error, the
first and last RSS and the timer ticks (equal ticks: the variants ran alike). A variant that
grows by more than another does so in the way it spins: nothing else differs.

Run::

    .venv/bin/python bench/bench_spin_growth.py                        # 10 min, four variants
    .venv/bin/python bench/bench_spin_growth.py --duration 900 --variants slices:0.05 once
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bench_realtime as rt
from bench_soak import Series, rss_bytes

VARIANTS = ("slices:0.05", "slices:1.0", "slices-pub:0.05", "once")


def child(variant: str, duration: float, interval: float, out: Path) -> None:
    """One variant: spin the bare node for ``duration`` s, write its RSS samples to ``out``."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from sensor_msgs.msg import Temperature

    from tcomp_ros.spin import make_executor, spin_until_shutdown

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
    samples: list[tuple[float, int | None]] = []
    start = time.monotonic()

    def sampled_until_done() -> bool:
        """Sample RSS every ``interval`` s; True once ``duration`` s have passed."""
        now = time.monotonic() - start
        if not samples or now >= samples[-1][0] + interval:
            samples.append((now, rss_bytes()))
        return now >= duration

    if kind == "once":
        executor = make_executor(node.context)
        executor.add_node(node)
        while not sampled_until_done():
            executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
        rclpy.try_shutdown()
    else:  # the product's loop, checking done() between slices
        spin_until_shutdown(node, done=sampled_until_done, timeout_sec=float(slice_text))
    node.destroy_node()
    out.write_text(json.dumps({"variant": variant, "samples": samples, "ticks": ticks[0]}))


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
    domain, env = rt.child_environment()
    print(
        f"bench_spin_growth: {len(args.variants)} variants side by side, {args.duration:g} s, "
        f"slope after {args.warmup:g} s, ROS_DOMAIN_ID={domain}",
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
            series = Series(variant)
            for t, value in found["samples"]:
                series.add(t, value)
            g = series.growth(args.warmup)
            print(
                f"{variant:<18} {g['slope']:+8.2f} ± {g['stderr']:.2f} MiB/h   "
                f"{g['first']:7.1f} -> {g['last']:7.1f} MiB   {found['ticks']}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
