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
``rate_block`` (issue 14)
    Sample rates 0.5-20 kHz × the four signals × K = 1, 2, 4 % (φ = 1), records of 10 s that
    start settled (1 s of warm-up): bias and std (% of truth) of τ1 and τ2 for the default path
    (:func:`tcomp_core.estimate` with no options, on the 10 s record and on its first 2 s, the
    node's window), β-GTLS (φ = 1, no pre-filter), ml-eiv with φ measured (``phi=None``) and
    the oracle; beside each std the Cramér–Rao bound of the record length
    (:mod:`tcomp_core.estimators.bound`, gas unknown) and the efficiency CRB std / std (the
    oracle knows the gas and may exceed 1).
``phi_model_block`` (issue 14)
    φ measured from the spectra alone (:func:`~tcomp_core.noise.estimate_noise`) and from the
    model (:func:`~tcomp_core.noise.model_noise` with ml-eiv's τ): mean and worst
    |φ̂/φ - 1| over the runs, ramp, exhaust and multisine, K = 0.5-4 %, φ = 0.1, 1, 10.
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
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from tcomp_core.errors import TcompError
from tcomp_core.estimators import Estimate, estimate, phi_from_data
from tcomp_core.estimators.bound import cramer_rao_bound
from tcomp_core.estimators.oracle import oracle_taus
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2, SimulatedPair, simulate_pair

SIGNALS = ("sinusoid", "ramp")
NOISE_LEVELS = (1.0, 2.0, 4.0, 6.0)
DEFAULT_RUNS = 200
QUICK_RUNS = 40
PHI_UNEQUAL = 0.16  # σ1²/σ2²: σ2/σ1 = 2.5
PHI_NOISE_LEVEL = 2.0
TRUTH = np.array([PAPER_TAU1, PAPER_TAU2])
ALL_SIGNALS = ("sinusoid", "ramp", "multisine", "exhaust")
RATES_HZ = (500, 1000, 2000, 5000, 10000, 20000)
RATE_NOISE_LEVELS = (1.0, 2.0, 4.0)
RATE_RUNS = 20
QUICK_RATE_RUNS = 6
RECORD_S, WINDOW_S, WARMUP_S = 10.0, 2.0, 1.0
PHI_MODEL_LEVELS = (0.5, 1.0, 2.0, 4.0)
PHI_MODEL_RATIOS = (0.1, 1.0, 10.0)

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


def _first_seconds(pair: SimulatedPair, seconds: float) -> SimulatedPair:
    n = round(seconds / pair.dt)
    return replace(
        pair,
        time=pair.time[:n],
        gas=pair.gas[:n],
        tc1=pair.tc1[:n],
        tc2=pair.tc2[:n],
        clean1=pair.clean1[:n],
        clean2=pair.clean2[:n],
    )


def _default_path(pair: SimulatedPair) -> tuple[tuple[float, float], Estimate | None]:
    result = estimate(pair.tc1, pair.tc2, pair.dt)
    return (result.tau1, result.tau2), result


def _crb_std(pair: SimulatedPair) -> NDArray[np.float64]:
    """Cramér–Rao bound on the std of τ1, τ2 for this record's gas and noise, % of truth."""
    bound = cramer_rao_bound(pair.gas, pair.tau1, pair.tau2, pair.dt, pair.sigma1, pair.sigma2)
    return 100.0 * np.sqrt(np.diag(bound)) / TRUTH


def rate_block(runs: int, seed: int, rates: Sequence[int]) -> None:
    """Bias, std, CRB and efficiency per sample rate, signal and K (see the module)."""
    long_estimators: dict[str, Estimator] = {
        "default": _default_path,
        "beta-gtls": _from_estimate("beta-gtls", 1.0),
        "ml-eiv phi^": _from_estimate("ml-eiv", None),
        "oracle": _oracle,
    }
    print(
        f"τ accuracy per sample rate: τ1 = {PAPER_TAU1} s, τ2 = {PAPER_TAU2} s, φ = 1, records "
        f"of {RECORD_S:g} s (window {WINDOW_S:g} s for 'default 2s'), settled, {runs} runs"
    )
    print("eff = CRB std / std; |bias| < 0.5 % and std <= 1 % is the goal at K = 2 %")
    header = (
        f"{'rate':>6} {'signal':<9}{'K %':>4}  {'method':<12}{'bias1':>9}{'std1':>8}"
        f"{'crb1':>7}{'eff1':>6}{'bias2':>9}{'std2':>8}{'crb2':>7}{'eff2':>6}{'fail':>5}"
    )
    print(header)
    print("-" * len(header))
    for rate in rates:
        for kind in ALL_SIGNALS:
            for level in RATE_NOISE_LEVELS:
                records = [
                    simulate_pair(
                        kind,  # type: ignore[arg-type]
                        dt=1.0 / rate,
                        duration=RECORD_S,
                        noise_percent=level,
                        seed=record_seed(seed, 2 + rate, ALL_SIGNALS.index(kind), level, run),
                        warmup=WARMUP_S,
                    )
                    for run in range(runs)
                ]
                windows = [_first_seconds(pair, WINDOW_S) for pair in records]
                cells = {
                    **run_cell(records, long_estimators),
                    "default 2s": run_cell(windows, {"default 2s": _default_path})["default 2s"],
                }
                bounds = {name: _crb_std(records[0]) for name in long_estimators}
                bounds["default 2s"] = _crb_std(windows[0])
                for index, (name, result) in enumerate(cells.items()):
                    bias, std, failed = bias_std(result["tau"])
                    crb = bounds[name]
                    eff = crb / std
                    lead = f"{rate:>6} {kind:<9}{level:>4g}" if index == 0 else " " * 19
                    print(
                        f"{lead}  {name:<12}{bias[0]:>+9.3f} {std[0]:>7.3f}{crb[0]:>7.3f}"
                        f"{eff[0]:>6.2f}{bias[1]:>+9.3f} {std[1]:>7.3f}{crb[1]:>7.3f}"
                        f"{eff[1]:>6.2f}{failed:>5}",
                        flush=True,
                    )
    print()


def phi_model_block(runs: int, seed: int, rates: Sequence[int]) -> None:
    """φ from the spectra alone against φ from the model (see the module)."""
    print(f"φ measured, {RECORD_S:g} s records, {runs} runs: mean and worst |φ̂/φ - 1| %")
    header = (
        f"{'rate':>6} {'signal':<9}{'K %':>5}{'φ':>6}  {'spectra mean':>13}{'worst':>8}"
        f"  {'model mean':>11}{'worst':>8}"
    )
    print(header)
    print("-" * len(header))
    for rate in rates:
        for kind in ("ramp", "exhaust", "multisine"):
            for level in PHI_MODEL_LEVELS:
                for phi in PHI_MODEL_RATIOS:
                    spectral, modelled = [], []
                    for run in range(runs):
                        keys = (seed, 3 + rate, ALL_SIGNALS.index(kind), level * phi, run)
                        pair = simulate_pair(
                            kind,  # type: ignore[arg-type]
                            dt=1.0 / rate,
                            duration=RECORD_S,
                            noise_percent=level,
                            phi=phi,
                            seed=record_seed(*keys),
                            warmup=WARMUP_S,
                        )
                        found = estimate(pair.tc1, pair.tc2, pair.dt)
                        taus = (found.tau1, found.tau2)
                        for out, given in ((spectral, None), (modelled, taus)):
                            try:
                                measured = phi_from_data(pair.tc1, pair.tc2, pair.dt, taus=given)
                            except TcompError:  # counted as a miss of 100 %
                                measured = 0.0
                            out.append(measured / phi - 1)
                    s_err, m_err = 100 * np.abs(spectral), 100 * np.abs(modelled)
                    print(
                        f"{rate:>6} {kind:<9}{level:>5g}{phi:>6g}  {s_err.mean():>13.1f}"
                        f"{s_err.max():>8.1f}  {m_err.mean():>11.1f}{m_err.max():>8.1f}",
                        flush=True,
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
    parser.add_argument(
        "--rate-runs",
        type=int,
        default=None,
        help=f"runs per cell of the rate and φ blocks ({RATE_RUNS}; {QUICK_RATE_RUNS} quick)",
    )
    parser.add_argument(
        "--rates",
        default=",".join(str(r) for r in RATES_HZ),
        help="sample rates of the rate and φ blocks, Hz, comma-separated",
    )
    parser.add_argument(
        "--blocks",
        default="tau,phi,rate,phi-model,reconstruction",
        help="which blocks to run, comma-separated (all by default)",
    )
    args = parser.parse_args(argv)
    args.rates = [int(r) for r in args.rates.split(",")]
    args.blocks = set(args.blocks.split(","))
    if args.rate_runs is None:
        args.rate_runs = QUICK_RATE_RUNS if args.quick else RATE_RUNS
    if args.runs is None:
        args.runs = QUICK_RUNS if args.quick else DEFAULT_RUNS
    if args.runs < 2:
        parser.error(f"--runs {args.runs} must be >= 2 for a standard deviation")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    if "tau" in args.blocks:
        tau_block(args.runs, args.seed)
    if "phi" in args.blocks:
        phi_block(args.runs, args.seed)
    if "rate" in args.blocks:
        rate_block(args.rate_runs, args.seed, args.rates)
    if "phi-model" in args.blocks:
        phi_model_block(args.rate_runs, args.seed, args.rates)
    if args.reconstruction_runs > 0 and "reconstruction" in args.blocks:
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
