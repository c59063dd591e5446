"""The campaign report: τ per probe over time, verdicts, model-error jumps, fouling alarms.

Everything is drawn from the campaign table's rows (:mod:`.table`). Per recording, τ1, τ2 and
the model error are the medians over its windows that were diagnosed; its verdict is the whole
recording's (the verdict most windows give).

* **Fouling alarm**: a probe whose τ1 or τ2 moved by more than ``drift_threshold`` (relative)
  from its first recording to its last; soot on a wire thickens it and slows it, a thinning
  wire speeds it up.
* **Model-error jump**: a recording whose model error is more than :data:`JUMP_FACTOR` times the
  median of the probe's earlier recordings (and above :data:`JUMP_FLOOR_PCT`): the first-order
  model, or the one diagnosed, no longer describes the probe.
* **Verdict change**: a recording whose verdict differs from the probe's previous one: when the
  diagnosis changed its mind.
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..htmlpage import bullet_list, image, page, section, table
from ..io.outputs import atomic_output

__all__ = [
    "JUMP_FACTOR",
    "RecordingPoint",
    "error_jumps",
    "fouling_alarms",
    "probe_series",
    "verdict_changes",
    "write_report",
]

#: A recording's model error this many times the median of the probe's earlier ones is a jump.
JUMP_FACTOR = 2.0
#: ... and above this, %: below it the model explains the record to its noise either way.
JUMP_FLOOR_PCT = 1.0
#: Window starts beyond this many seconds are dates (bag stamps), drawn as such.
EPOCH_S = 1e8


@dataclass(frozen=True)
class RecordingPoint:
    """One recording of a probe, summarised over its diagnosed windows.

    Attributes
    ----------
    recording : str
    start_s : float
        Start of its first window, s (epoch seconds for bags).
    tau1, tau2 : float
        Medians over its diagnosed windows, s (NaN when none was diagnosed).
    error_pct, base_error_pct : float
        Median model error of its windows, final model and first order, %.
    verdict : str
        The whole recording's verdict ('' when it failed).
    """

    recording: str
    start_s: float
    tau1: float
    tau2: float
    error_pct: float
    base_error_pct: float
    verdict: str


def _median(values: Sequence[Any]) -> float:
    finite = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return float(np.median(finite)) if finite else math.nan


def probe_series(rows: Sequence[dict[str, Any]]) -> dict[str, list[RecordingPoint]]:
    """Each probe's recordings in time order (see the module)."""
    by_recording: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        by_recording[(row.get("probe") or "", row["recording"])].append(row)
    series: dict[str, list[RecordingPoint]] = defaultdict(list)
    for (probe, recording), windows in by_recording.items():
        diagnosed = [w for w in windows if w.get("verdict")]
        starts = [w.get("window_start_s") for w in windows]
        start = min(
            (float(s) for s in starts if s is not None and math.isfinite(s)), default=math.nan
        )
        series[probe].append(
            RecordingPoint(
                recording=recording,
                start_s=start,
                tau1=_median([w.get("tau1") for w in diagnosed]),
                tau2=_median([w.get("tau2") for w in diagnosed]),
                error_pct=_median([w.get("error_pct") for w in diagnosed]),
                base_error_pct=_median([w.get("base_error_pct") for w in diagnosed]),
                verdict=str(windows[0].get("recording_verdict") or ""),
            )
        )
    for points in series.values():
        points.sort(key=lambda p: (math.inf if math.isnan(p.start_s) else p.start_s, p.recording))
    return dict(sorted(series.items()))


def fouling_alarms(
    series: dict[str, list[RecordingPoint]], threshold: float
) -> list[dict[str, Any]]:
    """Probes whose τ moved by more than ``threshold`` (relative), first to last recording."""
    alarms = []
    for probe, points in series.items():
        for name in ("tau1", "tau2"):
            values = [(p, getattr(p, name)) for p in points if math.isfinite(getattr(p, name))]
            if len(values) < 2:
                continue
            (first, start), (last, end) = values[0], values[-1]
            change = end / start - 1.0
            if abs(change) > threshold:
                alarms.append(
                    {
                        "probe": probe,
                        "tau": name,
                        "first": start,
                        "last": end,
                        "change": change,
                        "from": first.recording,
                        "to": last.recording,
                    }
                )
    return alarms


def error_jumps(series: dict[str, list[RecordingPoint]]) -> list[dict[str, Any]]:
    """Recordings whose model error jumped against the probe's earlier ones (see the module)."""
    jumps = []
    for probe, points in series.items():
        for index, point in enumerate(points):
            before = [p.base_error_pct for p in points[:index] if math.isfinite(p.base_error_pct)]
            if not before or not math.isfinite(point.base_error_pct):
                continue
            usual = float(np.median(before))
            if point.base_error_pct > max(JUMP_FACTOR * usual, JUMP_FLOOR_PCT):
                jumps.append(
                    {
                        "probe": probe,
                        "recording": point.recording,
                        "error_pct": point.base_error_pct,
                        "usual_pct": usual,
                        "verdict": point.verdict,
                    }
                )
    return jumps


def verdict_changes(series: dict[str, list[RecordingPoint]]) -> list[dict[str, Any]]:
    """Recordings whose verdict differs from the probe's previous recording's."""
    changes = []
    for probe, points in series.items():
        for previous, point in itertools.pairwise(points):
            if point.verdict != previous.verdict:
                changes.append(
                    {
                        "probe": probe,
                        "recording": point.recording,
                        "before": previous.verdict,
                        "after": point.verdict,
                    }
                )
    return changes


def _date(seconds: float) -> dt.datetime | None:
    """A window start as a UTC date when it is epoch seconds (a bag stamp), else None."""
    if math.isfinite(seconds) and seconds > EPOCH_S:
        return dt.datetime.fromtimestamp(seconds, tz=dt.UTC)
    return None


def _times(starts: Sequence[float]) -> list[Any]:
    """Window starts as dates when they all are epoch seconds, else as seconds."""
    dates = [_date(s) for s in starts]
    return dates if starts and all(d is not None for d in dates) else list(starts)


def _trend_figure(probe: str, rows: Sequence[dict[str, Any]]) -> Figure:
    """τ1 and τ2 per window (95 % intervals, each on its own scale), verdicts, model errors."""
    diagnosed = sorted(
        (r for r in rows if r.get("verdict") and r.get("window_start_s") is not None),
        key=lambda r: r["window_start_s"],
    )
    figure = Figure(figsize=(9.0, 8.0), layout="constrained")
    tau1_axes, tau2_axes, verdict_axes, error_axes = figure.subplots(
        4, 1, sharex=True, height_ratios=(2, 2, 1, 1.5)
    )
    times = _times([float(r["window_start_s"]) for r in diagnosed])
    for axes, name, color in ((tau1_axes, "tau1", "C0"), (tau2_axes, "tau2", "C1")):
        values = np.array([_value(r.get(name)) for r in diagnosed])
        pairs = list(zip(diagnosed, values, strict=True))
        low = np.array([_value(r.get(f"{name}_low"), v) for r, v in pairs])
        high = np.array([_value(r.get(f"{name}_high"), v) for r, v in pairs])
        spread = np.vstack([np.maximum(values - low, 0.0), np.maximum(high - values, 0.0)])
        axes.errorbar(
            times,
            values,
            yerr=np.nan_to_num(spread),
            fmt="o",
            ms=3,
            color=color,
            capsize=2,
            label=f"τ{name[-1]} per window (95 % interval)",
        )
        axes.set_ylabel(f"τ{name[-1]} (s)")
        axes.legend(loc="best")
    tau1_axes.set_title(f"probe {probe or '(none)'}")
    verdicts = sorted({str(r["verdict"]) for r in diagnosed})
    for level, verdict in enumerate(verdicts):
        picked = [t for t, r in zip(times, diagnosed, strict=True) if r["verdict"] == verdict]
        verdict_axes.plot(picked, [level] * len(picked), "s", ms=5)
    verdict_axes.set_yticks(range(len(verdicts)), verdicts)
    verdict_axes.set_ylim(-0.7, max(len(verdicts) - 0.3, 0.7))
    verdict_axes.set_ylabel("verdict")
    for key, label, style in (
        ("base_error_pct", "first order", "o-"),
        ("error_pct", "final model", "s--"),
    ):
        errors = np.array([_value(r.get(key)) for r in diagnosed])
        error_axes.plot(times, errors, style, ms=3, label=label)
    error_axes.set_ylabel("model error (%)")
    error_axes.legend(loc="best")
    dated = bool(times) and isinstance(times[0], dt.datetime)
    error_axes.set_xlabel("window start (UTC)" if dated else "window start (s)")
    return figure


def _value(value: Any, default: float = math.nan) -> float:
    """A table cell as a float (``default`` for None)."""
    return default if value is None else float(value)


def write_report(
    rows: Sequence[dict[str, Any]], path: Path, *, drift_threshold: float = 0.2
) -> Path:
    """Write the campaign's HTML report to ``path`` (replaced whole); returns ``path``."""
    series = probe_series(rows)
    alarms = fouling_alarms(series, drift_threshold)
    jumps = error_jumps(series)
    changes = verdict_changes(series)
    failed = sorted({(r["recording"], r.get("error", "")) for r in rows if r.get("error")})
    recordings = {r["recording"] for r in rows}
    summary = table(
        ["probes", "recordings", "windows diagnosed", "recordings failed"],
        [[len(series), len(recordings), sum(1 for r in rows if r.get("verdict")), len(failed)]],
    )
    parts = [section("Campaign", summary)]
    parts.append(
        section(
            f"Fouling alarms: τ moved by more than {100 * drift_threshold:g} % "
            "(first recording to last)",
            table(
                ["probe", "τ", "first (s)", "last (s)", "change", "from", "to"],
                [
                    [
                        a["probe"],
                        a["tau"],
                        a["first"],
                        a["last"],
                        f"{100 * a['change']:+.1f} %",
                        a["from"],
                        a["to"],
                    ]
                    for a in alarms
                ],
            )
            if alarms
            else "<p>none</p>",
        )
    )
    parts.append(
        section(
            f"First-order model-error jumps (more than {JUMP_FACTOR:g}× the probe's earlier "
            "recordings)",
            table(
                ["probe", "recording", "first-order error (%)", "earlier median (%)", "verdict"],
                [
                    [j["probe"], j["recording"], j["error_pct"], j["usual_pct"], j["verdict"]]
                    for j in jumps
                ],
            )
            if jumps
            else "<p>none</p>",
        )
    )
    parts.append(
        section(
            "Where the diagnosis changed its mind",
            bullet_list(
                f"{c['probe']}: {c['recording']}: {c['before'] or 'failed'} → "
                f"{c['after'] or 'failed'}"
                for c in changes
            ),
        )
    )
    by_probe: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        by_probe[row.get("probe") or ""].append(row)
    for probe, points in series.items():
        listing = table(
            [
                "recording",
                "start",
                "τ1 (s)",
                "τ2 (s)",
                "first-order error (%)",
                "final model error (%)",
                "verdict",
            ],
            [
                [
                    p.recording,
                    _start_text(p.start_s),
                    p.tau1,
                    p.tau2,
                    p.base_error_pct,
                    p.error_pct,
                    p.verdict or "failed",
                ]
                for p in points
            ],
        )
        figure = image(_trend_figure(probe, by_probe[probe]), f"tau over time, probe {probe}")
        parts.append(section(f"Probe {probe or '(none)'}", figure, listing))
    if failed:
        parts.append(
            section(
                "Recordings that failed", bullet_list(f"{name}: {error}" for name, error in failed)
            )
        )
    text = page("tcomp campaign", "\n".join(parts))
    with atomic_output(path, overwrite=True) as temporary:
        temporary.write_text(text, encoding="utf8")
    return path


def _start_text(seconds: float) -> str:
    date = _date(seconds)
    if date is not None:
        return date.strftime("%Y-%m-%d %H:%M:%S")
    return f"{seconds:.3f} s" if math.isfinite(seconds) else "n/a"
