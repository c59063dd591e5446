"""Does the default gas's std hold its error? With and without the first-order misfit.

For draws of the compensation campaign (``campaign_draws.py``: the detailed simulator's
records with every effect, class-2 sensors, 0.5–20 kHz), the default path as ``tcomp
reconstruct`` runs it (ml-eiv's τ, the Kalman smoother) is scored against the true gas (read
half a sample on, level removed: a class-2 offset is calibration). For each draw it prints the
gas error (°C rms), the median std, and the share of samples whose error lies within 2 and 4
std: with the std as the smoother gives it (``with``: the first-order misfit held,
:func:`tcomp_core.fusion.adequacy.first_order_misfit`) and without that term (``without``:
the noise-only std, as before it). Whether a misfit warning was given is marked per draw;
clean draws must have none.

Run::

    .venv/bin/python bench/bench_std_coverage.py --start 100 --count 60
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import campaign_draws  # noqa: E402

from tcomp_core.effects.chain import fractional_shift  # noqa: E402
from tcomp_core.errors import TcompError  # noqa: E402
from tcomp_core.estimators import estimate  # noqa: E402
from tcomp_core.fusion import fuse  # noqa: E402

#: Share of the record left out at each end (the smoother's start and end).
EDGE = 0.05


def score(index: int) -> dict:
    """One draw: its error, std and coverage with and without the misfit."""
    item = campaign_draws.draw(index)
    record, _ = campaign_draws.simulate(item)
    row: dict = {"index": index, "label": item.label, "clean": not item.effects}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found = estimate(record.tc1, record.tc2, record.dt)
            fused = fuse(record.tc1, record.tc2, record.dt, found.tau1, found.tau2)
    except TcompError as exc:
        row["refused"] = str(exc).split(":", 1)[0]
        return row
    truth = fractional_shift(record.ref, 0.5)[0]
    n = truth.size
    keep = np.zeros(n, dtype=bool)
    keep[int(EDGE * n) : n - int(EDGE * n)] = True
    keep &= np.isfinite(truth)
    error = (fused.gas - truth)[keep]
    error -= np.mean(error)
    with_misfit = fused.std[keep]
    without = np.sqrt(np.maximum(with_misfit**2 - fused.model.misfit_c**2, 0.0))
    row |= {
        "error_c": float(np.sqrt(np.mean(error**2))),
        "misfit_c": fused.model.misfit_c,
        "warned": bool(fused.misfit_warning),
    }
    for name, std in (("without", without), ("with", with_misfit)):
        row[f"std_{name}_c"] = float(np.median(std))
        for k in (2, 4):
            row[f"within{k}_{name}"] = float(np.mean(np.abs(error) <= k * std))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--start", type=int, default=100, help="first draw")
    parser.add_argument("--count", type=int, default=20, help="draws")
    args = parser.parse_args()
    rows = []
    print(
        f"{'draw':>4} {'label':52} {'error':>7} {'std w/o':>8} {'std':>7} "
        f"{'in 2sd w/o->with':>17} {'in 4sd w/o->with':>17}"
    )
    for index in range(args.start, args.start + args.count):
        row = score(index)
        rows.append(row)
        if "refused" in row:
            print(f"{index:4d} {row['label'][:52]:52} refused: {row['refused']}")
            continue
        print(
            f"{index:4d} {row['label'][:52]:52} {row['error_c']:7.3g} "
            f"{row['std_without_c']:8.3g} {row['std_with_c']:7.3g} "
            f"{row['within2_without']:8.2f}->{row['within2_with']:.2f} "
            f"{row['within4_without']:8.2f}->{row['within4_with']:.2f}"
            f"{'  WARNED' if row['warned'] else ''}"
        )
    scored = [row for row in rows if "refused" not in row]
    clean = [row for row in scored if row["clean"]]
    print(
        f"\nclean draws warned: {sum(row['warned'] for row in clean)} of {len(clean)}; "
        f"effect draws warned: {sum(row['warned'] for row in scored if not row['clean'])} of "
        f"{len(scored) - len(clean)}; refused (no gas): {len(rows) - len(scored)}"
    )
    # Where the noise-only std fails (fewer than 90 % within 4 std): what the misfit does.
    failing = [row for row in scored if row["within4_without"] < 0.9]
    if failing:
        for k in (2, 4):
            before = np.median([row[f"within{k}_without"] for row in failing])
            after = np.median([row[f"within{k}_with"] for row in failing])
            print(
                f"draws whose noise-only std holds < 90 % within 4 std ({len(failing)}): "
                f"median share within {k} std {before:.2f} -> {after:.2f}"
            )
    ratios = [
        row["std_with_c"] / row["std_without_c"]
        for row in clean
        if row["std_without_c"] > 0.0 and math.isfinite(row["std_without_c"])
    ]
    if ratios:
        print(
            f"clean draws: median std with / without the misfit {np.median(ratios):.3f} "
            f"(max {max(ratios):.3f})"
        )


if __name__ == "__main__":
    main()
