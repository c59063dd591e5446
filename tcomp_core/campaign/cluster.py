"""Running a campaign's recordings on a Dask cluster, with retries and a progress bar.

By default an embedded :class:`distributed.LocalCluster` of worker processes sized to the
machine (one thread each, one BLAS thread: a recording's work is one core's); a scheduler
address (``tcp://host:8786``) or a scheduler file runs the same tasks on an existing cluster,
whose workers must have tcomp installed and see the inputs and the output directory at the same
paths.

Each recording is one task (:func:`~.task.run_recording`). A task whose worker dies is run
again by the scheduler on another worker (up to ``distributed.scheduler.allowed-failures``
times); a task that raises is retried :data:`RETRIES` times. Finished results are in the ledger
as soon as a worker writes them, so a run cut at any point loses only the recordings in flight.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["ClusterSpec", "Job", "dask_client", "run_jobs"]

#: A task that raised is run again this many times before its error is the result.
RETRIES = 2
#: Environment of the embedded cluster's workers: one BLAS thread per worker process.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@dataclass(frozen=True)
class ClusterSpec:
    """Where the tasks run.

    Attributes
    ----------
    scheduler : str or None
        Address of an existing scheduler (``tcp://host:8786``).
    scheduler_file : Path or None
        Scheduler file of an existing cluster (``dask scheduler --scheduler-file``).
    workers : int or None
        Worker processes of the embedded cluster (None: one per core).
    """

    scheduler: str | None = None
    scheduler_file: Path | None = None
    workers: int | None = None

    def describe(self) -> str:
        """Where the tasks run, for messages."""
        if self.scheduler:
            return f"the scheduler at {self.scheduler}"
        if self.scheduler_file:
            return f"the cluster of {self.scheduler_file}"
        return f"a local cluster of {self.workers or os.cpu_count() or 1} worker processes"


@dataclass(frozen=True)
class Job:
    """One task: the callable's positional arguments and a name unique in the run."""

    name: str
    arguments: tuple[Any, ...]


@contextlib.contextmanager
def dask_client(spec: ClusterSpec) -> Iterator[Any]:
    """A :class:`distributed.Client` for ``spec``; the embedded cluster is closed after."""
    from distributed import Client, LocalCluster

    if spec.scheduler or spec.scheduler_file:
        client = (
            Client(spec.scheduler)
            if spec.scheduler
            else Client(scheduler_file=str(spec.scheduler_file))
        )
        with client:
            yield client
        return
    workers = spec.workers or os.cpu_count() or 1
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
            env=WORKER_ENV,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def run_jobs(
    client: Any,
    function: Callable[..., dict[str, Any]],
    jobs: Sequence[Job],
    *,
    on_result: Callable[[Job, dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run ``function(*job.arguments)`` for every job on ``client``; results in job order.

    A task that fails after its retries, or whose workers kept dying, gives
    ``{"error": "..."}`` (merged into what ``on_result`` sees) instead of stopping the others.
    """
    from distributed import as_completed

    futures = {
        client.submit(function, *job.arguments, key=job.name, retries=RETRIES, pure=False): job
        for job in jobs
    }
    results: dict[str, dict[str, Any]] = {}
    for future in as_completed(futures):
        job = futures[future]
        try:
            result = future.result()
        except Exception as exc:  # a task's own error, or KilledWorker: the job's result
            result = {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}
        results[job.name] = result
        if on_result is not None:
            on_result(job, result)
    return [results[job.name] for job in jobs]
