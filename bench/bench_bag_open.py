"""What opening a bag costs: ``read_bag`` of each bundled bag, and its ``metadata.yaml`` parse.

Every read of a bag directory parses its ``metadata.yaml`` (the file list, the topics). This
prints, per bundled bag, the median time of a whole ``read_bag`` and of the metadata parse by
the reader's loader (libyaml through PyYAML) against ruamel.yaml's pure-Python safe loader
(the reader's loader until 2026-12-06), measured in the same run.

Run::

    PYTHONPATH=. .venv/bin/python bench/bench_bag_open.py [--repeat 20]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from ruamel.yaml import YAML

from tcomp_core.io import read_bag
from tcomp_core.io.paths import _load_yaml

ROOT = Path(__file__).resolve().parents[1]


def median_ms(action: Callable[[], object], repeat: int) -> float:
    """Median wall time of ``action`` over ``repeat`` calls, ms (after one untimed call)."""
    action()
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        action()
        times.append(time.perf_counter() - started)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="timed calls of each")
    args = parser.parse_args()
    print(f"{'bag':24s} {'read_bag ms':>12s} {'libyaml ms':>11s} {'ruamel ms':>10s} {'x':>6s}")
    for metadata in sorted((ROOT / "bags").glob("*/metadata.yaml")):
        bag = metadata.parent
        text = metadata.read_text()
        read = median_ms(lambda bag=bag: read_bag(bag), args.repeat)
        fast = median_ms(lambda text=text: _load_yaml(text), args.repeat)
        slow = median_ms(lambda text=text: YAML(typ="safe").load(text), args.repeat)
        print(f"{bag.name:24s} {read:12.2f} {fast:11.2f} {slow:10.2f} {slow / fast:5.1f}x")


if __name__ == "__main__":
    main()
