"""What the verbs of ``tcomp`` share: argument types, the DATA arguments, reading the data.

Building a parser from this module costs only the standard library: the numerical core is
imported inside the functions that run a verb (:func:`read_data`, :func:`estimate_with`).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from ..choices import (
    DEFAULT_METHOD,
    DEFAULT_TOPICS,
    METHODS,
    names_a_saved_diagnosis,
    parse_effect_list,
)
from ..errors import TcompError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ..estimators import Estimate
    from ..io import Record
    from ..lines import ForeignLine

__all__ = [
    "Verbs",
    "add_data_arguments",
    "add_estimator_arguments",
    "add_force_argument",
    "add_output_argument",
    "add_source_arguments",
    "check_outputs",
    "effect_list",
    "estimate_with",
    "non_negative_float",
    "output_paths",
    "phi_or_auto",
    "positive_float",
    "read_data",
    "source_names",
]

#: The default topics as ``--help`` shows them.
_DEFAULT_NAMES = tuple(name for name in DEFAULT_TOPICS if name is not None)
#: The sub-command collection of the ``tcomp`` parser that each verb adds its parser to.
#: (argparse has no public name for that type.)
Verbs = argparse._SubParsersAction


def positive_float(text: str) -> float:
    """Argument type: a finite number > 0.

    Raises
    ------
    argparse.ArgumentTypeError
        Naming the text, which argparse prints as a usage error.
    """
    value = float(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return value


def non_negative_float(text: str) -> float:
    """Argument type: a finite number >= 0.

    Raises
    ------
    argparse.ArgumentTypeError
        Naming the text, which argparse prints as a usage error.
    """
    value = float(text)
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number >= 0")
    return value


def phi_or_auto(text: str) -> float | None:
    """Argument type of ``--phi``: a ratio > 0, or ``auto`` (None: measured from the data)."""
    return None if text == "auto" else positive_float(text)


def effect_list(text: str) -> list[str]:
    """Argument type: comma-separated effect names, each one of ``EFFECT_NAMES``.

    Raises
    ------
    argparse.ArgumentTypeError
        Naming the unknown effect and the known ones.
    """
    try:
        names = parse_effect_list(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return list(names or ())


def compensate_effects(text: str) -> str:
    """``--effects`` of reconstruct, process, campaign and fit as the engine takes it.

    A diagnosis file (``*.json``, as ``tcomp diagnose --json`` writes it) gives the effects of
    its final model, comma-separated (``"none"`` for first order), to be fitted on each record
    as a list given by name is, and says which; any other value is returned as given.

    Raises
    ------
    DataError
        Naming the file and what is wrong with it.
    """
    if not names_a_saved_diagnosis(text):
        return text
    from ..diagnose.saved import saved_diagnosis_effects  # loads scipy: only for a file

    found = saved_diagnosis_effects(text)
    print(f"--effects {text.strip()}: {found} (the final model of that diagnosis)")
    return found


def add_source_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--topics`` and ``--columns``: where tc1, tc2 and ref are in a bag or a CSV file."""
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help=f"bag topics of tc1, tc2 and optionally ref (default {' '.join(_DEFAULT_NAMES)})",
    )
    parser.add_argument(
        "--columns",
        nargs="+",
        metavar="COLUMN",
        help="CSV columns of tc1, tc2 and optionally ref (default tc1 tc2 ref)",
    )


def add_data_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the DATA argument (CSV file or MCAP bag) with ``--topics`` and ``--columns``."""
    parser.add_argument("data", type=Path, help="CSV file or rosbag2 MCAP bag")
    add_source_arguments(parser)


def add_estimator_arguments(parser: argparse.ArgumentParser, allow_all: bool = False) -> None:
    """Add ``--method``, ``--prefilter-hz``, ``--phi`` and ``--alpha``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The verb's parser.
    allow_all : bool
        Also offer ``--method all`` (every estimator in turn).
    """
    choices = [*METHODS, "all"] if allow_all else list(METHODS)
    parser.add_argument(
        "--method",
        choices=choices,
        default=DEFAULT_METHOD,
        help=f"estimator (default {DEFAULT_METHOD}: unbiased at any sample rate without a "
        "pre-filter; the paper's six keep their names)",
    )
    parser.add_argument(
        "--prefilter-hz",
        type=positive_float,
        help="zero-phase Butterworth pre-filter bandwidth before estimation, Hz",
    )
    parser.add_argument(
        "--phi",
        type=phi_or_auto,
        default=None,
        help="noise variance ratio sigma1^2/sigma2^2 for beta-gtls and ml-eiv; 'auto' (the "
        "default) measures it from the spectra, less the gas signal both sensors share (the "
        "model)",
    )
    parser.add_argument(
        "--alpha",
        type=positive_float,
        help="time constant ratio tau1/tau2 for tdr-kee (estimated at crossovers if omitted)",
    )


def add_output_argument(
    parser: argparse.ArgumentParser,
    help_text: str,
    *,
    required: bool = True,
    repeatable: bool = False,
) -> None:
    """Add ``-o/--output PATH``, the verb's output file or bag directory.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The verb's parser.
    help_text : str
        What the path is (its kinds: ``*.csv``, a bag directory, ...).
    required : bool
        The verb needs an output.
    repeatable : bool
        ``-o`` may be given several times (``args.output`` is then a list).
    """
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        action="append" if repeatable else "store",
        required=required,
        help=help_text,
    )


def add_force_argument(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, help_text: str
) -> None:
    """Add ``--force``: replace existing outputs, which are refused without it."""
    parser.add_argument("--force", action="store_true", help=help_text)


def source_names(values: list[str] | None, what: str) -> tuple[str, str, str | None] | None:
    """The ``--topics`` or ``--columns`` values as (tc1, tc2, ref or None); None if not given.

    Parameters
    ----------
    values : list of str or None
        The option's values.
    what : str
        ``"topics"`` or ``"columns"``, for the message.

    Raises
    ------
    TcompError
        If not two or three names are given.
    """
    if not values:
        return None
    if len(values) not in (2, 3):
        raise TcompError(f"--{what} takes the tc1 and tc2 {what} and optionally ref")
    return (values[0], values[1], values[2] if len(values) == 3 else None)


def read_data(args: argparse.Namespace) -> Record:
    """Read the DATA argument with the ``--topics`` / ``--columns`` options.

    Raises
    ------
    TcompError
        On a wrong number of topics or columns, or (as :class:`~tcomp_core.errors.DataError`)
        a file that cannot be read, naming the file, topic or column, sample and value.
    """
    from ..io import read_record

    topics = source_names(args.topics, "topics")
    columns = source_names(args.columns, "columns")
    return read_record(args.data, topics=topics, columns=columns)


def estimate_with(record: Record, args: argparse.Namespace, method: str) -> Estimate:
    """Estimate τ1, τ2 of ``record`` by ``method`` with the estimator options in ``args``.

    ``--phi`` applies to the estimators that take it, ``--alpha`` to ``tdr-kee`` alone.
    """
    import numpy as np

    from ..estimators import PHI_METHODS, estimate

    result = estimate(
        record.tc1,
        record.tc2,
        record.dt,
        method,  # type: ignore[arg-type]
        phi=args.phi if method in PHI_METHODS else 1.0,
        alpha=args.alpha if method == "tdr-kee" else None,
        prefilter_hz=args.prefilter_hz,
    )
    warn_beyond_class_2(
        record.source, result.params, float(np.nanmean(record.tc1) + np.nanmean(record.tc2)) / 2.0
    )
    warn_foreign_lines(record.source, result.lines)
    return result


def warn_foreign_lines(source: str, lines: Sequence[ForeignLine]) -> None:
    """Warn that τ was estimated with lines one sensor carries notched from both signals."""
    import warnings

    from ..errors import TcompWarning

    for channel in (1, 2):
        mine = [line for line in lines if line.channel == channel]
        if not mine:
            continue
        listed = ", ".join(
            f"{line.frequency_hz:.4g} Hz ({line.amplitude_c:.3g} °C)" for line in mine
        )
        warnings.warn(
            f"{source}: tc{channel} carries spectral lines that tc{3 - channel} does not: "
            f"{listed}, pick-up such as the mains, not gas. τ is estimated with them notched "
            f"from both readings, and the gas is reconstructed without them on tc{channel}; "
            "check that sensor's shielding and grounding",
            TcompWarning,
            stacklevel=2,
        )


def warn_beyond_class_2(source: str, params: dict[str, float], level_c: float = 0.0) -> None:
    """Warn when ml-eiv's fitted gain or level between the sensors lies beyond IEC 60584 class 2.

    The gain is fitted with τ and the level difference eliminated at every τ
    (:mod:`tcomp_core.estimators.mleiv`); beyond the tolerance, by the calibration effect's
    margin, they take up what the first-order model lacks (conduction to the supports reads as
    a gain of 1.4 on ``bags/conduction_500hz``; on exhaust pulses at 544 °C, supports held cold
    pulled the fine wire to 293 °C and the thick one to 159 °C, and first order read the
    134 °C between them as an offset, with τ 45 times the truth) or a miscalibration, and the
    user is told which command finds out.

    Parameters
    ----------
    source : str
        The record's name, for the message.
    params : dict
        The estimate's ``params`` (``gain``, ``offset_c``: tc1's reading minus the gain times
        tc2's at tc2's mean, degrees C).
    level_c : float
        Mean temperature of the readings, degrees C: class 2 allows 2.5 °C or 0.75 % of it.
    """
    import warnings

    from ..errors import TcompWarning
    from ..tolerance import class2_disagreement

    beyond = class2_disagreement(params.get("gain", 1.0), params.get("offset_c", 0.0), level_c)
    if not beyond:
        return
    warnings.warn(
        f"{source}: {beyond}: τ is first order's with that gain and level fitted. A "
        "difference that large is a physical effect the first-order model lacks (conduction to "
        "the supports, radiation) or a miscalibration: tcomp diagnose tells which, and "
        "--effects auto compensates it",
        TcompWarning,
        stacklevel=2,
    )


#: Options naming an output, and whether it is a directory (``-o`` is one unless ``*.csv``).
_OUTPUT_OPTIONS = {"output": None, "json": False, "png": False, "report": True}


def output_paths(args: argparse.Namespace) -> list[tuple[Path, bool]]:
    """Every output a verb's arguments name, with whether it is a directory.

    ``-o`` (one or several), ``--json FILE``, ``--png`` and ``--report DIR``; ``-o`` is a bag
    directory unless it ends in ``.csv`` (``tcomp process`` on a directory of inputs: a
    directory of outputs).
    """
    found = []
    for option, directory in _OUTPUT_OPTIONS.items():
        value = getattr(args, option, None)
        for path in value if isinstance(value, list) else [value]:
            if isinstance(path, Path):
                is_directory = directory if directory is not None else path.suffix != ".csv"
                found.append((path, is_directory))
    return found


def check_outputs(args: argparse.Namespace) -> None:
    """Before any work: refuse outputs that overlap the input, repeat, or exist without --force.

    Raises
    ------
    DataError
        Naming the output (and the input it would overwrite).
    """
    from ..errors import DataError
    from ..io.outputs import check_output, overlaps
    from ..io.paths import is_bag_directory

    data = getattr(args, "data", None)
    inputs = [data] if isinstance(data, Path) else []
    # process on a directory of inputs writes a directory of outputs, each checked as it goes.
    batch = isinstance(data, Path) and data.is_dir() and not is_bag_directory(data)
    outputs = output_paths(args)
    for index, (path, directory) in enumerate(outputs):
        for other, _ in outputs[:index]:
            if overlaps(path, other):
                raise DataError(f"{path}: named twice as an output (or inside {other})")
        for source in inputs:
            if overlaps(path, source):
                raise DataError(
                    f"{path}: the output would overwrite or sit inside the input {source} (or "
                    "contain it); choose another output path"
                )
        if not batch:
            check_output(path, bool(getattr(args, "force", False)), inputs, directory=directory)
