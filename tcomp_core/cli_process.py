"""The ``tcomp process`` command: recorded bags or CSV files in, compensated bags or CSV out."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .errors import TcompError
from .estimators import METHODS
from .io import DEFAULT_TOPICS
from .online import RECONSTRUCT_FROM, RECONSTRUCTIONS, OnlineConfig

__all__ = ["add_process_command"]


def _positive(text: str) -> float:
    value = float(text)
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return value


def _non_negative(text: str) -> float:
    value = float(text)
    if not (value >= 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number >= 0")
    return value


def add_process_command(verbs: Any) -> None:
    """Register ``process`` on the sub-parsers of ``tcomp``."""
    proc = verbs.add_parser(
        "process",
        help="process recorded bags or CSV files into a new bag (or CSV) with gas_temperature, "
        "the tau history and the diagnosis",
        description="Read a rosbag2 MCAP bag or CSV record chunk by chunk, estimate tau1, tau2 "
        "on a sliding window exactly as the compensator node does (re-estimation every "
        "--update-period-s of stamp time), reconstruct the gas temperature and write a new "
        "bag with the input topics, /gas_temperature, /diagnostics (one DiagnosticArray per "
        "estimate) and /diagnosis (the verdict); or, when OUTPUT ends in .csv, the columns "
        "time,tc1,tc2[,ref],gas,tau1,tau2. A directory of bags is processed into a directory, "
        "--jobs at a time.",
    )
    proc.add_argument(
        "data", type=Path, help="bag (directory or .mcap), CSV file, or a directory of them"
    )
    proc.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="output bag directory or .csv file; a directory for a directory of inputs",
    )
    proc.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help=f"bag topics of tc1, tc2 and optionally ref (default {' '.join(DEFAULT_TOPICS)})",
    )
    proc.add_argument(
        "--columns",
        nargs="+",
        metavar="COLUMN",
        help="CSV columns of tc1, tc2 and optionally ref (default tc1 tc2 ref)",
    )
    defaults = OnlineConfig()
    engine = proc.add_argument_group("estimation and reconstruction (the node's parameters)")
    engine.add_argument(
        "--window-s",
        type=_positive,
        default=defaults.window_s,
        help=f"estimation window, s (default {defaults.window_s:g})",
    )
    engine.add_argument(
        "--update-period-s",
        type=_positive,
        default=0.5,
        help="re-estimation period in stamp time, s (default 0.5)",
    )
    engine.add_argument(
        "--batch-s",
        type=_positive,
        default=0.1,
        help="pairs go to the compensator in batches of this much stamp "
        "time, s (default 0.1; keep it a divisor of --update-period-s)",
    )
    engine.add_argument(
        "--method",
        choices=METHODS,
        default=defaults.method,
        help=f"estimator (default {defaults.method})",
    )
    engine.add_argument(
        "--phi",
        type=_positive,
        default=defaults.phi,
        help="noise variance ratio sigma1^2/sigma2^2 (default 1)",
    )
    engine.add_argument(
        "--prefilter-hz",
        type=_non_negative,
        default=0.0,
        help="zero-phase pre-filter of the window, Hz (default 0 = off)",
    )
    engine.add_argument(
        "--postfilter-hz",
        type=_non_negative,
        default=0.0,
        help="causal low-pass on the gas temperature, Hz (default 0 = off)",
    )
    engine.add_argument(
        "--reconstruction",
        choices=RECONSTRUCTIONS,
        default="difference",
        help="Eq. (7) ('difference', default) or the causal Kalman filter",
    )
    engine.add_argument(
        "--reconstruct-from",
        choices=RECONSTRUCT_FROM,
        default="fused",
        help="which Eq. (7) reconstruction (default fused)",
    )
    engine.add_argument(
        "--sample-period-s",
        type=_non_negative,
        default=0.0,
        help="sample period, s (default 0 = learn it from the stamps)",
    )
    out = proc.add_argument_group("output")
    out.add_argument(
        "--no-diagnose",
        action="store_true",
        help="skip the diagnosis (it takes seconds to a minute)",
    )
    out.add_argument(
        "--diagnose-samples",
        type=int,
        default=20_000,
        help="the diagnosis sees the last this many pairs (default 20000)",
    )
    out.add_argument(
        "--compress",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="zstd-compress the bag's chunks (default; about a third of the size, and faster to "
        "write); --no-compress writes them plain, as ros2 bag record does",
    )
    out.add_argument(
        "--csv",
        action="store_true",
        help="with a directory of inputs: write CSV files instead of bags",
    )
    out.add_argument(
        "--frame-id", default="", help="frame_id of gas_temperature (default: that of tc1)"
    )
    out.add_argument("--force", action="store_true", help="replace existing outputs")
    out.add_argument(
        "--jobs", type=int, default=1, help="inputs processed in parallel processes (default 1)"
    )
    proc.set_defaults(handler=_cmd_process)


def _names(values: list[str] | None, what: str) -> tuple[str, str, str | None] | None:
    if not values:
        return None
    if len(values) not in (2, 3):
        raise TcompError(f"--{what} takes the tc1 and tc2 {what} and optionally ref")
    return (values[0], values[1], values[2] if len(values) == 3 else None)


def _config(args: argparse.Namespace) -> Any:
    from .io import DEFAULT_COLUMNS
    from .process import ProcessConfig

    online = OnlineConfig(
        window_s=args.window_s,
        method=args.method,
        phi=args.phi,
        prefilter_hz=args.prefilter_hz,
        postfilter_hz=args.postfilter_hz,
        reconstruction=args.reconstruction,
        reconstruct_from=args.reconstruct_from,
        sample_period_s=args.sample_period_s,
    )
    return ProcessConfig(
        online=online,
        update_period_s=args.update_period_s,
        batch_s=args.batch_s,
        topics=_names(args.topics, "topics") or DEFAULT_TOPICS,
        columns=_names(args.columns, "columns") or DEFAULT_COLUMNS,
        diagnose=not args.no_diagnose,
        diagnose_samples=args.diagnose_samples,
        compress=args.compress,
        overwrite=args.force,
        frame_id=args.frame_id,
    )


def _cmd_process(args: argparse.Namespace) -> int:
    from .process import find_inputs, format_summary, process_many

    if args.jobs < 1:
        raise TcompError(f"--jobs {args.jobs} must be >= 1")
    config = _config(args)
    data: Path = args.data
    batch = data.is_dir() and not (data / "metadata.yaml").is_file()
    if batch:
        if args.output.suffix.lower() == ".csv":
            raise TcompError(f"{args.output}: a directory of inputs needs an output directory")
        outcomes = process_many(
            find_inputs(data),
            args.output,
            config,
            jobs=args.jobs,
            suffix=".csv" if args.csv else "",
        )
    else:
        from .process import process_one

        outcome = process_one(data, args.output, config, True)
        if outcome.result is None:
            raise TcompError(outcome.error)
        outcomes = [outcome]
    for outcome in outcomes:
        if outcome.result is not None:
            for warning in outcome.result.warnings:
                print(f"tcomp process: warning: {warning}", file=sys.stderr)
            print(f"wrote {outcome.output}")
    print(format_summary(outcomes))
    return 1 if any(o.result is None for o in outcomes) else 0
