"""``tcomp sweep``: τ estimates against pre-filter bandwidth (Fig. 10)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..choices import METHODS
from .common import Verbs, add_data_arguments, add_force_argument, positive_float, read_data

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``sweep`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "sweep",
        help="tau estimates against pre-filter bandwidth (Fig. 10)",
        description="Estimate tau1, tau2 after pre-filtering at a range of bandwidths and pick "
        "the best pre-filtering frequency (first major local maximum above the fundamental).",
    )
    add_data_arguments(parser)
    parser.add_argument("--method", choices=METHODS, default="beta-gtls")
    parser.add_argument("--phi", type=positive_float, default=1.0)
    parser.add_argument("--alpha", type=positive_float)
    parser.add_argument(
        "--bandwidths", type=positive_float, nargs="+", metavar="HZ", help="bandwidths, Hz"
    )
    parser.add_argument("--png", type=Path, help="write the Fig. 10 plot to this PNG")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_force_argument(parser, "replace an existing --png")
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Sweep the pre-filter bandwidth, print a table or JSON (and plot to ``--png``)."""
    import numpy as np

    from ..estimators import PHI_METHODS
    from ..sweep import prefilter_sweep

    record = read_data(args)
    result = prefilter_sweep(
        record.tc1,
        record.tc2,
        record.dt,
        args.method,
        bandwidths_hz=args.bandwidths,
        phi=args.phi if args.method in PHI_METHODS else 1.0,
        alpha=args.alpha if args.method == "tdr-kee" else None,
    )
    if args.json:
        print(
            json.dumps(
                {
                    "method": result.method,
                    "fundamental_hz": result.fundamental_hz,
                    "best_hz": result.best_hz,
                    "best_is_peak": result.best_is_peak,
                    "bandwidths_hz": result.bandwidths_hz.tolist(),
                    "tau1": [None if np.isnan(v) else float(v) for v in result.tau1],
                    "tau2": [None if np.isnan(v) else float(v) for v in result.tau2],
                    "failures": list(result.failures),
                },
                indent=2,
            )
        )
    else:
        print(f"{record.source}: fundamental {result.fundamental_hz:.4g} Hz, {result.method}")
        print(f"{'bandwidth (Hz)':>14} {'tau1 (s)':>10} {'tau2 (s)':>10}")
        for index, bandwidth in enumerate(result.bandwidths_hz):
            mark = "  <- best" if index == result.best_index else ""
            if result.failures[index]:
                print(f"{bandwidth:>14.4g}     failed: {result.failures[index]}")
            else:
                print(
                    f"{bandwidth:>14.4g} {result.tau1[index]:>10.6f} "
                    f"{result.tau2[index]:>10.6f}{mark}"
                )
        if result.best_hz is None:
            print("no bandwidth gave an estimate")
        else:
            kind = "first major local maximum" if result.best_is_peak else "largest estimate"
            print(f"best pre-filtering frequency: {result.best_hz:.4g} Hz ({kind})")
    if args.png:
        from ..plots import plot_sweep

        print(f"wrote {plot_sweep(result, args.png)}")
    return 0
