"""The windows of a long record diagnosed in worker processes (``tcomp diagnose --jobs N``).

The windows of a record (:mod:`tcomp_core.diagnose.windowed`) are diagnosed independently of
each other, so ``N`` worker processes diagnose ``N`` at a time: a one-hour 5 kHz record is 60
windows of 60 s, each seconds of one core's work. The rows come back in window order, as
:func:`~tcomp_core.diagnose.windowed.diagnose_windows` takes them, and are those of the windows
diagnosed here: each worker runs the same :func:`~tcomp_core.diagnose.windowed.diagnose_window`
on the same window.

Memory stays bounded: at most :data:`WINDOWS_IN_FLIGHT_PER_WORKER` windows per worker are read
ahead of the row the caller waits for (a window's record is about 40 bytes a sample), and
each worker holds one window's diagnosis (about 1.5 kB a sample) at a time. The workers are
forked from the fork server of :mod:`tcomp_core.workers`, which has the numerical core imported.

A worker that dies (killed, out of memory) breaks the pool and fails every window in flight, and
which one killed it cannot be told: each of them is diagnosed again alone, one at a time in a
worker of its own, and a window whose worker dies then too gets a row that says so (the others
carry on, in a fresh pool).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

from ..effects import EFFECT_NAMES
from ..io.windows import Window
from ..workers import worker_context
from .ranking import MAX_EFFECTS
from .windowed import WindowResult, diagnose_window

__all__ = ["WINDOWS_IN_FLIGHT_PER_WORKER", "diagnose_in_processes"]

#: Windows handed to the pool per worker before the caller waits for the oldest row: one being
#: diagnosed and one queued, so a worker that finishes early starts the next window at once.
WINDOWS_IN_FLIGHT_PER_WORKER = 2

#: diagnose_window's signature: (window, candidates, max_effects) -> row.
DiagnoseWindow = Callable[[Window, Sequence[str], int], WindowResult]


@dataclass
class _Pending:
    """A window handed to the pool: its future, and whether it was diagnosed alone."""

    window: Window
    future: Future[WindowResult]
    alone: bool = False


def diagnose_in_processes(
    windows: Iterable[Window],
    jobs: int,
    candidates: Sequence[str] = EFFECT_NAMES,
    max_effects: int = MAX_EFFECTS,
    *,
    diagnose: DiagnoseWindow = diagnose_window,
) -> Iterator[WindowResult]:
    """Each window diagnosed in one of ``jobs`` worker processes; the rows in window order.

    Parameters
    ----------
    windows : iterable of Window
        From :class:`~tcomp_core.io.windows.WindowReader` (read as the rows are taken).
    jobs : int
        Worker processes.
    candidates, max_effects
        As :func:`~tcomp_core.diagnose.diagnose`.
    diagnose : callable
        The function each worker runs on a window (default
        :func:`~tcomp_core.diagnose.windowed.diagnose_window`; it must pickle: a module-level
        function or a partial of one).

    Yields
    ------
    WindowResult
        One row per window, in the order of ``windows``.

    Raises
    ------
    ValueError
        If ``jobs`` is below 1.
    """
    if jobs < 1:
        raise ValueError(f"{jobs=} must be >= 1")
    pool = _WindowPool(jobs, candidates, max_effects, diagnose)
    try:
        for window in windows:
            pool.add(window)
            if len(pool.pending) >= WINDOWS_IN_FLIGHT_PER_WORKER * jobs:
                yield pool.next_row()
        while pool.pending:
            yield pool.next_row()
    finally:
        pool.close()


class _WindowPool:
    """The windows in flight in a process pool, which is replaced when a worker dies."""

    def __init__(
        self,
        jobs: int,
        candidates: Sequence[str],
        max_effects: int,
        diagnose: DiagnoseWindow,
    ) -> None:
        self._jobs = jobs
        self._arguments = (list(candidates), max_effects)
        self._diagnose = diagnose
        self._executor = self._new_executor(jobs)
        self.pending: deque[_Pending] = deque()

    @staticmethod
    def _new_executor(workers: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, mp_context=worker_context())

    def add(self, window: Window) -> None:
        """Hand ``window`` to the pool."""
        self.pending.append(_Pending(window, self._submit(window)))

    def _submit(self, window: Window) -> Future[WindowResult]:
        try:
            return self._executor.submit(self._diagnose, window, *self._arguments)
        except BrokenProcessPool:  # a worker died since the last row was taken
            self._recover()
            return self._executor.submit(self._diagnose, window, *self._arguments)

    def next_row(self) -> WindowResult:
        """The oldest window's row (waited for), taken off :attr:`pending`."""
        while True:
            head = self.pending[0]
            try:
                row = head.future.result()
            except BrokenProcessPool as exc:
                if head.alone:
                    self.pending.popleft()
                    return _failed(head.window, exc)
                self._recover()
                continue
            self.pending.popleft()
            return row

    def _recover(self) -> None:
        """A fresh pool for a broken one; every window the broken one lost diagnosed alone.

        Only a broken pool is replaced, so no window in flight in a working one is lost. Each
        lost window runs by itself in a worker of its own, one after another (a rare path: the
        window that killed its worker, out of memory say, must not take others with it again).
        """
        self._executor.shutdown(wait=True)  # its workers are gone: every future is settled
        self._executor = self._new_executor(self._jobs)
        for index, item in enumerate(self.pending):
            # (A diagnosis that raised keeps its error: run here, it would have raised too.)
            if isinstance(item.future.exception(), BrokenProcessPool) and not item.alone:
                self.pending[index] = _Pending(item.window, self._alone(item.window), alone=True)

    def _alone(self, window: Window) -> Future[WindowResult]:
        """``window`` diagnosed in a pool of one worker, waited for: a settled future."""
        with self._new_executor(1) as solo:
            future = solo.submit(self._diagnose, window, *self._arguments)
            future.exception()  # waits
        return future

    def close(self) -> None:
        """Stop the workers; windows not yet diagnosed are dropped."""
        self._executor.shutdown(wait=True, cancel_futures=True)


def _failed(window: Window, error: BaseException) -> WindowResult:
    """The row of a window whose worker died, also when it was diagnosed alone."""
    return WindowResult.undiagnosed(
        window,
        "the worker process diagnosing it died, also when it was diagnosed alone "
        f"({' '.join(str(error).split())}); too little memory for a window this long?",
    )
