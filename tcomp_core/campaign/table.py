"""The campaign table: one row per recording and window, as Parquet and CSV.

Columns (:data:`SCHEMA`): the probe, the recording (its name in the campaign), the file, the
window (index, start as a UTC time and in seconds, length, samples), the window's diagnosis
(verdict, the final model's effects joined by ``+`` and their parameters as JSON, τ1 and τ2
with their 95 % intervals in seconds, the held-out model error of the final and of the base
model in %, why a window was not diagnosed), and of the whole recording: its verdict, matched
pairs, invalid and dropped samples, the streamed estimate's last τ, the compensated output
and the error that stopped it. A recording that failed as a whole is one row with window −1.
Bag stamps are absolute, so ``window_start`` is a date; a CSV file's times are as written.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..io.outputs import atomic_output

__all__ = ["SCHEMA_FIELDS", "campaign_rows", "read_table", "write_table"]

#: (column, pyarrow type name) in table order.
SCHEMA_FIELDS: tuple[tuple[str, str], ...] = (
    ("probe", "string"),
    ("recording", "string"),
    ("file", "string"),
    ("window", "int32"),
    ("window_start", "timestamp"),
    ("window_start_s", "float64"),
    ("window_length_s", "float64"),
    ("samples", "int64"),
    ("verdict", "string"),
    ("effects", "string"),
    ("params", "string"),
    ("tau1", "float64"),
    ("tau1_low", "float64"),
    ("tau1_high", "float64"),
    ("tau2", "float64"),
    ("tau2_low", "float64"),
    ("tau2_high", "float64"),
    ("error_pct", "float64"),
    ("base_error_pct", "float64"),
    ("problem", "string"),
    ("votes", "bool"),
    ("recording_verdict", "string"),
    ("pairs", "int64"),
    ("invalid", "int64"),
    ("dropped", "int64"),
    ("stream_tau1", "float64"),
    ("stream_tau2", "float64"),
    ("output", "string"),
    ("error", "string"),
)


def campaign_rows(entries: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The table's rows from the recordings' ledger entries (:func:`.task.run_recording`)."""
    rows = []
    for entry in entries:
        tau = entry.get("tau") or [math.nan, math.nan]
        recording = {
            "probe": entry.get("probe", ""),
            "recording": entry["recording"],
            "file": entry["file"],
            "recording_verdict": entry.get("verdict", ""),
            "pairs": entry.get("pairs", 0),
            "invalid": entry.get("invalid", 0),
            "dropped": entry.get("dropped", 0),
            "stream_tau1": tau[0],
            "stream_tau2": tau[1],
            "output": entry.get("output", ""),
            "error": entry.get("error", ""),
        }
        windows = entry.get("windows") or [{"window": -1}]
        rows += [{**recording, **window} for window in windows]
    return rows


def _arrow_type(name: str):
    import pyarrow as pa

    if name == "timestamp":
        return pa.timestamp("ns", tz="UTC")
    return getattr(pa, {"string": "string", "bool": "bool_"}.get(name, name))()


def _column(name: str, kind: str, rows: list[dict[str, Any]]) -> list[Any]:
    if kind == "timestamp":
        seconds = [row.get("window_start_s") for row in rows]
        return [None if s is None or not math.isfinite(s) else round(s * 1e9) for s in seconds]
    values = [row.get(name) for row in rows]
    if kind == "string":
        return ["" if v is None else str(v) for v in values]
    if kind == "float64":
        return [math.nan if v is None else float(v) for v in values]
    return values


def write_table(rows: list[dict[str, Any]], out_dir: Path) -> tuple[Path, Path]:
    """Write ``campaign.parquet`` and ``campaign.csv`` in ``out_dir``; returns their paths.

    Rows are sorted by probe, window start and recording; both files are replaced whole
    (:func:`~tcomp_core.io.atomic_output`).
    """
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    ordered = sorted(
        rows,
        key=lambda r: (
            str(r.get("probe", "")),
            _sortable(r.get("window_start_s")),
            str(r.get("recording", "")),
            int(r.get("window", -1)),
        ),
    )
    schema = pa.schema([(name, _arrow_type(kind)) for name, kind in SCHEMA_FIELDS])
    table = pa.table(
        {name: _column(name, kind, ordered) for name, kind in SCHEMA_FIELDS}, schema=schema
    )
    parquet, csv = out_dir / "campaign.parquet", out_dir / "campaign.csv"
    with atomic_output(parquet, overwrite=True) as temporary:
        pq.write_table(table, temporary)
    with atomic_output(csv, overwrite=True) as temporary:
        pa_csv.write_csv(table, temporary)
    return parquet, csv


def _sortable(value: Any) -> float:
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else math.inf


def read_table(path: Path) -> list[dict[str, Any]]:
    """The rows of a campaign's ``campaign.parquet`` as dicts (for the report and tests)."""
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()
