"""The node's job runner (tcomp_core.workers): where its worker process comes from."""

from __future__ import annotations

import os
import sys

from tcomp_core.workers import WORKER_PRELOAD, ProcessRunner


def _origin() -> tuple[int, int, bool]:
    """The worker's parent, priority and whether the core was imported before this job."""
    return os.getppid(), os.nice(0), all(name in sys.modules for name in WORKER_PRELOAD[1:])


def test_the_worker_is_forked_from_a_server_that_imported_the_core():
    """Not from the caller (a node's process runs DDS threads) and not spawned anew (a second
    of imports per worker): from the fork server, with the numerical core already imported."""
    runner = ProcessRunner()
    try:
        assert runner.start(wait_s=60.0)
        assert runner.submit(_origin)
        outcome = None
        while outcome is None:
            outcome = runner.poll()
        assert outcome.error == ""
        parent, niceness, preloaded = outcome.value
        assert parent != os.getpid()  # a spawned worker is the caller's child
        assert niceness >= os.nice(0) + 10  # still niced below its caller
        assert preloaded
        workers = runner.worker_pids
        assert workers and workers[0] != os.getpid()
    finally:
        runner.close()
