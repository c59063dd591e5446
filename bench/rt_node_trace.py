"""The compensator node with Python's allocations traced, for ``bench_soak.py --tracemalloc``.

Runs :func:`tcomp_ros.compensator.main` unchanged; a thread starts :mod:`tracemalloc` after
``--start`` seconds, appends the traced size (every Python object and numpy buffer the node
holds) and tracemalloc's own memory (its tables, native memory that the node's RSS includes)
to ``--out`` as a JSON line every ``--interval`` seconds, and on exit (SIGINT, as the
bench stops the node) writes the ``--top`` biggest differences, grouped by traceback, between a
snapshot taken ``--start`` seconds after tracing began and the end. A node whose resident
memory grows while the traced size stays flat grows in native code (rclpy, the middleware,
the C allocator), not in anything Python holds. Tracing slows every allocation: run the node
at a rate it keeps up with traced.

Standalone::

    .venv/bin/python bench/rt_node_trace.py --out trace.jsonl --ros-args -p window_s:=2.0
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
import tracemalloc
from pathlib import Path

from tcomp_ros.compensator import main as node_main


def _trace(out: Path, start_s: float, interval_s: float, stop: threading.Event, state: dict):
    if stop.wait(start_s):
        return
    tracemalloc.start(state["frames"])
    began = time.monotonic()
    with out.open("a") as file:
        while not stop.wait(interval_s):
            traced = tracemalloc.get_traced_memory()[0]
            # tracemalloc's own tables (native memory, in the RSS): not the node's growth.
            own = tracemalloc.get_tracemalloc_memory()
            file.write(json.dumps({"t": time.monotonic(), "traced": traced, "own": own}) + "\n")
            file.flush()
            if state["baseline"] is None and time.monotonic() - began >= start_s:
                state["baseline"] = tracemalloc.take_snapshot()


def _top_differences(state: dict, top: int) -> list[dict]:
    if state["baseline"] is None or not tracemalloc.is_tracing():
        return []
    stats = tracemalloc.take_snapshot().compare_to(state["baseline"], "traceback")
    return [
        {
            "size_diff": stat.size_diff,
            "count_diff": stat.count_diff,
            "traceback": stat.traceback.format()[-2 * state["frames"] :],
        }
        for stat in stats[:top]
    ]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="JSON lines: traced bytes")
    parser.add_argument("--start", type=float, default=70.0, help="tracing starts after, s")
    parser.add_argument("--interval", type=float, default=1.0, help="sampling period, s")
    parser.add_argument("--top", type=int, default=10, help="differences written at exit")
    parser.add_argument("--frames", type=int, default=8, help="traceback depth")
    args = parser.parse_args(argv[:split])
    stop = threading.Event()
    state: dict = {"baseline": None, "frames": args.frames}
    tracer = threading.Thread(
        target=_trace, args=(args.out, args.start, args.interval, stop, state), daemon=True
    )
    tracer.start()
    try:
        return node_main([sys.argv[0], *argv[split:]])  # rclpy skips the program name
    finally:
        stop.set()
        tracer.join(timeout=5.0)  # its last line written before this one
        differences = _top_differences(state, args.top)
        with args.out.open("a") as file:
            file.write(json.dumps({"top": differences}) + "\n")


if __name__ == "__main__":
    sys.exit(main())
