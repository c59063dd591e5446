"""PNG figures: the simulation study (Fig. 4), the pre-filter sweep (Fig. 10), reconstructions.

Uses :class:`matplotlib.figure.Figure` directly (no pyplot, no GUI backend), so plotting works on
headless machines and in worker processes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from .study import StudyResult
from .sweep import SweepResult

__all__ = ["plot_reconstruction", "plot_study", "plot_sweep"]


def plot_study(result: StudyResult, path: str | Path) -> Path:
    """Mean ± standard deviation of e_τ1 and e_τ2 against K for every method (Fig. 4)."""
    config = result.config
    mean, std = result.mean(), result.std()
    levels = np.asarray(config.noise_levels)
    figure = Figure(figsize=(11, 4.0 * len(config.signals)), layout="constrained")
    axes = figure.subplots(len(config.signals), 2, squeeze=False)
    offsets = np.linspace(-0.15, 0.15, len(config.methods))
    for s, signal_name in enumerate(config.signals):
        for which in (0, 1):
            ax = axes[s, which]
            for m, method in enumerate(config.methods):
                ax.errorbar(
                    levels + offsets[m],
                    mean[s, :, m, which],
                    yerr=std[s, :, m, which],
                    marker="o",
                    markersize=3,
                    capsize=2,
                    label=method,
                )
            ax.axhline(0.0, color="black", linewidth=0.6)
            ax.set_title(f"{signal_name}: e_tau{which + 1}")
            ax.set_xlabel("noise level K (%)")
            ax.set_ylabel(f"e_tau{which + 1} (%)")
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    return _save(figure, path)


def plot_sweep(result: SweepResult, path: str | Path) -> Path:
    """τ1 and τ2 against pre-filter bandwidth, best frequency marked (Fig. 10)."""
    figure = Figure(figsize=(8, 6), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    for ax, values, label in ((top, result.tau1, "tau1"), (bottom, result.tau2, "tau2")):
        ax.semilogx(result.bandwidths_hz, 1e3 * values, marker=".", label=result.method)
        ax.axvline(result.fundamental_hz, color="grey", linestyle=":", label="fundamental")
        if result.best_hz is not None:
            ax.axvline(result.best_hz, color="red", linestyle="--", label="best pre-filter")
        ax.set_ylabel(f"{label} (ms)")
        ax.grid(alpha=0.3, which="both")
    top.legend(fontsize=8)
    bottom.set_xlabel("pre-filter bandwidth (Hz)")
    return _save(figure, path)


def plot_reconstruction(
    time: NDArray[np.float64],
    series: dict[str, NDArray[np.float64]],
    path: str | Path,
    title: str = "",
) -> Path:
    """Overlay of temperature series against time (measurements, reconstructions, reference)."""
    figure = Figure(figsize=(10, 4), layout="constrained")
    ax = figure.subplots()
    for label, values in series.items():
        ax.plot(time[: values.size], values, linewidth=0.8, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("temperature (°C)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(figure, path)


def _save(figure: Figure, path: str | Path) -> Path:
    """Save under a temporary name, then rename (the caller has decided to replace ``path``)."""
    from .io import atomic_output

    target = Path(path)
    with atomic_output(target, overwrite=True) as temporary:
        figure.savefig(temporary, dpi=110, format=target.suffix.lstrip(".") or "png")
    return target
