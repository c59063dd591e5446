"""``tcomp study``: the Monte Carlo study of Fig. 4 (e_τ against noise level K)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..choices import SIGNALS
from .common import Verbs, add_force_argument, positive_float

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``study`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "study",
        help="Monte Carlo study of Fig. 4",
        description="e_tau against noise level K for every method on the sinusoid and the "
        "periodic ramp (tau1 = 0.0238 s, tau2 = 0.1168 s, tau_s = 0.002 s, 10 s runs).",
    )
    parser.add_argument("--runs", type=int, default=100, help="runs per noise level (default 100)")
    parser.add_argument(
        "--noise-levels", type=float, nargs="+", default=[0, 1, 2, 3, 4, 5, 6], metavar="K"
    )
    parser.add_argument("--signals", nargs="+", choices=SIGNALS, default=["sinusoid", "ramp"])
    parser.add_argument("--phi", type=positive_float, default=1.0, help="noise ratio of the data")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--png", type=Path, default=Path("out/study.png"), help="figure path")
    parser.add_argument("--json", type=Path, help="also write the table as JSON to this file")
    add_force_argument(parser, "replace an existing --png or --json")
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Run the study, print its table and findings, write the figure (and ``--json``)."""
    from ..plots import plot_study
    from ..study import StudyConfig, check_findings, format_table, run_study, summarise_findings

    config = StudyConfig(
        signals=tuple(args.signals),
        noise_levels=tuple(args.noise_levels),
        runs=args.runs,
        phi=args.phi,
        seed=args.seed,
    )
    result = run_study(config, progress=lambda line: print(line, file=sys.stderr))
    print(format_table(result))
    print(summarise_findings(check_findings(result)))
    print(f"wrote {plot_study(result, args.png)}")
    if args.json:
        from ..io import atomic_output

        with atomic_output(args.json, args.force) as temporary:
            temporary.write_text(json.dumps(result.to_dict(), indent=2))
        print(f"wrote {args.json}")
    return 0
