"""Does the gas's std hold its error when τ is estimated, not given?

The Kalman std (smoother and causal filter) is built from the noise, plus the first-order
misfit (``bench_std_coverage.py``), at the τ it is handed. An error δτ_i in τ moves the gas by
about (ĝ − T_i) δτ_i/τ_i through sensor i's inversion (a first-order sensor reads
g = T_i + τ_i dT_i/dt, so ∂g/∂log τ_i = g − T_i), which that std leaves out. Where the noise
leaves the std small (a periodic model of a sinusoid: the gas is predictable from its past) that
term dominates.

For lumped records (:func:`tcomp_core.simulate.simulate_pair`, K = 1 %) of each signal, the
default path's gas (ml-eiv's τ on the record, the smoother; ``--causal`` for the stream's
causal filter) and the same with the simulator's τ are scored against the truth over the record
less 5 % at each end: rms error, median std, share of samples within 2 and 4 std. The τ term:
the path's slope ∂ĝ/∂log τ_i (the same path at τ_i (1 + 1e-3), the same signal model) times
σ_i, ml-eiv's relative standard error of τ_i (``Estimate.tau_log_se``), combined as if τ1's and
τ2's errors were independent (``τ apart``) or one error of both (``τ common``: their ratio
pinned, as the cross-relation pins it best); each with the share within 4 std were it added in
quadrature. ``tcomp reconstruct`` adds the first (:mod:`tcomp_core.fusion.tau_spread`).

Run::

    .venv/bin/python bench/bench_std_tau.py [--seeds 5] [--first-seed 900] [--causal]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tcomp_core.estimators import estimate
from tcomp_core.fusion import fuse
from tcomp_core.fusion.tau_spread import tau_slope
from tcomp_core.simulate import SIGNALS, simulate_pair

#: Share of the record left out at each end (the smoother's start and end).
EDGE = 0.05


def _within(error: np.ndarray, std: np.ndarray, k: float) -> float:
    return float(np.mean(np.abs(error) <= k * std))


def score(kind: str, seed: int, causal: bool) -> dict[str, float]:
    """One record: the default path's gas with estimated and with true τ, against the truth."""
    pair = simulate_pair(kind, noise_percent=1.0, duration=16.0, seed=seed)
    found = estimate(pair.tc1, pair.tc2, pair.dt, phi=None)
    keep = slice(int(EDGE * pair.gas.size), pair.gas.size - int(EDGE * pair.gas.size))
    row: dict[str, float] = {}
    for label, taus in (("true", (pair.tau1, pair.tau2)), ("est", (found.tau1, found.tau2))):
        fused = fuse(pair.tc1, pair.tc2, pair.dt, *taus, causal=causal)
        error = (fused.gas - pair.gas)[keep]
        std = np.asarray(fused.std)[keep]
        row |= {
            f"{label}_error_c": float(np.sqrt(np.mean(error**2))),
            f"{label}_std_c": float(np.median(std)),
            f"{label}_in2": _within(error, std, 2.0),
            f"{label}_in4": _within(error, std, 4.0),
        }
        if label == "est":
            relative = found.tau_log_se()
            # ∂ĝ/∂log τ_i: the same path at τ_i (1 + STEP), as reconstruct's std takes it.
            slopes = [tau_slope(fused, pair.tc1, pair.tc2, i)[keep] for i in range(2)]
            parts = [slope * share for slope, share in zip(slopes, relative, strict=True)]
            apart = np.hypot(*parts)  # τ1's and τ2's errors independent
            common = np.abs(parts[0] + parts[1])  # one error of both (their ratio pinned)
            row["tau_term_c"] = float(np.median(apart))
            row["tau_common_c"] = float(np.median(common))
            row["est_in4_tau"] = _within(error, np.hypot(std, apart), 4.0)
            row["est_in4_common"] = _within(error, np.hypot(std, common), 4.0)
            row["tau1_error_pct"] = 100.0 * (found.tau1 / pair.tau1 - 1.0)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", type=int, default=5, help="records per signal")
    parser.add_argument("--first-seed", type=int, default=900)
    parser.add_argument(
        "--causal", action="store_true", help="the causal filter, not the smoother"
    )
    args = parser.parse_args()
    print(f"{'smoother' if not args.causal else 'causal filter'}, K = 1 %, 16 s at 500 Hz")
    print(
        f"{'signal':9} {'seed':>4} {'τ1 err %':>8} | {'true τ: err':>11} {'std':>7} {'in 4sd':>6} "
        f"| {'est τ: err':>10} {'std':>7} {'in 2sd':>6} {'in 4sd':>6} | {'τ apart':>7} "
        f"{'in 4sd':>6} | {'τ common':>8} {'in 4sd':>6}"
    )
    summary: dict[str, list[dict[str, float]]] = {}
    for kind in SIGNALS:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            row = score(kind, seed, args.causal)
            summary.setdefault(kind, []).append(row)
            print(
                f"{kind:9} {seed:4d} {row['tau1_error_pct']:8.2f} | {row['true_error_c']:11.4f} "
                f"{row['true_std_c']:7.4f} {row['true_in4']:6.2f} | {row['est_error_c']:10.4f} "
                f"{row['est_std_c']:7.4f} {row['est_in2']:6.2f} {row['est_in4']:6.2f} | "
                f"{row['tau_term_c']:7.4f} {row['est_in4_tau']:6.2f} | "
                f"{row['tau_common_c']:8.4f} {row['est_in4_common']:6.2f}"
            )
    print("\nper signal, estimated τ: least and median share within 4 std, without the τ term ->")
    print("with it (τ errors apart | common), and the median std's ratio with the common one")
    for kind, rows in summary.items():
        shares = {
            key: [row[key] for row in rows] for key in ("est_in4", "est_in4_tau", "est_in4_common")
        }
        wider = np.median(
            [np.hypot(r["est_std_c"], r["tau_common_c"]) / r["est_std_c"] for r in rows]
        )
        print(
            f"  {kind:9} "
            + " -> ".join(f"{min(v):.2f}/{np.median(v):.2f}" for v in shares.values())
            + f"   std x{wider:.2f}"
        )


if __name__ == "__main__":
    main()
