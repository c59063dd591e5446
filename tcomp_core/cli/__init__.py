"""The ``tcomp`` command line: the verbs that simulate, estimate, reconstruct, track, process.

Also sweep, study, diagnose and fit.

DATA arguments are a CSV file (``time,tc1,tc2[,ref]``) or a rosbag2 MCAP bag (directory or
``.mcap`` file) with ``sensor_msgs/msg/Temperature`` on ``/tc1/temperature``,
``/tc2/temperature`` and optionally ``/tref/temperature``. Errors are printed as one line naming
the file, column or topic, sample and value, with exit status 1.

Each verb is one module with ``add_parser(verbs)``, which adds its sub-parser and sets
``handler=run``, and ``run(args) -> int``, which does the work. :mod:`.common` holds what the
verbs share (argument types, the DATA arguments, reading the data). A verb module imports only
the standard library, :mod:`tcomp_core.choices` and :mod:`tcomp_core.errors` at module level and
the numerical core inside ``run``: ``tcomp --help`` then starts without numpy, scipy,
matplotlib, rosbags or mcap (``test/test_imports.py`` checks it).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, TextIO

from .. import __version__
from ..errors import TcompError, TcompWarning
from . import (
    campaign,
    diagnose,
    estimate,
    fit,
    process,
    reconstruct,
    simulate,
    study,
    sweep,
    track,
)
from .common import check_outputs, output_paths

__all__ = ["VERBS", "build_parser", "main"]


class _ShowWarning(Protocol):
    """The signature of ``warnings.showwarning``."""

    def __call__(
        self,
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None: ...


#: The verb modules, in the order ``tcomp --help`` lists them.
VERBS = (
    simulate,
    estimate,
    reconstruct,
    sweep,
    study,
    diagnose,
    fit,
    track,
    process,
    campaign,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``tcomp`` with one sub-command per verb."""
    parser = argparse.ArgumentParser(
        prog="tcomp",
        description="Two-thermocouple lag compensation (Hung, Irwin, Kee & McLoone 2005).",
    )
    parser.add_argument("--version", action="version", version=f"tcomp {__version__}")
    verbs = parser.add_subparsers(dest="verb", required=True, metavar="VERB")
    for verb in VERBS:
        verb.add_parser(verbs)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``tcomp`` with ``argv`` (``sys.argv[1:]`` by default); returns the exit status.

    Errors of the data or the options (``TcompError``, ``ValueError``, ``OSError``) are printed
    as one line ``tcomp VERB: error: ...`` on stderr with exit status 1; usage errors exit
    through argparse with status 2. Each :class:`~tcomp_core.errors.TcompWarning` issued while
    the verb runs is printed as one line ``tcomp VERB: warning: ...`` on stderr.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("always", TcompWarning)
        # numpy's arithmetic warnings on hostile data are noise beside the one error line.
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.showwarning = _warning_printer(args.verb, warnings.showwarning)
        try:
            check_outputs(args)
            return args.handler(args)
        except (TcompError, ValueError, OSError) as exc:
            print(f"tcomp {args.verb}: error: {_naming_the_file(exc, args)}", file=sys.stderr)
            return 1
        except (ArithmeticError, LookupError, MemoryError, RecursionError) as exc:
            # A failure on data no check foresaw: still one line naming the file, no traceback.
            what = f"{type(exc).__name__}: {exc}"
            print(
                f"tcomp {args.verb}: error: {_naming_the_file(what, args)} (unexpected on this "
                "input; please report it)",
                file=sys.stderr,
            )
            return 1


def _naming_the_file(error: BaseException | str, args: argparse.Namespace) -> str:
    """The error's text, prefixed with the input's path unless it already names a file."""
    text = " ".join(str(error).split())  # one line
    if isinstance(error, OSError) and error.filename is not None and error.strerror:
        text = f"{error.filename}: {error.strerror}"
    data = getattr(args, "data", None)
    named = [data] if data is not None else []
    named += [path for path, _ in output_paths(args)]
    if data is None or any(str(path) in text or Path(path).name in text for path in named):
        return text
    return f"{data}: {text}"


def _warning_printer(verb: str, fallback: _ShowWarning) -> _ShowWarning:
    """A ``warnings.showwarning`` printing a :class:`TcompWarning` as one line on stderr."""

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if issubclass(category, TcompWarning):
            print(f"tcomp {verb}: warning: {message}", file=sys.stderr)
        else:
            fallback(message, category, filename, lineno, file, line)

    return show
