"""``tcomp campaign``: every recording processed and diagnosed, the table and the report.

Layout of the output directory::

    OUT/recordings/NAME      the compensated output of each recording (bag, or NAME.csv)
    OUT/ledger/KEY.json      each recording's result, by content key (:mod:`.ledger`)
    OUT/campaign.parquet     the table, one row per recording and window (:mod:`.table`)
    OUT/campaign.csv         the same table as CSV
    OUT/report.html          τ per probe over time, verdicts, jumps, fouling alarms

A rerun with the same inputs and options finds every result in the ledger and does no work; new
or changed recordings are processed and the table and report are written again from all of
them, so a campaign can be extended day by day.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import DataError
from .cluster import ClusterSpec, Job, dask_client, run_jobs
from .inputs import Recording, find_recordings
from .ledger import Ledger
from .table import campaign_rows, write_table
from .task import CampaignOptions, run_recording

__all__ = ["CampaignResult", "run_campaign"]


@dataclass(frozen=True, kw_only=True)
class CampaignResult:
    """What a campaign run did.

    Attributes
    ----------
    recordings : int
        Recordings found.
    processed, reused, failed : int
        Processed in this run, taken from the ledger, failed (their rows say why).
    rows : list of dict
        The table's rows.
    table, csv, report : Path
        The files written.
    seconds : float
        Wall time of the run.
    pairs : int
        Pairs processed in this run.
    """

    recordings: int
    processed: int
    reused: int
    failed: int
    rows: list[dict[str, Any]] = field(repr=False)
    table: Path
    csv: Path
    report: Path
    seconds: float
    pairs: int


def output_path(recording: Recording, out_dir: Path, csv: bool) -> Path:
    """Where a recording's compensated output goes."""
    name = recording.name
    for suffix in (".mcap", ".csv", ".MCAP", ".CSV"):
        name = name.removesuffix(suffix)
    return out_dir / "recordings" / (name + (".csv" if csv else ""))


def run_campaign(
    inputs: Sequence[str | Path],
    out_dir: Path,
    options: CampaignOptions | None = None,
    spec: ClusterSpec | None = None,
    *,
    drift_threshold: float = 0.2,
    log: Callable[[str], None] | None = None,
) -> CampaignResult:
    """Process, diagnose, tabulate and report every recording of ``inputs`` into ``out_dir``.

    Parameters
    ----------
    inputs : sequence of str or Path
        Directories (walked), globs or recordings (:func:`~.inputs.find_recordings`).
    out_dir : Path
        The campaign's output directory (created; a rerun reuses its ledger).
    options : CampaignOptions, optional
    spec : ClusterSpec, optional
        Where the tasks run (default: an embedded local cluster).
    drift_threshold : float
        Relative change of a probe's τ, first recording to last, that raises a fouling alarm.
    log : callable, optional
        Told one line per finished recording (default: stderr, above a progress bar when
        stderr is a terminal).

    Raises
    ------
    DataError
        Inputs that hold no recording, or two recordings with one output name.
    """
    from .report import write_report

    started = time.perf_counter()
    options = options or CampaignOptions()
    spec = spec or ClusterSpec()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    bar = None
    log_is_default = log is None
    if log is None:
        log = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    recordings = find_recordings(
        inputs,
        rule=options.probe,
        tc_topics=(str(options.process.topics[0]), str(options.process.topics[1])),
        exclude=out_dir.resolve(),
    )
    outputs = [output_path(r, out_dir, options.csv) for r in recordings]
    if len(set(outputs)) != len(outputs):
        twice = sorted({str(o) for o in outputs if outputs.count(o) > 1})
        raise DataError(f"two recordings would write the same output: {', '.join(twice)}")
    ledger = Ledger(out_dir)
    described = options.describe()
    keys = [ledger.key(r, described) for r in recordings]
    ledger.save_digests()
    entries: dict[str, dict[str, Any]] = {}
    jobs: list[Job] = []
    for recording, key, output in zip(recordings, keys, outputs, strict=True):
        done = ledger.finished(key)
        if done is not None:
            entries[recording.name] = done
            continue
        arguments = (recording, str(output), str(ledger.entry_path(key)), key, options)
        jobs.append(Job(f"tcomp-{recording.name}-{key[:12]}", arguments))
    by_job = {job.name: job.arguments[0] for job in jobs}
    if jobs:
        log(
            f"tcomp campaign: {len(jobs)} of {len(recordings)} recordings to process on "
            f"{spec.describe()}"
        )
        finished = 0
        if log_is_default and sys.stderr.isatty():
            from tqdm import tqdm

            bar = tqdm(total=len(jobs), desc="tcomp campaign", unit="recording", file=sys.stderr)
            log = bar.write

        def tell(job: Job, result: dict[str, Any]) -> None:
            nonlocal finished
            finished += 1
            recording = by_job[job.name]
            outcome = result.get("error") or f"verdict {result.get('verdict', '?')}"
            log(f"[{finished}/{len(jobs)}] {recording.name}: {outcome}")
            if bar is not None:
                bar.update(1)

        try:
            with dask_client(spec) as client:
                results = run_jobs(client, run_recording, jobs, on_result=tell)
        finally:
            if bar is not None:
                bar.close()
        for job, result in zip(jobs, results, strict=True):
            recording = by_job[job.name]
            entries[recording.name] = {
                "recording": recording.name,
                "file": str(recording.path),
                "probe": recording.probe,
                **result,
            }
    else:
        log(f"tcomp campaign: all {len(recordings)} recordings are done (nothing to process)")
    ordered = [entries[r.name] for r in recordings]
    rows = campaign_rows(ordered)
    table, csv = write_table(rows, out_dir)
    report = write_report(rows, out_dir / "report.html", drift_threshold=drift_threshold)
    return CampaignResult(
        recordings=len(recordings),
        processed=len(jobs),
        reused=len(recordings) - len(jobs),
        failed=sum(1 for entry in ordered if entry.get("error")),
        rows=rows,
        table=table,
        csv=csv,
        report=report,
        seconds=time.perf_counter() - started,
        pairs=sum(int(entries[by_job[j.name].name].get("pairs", 0) or 0) for j in jobs),
    )
