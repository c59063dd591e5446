"""Accuracy of the time-constant estimators against the oracle (issue 5).

Blocks, each one function called by :func:`main`:

``tau_block``
    The paper's conditions (τ1 = 0.0238 s, τ2 = 0.1168 s, dt = 0.002 s, 10 s, equal noise),
    sinusoid and ramp, K = 1, 2, 4, 6 %. Per cell: bias = 100 (mean τ̂ - τ)/τ and std = 100
    std(τ̂)/τ (% of truth) of τ1 and τ2 for β-GTLS (φ = 1), ml-eiv (φ = 1, the same information)
    and the oracle (each sensor fitted to the known gas temperature); the ratio of each std to
    β-GTLS's; the share of runs whose ml-eiv 95 % interval holds the truth.
``phi_block``
    Unequal noise, σ2/σ1 = 2.5 (φ = 0.16) at K = 2 %: bias and std of β-GTLS assuming φ = 1,
    β-GTLS and ml-eiv with φ measured from the data, ml-eiv's interval coverage and the mean of
    the measured φ.
``reconstruction`` and ``tracking``
    e_Tg per reconstruction (the paper's 50 Hz post-filter, the hindsight-best post-filter,
    the Kalman smoother and causal filter) and the τ tracking error, from
    ``bench_reconstruction.py`` (``--reconstruction-runs`` records per cell; 0 skips them).

Every record is simulated with a seed drawn from ``SeedSequence([seed, block, signal, K, run])``,
so a cell's figures do not depend on which other cells run. A run an estimator fails on is
left out of that estimator's figures and counted in ``fail``.

Run::

    cd /work/main && PYTHONPATH=. .venv/bin/python bench/bench_accuracy.py          # 200 runs
    PYTHONPATH=. .venv/bin/python bench/bench_accuracy.py --quick                   # 40 runs
    PYTHONPATH=. .venv/bin/python bench/bench_accuracy.py --runs 1000 --seed 7
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from tcomp_core.errors import TcompError
from tcomp_core.estimators import Estimate, estimate
from tcomp_core.estimators.oracle import oracle_taus
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2, SimulatedPair, simulate_pair

SIGNALS = ("sinusoid", "ramp")
NOISE_LEVELS = (1.0, 2.0, 4.0, 6.0)
DEFAULT_RUNS = 200
QUICK_RUNS = 40
PHI_UNEQUAL = 0.16  # σ1²/σ2²: σ2/σ1 = 2.5
PHI_NOISE_LEVEL = 2.0
TRUTH = np.array([PAPER_TAU1, PAPER_TAU2])

#: An estimator of the benchmark: the record in, (τ1, τ2) and the estimate (or None) out.
Estimator = Callable[[SimulatedPair], tuple[tuple[float, float], Estimate | None]]


# ------------------------------------------------------------------------------- estimators


def _from_estimate(method: str, phi: float | None) -> Estimator:
    def run(pair: SimulatedPair) -> tuple[tuple[float, float], Estimate | None]:
        result = estimate(pair.tc1, pair.tc2, pair.dt, method, phi=phi)  # type: ignore[arg-type]
        return (result.tau1, result.tau2), result

    return run


def _oracle(pair: SimulatedPair) -> tuple[tuple[float, float], Estimate | None]:
    return oracle_taus(pair.tc1, pair.tc2, pair.gas, pair.dt), None


# ------------------------------------------------------------------------------- Monte Carlo


def record_seed(seed: int, block: int, signal: int, level: float, run: int) -> int:
    """Seed of one simulated record, independent of the other cells."""
    keys = [seed, block, signal, round(10 * level), run]
    return int(np.random.SeedSequence(keys).generate_state(1)[0])


def _covered(result: Estimate | None) -> NDArray[np.float64]:
    """Whether the 95 % intervals hold the truth, shape (2,); NaN without intervals."""
    if result is None or "tau1_ci_low" not in result.params:
        return np.full(2, np.nan)
    params = result.params
    return np.array(
        [
            params[f"tau{i}_ci_low"] <= truth <= params[f"tau{i}_ci_high"]
            for i, truth in zip((1, 2), TRUTH, strict=True)
        ],
        dtype=np.float64,
    )


def run_cell(
    records: Sequence[SimulatedPair], estimators: dict[str, Estimator]
) -> dict[str, dict[str, NDArray[np.float64]]]:
    """Run every estimator on every record.

    Returns
    -------
    dict
        Per estimator: ``tau`` (runs, 2) in s (NaN where it failed), ``covered`` (runs, 2) 0/1
        (NaN without intervals) and ``phi`` (runs,) the φ it used (NaN if none).
    """
    out = {
        name: {
            "tau": np.full((len(records), 2), np.nan),
            "covered": np.full((len(records), 2), np.nan),
            "phi": np.full(len(records), np.nan),
        }
        for name in estimators
    }
    for run, pair in enumerate(records):
        for name, estimator in estimators.items():
            try:
                taus, result = estimator(pair)
            except (TcompError, ValueError):
                continue
            out[name]["tau"][run] = taus
            out[name]["covered"][run] = _covered(result)
            if result is not None and result.phi is not None:
                out[name]["phi"][run] = result.phi
    return out


def simulate_records(
    kind: str, level: float, runs: int, seed: int, block: int, phi: float = 1.0
) -> list[SimulatedPair]:
    """``runs`` seeded records at the paper's conditions."""
    signal = SIGNALS.index(kind)
    return [
        simulate_pair(
            kind,  # type: ignore[arg-type]
            noise_percent=level,
            phi=phi,
            seed=record_seed(seed, block, signal, level, run),
        )
        for run in range(runs)
    ]


def bias_std(tau: NDArray[np.float64]) -> tuple[NDArray, NDArray, int]:
    """Bias and std in % of truth, shape (2,) each, and the number of failed runs."""
    ok = np.all(np.isfinite(tau), axis=1)
    if ok.sum() < 2:
        return np.full(2, np.nan), np.full(2, np.nan), int((~ok).sum())
    relative = 100.0 * (tau[ok] / TRUTH - 1.0)
    return relative.mean(axis=0), relative.std(axis=0, ddof=1), int((~ok).sum())


def _coverage_text(covered: NDArray[np.float64]) -> str:
    if np.all(np.isnan(covered)):
        return ""
    share = np.nanmean(covered, axis=0)
    return f"{share[0]:6.3f} {share[1]:6.3f}"


# ------------------------------------------------------------------------------- the blocks


def tau_block(runs: int, seed: int) -> None:
    """Bias, std, std ratio to β-GTLS and interval coverage on the paper's conditions."""
    estimators = {
        "beta-gtls": _from_estimate("beta-gtls", 1.0),
        "ml-eiv": _from_estimate("ml-eiv", 1.0),
        "oracle": _oracle,
    }
    print(
        f"τ accuracy, paper's conditions (τ1 = {PAPER_TAU1} s, τ2 = {PAPER_TAU2} s, "
        f"dt = 0.002 s, 10 s, φ = 1), {runs} runs per cell"
    )
    print("bias = 100 (mean τ̂ - τ)/τ, std = 100 std(τ̂)/τ; ratio = std / std of beta-gtls")
    header = (
        f"{'signal':<9}{'K %':>4}  {'method':<10}{'bias1':>8}{'std1':>8}{'bias2':>8}"
        f"{'std2':>8}{'ratio1':>8}{'ratio2':>8}  {'CI95 cover 1, 2':<15}{'fail':>5}"
    )
    print(header)
    print("-" * len(header))
    for kind in SIGNALS:
        for level in NOISE_LEVELS:
            records = simulate_records(kind, level, runs, seed, block=0)
            cell = run_cell(records, estimators)
            _, reference, _ = bias_std(cell["beta-gtls"]["tau"])
            for name, result in cell.items():
                bias, std, failed = bias_std(result["tau"])
                ratio = std / reference
                lead = f"{kind:<9}{level:>4g}" if name == "beta-gtls" else " " * 13
                print(
                    f"{lead}  {name:<10}{bias[0]:>+8.3f}{std[0]:>8.3f}{bias[1]:>+8.3f}"
                    f"{std[1]:>8.3f}{ratio[0]:>8.3f}{ratio[1]:>8.3f}  "
                    f"{_coverage_text(result['covered']):<15}{failed:>5}"
                )
    print()


def phi_block(runs: int, seed: int) -> None:
    """Unequal noise: β-GTLS with φ = 1 against β-GTLS and ml-eiv with φ from the data."""
    estimators = {
        "beta-gtls phi=1": _from_estimate("beta-gtls", 1.0),
        "beta-gtls phi=data": _from_estimate("beta-gtls", None),
        "ml-eiv phi=data": _from_estimate("ml-eiv", None),
    }
    print(
        f"unequal noise: σ2/σ1 = {PHI_UNEQUAL**-0.5:g} (φ = {PHI_UNEQUAL}), "
        f"K = {PHI_NOISE_LEVEL:g} %, {runs} runs per cell"
    )
    header = (
        f"{'signal':<9}  {'method':<19}{'bias1':>8}{'std1':>8}{'bias2':>8}{'std2':>8}"
        f"  {'CI95 cover 1, 2':<15}{'mean φ̂':>8}{'fail':>5}"
    )
    print(header)
    print("-" * len(header))
    for kind in SIGNALS:
        records = simulate_records(kind, PHI_NOISE_LEVEL, runs, seed, block=1, phi=PHI_UNEQUAL)
        cell = run_cell(records, estimators)
        for name, result in cell.items():
            bias, std, failed = bias_std(result["tau"])
            phi = result["phi"]
            mean_phi = f"{np.nanmean(phi):8.4f}" if np.any(np.isfinite(phi)) else f"{'':8}"
            lead = kind if name == "beta-gtls phi=1" else ""
            print(
                f"{lead:<9}  {name:<19}{bias[0]:>+8.3f}{std[0]:>8.3f}{bias[1]:>+8.3f}"
                f"{std[1]:>8.3f}  {_coverage_text(result['covered']):<15}{mean_phi}{failed:>5}"
            )
    print()


# ------------------------------------------------------------------------------- entry point


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=None, help=f"runs per cell ({DEFAULT_RUNS})")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_RUNS} runs per cell")
    parser.add_argument("--seed", type=int, default=0, help="base seed (0)")
    parser.add_argument(
        "--reconstruction-runs",
        type=int,
        default=10,
        help="records per cell of the e_Tg and tracking tables (10; 0 skips them)",
    )
    args = parser.parse_args(argv)
    if args.runs is None:
        args.runs = QUICK_RUNS if args.quick else DEFAULT_RUNS
    if args.runs < 2:
        parser.error(f"--runs {args.runs} must be >= 2 for a standard deviation")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    tau_block(args.runs, args.seed)
    phi_block(args.runs, args.seed)
    if args.reconstruction_runs > 0:
        # A sibling script, importable because Python puts bench/ first on the path.
        from bench_reconstruction import reconstruction_table, tracking_table

        print(f"\ne_Tg (%), mean of {args.reconstruction_runs} seeded 10 s records, true τ\n")
        reconstruction_table(args.reconstruction_runs)
        print("\nτ tracking: ±30 % velocity change over 8 s, K = 1 %")
        tracking_table(max(2, args.reconstruction_runs // 4))
    print(f"seed {args.seed}, {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
