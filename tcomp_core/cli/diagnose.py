"""``tcomp diagnose``: compare the model with the data, find where it fails and the effect.

A record of at most :data:`~tcomp_core.io.windows.WHOLE_SAMPLES` samples is diagnosed whole; a
longer one (or any with ``--window-s``) window by window as it streams from the file, in memory
that does not grow with its length (:mod:`tcomp_core.diagnose.windowed`); ``--whole`` diagnoses
any record whole.
"""

from __future__ import annotations

import argparse
from collections import deque
from typing import TYPE_CHECKING

from ..choices import EFFECT_NAMES
from .common import (
    Verbs,
    add_data_arguments,
    effect_list,
    positive_float,
    read_data,
    source_names,
)
from .diagnosis import add_outputs, write_diagnosis, write_windowed

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

    from ..io.windows import Window, WindowReader

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``diagnose`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "diagnose",
        help="compare the model with the data, find where it fails and the missing effect",
        description="Fit the first-order model (by the cross-relation from a beta-GTLS start, "
        "or at the default path's ml-eiv tau where those simulate better), score its free-run "
        "simulation of the slow sensor on held-out blocks, analyse where it fails, rank the "
        f"effects ({', '.join(EFFECT_NAMES)}) by held-out error after refitting, and add the best "
        "while the error falls significantly. A long record (over 600 000 samples: 2 minutes "
        "at 5 kHz) is diagnosed in windows streamed from the file (60 s at 5 kHz, 300 000 "
        "samples), each with its own row, and the whole record's verdict is the one most "
        "windows give.",
    )
    add_data_arguments(parser)
    parser.add_argument(
        "--candidates",
        type=effect_list,
        default=list(EFFECT_NAMES),
        help="comma-separated effects to consider (default all)",
    )
    parser.add_argument(
        "--max-effects", type=int, default=3, help="most effects to add (default 3)"
    )
    length = parser.add_mutually_exclusive_group()
    length.add_argument(
        "--window-s",
        type=positive_float,
        metavar="SECONDS",
        help="diagnose in windows of this many seconds, read as the file streams (default: "
        "the whole record up to 600 000 samples, windows of 300 000 samples beyond)",
    )
    length.add_argument(
        "--whole",
        action="store_true",
        help="diagnose the whole record at once whatever its length (about 1.5 kB of memory "
        "per sample: 4.7 GB for 10 minutes at 5 kHz)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="windows diagnosed at once, in worker processes (default 1: one at a time here); "
        "each holds a window's diagnosis, about 1.5 kB per sample (450 MB for 60 s at 5 kHz). "
        "A record diagnosed whole is one job",
    )
    add_outputs(parser)
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Diagnose the record (whole or in windows) and print (and write) the result.

    Raises
    ------
    ValueError
        If ``--max-effects`` is negative or ``--jobs`` below 1.
    """
    import itertools

    from ..diagnose import diagnose
    from ..io.windows import WindowReader

    if args.max_effects < 0:
        raise ValueError(f"--max-effects {args.max_effects} must be >= 0")
    if args.jobs < 1:
        raise ValueError(f"--jobs {args.jobs} must be >= 1")
    if args.whole:
        record = read_data(args)
    else:
        reader = WindowReader(
            args.data,
            args.window_s,
            topics=source_names(args.topics, "topics"),
            columns=source_names(args.columns, "columns"),
        )
        windows = iter(reader)
        first = next(windows)
        if not reader.whole:
            return _in_windows(args, reader, itertools.chain([first], windows))
        if first.record is None:  # a whole record raises instead; kept for the type checker
            raise ValueError(first.problem)
        record = first.record
    if args.jobs > 1:
        print(
            f"{args.data}: diagnosed whole, in one process (--jobs {args.jobs} shares out the "
            "windows of a record diagnosed in windows: see --window-s)",
            flush=True,
        )
    diagnosis = diagnose(record, candidates=args.candidates, max_effects=args.max_effects)
    return write_diagnosis(diagnosis, args)


def _in_windows(args: argparse.Namespace, reader: WindowReader, windows: Iterable[Window]) -> int:
    """Diagnose the windows the reader hands over and print (and write) the result."""
    from ..diagnose.window_pool import diagnose_in_processes
    from ..diagnose.windowed import diagnose_windows
    from ..io.windows import WHOLE_SAMPLES
    from ..process.progress import progress_bar

    if reader.automatic:
        print(
            f"{args.data}: longer than {WHOLE_SAMPLES} samples: diagnosed in windows of "
            f"{reader.window_s:g} s as it streams (--window-s chooses the length, --whole "
            "diagnoses it at once)",
            flush=True,
        )
    bar = progress_bar(f"diagnose {args.data.name}")
    # Where the reader stood when it handed each window over: a row's progress is its window's,
    # not the reader's, which runs up to two windows per worker ahead with --jobs.
    read_to: deque[tuple[float, int]] = deque()

    def noting(windows: Iterable[Window]) -> Iterator[Window]:
        for window in windows:
            read_to.append((reader.fraction, reader.samples_read))
            yield window

    try:
        result = diagnose_windows(
            noting(windows),
            source=str(args.data),
            window_s=lambda: float(reader.window_s or 0.0),
            automatic=reader.automatic,
            candidates=args.candidates,
            max_effects=args.max_effects,
            progress=None if bar is None else lambda _row: bar.update(*read_to.popleft()),
            diagnose_all=None
            if args.jobs == 1
            else lambda windows: diagnose_in_processes(
                windows, args.jobs, args.candidates, args.max_effects
            ),
        )
    finally:
        if bar is not None:
            bar.close()
    return write_windowed(result, args)
