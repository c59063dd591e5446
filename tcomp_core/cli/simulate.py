"""``tcomp simulate``: write simulated two-thermocouple data (CSV and/or MCAP bag)."""

from __future__ import annotations

import argparse

from ..choices import PAPER_DT, PAPER_TAU1, PAPER_TAU2, SIGNALS
from .common import Verbs, add_force_argument, add_output_argument, positive_float

__all__ = ["add_parser", "run"]


def add_parser(verbs: Verbs) -> argparse.ArgumentParser:
    """Add ``simulate`` to the sub-commands of ``tcomp``; returns its parser."""
    parser = verbs.add_parser(
        "simulate",
        help="write simulated two-thermocouple data (CSV and/or MCAP bag)",
        description="Simulate two first-order thermocouples in one gas (Fig. 2) and write the "
        "record; the true gas temperature goes to the ref column/topic.",
    )
    add_output_argument(
        parser,
        "output path, repeatable: *.csv for CSV, anything else for a rosbag2 MCAP bag",
        repeatable=True,
    )
    parser.add_argument("--signal", choices=SIGNALS, default="sinusoid", help="gas temperature")
    parser.add_argument("--tau1", type=positive_float, default=PAPER_TAU1, help="tau1, s")
    parser.add_argument("--tau2", type=positive_float, default=PAPER_TAU2, help="tau2, s")
    parser.add_argument(
        "-K", "--noise", type=float, default=0.0, help="noise level K, percent (Eq. 22)"
    )
    parser.add_argument("--phi", type=positive_float, default=1.0, help="noise ratio s1^2/s2^2")
    parser.add_argument(
        "--rate", type=positive_float, default=1.0 / PAPER_DT, help="sample rate, Hz"
    )
    parser.add_argument("--duration", type=positive_float, default=10.0, help="length, s")
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument("--no-ref", action="store_true", help="leave out the true gas temperature")
    add_force_argument(parser, "overwrite existing outputs")
    parser.set_defaults(handler=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Simulate the record and write it to every ``--output``; returns the exit status 0."""
    from ..io import write_series
    from ..simulate import simulate_pair

    data = simulate_pair(
        args.signal,
        tau1=args.tau1,
        tau2=args.tau2,
        dt=1.0 / args.rate,
        duration=args.duration,
        noise_percent=args.noise,
        phi=args.phi,
        seed=args.seed,
    )
    for path in args.output:
        written = write_series(
            path,
            data.time,
            data.tc1,
            data.tc2,
            None if args.no_ref else data.gas,
            overwrite=args.force,
        )
        print(
            f"wrote {written}: {args.signal}, {data.time.size} samples at {args.rate:g} Hz, "
            f"tau1 = {args.tau1:g} s, tau2 = {args.tau2:g} s, K = {args.noise:g} %"
        )
    return 0
