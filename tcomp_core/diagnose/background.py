"""Run the diagnosis in a worker process, away from a real-time caller's thread.

A diagnosis fits many nonlinear models and takes seconds; the compensator node must keep
publishing every sample pair within milliseconds meanwhile. :class:`BackgroundDiagnoser` hands
one job at a time to a single worker process and lets the caller collect the result without
blocking::

    diagnoser = BackgroundDiagnoser()
    diagnoser.submit(time, tc1, tc2, dt, effects=("conduction",), find_suspect=True)
    ...
    result = diagnoser.poll()  # None until the job is done, then its result once

The worker is started with ``spawn``, not ``fork``: a ROS node's process runs DDS threads, and
a forked child would inherit their locks in whatever state they were. As with any spawned
process, the worker imports the caller's main script: a script that submits jobs must guard its
entry point with ``if __name__ == "__main__":`` (console scripts and ``python -m`` do), else
every job reports that the worker died.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..choices import parse_effect_list
from ..compensation import (
    OutputModel,
    default_estimate,
    default_first_order_failure,
    output_model_from_diagnosis,
    output_model_with_fallback,
)
from ..io import Record
from ..workers import JobRunner, ProcessRunner
from .pipeline import diagnose, fit_effects

__all__ = ["BackgroundDiagnoser", "parse_effects", "run_job"]


def parse_effects(effects: str | Sequence[str]) -> tuple[str, ...]:
    """Check a set of effect names; a string is split at commas.

    Parameters
    ----------
    effects : str or sequence of str
        Names from :data:`~tcomp_core.effects.EFFECT_NAMES`, e.g. ``"conduction, delay"``.
        ``""`` and ``"none"`` mean the base model alone.

    Returns
    -------
    tuple of str
        The names, stripped, in the order given.

    Raises
    ------
    ValueError
        On an unknown or repeated name.
    """
    parsed = parse_effect_list(effects)
    assert parsed is not None  # "auto" is not allowed here
    return parsed


def run_job(
    record: Record,
    effects: tuple[str, ...] | None,
    find_suspect: bool,
    output: bool = False,
) -> dict[str, Any]:
    """Fit the base model plus ``effects`` and, if asked, look for the top suspect.

    Runs in the worker process (module level, so it pickles by reference).

    Parameters
    ----------
    record : Record
        The data to diagnose.
    effects : tuple of str or None
        Effects to add to the base model, in order (checked by :func:`parse_effects`); None
        runs the whole diagnosis and takes its final model (``auto``).
    find_suspect : bool
        Also run :func:`~tcomp_core.diagnose.diagnose` with one effect at most.
    output : bool
        Also return the fit as an output model (``output_model``, for compensation).

    Returns
    -------
    dict
        ``effects`` (list of str, the final model's for ``auto``); ``base_error_pct`` and
        ``error_pct``: held-out model error of the base model and of the base plus ``effects``,
        %; ``tau1``, ``tau2``: time constants with ``effects``, s; ``at_bound``: parameters of
        that fit on a physical bound; ``top_suspect``: the first significant suspect of the
        diagnosis, ``"none"`` when none is significant or none was looked for;
        ``top_suspect_error_pct``: held-out error with it, % (NaN without one); ``samples``:
        samples diagnosed; ``seconds``: duration of the job, s; with ``output`` also
        ``output_model`` (:class:`~tcomp_core.compensation.OutputModel`). On any error, only
        ``{"error": message}``.
    """
    started = _time.perf_counter()
    try:
        # The default path's τ: what the output model falls back to, and what every fit here
        # is judged against (estimated once; the diagnosis would estimate it per call).
        plain = default_estimate(record)
        published = None if plain is None else (float(plain.tau1), float(plain.tau2))
        lines = () if plain is None else plain.lines
        diagnosed = partial(
            diagnose, published_taus=published, published_lines=lines, published_tried=True
        )
        fitted_with = partial(
            fit_effects, published_taus=published, published_lines=lines, published_tried=True
        )
        if effects is None:
            fitted = diagnosed(record)
            suspect = next((item for item in fitted.suspects if item.significant), None)
        else:
            fitted = fitted_with(record, effects)
            suspect = None
            if find_suspect:
                suspects = diagnosed(record, max_effects=1).suspects
                suspect = next((item for item in suspects if item.significant), None)
        judged: Callable[..., OutputModel] = (
            partial(output_model_with_fallback, record)
            if effects is None
            else output_model_from_diagnosis
        )
        model = (
            judged(
                fitted,
                first_order_taus=published,
                first_order_failure=default_first_order_failure(record, plain),
            )
            if output
            else None
        )
    except Exception as exc:  # the caller must learn of any failure, not lose its worker
        return {"error": f"{type(exc).__name__}: {exc}"}
    result = {
        "effects": list(fitted.final.effects),
        "base_error_pct": float(fitted.base.error_pct),
        "error_pct": float(fitted.final.error_pct),
        "tau1": float(fitted.final.tau1),
        "tau2": float(fitted.final.tau2),
        "at_bound": list(fitted.final.at_bound),
        "top_suspect": suspect.effect if suspect else "none",
        "top_suspect_error_pct": float(suspect.error_pct) if suspect else math.nan,
        "samples": int(record.tc1.size),
        "seconds": _time.perf_counter() - started,
    }
    if model is not None:
        result["output_model"] = model
    return result


class BackgroundDiagnoser:
    """One diagnosis at a time in a job runner; submit and poll never block.

    Parameters
    ----------
    runner : JobRunner, optional
        Where the jobs run: by default a worker process at a lower priority
        (:class:`~tcomp_core.workers.ProcessRunner`, spawned on the first :meth:`submit`);
        :class:`~tcomp_core.workers.InlineRunner` runs them in the caller. If the worker dies,
        the job reports an error and the next submit starts a new one.
    """

    def __init__(self, runner: JobRunner | None = None) -> None:
        self._runner = runner if runner is not None else ProcessRunner()
        self._latest: dict[str, Any] | None = None
        self._unread = False
        self._closed = False

    @property
    def busy(self) -> bool:
        """Whether a job is running."""
        return self._runner.busy

    @property
    def runner(self) -> JobRunner:
        """Where the jobs run."""
        return self._runner

    @property
    def latest(self) -> dict[str, Any] | None:
        """The result of the last finished job seen by :meth:`poll` or :meth:`submit`, if any."""
        return self._latest

    def submit(
        self,
        time: ArrayLike,
        tc1: ArrayLike,
        tc2: ArrayLike,
        dt: float,
        *,
        effects: Sequence[str] | None,
        find_suspect: bool,
        output: bool = False,
    ) -> bool:
        """Start a diagnosis of a uniformly sampled record unless one is running.

        Parameters
        ----------
        time : array_like, shape (N,)
            Sample times, s.
        tc1, tc2 : array_like, shape (N,)
            Thermocouple temperatures, degrees C.
        dt : float
            Sample interval, s.
        effects : sequence of str or None
            Effects to add to the base model (see :func:`run_job`); None: the diagnosis's
            final model.
        find_suspect : bool
            Also look for the effect the base model misses most.
        output : bool
            Also return the fit as an output model (see :func:`run_job`).

        Returns
        -------
        bool
            True if the job started, False if another one is still running.

        Raises
        ------
        ValueError
            On an unknown or repeated effect, or arrays that do not form a record
            (:class:`~tcomp_core.errors.DataError`).
        RuntimeError
            After :meth:`close`.
        """
        if self._closed:
            raise RuntimeError("the background diagnoser is closed")
        names = None if effects is None else parse_effects(effects)
        record = Record(
            time=np.asarray(time, dtype=np.float64),
            tc1=np.asarray(tc1, dtype=np.float64),
            tc2=np.asarray(tc2, dtype=np.float64),
            ref=None,
            source="background diagnosis",
            dt=float(dt),
        )
        if self.busy:
            return False
        self._collect()  # keep a finished, unread result for poll()
        return self._runner.submit(run_job, record, names, find_suspect, output)

    def poll(self) -> dict[str, Any] | None:
        """The result of a job that finished since the last call, else None (never blocks)."""
        self._collect()
        if not self._unread:
            return None
        self._unread = False
        return self._latest

    def close(self) -> None:
        """Stop the worker, abandoning a running job; later calls do nothing."""
        self._closed = True
        self._runner.close()

    def _collect(self) -> None:
        outcome = self._runner.poll()
        if outcome is None:
            return
        if outcome.error:
            self._latest = {"error": outcome.error.replace("worker died", "diagnosis worker died")}
        else:
            self._latest = outcome.value
        self._unread = True
