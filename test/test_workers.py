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
        # Still niced below its caller (as far as 19, the lowest priority: make test runs
        # this at 10).
        assert niceness >= min(os.nice(0) + 10, 19)
        assert preloaded
        workers = runner.worker_pids
        assert workers and workers[0] != os.getpid()
    finally:
        runner.close()


def _compiler_state() -> tuple[bool, bool, bool]:
    """Before this job imports anything: numba imported, its CPU target's contexts built, the
    node's online core imported."""
    numba = sys.modules.get("numba")
    target = vars(numba.core.registry.cpu_target) if numba is not None else {}
    return (
        numba is not None,
        "_toplevel_target_context" in target and "_toplevel_typing_context" in target,
        "tcomp_core.online" in sys.modules,
    )


def test_a_worker_is_forked_with_numbas_compiler_ready():
    """Each worker's first loop would otherwise import numba and build its typing and target
    contexts (about 0.35 s of CPU per worker, more on a loaded machine): the fork server has
    done it once. The job is the worker's first (no ``start``, whose warm-up job imports the
    core in the worker itself)."""
    runner = ProcessRunner()
    try:
        assert runner.submit(_compiler_state)
        outcome = None
        while outcome is None:
            outcome = runner.poll()
        assert outcome.error == ""
        assert outcome.value == (True, True, True)
    finally:
        runner.close()
