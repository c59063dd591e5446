"""Simulation study of Sec. IV A (Fig. 4): estimation error against noise level.

For each gas signal and noise level K, ``runs`` records of 10 s are simulated with the paper's
time constants (τ1 = 0.0238 s, τ2 = 0.1168 s, τ_s = 0.002 s) and independent noise; every method
estimates τ1 and τ2 from the same records, and the mean and standard deviation of e_τ (Eq. 23)
are tabulated. TDR-Kee is given the true ratio α, as in the paper. Seeds derive from one base
seed through :class:`numpy.random.SeedSequence`, so a study is reproducible run for run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .errors import TcompError
from .estimators import METHODS, PAPER_METHODS, estimate
from .metrics import tau_error_percent
from .simulate import PAPER_DT, PAPER_DURATION, PAPER_TAU1, PAPER_TAU2, simulate_pair

__all__ = [
    "Finding",
    "StudyConfig",
    "StudyResult",
    "check_findings",
    "format_table",
    "run_study",
    "summarise_findings",
]


@dataclass(frozen=True, kw_only=True)
class StudyConfig:
    """Settings of a Monte Carlo study; defaults are the paper's (Fig. 4)."""

    signals: tuple[str, ...] = ("sinusoid", "ramp")
    noise_levels: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    runs: int = 100
    methods: tuple[str, ...] = PAPER_METHODS
    tau1: float = PAPER_TAU1
    tau2: float = PAPER_TAU2
    dt: float = PAPER_DT
    duration: float = PAPER_DURATION
    phi: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.runs < 2:
            raise ValueError(f"runs={self.runs} must be >= 2 for a standard deviation")
        unknown = sorted(set(self.methods) - set(METHODS))
        if unknown:
            raise ValueError(f"unknown methods {unknown}; choose from {', '.join(METHODS)}")
        if any(level < 0 for level in self.noise_levels):
            raise ValueError(f"noise levels {self.noise_levels} must be >= 0 %")


@dataclass(frozen=True, kw_only=True)
class StudyResult:
    """Percentage errors of every run.

    Attributes
    ----------
    config : StudyConfig
    errors : ndarray, shape (signals, noise levels, methods, runs, 2)
        e_τ1 and e_τ2 in percent (Eq. 23); NaN where a method failed.
    """

    config: StudyConfig
    errors: NDArray[np.float64]
    failure_examples: dict[str, str] = field(default_factory=dict)

    def mean(self) -> NDArray[np.float64]:
        """Mean e_τ over successful runs, shape (signals, noise levels, methods, 2), percent."""
        return _nan_stat(np.nanmean, self.errors)

    def std(self) -> NDArray[np.float64]:
        """Standard deviation of e_τ over successful runs, same shape as :meth:`mean`."""
        return _nan_stat(lambda values, axis: np.nanstd(values, axis=axis, ddof=1), self.errors)

    def failures(self) -> NDArray[np.int64]:
        """Number of failed runs, shape (signals, noise levels, methods)."""
        return np.isnan(self.errors[..., 0]).sum(axis=-1)

    def to_dict(self) -> dict[str, object]:
        """Plain-JSON summary: config, mean, std and failures per signal, K and method."""
        mean, std, failed = self.mean(), self.std(), self.failures()
        rows = []
        for s, signal_name in enumerate(self.config.signals):
            for k, level in enumerate(self.config.noise_levels):
                for m, method in enumerate(self.config.methods):
                    rows.append(
                        {
                            "signal": signal_name,
                            "K": level,
                            "method": method,
                            "mean_e_tau1": _json_float(mean[s, k, m, 0]),
                            "std_e_tau1": _json_float(std[s, k, m, 0]),
                            "mean_e_tau2": _json_float(mean[s, k, m, 1]),
                            "std_e_tau2": _json_float(std[s, k, m, 1]),
                            "failed_runs": int(failed[s, k, m]),
                        }
                    )
        return {"config": self.config.__dict__, "rows": rows}


def _json_float(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _nan_stat(statistic, errors: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.full((*errors.shape[:3], 2), np.nan)
    counts = (~np.isnan(errors[..., 0])).sum(axis=-1)
    enough = counts >= 2
    reduced = errors.transpose(0, 1, 2, 4, 3)[enough]
    if reduced.size:
        out[enough] = statistic(reduced, axis=-1)
    return out


def run_study(
    config: StudyConfig | None = None,
    progress: Callable[[str], None] | None = None,
) -> StudyResult:
    """Run the Monte Carlo study.

    Parameters
    ----------
    config : StudyConfig, optional
        The paper's settings when omitted.
    progress : callable, optional
        Called with a line of text after each (signal, K) cell.

    Returns
    -------
    StudyResult
    """
    config = config or StudyConfig()
    shape = (len(config.signals), len(config.noise_levels), len(config.methods), config.runs, 2)
    errors = np.full(shape, np.nan)
    examples: dict[str, str] = {}
    alpha = config.tau1 / config.tau2
    for s, signal_name in enumerate(config.signals):
        for k, level in enumerate(config.noise_levels):
            for run in range(config.runs):
                seed = int(np.random.SeedSequence([config.seed, s, k, run]).generate_state(1)[0])
                data = simulate_pair(
                    signal_name,  # type: ignore[arg-type]
                    tau1=config.tau1,
                    tau2=config.tau2,
                    dt=config.dt,
                    duration=config.duration,
                    noise_percent=level,
                    phi=config.phi,
                    seed=seed,
                )
                for m, method in enumerate(config.methods):
                    try:
                        result = estimate(
                            data.tc1,
                            data.tc2,
                            data.dt,
                            method,  # type: ignore[arg-type]
                            alpha=alpha if method == "tdr-kee" else None,
                        )
                    except (TcompError, ValueError) as exc:
                        examples.setdefault(method, f"{signal_name}, K={level:g}: {exc}")
                        continue
                    errors[s, k, m, run, 0] = tau_error_percent(config.tau1, result.tau1)
                    errors[s, k, m, run, 1] = tau_error_percent(config.tau2, result.tau2)
            if progress is not None:
                progress(f"{signal_name}: K = {level:g} % done ({config.runs} runs)")
    return StudyResult(config=config, errors=errors, failure_examples=examples)


def format_table(result: StudyResult) -> str:
    """The Fig. 4 table: mean ± std of e_τ1 and e_τ2 (%) per signal, K and method."""
    config = result.config
    mean, std, failed = result.mean(), result.std(), result.failures()
    width = 17
    lines = []
    for s, signal_name in enumerate(config.signals):
        for which in (0, 1):
            lines.append(
                f"{signal_name}: e_tau{which + 1} (%) mean ± std over {config.runs} runs "
                f"(tau{which + 1} = {(config.tau1, config.tau2)[which]:g} s)"
            )
            lines.append("K (%) " + "".join(f"{method:>{width}}" for method in config.methods))
            for k, level in enumerate(config.noise_levels):
                cells = []
                for m in range(len(config.methods)):
                    if np.isnan(mean[s, k, m, which]):
                        cell = "failed"
                    else:
                        cell = f"{mean[s, k, m, which]:+.2f} ± {std[s, k, m, which]:.2f}"
                        if failed[s, k, m]:
                            cell += f"*{failed[s, k, m]}"
                    cells.append(f"{cell:>{width}}")
                lines.append(f"{level:>5g} " + "".join(cells))
            lines.append("")
    if failed.any():
        lines.append("*n: n runs failed and are excluded; first failure per method:")
        lines.extend(f"  {method}: {text}" for method, text in result.failure_examples.items())
    return "\n".join(lines)


@dataclass(frozen=True)
class Finding:
    """One of the paper's findings checked on a study: the claim, whether it holds, the figures."""

    claim: str
    holds: bool
    detail: str


def check_findings(result: StudyResult, bias_limit: float = 0.5) -> list[Finding]:
    """Check the paper's findings (Sec. IV A) on a study with equal noise variances.

    1. β-GTLS and γ-TLS are unbiased: |mean e_τ| < ``bias_limit`` % for every K ≤ 2 %.
    2. β-GTLS and γ-TLS agree with each other (mean difference below a tenth of their spread).
    3. γ-LS and β-LS are biased alike: mean e_τ1 > 1 % for every K > 0, within 25 % of each
       other.
    4. TLS standard deviations exceed LS ones at the largest noise level.
    """
    config = result.config
    mean, std = result.mean(), result.std()
    methods = list(config.methods)
    needed = {"beta-gtls", "gamma-tls", "gamma-ls", "beta-ls"}
    if not needed <= set(methods):
        raise ValueError(f"the findings need the methods {sorted(needed)}")
    gtls, gtls_g = methods.index("beta-gtls"), methods.index("gamma-tls")
    ls_g, ls_b = methods.index("gamma-ls"), methods.index("beta-ls")
    levels = np.asarray(config.noise_levels)
    low = np.flatnonzero(levels <= 2.0)
    noisy = np.flatnonzero(levels > 0.0)
    top = int(np.argmax(levels))
    findings = []

    worst = np.nanmax(np.abs(mean[:, low][:, :, [gtls, gtls_g]]))
    findings.append(
        Finding(
            "beta-gtls and gamma-tls unbiased for K <= 2 %",
            bool(worst < bias_limit),
            f"largest |mean e_tau| = {worst:.3f} % (limit {bias_limit} %)",
        )
    )
    gap = np.nanmax(np.abs(mean[:, :, gtls] - mean[:, :, gtls_g]))
    spread = np.nanmax(std[:, noisy][:, :, [gtls, gtls_g]]) if noisy.size else np.nan
    findings.append(
        Finding(
            "beta-gtls and gamma-tls agree",
            bool(gap < 0.1 * spread) if noisy.size else bool(gap < 1e-6),
            f"largest difference of mean e_tau = {gap:.3f} % against std up to {spread:.3f} %",
        )
    )
    if noisy.size:
        ls_bias = mean[:, noisy][:, :, [ls_g, ls_b], 0]
        biased = bool(np.all(ls_bias > 1.0))
        ratio = np.abs(ls_bias[..., 0] - ls_bias[..., 1]) / np.abs(ls_bias[..., 1])
        findings.append(
            Finding(
                "gamma-ls and beta-ls biased alike",
                biased and bool(np.nanmax(ratio) < 0.25),
                f"mean e_tau1 of gamma-ls / beta-ls from {np.nanmin(ls_bias):.2f} % to "
                f"{np.nanmax(ls_bias):.2f} %; largest relative difference {np.nanmax(ratio):.2f}",
            )
        )
        tls_std = std[:, top][:, [gtls, gtls_g], 0]
        ls_std = std[:, top][:, [ls_b, ls_g], 0]
        findings.append(
            Finding(
                f"TLS std larger than LS std (K = {levels[top]:g} %)",
                bool(np.all(tls_std > ls_std)),
                "std e_tau1 TLS (beta-gtls, gamma-tls) "
                + ", ".join(f"{v:.2f}" for v in tls_std.ravel())
                + " vs LS (beta-ls, gamma-ls) "
                + ", ".join(f"{v:.2f}" for v in ls_std.ravel()),
            )
        )
    return findings


def summarise_findings(findings: Sequence[Finding]) -> str:
    """One line per finding: HOLDS / FAILS, the claim and the figures behind it."""
    return "\n".join(
        f"[{'HOLDS' if item.holds else 'FAILS'}] {item.claim}: {item.detail}" for item in findings
    )
