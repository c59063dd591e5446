"""``tcomp diagnose``: compare the model with the data, find where it fails and the effect."""

from __future__ import annotations

import argparse

from ..choices import EFFECT_NAMES
from .common import Verbs, add_data_arguments, effect_list, read_data
from .diagnosis import add_outputs, write_diagnosis

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``diagnose`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "diagnose",
        help="compare the model with the data, find where it fails and the missing effect",
        description="Fit the first-order model (beta-GTLS), score its free-run simulation of "
        "the slow sensor on held-out blocks, analyse where it fails, rank the effects "
        f"({', '.join(EFFECT_NAMES)}) by held-out error after refitting, and add the best "
        "while the error falls significantly.",
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
    add_outputs(parser)
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Diagnose the record and print (and write) the result.

    Raises
    ------
    ValueError
        If ``--max-effects`` is negative.
    """
    from ..diagnose import diagnose

    if args.max_effects < 0:
        raise ValueError(f"--max-effects {args.max_effects} must be >= 0")
    record = read_data(args)
    diagnosis = diagnose(record, candidates=args.candidates, max_effects=args.max_effects)
    return write_diagnosis(diagnosis, args)
