"""``tcomp estimate``: τ1 and τ2 from the two thermocouple signals alone."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from ..choices import METHODS
from ..errors import TcompError
from .common import Verbs, add_data_arguments, add_estimator_arguments, estimate_with, read_data

if TYPE_CHECKING:
    from ..estimators import Estimate

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``estimate`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "estimate",
        help="estimate tau1 and tau2 from two thermocouple signals",
        description="Estimate both time constants from the two signals alone.",
    )
    add_data_arguments(parser)
    add_estimator_arguments(parser, allow_all=True)
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=run)
    return parser


def _row(result: Estimate) -> str:
    raw = ", ".join(f"{key}={value:.6g}" for key, value in result.params.items())
    return (
        f"{result.method:<10} {result.tau1:>10.6f} {result.tau2:>10.6f} {result.alpha:>8.4f} "
        f"{result.condition:>9.3g}  {raw}"
    )


def run(args: argparse.Namespace) -> int:
    """Estimate by ``--method`` (every estimator for ``all``) and print a table or JSON.

    With ``all``, an estimator that fails is listed as failed; with one estimator its error
    propagates (exit status 1 in :func:`tcomp_core.cli.main`).
    """
    record = read_data(args)
    methods = METHODS if args.method == "all" else (args.method,)
    results: list[Estimate] = []
    failures: dict[str, str] = {}
    for method in methods:
        try:
            results.append(estimate_with(record, args, method))
        except (TcompError, ValueError) as exc:
            if len(methods) == 1:
                raise
            failures[method] = str(exc)
    if args.json:
        payload: dict[str, object] = {
            "source": record.source,
            "samples": int(record.tc1.size),
            "dt": record.dt,
        }
        if len(methods) == 1:
            payload.update(results[0].to_dict())
        else:
            payload["estimates"] = [result.to_dict() for result in results]
            payload["failures"] = failures
        print(json.dumps(payload, indent=2))
        return 0
    print(f"{record.source}: {record.tc1.size} samples, dt = {record.dt:.6g} s")
    print(f"{'method':<10} {'tau1 (s)':>10} {'tau2 (s)':>10} {'alpha':>8} {'condition':>9}  raw")
    for result in results:
        print(_row(result))
    for method, text in failures.items():
        print(f"{method:<10} failed: {text}")
    for result in results:
        if wide := result.wide_interval():
            print(
                f"{result.method}: {wide}: these data do not pin it down (the node and "
                "tcomp process refuse such a window and keep the last tau they accepted)"
            )
    return 0
