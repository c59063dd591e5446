"""Run slow jobs away from a real-time caller: in a worker process, or inline for a replay.

The compensator node must publish every sample pair within milliseconds while model fits take
from tens of milliseconds (a signal model) to seconds (a diagnosis). A :class:`JobRunner` takes
one job at a time and lets the caller collect its outcome without blocking:

    runner = ProcessRunner()
    runner.submit(function, argument)   # False while a job runs
    ...
    outcome = runner.poll()             # None until the job is done, then its outcome once

:class:`ProcessRunner` runs the job in one worker process at a lower priority (the
node's model fits); :class:`ThreadRunner` in one thread of the caller's process (the node's τ
re-estimation: milliseconds of numpy and scipy that need the window's copy, not a process);
:class:`InlineRunner` runs it at once in the caller (``tcomp process``, which replays a record
in stamp time, so a job's result lands at the same stamp on every run).

The worker is not forked from the caller: a ROS node's process runs DDS threads, and a forked
child would inherit their locks in whatever state they were. It is forked from a *fork server*
(``forkserver``), a clean single-threaded process started once per caller that has imported the
numerical core (:data:`WORKER_PRELOAD`): a worker then starts in milliseconds instead of the
second of imports a ``spawn``-ed one took (0.9 s of CPU each; the node starts two, and again
after a worker dies). As with ``spawn``, the server imports the caller's main script: a script
that submits jobs must guard its entry point with ``if __name__ == "__main__":`` (console
scripts and ``python -m`` do), else every job reports that the worker died.
"""

from __future__ import annotations

import contextlib
import importlib
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = [
    "WORKER_NICENESS",
    "WORKER_PRELOAD",
    "InlineRunner",
    "JobRunner",
    "Outcome",
    "ProcessRunner",
    "ThreadRunner",
    "worker_context",
]

#: What the fork server imports before it forks workers: the caller's main script (where a job's
#: function may live, as ``spawn`` imports it), and the numerical core the jobs run with numba's
#: compiler ready (:mod:`tcomp_core.worker_preload`).
WORKER_PRELOAD: tuple[str, ...] = ("__main__", "tcomp_core.worker_preload")
#: The worker runs this much nicer than its caller: on a small machine the real-time work of
#: the caller comes first and the jobs take the spare CPU.
WORKER_NICENESS = 10


@dataclass(frozen=True)
class Outcome:
    """What a job gave: its value, or why it failed.

    Attributes
    ----------
    value : Any
        The job's return value (None when it failed).
    error : str
        ``'ExceptionType: message'`` when the job raised or its worker died ('' otherwise).
    """

    value: Any = None
    error: str = ""


class JobRunner(Protocol):
    """One job at a time; submit and poll never block."""

    @property
    def busy(self) -> bool:
        """Whether a job is running."""

    def submit(self, function: Callable[..., Any], /, *args: Any) -> bool:
        """Start ``function(*args)`` unless a job runs; whether it started."""

    def poll(self) -> Outcome | None:
        """The outcome of a job that finished since the last call, else None."""

    def close(self) -> None:
        """Stop, abandoning a running job; later submits raise RuntimeError."""


class InlineRunner:
    """Runs each job at once in the caller: its outcome is ready at the next :meth:`poll`."""

    def __init__(self) -> None:
        self._outcome: Outcome | None = None
        self._closed = False

    @property
    def busy(self) -> bool:
        """Never: a job is done when :meth:`submit` returns."""
        return False

    def submit(self, function: Callable[..., Any], /, *args: Any) -> bool:
        """Run ``function(*args)`` now; an exception becomes the outcome's error."""
        if self._closed:
            raise RuntimeError("the runner is closed")
        try:
            self._outcome = Outcome(function(*args))
        except Exception as exc:  # the caller learns of any failure through poll()
            self._outcome = Outcome(error=f"{type(exc).__name__}: {exc}")
        return True

    def poll(self) -> Outcome | None:
        """The outcome of the last job, once."""
        outcome, self._outcome = self._outcome, None
        return outcome

    def close(self) -> None:
        """Refuse later jobs."""
        self._closed = True


class ThreadRunner:
    """One job at a time in one thread of the caller's process.

    For jobs of milliseconds whose inputs are large to pickle and whose work is mostly numpy
    and scipy: the caller's own thread (a node's executor) takes the interpreter back at least
    every :func:`sys.getswitchinterval` (5 ms) and whenever the job is inside a routine that
    releases it, instead of waiting for the whole job. The job must not share mutable state
    with the caller (give it copies).
    """

    def __init__(self, name: str = "tcomp-job") -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)
        self._future: Future | None = None
        self._closed = False

    @property
    def busy(self) -> bool:
        """Whether a job is running (or finished and not yet polled)."""
        return self._future is not None and not self._future.done()

    def submit(self, function: Callable[..., Any], /, *args: Any) -> bool:
        """Start ``function(*args)`` on the thread unless a job runs; whether it started."""
        if self._closed:
            raise RuntimeError("the runner is closed")
        if self._future is not None and not self._future.done():
            return False
        self._future = self._pool.submit(function, *args)
        return True

    def poll(self) -> Outcome | None:
        """The outcome of a job that finished since the last call, else None."""
        future = self._future
        if future is None or not future.done():
            return None
        self._future = None
        error = future.exception()
        if error is not None:
            return Outcome(error=f"{type(error).__name__}: {error}")
        return Outcome(future.result())

    def close(self) -> None:
        """Refuse later jobs; a running one finishes on its own (its outcome is dropped)."""
        self._closed = True
        self._pool.shutdown(wait=False, cancel_futures=True)


def _start_worker(pin_heap: bool) -> None:
    """Initializer of the worker process: lower its priority, pin glibc's mmap threshold.

    The worker yields the CPU to the caller, and its threshold is pinned as the node's process
    pins it (:mod:`tcomp_core.memory`): a worker frees window-sized arrays job after job as
    the node does (a signal model's segment and priming pairs, a diagnosis's record), so its
    heap fragments the same way once glibc has raised the threshold.
    """
    os.nice(WORKER_NICENESS)
    if pin_heap:
        from .memory import pin_mmap_threshold

        pin_mmap_threshold()


def worker_context() -> multiprocessing.context.BaseContext:
    """The fork server's context, the core preloaded (the server is one per process).

    For :class:`ProcessRunner` and for pools of workers (``tcomp diagnose --jobs``).

    ``spawn`` where the platform has no fork server (Windows).
    """
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(WORKER_PRELOAD))
    return context


class ProcessRunner:
    """One job at a time in a worker process at a lower priority.

    The worker is started on the first :meth:`submit` (or :meth:`start`) and kept for later
    jobs (forked from the fork server: milliseconds, once the server has imported the core;
    the first start in a process waits for that, about a second). If it dies, the job's outcome
    says so and the next submit starts a new one. Functions and arguments must pickle
    (module-level functions, numpy arrays, dataclasses).

    Parameters
    ----------
    pin_heap : bool
        Pin glibc's mmap threshold in the worker (default; False leaves it to glibc, as
        ``bench/bench_soak.py --glibc-dynamic`` measures).
    """

    def __init__(self, *, pin_heap: bool = True) -> None:
        self._pin_heap = pin_heap
        self._pool: ProcessPoolExecutor | None = None
        self._future: Future[Any] | None = None
        self._outcome: Outcome | None = None
        self._closed = False

    @property
    def busy(self) -> bool:
        """Whether a job is running."""
        return self._future is not None and not self._future.done()

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the live worker (empty before it is started)."""
        pool = self._pool
        processes = getattr(pool, "_processes", None) or {}
        return [process.pid for process in processes.values() if process.pid is not None]

    def start(self, wait_s: float = 0.0) -> bool:
        """Spawn the worker now, so that the first job does not wait for its imports.

        Parameters
        ----------
        wait_s : float
            Wait up to this long for it to be ready, s (0: return at once).

        Returns
        -------
        bool
            Whether the worker is ready (False while it starts).
        """
        if self._closed:
            raise RuntimeError("the runner is closed")
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                max_workers=1,
                mp_context=worker_context(),
                initializer=_start_worker,
                initargs=(self._pin_heap,),
            )
            self._future = self._pool.submit(_warm_up)
        future = self._future
        if wait_s > 0.0 and future is not None:
            with contextlib.suppress(Exception):  # a failure shows in the next job's outcome
                future.result(timeout=wait_s)
        return not self.busy

    def submit(self, function: Callable[..., Any], /, *args: Any) -> bool:
        """Start ``function(*args)`` in the worker unless a job runs; whether it started."""
        if self._closed:
            raise RuntimeError("the runner is closed")
        if self.busy:
            return False
        self._collect()  # keep a finished, unread outcome for poll()
        self.start()
        assert self._pool is not None
        try:
            self._future = self._pool.submit(function, *args)
        except BrokenProcessPool as exc:  # died between jobs: the next submit starts anew
            self._drop_pool()
            self._outcome = Outcome(error=f"the worker died: {exc}")
            return False
        return True

    def poll(self) -> Outcome | None:
        """The outcome of a job that finished since the last call, else None (never blocks)."""
        self._collect()
        outcome, self._outcome = self._outcome, None
        return outcome

    def close(self) -> None:
        """Stop the worker, abandoning a running job; later calls do nothing."""
        self._closed = True
        pool, self._pool = self._pool, None
        self._future = None
        if pool is None:
            return
        # A running job is disposable: end the worker now instead of letting the caller's exit
        # wait seconds for it (ProcessPoolExecutor has no public way before Python 3.14).
        workers = list((pool._processes or {}).values())
        for worker in workers:
            worker.terminate()
        for worker in workers:
            worker.join(timeout=5.0)
        # A worker killed while it wrote a result leaves half a message in the result pipe, and
        # the pool's manager thread blocked reading the rest. Closing this process's copy of the
        # pipe's write end (the dead worker held the only other) ends that read with EOF, so
        # the manager thread sees a broken pool and stops; waiting for it keeps it from racing
        # the interpreter's exit hook (an ignored OSError on Python 3.11).
        with contextlib.suppress(AttributeError, OSError):
            pool._result_queue._writer.close()  # type: ignore[attr-defined]
        pool.shutdown(wait=True, cancel_futures=True)

    def _drop_pool(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)  # its worker is gone: returns at once
        self._pool = None

    def _collect(self) -> None:
        future = self._future
        if future is None or not future.done():
            return
        self._future = None
        try:
            value = future.result()
        except BrokenProcessPool as exc:
            self._outcome = Outcome(error=f"the worker died: {exc}")
            self._drop_pool()
            return
        except Exception as exc:  # the job raised, or its data failed to pickle
            self._outcome = Outcome(error=f"{type(exc).__name__}: {exc}")
            return
        if value != _WARMED_UP:
            self._outcome = Outcome(value)


_WARMED_UP = "tcomp worker ready"


def _warm_up() -> str:
    """The worker's first task: the core imported, so that jobs start at once.

    Forked from the fork server it is there already; a spawned worker (no fork server)
    imports it here, by name as the server does: the core's own modules use this runner, so
    an import statement here would close an import cycle.
    """
    for name in WORKER_PRELOAD[1:]:
        importlib.import_module(name)

    return _WARMED_UP
