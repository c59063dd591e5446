"""The key-values that describe the online engine and its latest estimate.

The compensator node's ``/diagnostics`` and the τ history of ``tcomp process`` carry the same
names and formats, so a bag processed offline reads like the node's own record of it.
"""

from __future__ import annotations

import math

from .online import EstimateStatus, OnlineCompensator

__all__ = ["engine_values", "format_value"]


def format_value(value: float) -> str:
    """A number as diagnostics carry it: 6 significant digits, ``nan`` when not finite."""
    return "nan" if not math.isfinite(value) else f"{value:.6g}"


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
        ``tau1_s``, ``tau2_s`` (in use, s), ``alpha``, ``method``, ``reconstruction``,
        ``signal_model``, ``signal_model_error``, ``tracking_memory_s``, ``window_samples``,
        ``window_s``, ``sample_period_s``, ``gaps``, ``fit_error_pct``, ``noise_floor_pct``,
        ``model_error_pct``, ``condition``, ``latest_tau1_s``, ``latest_tau2_s``, the 95 %
        intervals ``tau{1,2}_ci_{low,high}_s`` (nan for estimators without them),
        ``estimate_accepted`` and ``last_reason``.
    """
    config = engine.config
    tau = engine.tau
    estimate = None if status is None else status.estimate
    fusion = engine.fusion_model
    return {
        "tau1_s": format_value(tau[0] if tau else math.nan),
        "tau2_s": format_value(tau[1] if tau else math.nan),
        "alpha": format_value(tau[0] / tau[1] if tau else math.nan),
        "method": config.method,
        "reconstruction": config.reconstruction,
        "signal_model": fusion.kind if fusion else "",
        "signal_model_error": engine.fusion_error,
        "tracking_memory_s": format_value(config.tracking_memory_s),
        "window_samples": str(engine.window_samples),
        "window_s": format_value(config.window_s),
        "sample_period_s": format_value(engine.period_s or math.nan),
        "gaps": str(engine.counters["gaps"]),
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
        "estimate_accepted": str(bool(status and status.accepted)).lower(),
        "last_reason": status.reason if status else "",
    }
