"""The compensator's health assessment: level, message and key-values of its diagnostic status.

Pure Python (no rclpy) so the rules are testable on their own; the node turns the result into a
``diagnostic_msgs/DiagnosticStatus`` once a second, as ``diagnostic_updater`` would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

__all__ = ["Health", "Level", "SensorActivity", "assess"]


class Level(IntEnum):
    """Diagnostic levels of ``diagnostic_msgs/DiagnosticStatus``."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass
class SensorActivity:
    """What one input topic did since the node started and in the last report period."""

    name: str
    received: int = 0
    invalid: int = 0
    invalid_since_report: int = 0
    last_invalid: str = ""
    silent_for_s: float = math.inf
    rate_hz: float = 0.0


@dataclass(frozen=True)
class Health:
    """Level, one-line message and key-values of the diagnostic status."""

    level: Level
    message: str
    values: dict[str, str] = field(default_factory=dict)


def _fmt(value: float) -> str:
    return "nan" if value is None or not math.isfinite(value) else f"{value:.6g}"


def assess(
    sensors: list[SensorActivity],
    *,
    silence_timeout_s: float,
    estimate_age_s: float,
    stale_after_s: float,
    status_reason: str,
    accepted: bool,
    poor_fit: bool,
    model_error_pct: float,
    max_model_error_pct: float,
    values: dict[str, str],
) -> Health:
    """Decide the diagnostic level, in order of severity.

    ERROR when a sensor is silent for longer than ``silence_timeout_s`` or sent non-finite values
    since the last report; STALE when no estimate was accepted within ``stale_after_s``; WARN
    when the latest estimate was refused (ill-conditioned, unphysical) or the model fits poorly;
    OK otherwise.
    """
    errors = []
    for sensor in sensors:
        if sensor.silent_for_s > silence_timeout_s:
            silent = (
                "never heard"
                if math.isinf(sensor.silent_for_s)
                else (f"silent for {sensor.silent_for_s:.1f} s")
            )
            errors.append(f"{sensor.name} {silent}")
        if sensor.invalid_since_report:
            errors.append(
                f"{sensor.name} sent {sensor.invalid_since_report} non-finite value(s), "
                f"last {sensor.last_invalid}"
            )
    if errors:
        return Health(Level.ERROR, "; ".join(errors), values)
    if not estimate_age_s <= stale_after_s:
        why = status_reason or "waiting for the window to fill"
        age = (
            "no estimate yet"
            if math.isinf(estimate_age_s)
            else (f"last accepted estimate {estimate_age_s:.1f} s old")
        )
        return Health(Level.STALE, f"{age}: {why}", values)
    if not accepted and status_reason:
        return Health(Level.WARN, f"latest estimate refused: {status_reason}", values)
    if poor_fit:
        return Health(
            Level.WARN,
            f"poor fit: model error {_fmt(model_error_pct)} % exceeds "
            f"{_fmt(max_model_error_pct)} %: the first-order model misses an effect",
            values,
        )
    return Health(Level.OK, "estimating", values)
