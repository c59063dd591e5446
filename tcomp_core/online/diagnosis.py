"""The engine's background diagnosis and its output models: when, on what, and what is taken.

The rules the compensator node follows (and ``tcomp process``, which drives the same
:class:`DiagnosisPolicy` through its :class:`~.engine.Engine`):

- **When.** Every ``diagnosis_period_s`` while the first-order fit is poor or ``effects`` is
  set (:meth:`DiagnosisPolicy.periodic`), and at the next report once ``effects`` or
  ``compensate_effects`` changes (:meth:`DiagnosisPolicy.poll`); one job at a time. A model that
  fits is not diagnosed: a job costs seconds of CPU, which a 2-core machine feels.
- **On what.** The window's longest gap-free stretch (at least :data:`MIN_DIAGNOSIS_S` and
  :data:`MIN_DIAGNOSIS_SAMPLES`, at most the newest :data:`MAX_DIAGNOSIS_S`); with
  ``compensate_effects`` the newest gap-free pairs with their stamps instead (their stream is
  compensated from there on).
- **What is taken** (:func:`judge_output`): a fit whose model has an effect a stream can
  apply, no parameter on a physical bound and a held-out error at least :data:`MIN_ERROR_FALL`
  below first order's becomes the published model; a later fit that fails those checks, a fit
  older than :data:`OUTPUT_STALE_PERIODS` diagnosis periods plus the time the last job took
  (never with a period of 0: a fit on data taken at t lands only when the job ends), or
  ``compensate_effects`` set false return to first order.
- **What is said**: :meth:`DiagnosisPolicy.values`, one vocabulary for the node's
  ``/diagnostics`` and ``tcomp process`` (:func:`diagnosis_values` for a result alone).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..compensation import OutputModel
from ..diagnose.background import BackgroundDiagnoser
from ..workers import JobRunner
from .compensator import OnlineCompensator
from .config import EstimateStatus, OnlineConfig
from .health import format_value

__all__ = [
    "MAX_DIAGNOSIS_S",
    "MIN_DIAGNOSIS_S",
    "MIN_DIAGNOSIS_SAMPLES",
    "MIN_ERROR_FALL",
    "OUTPUT_STALE_PERIODS",
    "DiagnosisPolicy",
    "diagnosis_values",
    "judge_output",
]

#: The background diagnosis needs a gap-free stretch of the window this long, seconds ...
MIN_DIAGNOSIS_S = 2.0
#: ... holding at least this many samples.
MIN_DIAGNOSIS_SAMPLES = 1000
#: A job diagnoses at most the newest this many seconds of it (its cost grows with the length).
MAX_DIAGNOSIS_S = 60.0
#: A fit compensates the published gas when it lowers the held-out error by this share ...
MIN_ERROR_FALL = 0.2
#: ... and until it is this many diagnosis periods (plus the time the last job took, from its
#: submission to its result) old without a newer accepted fit.
OUTPUT_STALE_PERIODS = 3.0


def judge_output(model: OutputModel, pairs: int) -> str:
    """Why ``model`` may not make the published gas ('' when it may), and the fit in words.

    Returns
    -------
    str
        ``''`` when the model has an effect a causal stream applies, no parameter on a bound
        and a held-out error at least :data:`MIN_ERROR_FALL` below first order's; else the
        reason, followed by ``'; '`` and the fit's figures.
    """
    return _judgement(model, pairs)[0]


def _judgement(model: OutputModel, pairs: int) -> tuple[str, str]:
    error, base = model.error_pct, model.base_error_pct
    where = f"fit of {pairs} pairs: held-out error {error:.3g} % ({base:.3g} % first order)"
    if not model.applied(causal_stream=True):
        # Why each effect stays first order (not trusted with the gas, ordinary size, ...).
        reasons = sorted({p.reason for p in model.stream_pieces() if p.handling == "first order"})
        why = f" ({'; '.join(reasons)})" if reasons else ""
        return f"no effect to compensate{why}; {where}", where
    if model.at_bound:
        return f"parameters on a bound ({', '.join(model.at_bound)}); {where}", where
    if not error <= (1.0 - MIN_ERROR_FALL) * base:
        fall = f"{100 * MIN_ERROR_FALL:g} %"
        return f"the effects lower the error by less than {fall}; {where}", where
    return "", where


def diagnosis_values(
    result: dict[str, Any], requested: tuple[str, ...] | None, *, age_s: float = math.nan
) -> dict[str, str]:
    """Key-values of a diagnosis result (:func:`~tcomp_core.diagnose.background.run_job`'s).

    Parameters
    ----------
    result : dict
        The job's result ({} before any).
    requested : tuple of str or None
        The effects asked for (None: ``auto``); the errors and τ with the effects are shown only
        when ``result`` fitted these.
    age_s : float
        Time since the data of the result were taken, s.
    """
    fitted = result if result and result.get("requested", ()) == requested else {}
    return {
        "effects": "auto" if requested is None else ",".join(requested) or "none",
        "effects_error_pct": format_value(fitted.get("error_pct", math.nan)),
        "base_error_pct": format_value(result.get("base_error_pct", math.nan)),
        "effects_tau1_s": format_value(fitted.get("tau1", math.nan)),
        "effects_tau2_s": format_value(fitted.get("tau2", math.nan)),
        "top_suspect": str(result.get("top_suspect", "none")),
        "top_suspect_error_pct": format_value(result.get("top_suspect_error_pct", math.nan)),
        "diagnosis_age_s": format_value(age_s),
        "diagnosis_duration_s": format_value(result.get("seconds", math.nan)),
    }


class DiagnosisPolicy:
    """The background diagnosis of one engine and the output models it yields (module notes).

    Parameters
    ----------
    config : OnlineConfig
        ``effects``, ``compensate_effects``, ``diagnosis_period_s``.
    runner : JobRunner, optional
        Where the diagnoses run (a worker process by default; inline for a replay).

    Attributes
    ----------
    log : list of (str, str)
        ``(level, message)`` of what happened since the caller last emptied it (``'info'`` or
        ``'warning'``): a job that landed or failed, a change of the published model.
    """

    def __init__(self, config: OnlineConfig, runner: JobRunner | None = None) -> None:
        self._diagnoser = BackgroundDiagnoser(runner)
        self._config = config
        self._effects = config.requested_effects
        self._result: dict[str, Any] = {}  # the latest successful diagnosis
        self._error = ""
        self._at = math.nan  # when the data of that diagnosis were taken (caller's clock, s)
        self._submitted_at = math.nan
        self._submitted: tuple[tuple[str, ...] | None, tuple | None] = ((), None)
        self._output_fitted_at = math.nan  # when the data of the output model were taken
        self._job_lag = 0.0  # the last job's time from submission to result, caller's clock
        #: A job is to start as soon as the window is long enough and the worker free.
        self.wanted = self.effects_set
        #: Jobs started so far.
        self.started = 0
        self.log: list[tuple[str, str]] = []

    @property
    def effects_set(self) -> bool:
        """Whether effects (or ``auto``) are asked for."""
        return self._effects is None or bool(self._effects)

    @property
    def compensating(self) -> bool:
        """Whether accepted fits make the published gas."""
        return self._config.compensate_effects

    @property
    def busy(self) -> bool:
        """Whether a job runs."""
        return self._diagnoser.busy

    def close(self) -> None:
        """Stop the worker, abandoning a running job."""
        self._diagnoser.close()

    def reconfigure(self, config: OnlineConfig, compensator: OnlineCompensator) -> None:
        """Take new settings: a change of effects, or compensation turned on, asks for a job."""
        old, self._config = self._config, config
        effects = config.requested_effects
        if old.compensate_effects and not config.compensate_effects:
            self._set_output(compensator, None, "compensate_effects is false")
        turned_on = config.compensate_effects and not old.compensate_effects
        if effects != self._effects or turned_on:
            self._effects = effects
            self.wanted = True

    # -- when ----------------------------------------------------------------------------------
    def periodic(self, now: float, compensator: OnlineCompensator) -> bool:
        """The period's tick: diagnose while the fit is poor or effects are set, else rest.

        Returns whether a job started.
        """
        self._check_output_age(now, compensator)
        status = compensator.last_status
        if self.effects_set or (status is not None and status.poor_fit):
            return self.start(now, compensator)
        return False

    def poll(self, now: float, compensator: OnlineCompensator) -> None:
        """The report tick: start a job that was asked for, else collect one that finished."""
        if self.wanted:
            self.start(now, compensator)
        else:
            self._collect(now, compensator)
        self._check_output_age(now, compensator)

    def start(self, now: float, compensator: OnlineCompensator) -> bool:
        """Diagnose now, unless a job runs or the stretch is too short; whether one started."""
        self._collect(now, compensator)  # a finished job's result belongs to the previous submit
        period = compensator.period_s
        record = self._output_record(compensator) if self.compensating else None
        segment = np.column_stack(record[1:]) if record is not None else self._segment(compensator)
        if segment is None or period is None or self._diagnoser.busy:
            return False
        status: EstimateStatus | None = compensator.last_status
        try:
            started = self._diagnoser.submit(
                np.arange(segment.shape[0]) * period,
                segment[:, 0],
                segment[:, 1],
                period,
                effects=self._effects,
                find_suspect=self.effects_set or bool(status and status.poor_fit),
                output=record is not None,
            )
        except Exception as exc:  # never stop the stream for the diagnosis
            self._error = f"{type(exc).__name__}: {exc}"
            self.log.append(("warning", f"diagnosis not started: {self._error}"))
            return False
        if started:
            self.started += 1
            self._submitted_at = now
            self._submitted = (self._effects, record)
            self.wanted = False
            self._collect(now, compensator)  # an inline runner has finished already
        return started

    # -- on what -------------------------------------------------------------------------------
    @staticmethod
    def _needed(period: float) -> int:
        return max(MIN_DIAGNOSIS_SAMPLES, round(MIN_DIAGNOSIS_S / period))

    def _segment(self, compensator: OnlineCompensator) -> np.ndarray | None:
        """The window's longest gap-free stretch (newest MAX_DIAGNOSIS_S), if long enough."""
        period = compensator.period_s
        if not period:
            return None
        longest = compensator.longest_segment()
        needed = self._needed(period)
        if longest.shape[0] < needed:
            return None
        return longest[-max(needed, round(MAX_DIAGNOSIS_S / period)) :]

    def _output_record(self, compensator: OnlineCompensator) -> tuple | None:
        """The newest gap-free pairs with stamps (at most MAX_DIAGNOSIS_S), if long enough."""
        period = compensator.period_s
        recent = compensator.recent
        if not period or recent.size == 0:
            return None
        stamps, tc1, tc2 = recent.newest(compensator.config.gap_factor)[:3]
        stamps, tc1, tc2 = (c[-round(MAX_DIAGNOSIS_S / period) :] for c in (stamps, tc1, tc2))
        if stamps.size < self._needed(period):
            return None
        return stamps, tc1, tc2

    # -- what is taken -------------------------------------------------------------------------
    def take(
        self,
        compensator: OnlineCompensator,
        model: OutputModel,
        origin_ns: int,
        record: tuple,
        now: float,
        how: str = "",
    ) -> bool:
        """Publish the gas of ``model`` if :func:`judge_output` passes it, else first order.

        ``how`` is said of the fit in ``output_model_note``. Returns whether it was taken.
        """
        refusal, where = _judgement(model, int(record[0].size))
        if refusal:
            self._set_output(compensator, None, f"{refusal}{how}")
            return False
        self._output_fitted_at = now
        self._set_output(compensator, model, f"{where}{how}", origin_ns, record)
        return True

    def _set_output(
        self,
        compensator: OnlineCompensator,
        model: OutputModel | None,
        note: str,
        origin_ns: int = 0,
        record: tuple | None = None,
    ) -> None:
        was = compensator.output_model
        compensator.use_output_model(model, origin_ns, record)
        compensator.output_note = note
        if model is not None or was is not None:
            name = model.name(causal_stream=True) if model is not None else "first-order"
            self.log.append(("info", f"published gas now uses {name}: {note}"))

    def _check_output_age(self, now: float, compensator: OnlineCompensator) -> None:
        """Back to first order when the output model's fit is stale."""
        period = self._config.diagnosis_period_s
        if compensator.output_model is None or period <= 0.0:
            return
        age = now - self._output_fitted_at
        if age > OUTPUT_STALE_PERIODS * period + self._job_lag:
            self._set_output(compensator, None, f"stale: the last accepted fit is {age:.3g} s old")

    def _collect(self, now: float, compensator: OnlineCompensator) -> None:
        """Take a finished job's result, if any (``now``: the caller's clock, seconds)."""
        result = self._diagnoser.poll()
        if result is not None:
            self._job_lag = max(0.0, now - self._submitted_at)
        if result is not None and "error" in result:
            self._error = str(result["error"])
            self.log.append(("warning", f"diagnosis failed: {self._error}"))
            return
        if result is None:
            return
        result["requested"] = self._submitted[0]
        self._result = result
        self._error = ""
        self._at = self._submitted_at
        _, record = self._submitted
        model = result.get("output_model")
        if self.compensating and model is not None and record is not None:
            self.take(compensator, model, int(record[0][0]), record, self._submitted_at)
        self.log.append(
            (
                "info",
                f"diagnosis of {result['samples']} samples in {result['seconds']:.1f} s: "
                f"error {result['base_error_pct']:.3g} % (base), {result['error_pct']:.3g} % "
                f"(effects: {', '.join(result['effects']) or 'none'}); top suspect "
                f"{result['top_suspect']}",
            )
        )

    # -- what is said ----------------------------------------------------------------------------
    def values(self, now: float) -> dict[str, str]:
        """Key-values of the latest diagnosis (:data:`~.health.NO_DIAGNOSIS` before any)."""
        values = diagnosis_values(self._result, self._effects, age_s=now - self._at)
        return {**values, "diagnosis_error": self._error}

    def adopt(
        self,
        compensator: OnlineCompensator,
        model: OutputModel,
        origin_ns: int,
        record: tuple,
        now: float,
        how: str,
        seconds: float = math.nan,
    ) -> bool:
        """Take a fit made elsewhere (``tcomp process --effects``) as a landed job's result.

        It is judged like a background fit (:meth:`take`), and the diagnostics show it.
        """
        self._result = {
            "effects": list(model.effects),
            "base_error_pct": model.base_error_pct,
            "error_pct": model.error_pct,
            "tau1": model.tau1,
            "tau2": model.tau2,
            "samples": int(record[0].size),
            "seconds": seconds,
            "requested": self._effects,
        }
        self._at = now
        return self.take(compensator, model, origin_ns, record, now, f"; {how}" if how else "")
