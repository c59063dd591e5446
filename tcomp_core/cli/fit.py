"""``tcomp fit``: fit the first-order model plus a chosen list of effects."""

from __future__ import annotations

import argparse

from ..choices import EFFECT_NAMES
from ..errors import DataError
from .common import Verbs, add_data_arguments, compensate_effects, effect_list, read_data
from .diagnosis import add_outputs, write_diagnosis

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``fit`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "fit",
        help="fit the model with a chosen set of effects",
        description="Fit the first-order model plus the effects given, in that order, and "
        "score every step on held-out blocks like diagnose does.",
    )
    add_data_arguments(parser)
    parser.add_argument(
        "--effects",
        type=_fitted_effects,
        required=True,
        help=f"comma-separated effects to add, from {', '.join(EFFECT_NAMES)}, or a diagnosis "
        "saved by 'tcomp diagnose --json' (FILE.json: the effects its final model found)",
    )
    add_outputs(parser)
    parser.set_defaults(handler=run)
    return parser


def _fitted_effects(text: str) -> list[str]:
    """Argument type of ``--effects``: :func:`effect_list`, or a saved diagnosis's effects.

    Raises
    ------
    argparse.ArgumentTypeError
        Naming the unknown effect, or the diagnosis file and what is wrong with it.
    """
    try:
        text = compensate_effects(text)
    except DataError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return effect_list(text)


def run(args: argparse.Namespace) -> int:
    """Fit the effects in order, scoring each step, and print (and write) the result."""
    from ..diagnose import fit_effects

    return write_diagnosis(fit_effects(read_data(args), args.effects), args)
