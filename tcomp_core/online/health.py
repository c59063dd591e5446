"""Health of the online engine: one level enum, one rule set, one key-value formatter.

The compensator node's ``/diagnostics`` and the ``/diagnostics`` history ``tcomp process``
writes come from here, so a bag processed offline reads like the node's own record of it: the
same keys, the same counters (:data:`~.pairing.COUNTER_NAMES`), the same levels. Time enters as
an explicit ``now`` (seconds): the node passes its clock, ``tcomp process`` the stamp time it
has reached; nothing here reads a clock.

Rules (:func:`assess`, in order of severity): ERROR when a sensor has been silent for longer
than ``silence_timeout_s`` or sent non-finite values since the last report; STALE when no
estimate was accepted within ``stale_after_s``; WARN when the latest estimate was refused
(ill-conditioned, unphysical) or the model fits poorly; OK otherwise.

Values that only make sense live are :data:`LIVE_ONLY_KEYS`: the publish latency (wall clock
against input stamps). Offline they are ``nan``. The background diagnosis of the node
(:data:`DIAGNOSIS_KEYS`) reads, offline, as the node's before its first job: ``tcomp process``
puts its closing diagnosis on ``/diagnosis`` instead.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum

from ..lines import ForeignLine
from ..tolerance import class2_disagreement
from .compensator import OnlineCompensator
from .config import EstimateStatus
from .pairing import INPUT_NAMES, PairCounters

__all__ = [
    "DIAGNOSIS_KEYS",
    "LIVE_ONLY_KEYS",
    "NO_DIAGNOSIS",
    "NO_LATENCY",
    "Health",
    "HealthMonitor",
    "Level",
    "assess",
    "engine_values",
    "format_value",
]


class Level(IntEnum):
    """Diagnostic levels of ``diagnostic_msgs/DiagnosticStatus``."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


def format_value(value: float) -> str:
    """A number as diagnostics carry it: 6 significant digits, ``nan`` when not finite."""
    return "nan" if not math.isfinite(value) else f"{value:.6g}"


#: Keys of the node's background diagnosis, with their values before any diagnosis ran.
NO_DIAGNOSIS: dict[str, str] = {
    "effects": "none",
    "effects_error_pct": "nan",
    "base_error_pct": "nan",
    "effects_tau1_s": "nan",
    "effects_tau2_s": "nan",
    "top_suspect": "none",
    "top_suspect_error_pct": "nan",
    "diagnosis_age_s": "nan",
    "diagnosis_duration_s": "nan",
    "diagnosis_error": "",
}
DIAGNOSIS_KEYS: tuple[str, ...] = tuple(NO_DIAGNOSIS)
#: Keys that only make sense live: publish latency against the wall clock, milliseconds, and
#: the node's callbacks that failed (counted and reported, never raised into the executor).
NO_LATENCY: dict[str, str] = {
    "latency_p50_ms": "nan",
    "latency_p99_ms": "nan",
    "latency_max_ms": "nan",
    "latency_p99_total_ms": "nan",
    "callback_errors": "0",
    "last_callback_error": "",
}
LIVE_ONLY_KEYS: tuple[str, ...] = tuple(NO_LATENCY)


def output_values(engine: OnlineCompensator) -> dict[str, str]:
    """Which model the published gas temperature uses, as diagnostic key-values.

    ``output_model`` (``first-order`` or ``first-order+effect+...``: the model in use), its
    held-out error ``output_model_error_pct``, ``output_model_since`` (stamp of the first gas
    sample published with it, ns; empty before), ``output_model_tau{1,2}_s``,
    ``output_model_level_shift_c``, ``output_model_latency_samples``, ``output_model_pieces``
    (how each effect is treated), ``output_model_pending`` (a model set and being built, which
    takes over when built; '' when none) and ``output_model_note`` (the reason for the choice).
    """
    output = engine.output
    model = None if output is None else output.model
    pending = engine.output_model
    pieces = model.stream_pieces() if model is not None else ()
    return {
        "output_model": model.name(causal_stream=True) if model is not None else "first-order",
        "output_model_error_pct": format_value(model.error_pct if model else math.nan),
        "output_model_since": ""
        if output is None or output.since_ns is None
        else str(output.since_ns),
        "output_model_tau1_s": format_value(model.tau1 if model else math.nan),
        "output_model_tau2_s": format_value(model.tau2 if model else math.nan),
        "output_model_level_shift_c": format_value(output.level_shift_c if output else 0.0),
        "output_model_latency_samples": str(output.latency if output else 0),
        "output_model_pieces": "; ".join(f"{p.effect}: {p.handling}" for p in pieces),
        "output_model_pending": ""
        if pending is None or pending is model
        else pending.name(causal_stream=True),
        "output_model_note": engine.output_note,
    }


def engine_values(engine: OnlineCompensator, status: EstimateStatus | None) -> dict[str, str]:
    """Settings, τ in use and the latest estimate of ``engine``, as diagnostic key-values.

    Parameters
    ----------
    engine : OnlineCompensator
    status : EstimateStatus or None
        The latest re-estimation (None before the first).

    Returns
    -------
    dict of str to str
        ``tau1_s``, ``tau2_s`` (s) and ``alpha`` of the model that produces the published gas
        (the output model's, the Kalman filter's or Eq. (7)'s), ``first_order_tau1_s``,
        ``first_order_tau2_s`` (the accepted first-order estimate), ``method``,
        ``reconstruction`` (what makes the published gas: ``kalman`` or ``difference``),
        ``signal_model`` (the Kalman filter's, ``(interim)`` until the fitted one lands; ''
        for Eq. 7), ``signal_model_note`` (what could not be fitted and what is used
        instead), ``first_order_misfit_c`` (°C: the readings' departure from the model the
        filter's std holds, :func:`~tcomp_core.fusion.adequacy.first_order_misfit`),
        ``tracking_memory_s``, ``window_samples``, ``window_s``,
        ``sample_period_s``, ``gaps``, ``rate_changes`` (times the stamps' rate changed and
        the window restarted), ``fit_error_pct``, ``noise_floor_pct``,
        ``model_error_pct``, ``condition``, ``latest_tau1_s``, ``latest_tau2_s``, the 95 %
        intervals ``tau{1,2}_ci_{low,high}_s`` (nan for estimators without them),
        ``foreign_lines`` (spectral lines one sensor carried and the other did not, notched
        from the latest estimate: ``tc2: 50 Hz, 150 Hz``, '' for none; mains pick-up,
        :func:`tcomp_core.lines.foreign_lines`), ``sensor_disagreement`` (the gain and level
        the latest estimate fitted between the sensors when beyond IEC 60584 class 2 by the
        calibration's margin, '' within: :func:`tcomp_core.tolerance.class2_disagreement`; a
        physical effect first order lacks, such as conduction to the supports, or a
        miscalibration), ``estimate_accepted`` and ``last_reason``.
    """
    config = engine.config
    tau = engine.published_tau
    first_order = engine.tau
    estimate = None if status is None else status.estimate
    return {
        "tau1_s": format_value(tau[0] if tau else math.nan),
        "tau2_s": format_value(tau[1] if tau else math.nan),
        "alpha": format_value(tau[0] / tau[1] if tau else math.nan),
        "first_order_tau1_s": format_value(first_order[0] if first_order else math.nan),
        "first_order_tau2_s": format_value(first_order[1] if first_order else math.nan),
        "method": config.method,
        "reconstruction": engine.reconstruction,
        "signal_model": engine.signal_model_name,
        "signal_model_note": engine.fusion_note,
        "first_order_misfit_c": format_value(engine.misfit_c),
        "tracking_memory_s": format_value(config.tracking_memory_s),
        "window_samples": str(engine.window_samples),
        "window_s": format_value(config.window_s),
        "sample_period_s": format_value(engine.period_s or math.nan),
        "gaps": str(engine.counters["gaps"]),
        "rate_changes": str(engine.rate_changes),
        "fit_error_pct": format_value(status.fit_error_pct if status else math.nan),
        "noise_floor_pct": format_value(status.noise_floor_pct if status else math.nan),
        "model_error_pct": format_value(status.model_error_pct if status else math.nan),
        "condition": format_value(estimate.condition if estimate else math.nan),
        "latest_tau1_s": format_value(estimate.tau1 if estimate else math.nan),
        "latest_tau2_s": format_value(estimate.tau2 if estimate else math.nan),
        **{
            f"tau{i}_ci_{end}_s": format_value(
                estimate.params.get(f"tau{i}_ci_{end}", math.nan) if estimate else math.nan
            )
            for i in (1, 2)
            for end in ("low", "high")
        },
        "foreign_lines": _lines_value(estimate.lines if estimate else ()),
        "sensor_disagreement": sensor_disagreement(status),
        **output_values(engine),
        "estimate_accepted": str(bool(status and status.accepted)).lower(),
        "last_reason": status.reason if status else "",
    }


def sensor_disagreement(status: EstimateStatus | None) -> str:
    """How the sensors' fitted gain and level lie beyond class 2 in ``status``, or ''.

    :func:`tcomp_core.tolerance.class2_disagreement` at the window's level; '' without an
    estimate or for estimators that fit neither (β, γ, TDR).
    """
    estimate = None if status is None else status.estimate
    if estimate is None or status is None or not math.isfinite(status.level_c):
        return ""
    return class2_disagreement(
        estimate.params.get("gain", 1.0), estimate.params.get("offset_c", 0.0), status.level_c
    )


def _lines_value(lines: Sequence[ForeignLine]) -> str:
    parts = []
    for channel in (1, 2):
        mine = [f"{line.frequency_hz:.4g} Hz" for line in lines if line.channel == channel]
        if mine:
            parts.append(f"tc{channel}: {', '.join(mine)}")
    return "; ".join(parts)


@dataclass(frozen=True)
class Health:
    """Level, one-line message and key-values of the diagnostic status."""

    level: Level
    message: str
    values: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class SensorReport:
    """What one input did, as the rules see it.

    Attributes
    ----------
    name : str
        'tc1' or 'tc2'.
    silent_for_s : float
        Time since the input was last heard, seconds (inf when never).
    invalid_since_report : int
        Non-finite samples since the last report.
    last_invalid_ns : int
        Stamp of the latest of them, ns.
    """

    name: str
    silent_for_s: float
    invalid_since_report: int = 0
    last_invalid_ns: int = 0


def assess(
    sensors: list[SensorReport],
    *,
    silence_timeout_s: float,
    estimate_age_s: float,
    stale_after_s: float,
    status: EstimateStatus | None,
    max_model_error_pct: float,
) -> tuple[Level, str]:
    """Decide the diagnostic level and message (the module's rules, in order of severity).

    Parameters
    ----------
    sensors : list of SensorReport
    silence_timeout_s : float
        A sensor silent this long is an ERROR, seconds.
    estimate_age_s : float
        Time since the latest accepted estimate, seconds (inf when none).
    stale_after_s : float
        An estimate older than this is STALE, seconds.
    status : EstimateStatus or None
        The latest re-estimation.
    max_model_error_pct : float
        Model error above which the fit is poor, percent.

    Returns
    -------
    (Level, str)
    """
    errors = []
    for sensor in sensors:
        if sensor.silent_for_s > silence_timeout_s:
            silent = (
                "never heard"
                if math.isinf(sensor.silent_for_s)
                else f"silent for {sensor.silent_for_s:.1f} s"
            )
            errors.append(f"{sensor.name} {silent}")
        if sensor.invalid_since_report:
            errors.append(
                f"{sensor.name} sent {sensor.invalid_since_report} invalid value(s) "
                "(not finite or outside the physical range), "
                f"last at stamp {sensor.last_invalid_ns * 1e-9:.6f} s"
            )
    if errors:
        return Level.ERROR, "; ".join(errors)
    reason = status.reason if status else ""
    if not estimate_age_s <= stale_after_s:
        why = reason or "waiting for the window to fill"
        age = (
            "no estimate yet"
            if math.isinf(estimate_age_s)
            else f"last accepted estimate {estimate_age_s:.1f} s old"
        )
        return Level.STALE, f"{age}: {why}"
    if status is not None and not status.accepted and reason:
        return Level.WARN, f"latest estimate refused: {reason}"
    if status is not None and status.poor_fit:
        return (
            Level.WARN,
            f"poor fit: model error {format_value(status.model_error_pct)} % exceeds "
            f"{format_value(max_model_error_pct)} %: the first-order model misses an effect",
        )
    return Level.OK, "estimating"


class HealthMonitor:
    """The time-dependent part of the health: when each input was heard, report periods.

    Parameters
    ----------
    silence_timeout_s : float
        A sensor silent this long is an ERROR, seconds.
    stale_after_s : float
        An accepted estimate older than this is STALE, seconds.
    """

    def __init__(self, silence_timeout_s: float, stale_after_s: float) -> None:
        self.silence_timeout_s = silence_timeout_s
        self.stale_after_s = stale_after_s
        self._heard = [math.nan, math.nan]
        self._accepted_at = math.nan
        self._report_time = math.nan
        self._received_at_report = [0, 0]
        self._invalid_at_report = [0, 0]
        self._malformed_at_report = [0, 0]
        self._discontinuities_at_report = 0
        self._widened_at_report = 0
        self._published_at_report = 0

    def heard(self, index: int, now: float) -> None:
        """Input ``index`` delivered samples at ``now`` (seconds)."""
        self._heard[index] = now
        if math.isnan(self._report_time):
            self._report_time = now

    def estimated(self, status: EstimateStatus, now: float) -> None:
        """A re-estimation happened at ``now`` (seconds)."""
        if status.accepted:
            self._accepted_at = now

    def estimate_age_s(self, now: float) -> float:
        """Seconds since the latest accepted estimate (inf when none)."""
        return now - self._accepted_at if math.isfinite(self._accepted_at) else math.inf

    def report(
        self,
        now: float,
        *,
        engine: OnlineCompensator,
        counters: PairCounters,
        published: int,
        max_model_error_pct: float,
        malformed_reasons: Sequence[str] = ("", ""),
        extra: Mapping[str, str] = NO_DIAGNOSIS | NO_LATENCY,
        new_period: bool = True,
    ) -> Health:
        """The status at ``now`` (seconds), by default starting a new report period.

        Parameters
        ----------
        now : float
            Seconds on the caller's clock (the node's clock, or stamp time offline).
        engine : OnlineCompensator
        counters : PairCounters
            The pair matcher's counters.
        published : int
            Gas samples published so far.
        max_model_error_pct : float
            Model error above which the fit is poor, percent.
        malformed_reasons : sequence of str, length 2
            Why the latest undecodable message of each input failed ('' when none did).
        extra : mapping of str to str
            The diagnosis and latency key-values (:data:`NO_DIAGNOSIS`, :data:`NO_LATENCY`
            offline).
        new_period : bool
            Start a new report period (rates and invalid samples count from ``now``).
        """
        elapsed = max(now - self._report_time, 1e-9) if math.isfinite(self._report_time) else 0
        rates = [
            (counters.received[i] - self._received_at_report[i]) / elapsed if elapsed else 0.0
            for i in (0, 1)
        ]
        status = engine.last_status
        age = self.estimate_age_s(now)
        unmatched = counters.total_unmatched
        values = {
            **engine_values(engine, status),
            "rate_tc1_hz": format_value(rates[0]),
            "rate_tc2_hz": format_value(rates[1]),
            "received_tc1": str(counters.received[0]),
            "received_tc2": str(counters.received[1]),
            "matched": str(counters.matched),
            "dropped": str(unmatched + counters.out_of_order + counters.duplicates),
            "unmatched": str(unmatched),
            "out_of_order": str(counters.out_of_order),
            "duplicates": str(counters.duplicates),
            "invalid_tc1": str(counters.invalid[0]),
            "invalid_tc2": str(counters.invalid[1]),
            "malformed_tc1": str(counters.malformed[0]),
            "malformed_tc2": str(counters.malformed[1]),
            "discontinuities": str(counters.discontinuities),
            "published": str(published),
            "held": str(engine.held_pairs),
            "unreconstructed": str(engine.counters["unreconstructed"]),
            "widened": str(engine.widened),
            "estimate_age_s": format_value(age),
            **extra,
        }
        sensors = [
            SensorReport(
                name=name,
                silent_for_s=now - self._heard[i] if math.isfinite(self._heard[i]) else math.inf,
                invalid_since_report=counters.invalid[i] - self._invalid_at_report[i],
                last_invalid_ns=counters.last_invalid_ns[i],
            )
            for i, name in enumerate(INPUT_NAMES)
        ]
        level, message = assess(
            sensors,
            silence_timeout_s=self.silence_timeout_s,
            estimate_age_s=age,
            stale_after_s=self.stale_after_s,
            status=status,
            max_model_error_pct=max_model_error_pct,
        )
        model = engine.output_model
        if level == Level.WARN and status is not None and status.poor_fit and model is not None:
            # The first-order window estimate still fits poorly; the published gas does not
            # rely on it.
            message += f"; the published gas uses {model.name(causal_stream=True)}"
        notes = self._input_notes(counters, malformed_reasons)
        widened = engine.widened - self._widened_at_report
        if widened:
            notes.append(
                f"the readings disagree with the filter's model: {widened} of the "
                f"{max(published - self._published_at_report, widened)} gas values since the "
                "last report carry a std widened 2x or more"
            )
        if engine.misfit_warning:
            notes.append(engine.misfit_warning)
        if engine.rate_note:  # until an estimate at the new rate is accepted
            notes.append(engine.rate_note)
        if notes:
            # Never hidden behind an OK: at least a WARN, appended to any other message.
            message = "; ".join(notes if level == Level.OK else [message, *notes])
            level = max(level, Level.WARN)
        if not new_period:
            return Health(level, message, values)
        self._report_time = now
        self._received_at_report = list(counters.received)
        self._invalid_at_report = list(counters.invalid)
        self._malformed_at_report = list(counters.malformed)
        self._discontinuities_at_report = counters.discontinuities
        self._widened_at_report = engine.widened
        self._published_at_report = published
        return Health(level, message, values)

    def _input_notes(self, counters: PairCounters, reasons: Sequence[str]) -> list[str]:
        """Malformed messages and discontinuities since the last report, in words."""
        notes = []
        for i, name in enumerate(INPUT_NAMES):
            count = counters.malformed[i] - self._malformed_at_report[i]
            if count:
                notes.append(f"{name}: {count} malformed message(s) skipped ({reasons[i]})")
        if counters.discontinuities > self._discontinuities_at_report:
            notes.append(
                "stamps jumped back: window restarted at stamp "
                f"{counters.last_discontinuity_ns * 1e-9:.6f} s"
            )
        return notes
