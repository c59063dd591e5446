"""The compensator node with its timer callbacks timed (and optionally cProfiled), for the bench.

Runs :class:`tcomp_ros.compensator.CompensatorNode` unchanged except that ``_process``,
``_update_estimate`` and ``publish_diagnostics`` are wrapped to record their wall time, and
the subscription callbacks are counted; the spin loop is
:func:`tcomp_ros.spin.spin_until_shutdown`, as in the real entry point. At exit (SIGINT,
SIGTERM) a JSON summary goes to ``--out``: per callback, calls and p50/p99/max/total time, the
``_process`` batch sizes and the gaps between consecutive ``_process`` runs (how late the 5 ms
timer fires). With ``--profile FILE`` the whole run is under cProfile and the stats are dumped
to FILE (read with ``python -m pstats FILE``).

Used by ``bench_realtime.py --node-probe [--node-profile]``; standalone::

    .venv/bin/python bench/rt_node_probe.py --out probe.json --ros-args -p window_s:=2.0
"""

from __future__ import annotations

import argparse
import cProfile
import json
import sys
import time
from pathlib import Path

import numpy as np
import rclpy

from tcomp_ros.compensator import CompensatorNode
from tcomp_ros.spin import LONG_RUN_SLICE_S, spin_until_shutdown


class TimedCompensatorNode(CompensatorNode):
    """CompensatorNode whose timer callbacks record their durations."""

    def __init__(self, **kwargs) -> None:
        self.started = time.perf_counter()
        #: per timed call: (name, seconds since start, duration s), for the slowest calls
        self.calls: list[tuple[str, float, float]] = []
        self.timings: dict[str, list[float]] = {
            "_process": [],
            "_update_estimate": [],
            "publish_diagnostics": [],
        }
        self.batch_pairs: list[int] = []
        self.process_starts: list[float] = []
        #: per _process call: (start, inbox tc1, inbox tc2, matched before, duration)
        self.trace: list[tuple[float, int, int, int, float]] = []
        super().__init__(**kwargs)

    def _process(self) -> None:
        start = time.perf_counter()
        self.process_starts.append(start)
        before = self.engine.published
        inbox = (len(self._inbox[0][0]), len(self._inbox[1][0]), self.engine.counters.matched)
        super()._process()
        elapsed = time.perf_counter() - start
        self.timings["_process"].append(elapsed)
        self.calls.append(("_process", start - self.started, elapsed))
        self.trace.append((start, *inbox, elapsed))
        self.batch_pairs.append(self.engine.published - before)

    def update_estimate(self) -> None:
        start = time.perf_counter()
        super().update_estimate()
        self.timings["_update_estimate"].append(time.perf_counter() - start)
        self.calls.append(
            ("_update_estimate", start - self.started, self.timings["_update_estimate"][-1])
        )

    def publish_diagnostics(self) -> None:
        start = time.perf_counter()
        super().publish_diagnostics()
        self.timings["publish_diagnostics"].append(time.perf_counter() - start)
        self.calls.append(
            ("publish_diagnostics", start - self.started, self.timings["publish_diagnostics"][-1])
        )

    def summary(self) -> dict:
        result: dict[str, object] = {}
        for name, values in self.timings.items():
            ms = np.asarray(values) * 1e3
            result[name] = summarise(ms)
        busy = [i for i, n in enumerate(self.batch_pairs) if n > 0]
        pairs = np.asarray([self.batch_pairs[i] for i in busy], dtype=float)
        per_pair_us = (
            np.asarray([self.timings["_process"][i] for i in busy]) * 1e6 / pairs
            if busy
            else np.empty(0)
        )
        result["batch_pairs"] = summarise(pairs)
        result["process_us_per_pair"] = summarise(per_pair_us)
        result["process_interval_ms"] = summarise(np.diff(self.process_starts) * 1e3)
        slowest = sorted(self.calls, key=lambda call: -call[2])[:8]
        result["slowest_ms_at_s"] = [(n, round(at, 2), round(d * 1e3, 1)) for n, at, d in slowest]
        result["received"] = list(self.received)
        result["published"] = self.engine.published
        return result


def summarise(values: np.ndarray) -> dict:
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return {"n": 0}
    return {
        "n": int(values.size),
        "p50": round(float(np.percentile(values, 50)), 3),
        "p99": round(float(np.percentile(values, 99)), 3),
        "max": round(float(values.max()), 3),
        "total": round(float(values.sum()), 1),
    }


def main() -> int:
    argv = sys.argv[1:]
    ros_args = []
    if "--ros-args" in argv:
        cut = argv.index("--ros-args")
        argv, ros_args = argv[:cut], argv[cut:]
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--profile", default="")
    args = parser.parse_args(argv)
    profiler = cProfile.Profile() if args.profile else None
    rclpy.init(args=[sys.argv[0], *ros_args])
    node = TimedCompensatorNode()
    try:
        if profiler is not None:
            profiler.enable()
        spin_until_shutdown(node, timeout_sec=LONG_RUN_SLICE_S)  # as the node's main()
    finally:
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(args.profile)
        Path(args.out).write_text(json.dumps(node.summary()))
        np.save(Path(args.out).with_suffix(".trace.npy"), np.asarray(node.trace))
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
