"""The work of one recording: ``tcomp process`` on it, then its diagnosis window by window.

The compensated output is written by :func:`tcomp_core.process.process`, the engine of
``tcomp process`` and the node (no second code path); its closing diagnosis is replaced by the
windowed one of ``tcomp diagnose`` (:func:`tcomp_core.diagnose.windowed.diagnose_windows`),
which gives one row per window: the table's rows. The function runs in a Dask worker: it takes
and returns plain values, and writes its result to the ledger itself once the output is
complete, so a result survives the client. On a cluster each window's diagnosis is a task of
its own (:data:`WINDOWS_IN_FLIGHT` of a recording at once, their records handed over as they
are read), so the windows of one long recording are diagnosed on every worker; the recording's
task leaves its worker's thread to them while it waits.
"""

from __future__ import annotations

import json
import math
import time
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..diagnose.windowed import WindowResult
from ..errors import DataError, TcompError
from ..io.windows import Window
from ..process import ProcessConfig, process
from .inputs import ProbeRule, Recording
from .ledger import write_entry

__all__ = ["WINDOWS_IN_FLIGHT", "CampaignOptions", "run_recording"]

#: Windows of one recording diagnosed at once on a cluster (their records are held meanwhile).
WINDOWS_IN_FLIGHT = 4
#: A window's task that raised is run again this many times.
WINDOW_RETRIES = 2


@dataclass(frozen=True, kw_only=True)
class CampaignOptions:
    """What every recording of a campaign is processed with.

    Attributes
    ----------
    process : ProcessConfig
        As ``tcomp process`` takes it (its closing diagnosis is replaced by the windows').
    window_s : float
        Diagnosis window, seconds of sample time (``math.inf``: the whole recording).
    probe : ProbeRule
    csv : bool
        Write the compensated outputs as CSV files instead of bags.
    """

    process: ProcessConfig = field(default_factory=ProcessConfig)
    window_s: float = 60.0
    probe: ProbeRule = field(default_factory=ProbeRule)
    csv: bool = False

    def describe(self) -> dict[str, Any]:
        """The options as JSON-ready values: part of each recording's ledger key."""
        return {
            "online": asdict(self.process.online),
            "process": {
                "batch_s": self.process.batch_s,
                "topics": self.process.topics,
                "columns": self.process.columns,
                "effects": self.process.effects,
                "diagnose_samples": self.process.diagnose_samples,
                "compress": self.process.compress,
                "frame_id": self.process.frame_id,
            },
            "window_s": self.window_s if math.isfinite(self.window_s) else "whole",
            "probe": [self.probe.kind, self.probe.level, list(self.probe.mapping)],
            "csv": self.csv,
        }


def _number(value: float | None) -> float:
    return float(value) if value is not None else math.nan


def _counts(counters: dict[str, Any]) -> tuple[int, int]:
    """Invalid (not finite, out of range, undecodable) and dropped (unpaired, late) samples."""
    invalid = sum(int(counters.get(k, 0)) for k in ("invalid_tc1", "invalid_tc2"))
    invalid += sum(int(counters.get(k, 0)) for k in ("malformed_tc1", "malformed_tc2"))
    dropped = sum(
        int(counters.get(k, 0))
        for k in ("unmatched_tc1", "unmatched_tc2", "out_of_order", "duplicates")
    )
    return invalid, dropped


def run_recording(
    recording: Recording,
    output: str,
    entry_path: str,
    key: str,
    options: CampaignOptions,
) -> dict[str, Any]:
    """Process and diagnose one recording; write and return its ledger entry.

    Parameters
    ----------
    recording : Recording
    output : str
        The compensated output (a bag directory, or a ``.csv`` file); replaced if it exists
        (a run cut after writing it and before its entry).
    entry_path : str
        Where the entry goes (:meth:`~.ledger.Ledger.entry_path`).
    key : str
        The recording's ledger key.
    options : CampaignOptions

    Returns
    -------
    dict
        ``recording``, ``file``, ``probe``, ``output``, ``key``, ``pairs``, ``invalid``,
        ``dropped``, ``tau`` (the streamed estimate's last τ1, τ2), ``verdict`` (the whole
        recording's, from its windows), ``seconds``, ``warnings``, ``windows`` (one dict per
        window: see :func:`_window_row`) and ``error`` ('' unless the recording failed; a
        failed recording's entry is returned, not written, so a rerun tries it again).
    """
    from ..diagnose.windowed import diagnose_windows
    from ..io.windows import WindowReader

    started = time.perf_counter()
    topics = recording.topics or options.process.topics
    config = replace(options.process, topics=topics, overwrite=True, diagnose=False)
    entry: dict[str, Any] = {
        "recording": recording.name,
        "file": str(recording.path),
        "probe": recording.probe,
        "output": output,
        "key": key,
        "windows": [],
        "warnings": [],
        "error": "",
    }
    try:
        result = process(recording.path, Path(output), config)
        entry["pairs"] = result.pairs
        entry["invalid"], entry["dropped"] = _counts(result.counters)
        entry["tau"] = [_number(t) for t in (result.tau or (None, None))]
        entry["warnings"] = list(result.warnings)
        reader = WindowReader(
            recording.path, options.window_s, topics=topics, columns=config.columns
        )
        starts: dict[int, float] = {}
        spans: dict[int, float] = {}  # a window's record length, s (a whole record's too)
        frames: list[str] = []

        def windows():
            for window in reader:
                record = window.record
                if record is not None:
                    starts[window.index] = float(record.time[0]) - window.start_s
                    spans[window.index] = float(record.time[-1] - record.time[0]) + record.dt
                    frames.append(record.frame_id)
                yield window

        rows: list[WindowResult] = []
        try:
            found = diagnose_windows(
                windows(),
                source=str(recording.path),
                window_s=options.window_s,
                progress=rows.append,
                diagnose_all=_diagnose_on_cluster,
            )
            entry["verdict"] = found.whole.verdict
            rows = found.windows
        except DataError as exc:  # no window could be diagnosed: the rows say why
            entry["verdict"] = f"failed: {exc}"
        origin = min(starts.values()) if starts else math.nan
        entry["probe"] = options.probe.probe(recording, topics[0], frames[0] if frames else "")
        entry["windows"] = [
            _window_row(row.summary(), origin, spans.get(row.index)) for row in rows
        ]
    except (TcompError, ValueError, OSError) as exc:
        entry["error"] = " ".join(str(exc).split())
        entry["seconds"] = time.perf_counter() - started
        return entry
    entry["seconds"] = time.perf_counter() - started
    write_entry(Path(entry_path), entry)
    return entry


def _diagnose_on_cluster(windows: Iterable[Window]) -> Iterator[WindowResult]:
    """Each window's diagnosis as a task of the cluster this runs on, rows in window order.

    Outside a Dask worker (a recording run directly) the windows are diagnosed here in turn.
    """
    from ..diagnose.windowed import diagnose_window

    try:
        from distributed import get_worker, worker_client

        get_worker()
    except (ImportError, ValueError):  # not in a worker
        yield from (diagnose_window(window) for window in windows)
        return
    with worker_client() as client:
        pending: deque[Any] = deque()
        for window in windows:
            future = client.submit(diagnose_window, window, retries=WINDOW_RETRIES, pure=False)
            pending.append(future)
            if len(pending) >= WINDOWS_IN_FLIGHT:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


def _window_row(
    summary: dict[str, Any], origin_s: float, span_s: float | None = None
) -> dict[str, Any]:
    """A window's diagnosis as a table row: absolute start, τ with intervals, effects.

    The length is the window's (``span_s``, what its record covers, when the window has no
    finite length: a recording diagnosed whole).
    """
    low_high = {name: summary[f"{name}_95"] or [None, None] for name in ("tau1", "tau2")}
    start = summary["start_s"]
    return {
        "window": summary["index"],
        "window_start_s": origin_s + start if np.isfinite(origin_s) else start,
        "window_length_s": summary["length_s"] if summary["length_s"] is not None else span_s,
        "samples": summary["samples"],
        "verdict": summary["verdict"] or "",
        "effects": "+".join(summary["effects"]),
        "params": json.dumps(summary["params"], sort_keys=True),
        "tau1": summary["tau1"],
        "tau1_low": low_high["tau1"][0],
        "tau1_high": low_high["tau1"][1],
        "tau2": summary["tau2"],
        "tau2_low": low_high["tau2"][0],
        "tau2_high": low_high["tau2"][1],
        "error_pct": summary["error_pct"],
        "base_error_pct": summary["base_error_pct"],
        "problem": summary["problem"],
        "votes": summary["votes"],
    }
