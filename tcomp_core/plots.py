"""PNG figures: the simulation study (Fig. 4), the pre-filter sweep (Fig. 10), reconstructions.

Uses :class:`matplotlib.figure.Figure` directly (no pyplot, no GUI backend), so plotting works on
headless machines and in worker processes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from .study import StudyResult
from .sweep import SweepResult

__all__ = [
    "busiest_window",
    "plot_reconstruction",
    "plot_study",
    "plot_sweep",
    "reconstruction_figure",
    "signal_frequency_hz",
    "zoom_length",
]


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


#: The zoom shows this many periods at the signal's mean frequency ...
ZOOM_PERIODS = 5.0
#: ... or this long when no signal shows above the noise, s.
ZOOM_DEFAULT_S = 1.0
#: A spectral bin holds signal when its power exceeds the white-noise floor this many times.
SIGNAL_OVER_FLOOR = 100.0
#: Above this many samples a whole-record panel draws each series as its min..max envelope
#: over this many bins (a stride would hide spikes and single bad samples).
MAX_POINTS = 20_000
#: Stamps beyond this many seconds are wall-clock time (Unix epoch), shown as a UTC date.
EPOCH_AFTER_S = 1.0e8


def signal_frequency_hz(values: NDArray[np.float64], dt: float) -> float:
    """Power-weighted mean frequency of the signal in ``values``, Hz (NaN when none shows).

    Only the bins whose power is above :data:`SIGNAL_OVER_FLOOR` times the white-noise floor
    (the median power of the top quarter of the band) count, so the noise does not pull the
    figure to half the Nyquist frequency, nor one slow tone hide a broadband signal.
    """
    finite = np.where(np.isfinite(values), values, np.nanmean(values))
    power = np.abs(np.fft.rfft(finite - finite.mean()))[1:] ** 2
    if power.size < 4:
        return math.nan
    frequency = np.fft.rfftfreq(finite.size, dt)[1:]
    floor = float(np.median(power[-(power.size // 4) :]))
    signal = power > SIGNAL_OVER_FLOOR * floor
    if not signal.any():
        return math.nan
    return float(np.sum(frequency[signal] * power[signal]) / np.sum(power[signal]))


def zoom_length(values: NDArray[np.float64], dt: float) -> int:
    """Samples in :data:`ZOOM_PERIODS` periods at :func:`signal_frequency_hz` of ``values``.

    :data:`ZOOM_DEFAULT_S` when no signal shows above the noise; at least 10 samples, at most
    half the record.
    """
    frequency = signal_frequency_hz(values, dt)
    length_s = ZOOM_PERIODS / frequency if frequency > 0 else ZOOM_DEFAULT_S
    return int(min(max(10, round(length_s / dt)), max(values.size // 2, 1)))


def busiest_window(values: NDArray[np.float64], length: int) -> slice:
    """The ``length`` samples of ``values`` where it moves most (largest variance), a slice."""
    finite = np.where(np.isfinite(values), values, np.nanmean(values))
    n = finite.size
    if length >= n:
        return slice(0, n)
    centred = finite - finite.mean()
    sums = np.concatenate(([0.0], np.cumsum(centred)))
    squares = np.concatenate(([0.0], np.cumsum(centred**2)))
    window_sum = sums[length:] - sums[:-length]
    variance = (squares[length:] - squares[:-length]) / length - (window_sum / length) ** 2
    start = int(np.argmax(variance))
    return slice(start, start + length)


def _envelope(ax: Axes, time: NDArray, values: NDArray, **style: Any) -> None:
    """``values`` against ``time``; beyond :data:`MAX_POINTS` as its per-bin min..max band."""
    if values.size <= MAX_POINTS:
        ax.plot(time, values, **style)
        return
    edges = np.linspace(0, values.size, MAX_POINTS // 2 + 1).astype(int)
    # fmin/fmax skip NaN; an all-NaN bin stays NaN and is drawn as a gap.
    low = np.fmin.reduceat(values, edges[:-1])
    high = np.fmax.reduceat(values, edges[:-1])
    centres = time[(edges[:-1] + edges[1:] - 1) // 2]
    color, label = style.get("color"), style.get("label")
    ax.fill_between(centres, low, high, color=color, alpha=0.5, linewidth=0, label=label)


def _time_axis(time: NDArray[np.float64]) -> tuple[NDArray[np.float64], str]:
    """Time from the start of the record, s, and how the start reads."""
    start = float(time[0])
    if abs(start) > EPOCH_AFTER_S:
        from datetime import UTC, datetime

        stamp = datetime.fromtimestamp(start, UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
        origin = f"record starts {stamp} UTC"
    else:
        origin = f"record starts at t = {start:.6g} s"
    return time - start, origin


def reconstruction_figure(
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    gas: NDArray[np.float64],
    *,
    ref: NDArray[np.float64] | None = None,
    std: NDArray[np.float64] | None = None,
    title: str = "",
    ref_label: str = "ref",
) -> Figure:
    """The readings, the reconstructed gas and its error: the whole record and a zoom.

    Left, the whole record; right, a zoom of :data:`ZOOM_PERIODS` periods at the signal's mean
    frequency (:func:`zoom_length`), where the faster sensor moves most (shaded on the left).
    Top, the temperatures (the gas with its ±2σ band when ``std`` is given); bottom, the error
    of the gas against ``ref`` (in the zoom with the ±2σ the gas claims), or without one the
    two sensors' disagreement tc1 − tc2, each with its rms over the record in the legend.
    Time runs from the start of the record.

    Parameters
    ----------
    time : ndarray, shape (N,)
        Sample times, s.
    tc1, tc2 : ndarray, shape (N,)
        The readings, degrees C.
    gas : ndarray, shape (M,), M ≤ N
        The reconstructed gas temperature (NaN where none), degrees C.
    ref : ndarray, shape (M,) or longer, optional
        A reference gas temperature, degrees C.
    std : ndarray, shape (M,), optional
        The gas's standard deviation, degrees C.
    title : str
        Figure title (e.g. the input file).
    ref_label : str
        How the reference is named (e.g. where it is read).
    """
    count = gas.size
    elapsed, origin = _time_axis(time[:count])
    # The faster sensor (the rougher reading) shows the signal's time scale best.
    fast = max((tc1[:count], tc2[:count]), key=lambda values: float(np.nanstd(np.diff(values))))
    window = busiest_window(fast, zoom_length(fast, float(np.median(np.diff(time)))))
    if ref is not None:
        ref = ref[:count]
        error, error_label = gas - ref, f"gas − {ref_label}"
    else:
        error = tc1[:count] - tc2[:count]
        error_label = "tc1 − tc2 (no ref: the sensors' disagreement)"
    finite = error[np.isfinite(error)]
    rms = float(np.sqrt(np.mean(finite**2))) if finite.size else math.nan
    figure = Figure(figsize=(14, 7), layout="constrained")
    axes = figure.subplots(2, 2, sharex="col", height_ratios=(2, 1))
    zoom_time = elapsed[window]
    for column, part in enumerate((slice(None), window)):
        top, bottom = axes[0, column], axes[1, column]
        draw = _envelope if column == 0 else _line
        t = elapsed[part]
        draw(top, t, tc1[:count][part], color="tab:blue", linewidth=0.8, label="tc1")
        draw(top, t, tc2[:count][part], color="tab:orange", linewidth=0.8, label="tc2")
        if std is not None and column == 1:
            top.fill_between(
                t,
                (gas - 2 * std)[part],
                (gas + 2 * std)[part],
                color="tab:green",
                alpha=0.2,
                linewidth=0,
                label="gas ± 2σ",
            )
        draw(top, t, gas[part], color="tab:green", linewidth=1.0, label="gas (reconstructed)")
        if ref is not None:
            draw(top, t, ref[part], color="black", linewidth=0.8, linestyle="--", label=ref_label)
        draw(
            bottom,
            t,
            error[part],
            color="tab:red",
            linewidth=0.8,
            label=f"{error_label} (rms over the record {rms:.3g} °C)",
        )
        if std is not None and ref is not None and column == 1:
            claimed = 2 * std[part]
            bottom.fill_between(t, -claimed, claimed, color="grey", alpha=0.3, label="± 2σ")
        bottom.axhline(0.0, color="black", linewidth=0.5)
        bottom.set_xlabel(f"time from the start of the record (s); {origin}")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
            ax.ticklabel_format(axis="both", useOffset=False)
        top.set_ylabel("temperature (°C)")
        bottom.set_ylabel("error (°C)")
    axes[0, 0].axvspan(zoom_time[0], zoom_time[-1], color="grey", alpha=0.25, label="zoom")
    axes[0, 0].set_title(f"whole record: {time.size} samples, {elapsed[-1]:.4g} s")
    axes[0, 1].set_title(
        f"zoom: {zoom_time[0]:.4g}–{zoom_time[-1]:.4g} s, where the signal moves most"
    )
    handles: dict[str, Any] = {}
    for ax in axes.flat:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    figure.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=4)
    if title:
        figure.suptitle(title)
    return figure


def _line(ax: Axes, time: NDArray, values: NDArray, **style: Any) -> None:
    ax.plot(time, values, **style)


def plot_reconstruction(
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    gas: NDArray[np.float64],
    path: str | Path,
    *,
    ref: NDArray[np.float64] | None = None,
    std: NDArray[np.float64] | None = None,
    title: str = "",
    ref_label: str = "ref",
) -> Path:
    """Write :func:`reconstruction_figure` to ``path`` (PNG); returns ``path``."""
    figure = reconstruction_figure(
        time, tc1, tc2, gas, ref=ref, std=std, title=title, ref_label=ref_label
    )
    return _save(figure, path)


def _save(figure: Figure, path: str | Path) -> Path:
    """Save under a temporary name, then rename (the caller has decided to replace ``path``)."""
    from .io import atomic_output

    target = Path(path)
    with atomic_output(target, overwrite=True) as temporary:
        figure.savefig(temporary, dpi=110, format=target.suffix.lstrip(".") or "png")
    return target
