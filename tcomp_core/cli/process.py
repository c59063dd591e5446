"""``tcomp process``: recorded bags or CSV files in, compensated bags or CSV out.

The engine options are the compensator node's parameters, declared once in
:mod:`tcomp_core.parameters` (numpy-free, so building the parser loads no numerical module).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from .. import parameters
from ..choices import DEFAULT_COLUMNS, DEFAULT_TOPICS
from ..errors import TcompError
from .common import (
    Verbs,
    add_force_argument,
    add_output_argument,
    add_source_arguments,
    compensate_effects,
    non_negative_float,
    positive_float,
    source_names,
)

if TYPE_CHECKING:
    from ..process import ProcessConfig

__all__ = [
    "add_engine_arguments",
    "add_parser",
    "add_stream_output_arguments",
    "process_config",
    "run",
]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``process`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "process",
        help="process recorded bags or CSV files into a new bag (or CSV) with gas_temperature, "
        "the tau history and the diagnosis",
        description="Read a rosbag2 MCAP bag or CSV record chunk by chunk, estimate tau1, tau2 "
        "on a sliding window exactly as the compensator node does (re-estimation every "
        "--update-period-s of stamp time), reconstruct the gas temperature and write a new "
        "bag with the input topics, /gas_temperature, /diagnostics (the node's status, one "
        "per second of stamp time) and /diagnosis (the verdict); or, when OUTPUT ends in .csv, "
        "the columns time,tc1,tc2[,ref],gas,gas_variance,tau1,tau2. A directory of bags is "
        "processed into a directory, "
        "--jobs at a time.",
    )
    parser.add_argument(
        "data", type=Path, help="bag (directory or .mcap), CSV file, or a directory of them"
    )
    add_output_argument(
        parser, "output bag directory or .csv file; a directory for a directory of inputs"
    )
    add_source_arguments(parser)
    add_engine_arguments(parser)
    _add_output_arguments(parser)
    parser.set_defaults(handler=run)
    return parser


#: The node's parameters ``process`` takes as options (``--window-s`` for ``window_s``);
#: defaults, choices and help come from their declaration (:mod:`tcomp_core.parameters`).
ENGINE_OPTIONS = (
    "window_s",
    "update_period_s",
    "method",
    "phi",
    "prefilter_hz",
    "postfilter_hz",
    "reconstruction",
    "signal_model",
    "reconstruct_from",
    "sample_period_s",
    "sync_slop_s",
)


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the node's parameters ``process`` takes (:data:`ENGINE_OPTIONS`) and ``--batch-s``."""
    engine = parser.add_argument_group(
        "estimation and reconstruction (the node's parameters, their defaults the node's)"
    )
    for name in ENGINE_OPTIONS:
        spec = parameters.spec(name)
        kwargs: dict[str, object] = {"default": spec.default}
        if spec.choices:
            kwargs["choices"] = spec.choices
        elif spec.kind is float:
            kwargs["type"] = positive_float if (spec.low or 0.0) > 0.0 else non_negative_float
        default = f"{spec.default:g}" if isinstance(spec.default, float) else spec.default
        engine.add_argument(
            "--" + name.replace("_", "-"),
            help=f"{spec.description} (default {default})".replace("%", "%%"),
            **kwargs,  # type: ignore[arg-type]
        )
    engine.add_argument(
        "--batch-s",
        type=positive_float,
        default=0.1,
        help="pairs go to the compensator in batches of this much stamp "
        "time, s (default 0.1; keep it a divisor of --update-period-s)",
    )


def _add_output_arguments(parser: argparse.ArgumentParser) -> None:
    out = parser.add_argument_group("output")
    out.add_argument(
        "--no-diagnose",
        action="store_true",
        help="skip the diagnosis (it takes seconds to a minute)",
    )
    add_stream_output_arguments(out)
    out.add_argument(
        "--csv",
        action="store_true",
        help="with a directory of inputs: write CSV files instead of bags",
    )
    add_force_argument(out, "replace existing outputs")
    out.add_argument(
        "--jobs", type=int, default=1, help="inputs processed in parallel processes (default 1)"
    )


def add_stream_output_arguments(group: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add how the compensated output is made: effects, diagnosis samples, compression, frame."""
    group.add_argument(
        "--diagnose-samples",
        type=int,
        default=20_000,
        help="the diagnosis sees the last this many pairs, the --effects fit the first this "
        "many (default 20000)",
    )
    group.add_argument(
        "--effects",
        default="none",
        help="publish the gas temperature compensated with physics beyond first order: 'auto' "
        "(the diagnosis's final model), comma-separated effects, or a diagnosis saved by "
        "'tcomp diagnose --json' (FILE.json: the effects its final model found), fitted on "
        "the first --diagnose-samples pairs; 'none' (default) publishes first order",
    )
    group.add_argument(
        "--compress",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="zstd-compress the bag's chunks (default; about a third of the size, and faster to "
        "write); --no-compress writes them plain, as ros2 bag record does",
    )
    group.add_argument(
        "--frame-id", default="", help="frame_id of gas_temperature (default: that of tc1)"
    )


def process_config(args: argparse.Namespace) -> ProcessConfig:
    """The :class:`~tcomp_core.process.ProcessConfig` the parsed options describe.

    Options a verb does not offer (``--no-diagnose``, ``--force``: ``tcomp campaign``) take
    their defaults.

    Raises
    ------
    TcompError
        On a wrong number of ``--topics`` or ``--columns``; ``ValueError`` from the configs
        on a value they refuse.
    """
    from ..online import OnlineConfig
    from ..process import ProcessConfig

    online = OnlineConfig(**{name: getattr(args, name) for name in ENGINE_OPTIONS})
    return ProcessConfig(
        online=online,
        batch_s=args.batch_s,
        topics=source_names(args.topics, "topics") or DEFAULT_TOPICS,
        columns=source_names(args.columns, "columns") or DEFAULT_COLUMNS,
        diagnose=not getattr(args, "no_diagnose", False),
        diagnose_samples=args.diagnose_samples,
        effects=compensate_effects(args.effects),
        compress=args.compress,
        overwrite=getattr(args, "force", False),
        frame_id=args.frame_id,
    )


def run(args: argparse.Namespace) -> int:
    """Process one input, or a directory of them ``--jobs`` at a time; print the summary.

    Returns
    -------
    int
        0, or 1 if any input of a directory failed.

    Raises
    ------
    TcompError
        On a bad option or a single input that fails.
    """
    from ..io import is_bag_directory, is_csv
    from ..process import find_inputs, format_summary, process_many, process_one

    if args.jobs < 1:
        raise TcompError(f"--jobs {args.jobs} must be >= 1")
    config = process_config(args)
    data: Path = args.data
    batch = data.is_dir() and not is_bag_directory(data)
    if batch:
        if is_csv(args.output):
            raise TcompError(f"{args.output}: a directory of inputs needs an output directory")
        outcomes = process_many(
            find_inputs(data),
            args.output,
            config,
            jobs=args.jobs,
            suffix=".csv" if args.csv else "",
        )
    else:
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
