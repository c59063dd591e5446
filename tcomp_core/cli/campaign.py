"""``tcomp campaign``: many recordings of many probes, processed and diagnosed on Dask.

The engine options are those of ``tcomp process`` (the node's parameters), declared once in
:mod:`tcomp_core.parameters`.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..errors import TcompError
from .common import Verbs, add_source_arguments, positive_float
from .process import add_engine_arguments, add_stream_output_arguments, process_config

__all__ = ["add_parser", "run"]


def _window_length(text: str) -> float:
    """Argument type: a window length > 0 in seconds, or ``whole``/``inf`` (one window)."""
    return math.inf if text.strip().lower() in ("whole", "inf") else positive_float(text)


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``campaign`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "campaign",
        help="process and diagnose every recording of a campaign on a Dask cluster; write a "
        "table (Parquet and CSV) and an HTML report of tau per probe over time",
        description="Walk directories or globs of recordings (bags and CSV files), process each "
        "as tcomp process does (a compensated bag or CSV in OUT/recordings), diagnose it in "
        "windows of --diagnosis-window-s, and write OUT/campaign.parquet and OUT/campaign.csv "
        "(one row per recording and window: probe, start, tau1, tau2 with their intervals, "
        "model error, verdict, effects and their parameters, invalid and dropped samples) and "
        "OUT/report.html (tau per probe over time, verdicts, model-error jumps, fouling "
        "alarms). Runs on an embedded local Dask cluster, or on an existing one "
        "(--scheduler, --scheduler-file). A rerun skips recordings whose results are "
        "complete (same bytes, same options).",
    )
    parser.add_argument(
        "inputs",
        nargs="+",
        help="directories (walked recursively), globs (quote them: 'cells/*/day*.mcap') or "
        "recordings",
    )
    # Not the -o of the other verbs (an output refused when it exists): a campaign's directory
    # is extended by every rerun.
    parser.add_argument(
        "-o",
        "--output",
        dest="campaign_dir",
        type=Path,
        required=True,
        help="the campaign's output directory (created; a rerun reuses and extends it)",
    )
    add_source_arguments(parser)
    group = parser.add_argument_group("campaign")
    group.add_argument(
        "--diagnosis-window-s",
        type=_window_length,
        default=60.0,
        help="diagnosis window, seconds of sample time (default 60; 'whole' diagnoses each "
        "recording in one window)",
    )
    group.add_argument(
        "--probe",
        default="dir",
        help="where a recording's probe id comes from: dir (its directory's name, default), "
        "dir:N (N levels up), topic (the tc1 topic's namespace; a bag holding several probes "
        "is one recording per namespace), frame (tc1's frame_id) or map:FILE (CSV rows "
        "'pattern,probe')",
    )
    group.add_argument(
        "--drift-threshold",
        type=positive_float,
        default=0.2,
        help="relative change of a probe's tau, first recording to last, that raises a "
        "fouling alarm (default 0.2)",
    )
    group.add_argument(
        "--csv", action="store_true", help="write the compensated outputs as CSV, not bags"
    )
    cluster = parser.add_argument_group("cluster (default: a local cluster, one worker per core)")
    where = cluster.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of a running scheduler, tcp://host:8786")
    where.add_argument("--scheduler-file", type=Path, help="scheduler file of a running cluster")
    where.add_argument(
        "--workers", type=int, help="worker processes of the local cluster (default: cores)"
    )
    add_engine_arguments(parser)
    add_stream_output_arguments(parser.add_argument_group("output"))
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Run the campaign and print where its table and report are.

    Returns
    -------
    int
        0, or 1 if any recording failed (its row says why).

    Raises
    ------
    TcompError
        On a bad option or inputs holding no recording.
    """
    from ..campaign import CampaignOptions, ClusterSpec, ProbeRule, run_campaign

    if args.workers is not None and args.workers < 1:
        raise TcompError(f"--workers {args.workers} must be >= 1")
    options = CampaignOptions(
        process=process_config(args),
        window_s=args.diagnosis_window_s,
        probe=ProbeRule.parse(args.probe),
        csv=args.csv,
    )
    spec = ClusterSpec(args.scheduler, args.scheduler_file, args.workers)
    result = run_campaign(
        args.inputs, args.campaign_dir, options, spec, drift_threshold=args.drift_threshold
    )
    print(
        f"{result.recordings} recordings: {result.processed} processed, {result.reused} "
        f"reused, {result.failed} failed ({result.seconds:.1f} s"
        + (f", {result.pairs / result.seconds:.3g} pairs/s" if result.pairs else "")
        + ")"
    )
    print(f"wrote {result.table}")
    print(f"wrote {result.csv}")
    print(f"wrote {result.report}")
    return 1 if result.failed else 0
