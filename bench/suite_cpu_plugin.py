"""pytest plugin of ``bench_suite.py``: each test's wall time and CPU time, one JSON line each.

The CPU is the worker process's own (``RUSAGE_SELF``) and that of the processes it started
and reaped during the test (``RUSAGE_CHILDREN``), in seconds, and when it ended (``end``, epoch
s: which worker finished last, and when); the lines go to the file named
by ``$SUITE_CPU_RECORD`` (appended, one writer per line: the workers share it).
"""

from __future__ import annotations

import json
import os
import resource
import time

import pytest


def _cpu_s() -> tuple[float, float]:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    start = time.perf_counter()
    own, children = _cpu_s()
    yield
    wall = time.perf_counter() - start
    own_after, children_after = _cpu_s()
    path = os.environ.get("SUITE_CPU_RECORD")
    if not path:
        return
    line = json.dumps(
        {
            "id": item.nodeid,
            "wall": wall,
            "self": own_after - own,
            "children": children_after - children,
            "worker": os.environ.get("PYTEST_XDIST_WORKER", ""),
            "end": time.time(),
        }
    )
    with open(path, "a", encoding="utf-8") as handle:
        handle.write(line + "\n")
