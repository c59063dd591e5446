"""``make demo``: simulate, estimate, reconstruct, then diagnose a bag with a hidden effect.

Runs the ``tcomp`` command line step by step, printing each command before its output, so the
demo doubles as a usage example. First the paper's periodic ramp (τ1 = 0.0238 s,
τ2 = 0.1168 s, τ_s = 0.002 s, 10 s) with K = 2 % noise, written as CSV and as an MCAP bag:
every estimator, the reconstruction and the pre-filter sweep. Then ``tcomp diagnose`` on the
bundled bag ``bags/conduction_500hz``, whose sensors lose heat to their supports: the base
model's fit failing, where, the suspects, the refit and the error falling, and the HTML report.
Last, the gas temperature compensated with the physics found (``--effects diagnosis.json``,
the diagnosis just saved), offline and as the node publishes it (``tcomp process``), its error
against the reference falling, and the hot bag ``bags/radiation_500hz`` whose radiation error
is removed in level (``--effects auto``: diagnosed and compensated in one step).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from .bundled import bundled_bag
from .cli import main as tcomp

__all__ = ["main"]


def _run(arguments: list[str]) -> None:
    print(f"\n$ tcomp {shlex.join(arguments)}", flush=True)
    status = tcomp(arguments)
    if status != 0:
        raise SystemExit(status)


def main(argv: list[str] | None = None) -> int:
    """Run the demo, writing its files under ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    parser.add_argument(
        "--effect-bag",
        type=Path,
        default=bundled_bag("conduction_500hz"),
        help="bag with a hidden effect to diagnose and compensate",
    )
    parser.add_argument(
        "--radiation-bag",
        type=Path,
        default=bundled_bag("radiation_500hz"),
        help="hot bag whose wires radiate to a colder wall, compensated in level",
    )
    args = parser.parse_args(argv)
    out = args.out
    bag, csv = out / "ramp_bag", out / "ramp.csv"
    _run(
        [
            *("simulate", "--signal", "ramp", "-K", "2", "--seed", "7", "--force"),
            *("-o", str(csv), "-o", str(bag)),
        ]
    )
    _run(["estimate", str(bag), "--method", "all"])
    # The default reconstruction is the best one offline: the Kalman smoother of both sensors,
    # its gas model fitted to the data. The paper's Eq. (7) with its 50 Hz post-filter beside.
    _run(
        [
            *("reconstruct", str(bag), "-o", str(out / "reconstructed.csv"), "--force"),
            *("--png", str(out / "reconstructed.png")),
        ]
    )
    _run(
        [
            *("reconstruct", str(csv), "-o", str(out / "reconstructed_postfiltered_bag")),
            *("--force", "--reconstruction", "difference", "--postfilter-hz", "50"),
        ]
    )
    _run(["sweep", str(csv), "--png", str(out / "sweep.png"), "--force"])
    _run(
        [
            *("diagnose", str(args.effect_bag)),
            *("--report", str(out / "diagnosis"), "--json", str(out / "diagnosis.json")),
            "--force",  # the demo may run again over its own outputs
        ]
    )
    # Compensate with the physics the diagnosis found (its JSON names the effects, fitted here
    # without diagnosing again): the gas error against the reference falls.
    found = str(out / "diagnosis.json")
    _run(
        [
            *("reconstruct", str(args.effect_bag), "--effects", found),
            *("-o", str(out / "compensated.csv"), "--force"),
            *("--png", str(out / "compensated.png")),
        ]
    )
    _run(
        [
            *("process", str(args.effect_bag), "-o", str(out / "compensated_bag")),
            *("--effects", found, "--no-diagnose", "--force"),
        ]
    )
    # A hot record: radiation to a colder wall makes both wires read low; compensated in level,
    # with the effects the diagnosis run by ``--effects auto`` finds.
    _run(
        [
            *("reconstruct", str(args.radiation_bag), "--effects", "auto"),
            *("-o", str(out / "radiation_compensated.csv"), "--force"),
        ]
    )
    print(f"\ndemo outputs in {out}/; the diagnosis report is {out / 'diagnosis' / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
