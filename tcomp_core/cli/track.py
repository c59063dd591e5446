"""``tcomp track``: τ1(t), τ2(t) through a record whose flow velocity changes."""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import TcompError
from .common import (
    Verbs,
    add_data_arguments,
    add_force_argument,
    add_output_argument,
    positive_float,
    read_data,
)

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from ..tracking import TauTrack

__all__ = ["PRINTED_ROWS", "add_parser", "run"]

#: Rows of the τ history printed to the terminal (the CSV holds every estimate).
PRINTED_ROWS = 12


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``track`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "track",
        help="track tau1(t), tau2(t) as the flow velocity changes",
        description="Track both time constants through a record with an exponentially "
        "forgetting beta-GTLS. The ratio tau1/tau2 depends on the wire diameters alone, so by "
        "default it is estimated over the whole record and only the common scale is tracked.",
    )
    add_data_arguments(parser)
    parser.add_argument(
        "--memory-s",
        type=positive_float,
        default=0.5,
        help="forgetting time constant, s: shorter follows faster changes (default 0.5)",
    )
    parser.add_argument(
        "--step-s", type=positive_float, default=0.1, help="interval between estimates, s"
    )
    parser.add_argument(
        "--causal",
        action="store_true",
        help="one-sided memory, as online (lags by about --memory-s); default two-sided",
    )
    parser.add_argument(
        "--free-ratio", action="store_true", help="track tau1 and tau2 independently"
    )
    add_output_argument(parser, "write time,tau1,tau2 to this CSV", required=False)
    add_force_argument(parser, "overwrite an existing output")
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Track τ1, τ2, print a summary and write the history to ``--output``.

    Raises
    ------
    TcompError
        If ``--output`` exists without ``--force``, or no window gave an estimate.
    """
    import numpy as np

    from ..tracking import track_tau

    if args.output is not None and args.output.exists() and not args.force:
        raise TcompError(f"{args.output} exists; pass --force to overwrite it")
    record = read_data(args)
    track = track_tau(
        record.tc1,
        record.tc2,
        record.dt,
        memory_s=args.memory_s,
        step_s=args.step_s,
        constrain_ratio=not args.free_ratio,
        centered=not args.causal,
    )
    found = np.isfinite(track.tau1)
    if not found.any():
        raise TcompError(f"{args.data}: no window of {args.memory_s:g} s gave an estimate")
    _print_track(track, found, float(record.time[0]))
    if args.output is not None:
        _write_track(args.output, track, float(record.time[0]), args)
        print(f"wrote {args.output}: {track.time.size} estimates")
    return 0


def _print_track(track: TauTrack, found: NDArray[np.bool_], start_s: float) -> None:
    import numpy as np

    memory = "two-sided" if track.centered else "causal"
    ratio = "free" if math.isnan(track.ratio) else f"held at {track.ratio:.4f}"
    print(f"memory {track.memory_s:g} s ({memory}), ratio tau1/tau2 {ratio}")
    print(f"{'time s':>10} {'tau1 s':>10} {'tau2 s':>10}")
    shown = np.unique(np.linspace(0, track.time.size - 1, PRINTED_ROWS).round().astype(int))
    for index in shown:
        print(
            f"{start_s + track.time[index]:>10.3f} {track.tau1[index]:>10.6f} "
            f"{track.tau2[index]:>10.6f}"
        )
    for name, values in (("tau1", track.tau1[found]), ("tau2", track.tau2[found])):
        low, median, high = np.percentile(values, [0, 50, 100])
        print(
            f"{name}: median {median:.6f} s, range {low:.6f} .. {high:.6f} s "
            f"({100 * (high / low - 1):.1f} % swing)"
        )
    missing = int((~found).sum())
    if missing:
        print(f"{missing} of {found.size} windows gave no estimate (NaN in the CSV)")


def _write_track(path: Path, track: TauTrack, start_s: float, args: argparse.Namespace) -> None:
    from ..io import atomic_output

    with (
        atomic_output(path, args.force, [args.data]) as temporary,
        temporary.open("w", newline="") as stream,
    ):
        writer = csv.writer(stream)
        writer.writerow(["time", "tau1", "tau2"])
        for row in zip(start_s + track.time, track.tau1, track.tau2, strict=True):
            writer.writerow([repr(float(value)) for value in row])
