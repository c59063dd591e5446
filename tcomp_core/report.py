"""The HTML report of ``tcomp diagnose``: one self-contained page with embedded figures.

The page holds no external reference: figures are PNGs drawn with
:class:`matplotlib.figure.Figure` (no pyplot, no GUI backend) and embedded as base64 data URIs,
the style sheet is inline, and every piece of text is escaped.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from html import escape
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from .diagnose.pipeline import fused_gas
from .diagnose.residuals import Autocorrelation
from .diagnose.result import Diagnosis, ModelFit, Suspect
from .diagnose.windowed import WindowedDiagnosis
from .htmlpage import bullet_list as _list
from .htmlpage import image as _image
from .htmlpage import number as _num
from .htmlpage import page as _page
from .htmlpage import section as _section
from .htmlpage import table as _table
from .plots import zoom_length

__all__ = ["write_report", "write_windowed_report"]

#: Most points drawn per line (longer series are thinned by a stride).
MAX_POINTS = 20_000

# -- data helpers -------------------------------------------------------------------------------


def _label(fit: ModelFit) -> str:
    return "base" if not fit.effects else "base + " + " + ".join(fit.effects)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Start and stop indices of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _zoom(diagnosis: Diagnosis) -> slice:
    """Five periods of the signal from the first held-out block.

    The length is :func:`~tcomp_core.plots.zoom_length` of the faster sensor.
    """
    fast = (diagnosis.tc1, diagnosis.tc2)[2 - diagnosis.slow]
    n = fast.size
    length = zoom_length(fast, diagnosis.dt)
    runs = _runs(diagnosis.validation)
    start = min(int(runs[0][0]) if runs else 0, n - length)
    return slice(start, start + length)


def _plot(ax: Axes, time: NDArray, values: NDArray, **style: Any) -> None:
    step = max(1, values.size // MAX_POINTS)
    ax.plot(time[::step], values[::step], **style)


def _shade(ax: Axes, diagnosis: Diagnosis, window: slice) -> None:
    time = diagnosis.time[window]
    for k, (start, stop) in enumerate(_runs(diagnosis.validation[window])):
        label = "held out" if k == 0 else None
        ax.axvspan(time[start], time[stop - 1], color="tab:green", alpha=0.08, label=label)


# -- figures ------------------------------------------------------------------------------------


def _comparison_figure(diagnosis: Diagnosis) -> Figure:
    slow = diagnosis.slow
    measured = (diagnosis.tc1, diagnosis.tc2)[slow - 1]
    fits = [diagnosis.base] + ([diagnosis.final] if diagnosis.final.effects else [])
    figure = Figure(figsize=(10, 6.5), layout="constrained")
    axes = figure.subplots(2, 1)
    for ax, window in zip(axes, (slice(None), _zoom(diagnosis)), strict=True):
        time = diagnosis.time[window]
        _shade(ax, diagnosis, window)
        for fit in fits:
            _plot(ax, time, fit.predicted[window], linewidth=1.4, label=f"{_label(fit)} free run")
        _plot(ax, time, measured[window], color="black", linewidth=0.7, label=f"tc{slow} measured")
        ax.set_ylabel("temperature (°C)")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"tc{slow} simulated from tc{3 - slow}: whole record and zoom")
    axes[1].set_xlabel("time (s)")
    axes[0].legend(fontsize=8)
    return figure


def _residual_figure(diagnosis: Diagnosis) -> Figure:
    acf, ccf = diagnosis.failure.acf, diagnosis.failure.ccf_input
    figure = Figure(figsize=(10, 3.5), layout="constrained")
    left, right = figure.subplots(1, 2)
    for ax, result, title in (
        (left, acf, "autocorrelation of the residual"),
        (right, ccf, "residual vs fast sensor's rate (positive lag: residual follows)"),
    ):
        lags_ms = 1e3 * result.lags_s
        ax.axhspan(-result.bound, result.bound, color="tab:blue", alpha=0.15, label="bound")
        ax.plot(lags_ms, result.values, color="black", linewidth=0.9)
        ax.axhline(0.0, color="grey", linewidth=0.5)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("lag (ms)")
        ax.grid(alpha=0.3)
    right.plot(1e3 * ccf.peak_lag_s, ccf.peak, "o", color="tab:red", label="peak")
    left.set_ylabel("correlation")
    right.legend(fontsize=8)
    return figure


def _where_figure(diagnosis: Diagnosis) -> Figure:
    failure = diagnosis.failure
    figure = Figure(figsize=(10, 7), layout="constrained")
    (errors, taus), (bands, levels) = figure.subplots(2, 2)
    windows = failure.windowed_error
    errors.bar(windows.centres_s, windows.error_pct, width=0.8 * failure.window_s)
    errors.set(title="held-out error per window", xlabel="time (s)", ylabel="error (%)")
    wt = failure.windowed_tau
    for values, name, marker in ((wt.tau1, "tau1", "o-"), (wt.tau2, "tau2", "s-")):
        finite = values[np.isfinite(values)]
        median = float(np.median(finite)) if finite.size else math.nan
        label = f"{name} (median {_num(1e3 * median, '.3g')} ms)"
        taus.plot(wt.centres_s, 100.0 * (values / median - 1.0), marker, label=label)
    taus.set(title="time constants per window (beta-GTLS)", xlabel="time (s)")
    taus.set_ylabel("change from median (%)")
    taus.legend(fontsize=8)
    b = failure.bands
    names = [f"{_num(lo, '.3g')}–{_num(hi, '.3g')}" for lo, hi in itertools.pairwise(b.edges_hz)]
    bands.bar(range(len(names)), 100 * b.residual_share)
    bands.set_xticks(range(len(names)), names, rotation=30, fontsize=8)
    bands.set(title="share of residual power per band", xlabel="band (Hz)", ylabel="share (%)")
    lv = failure.levels
    levels.errorbar(
        lv.centres, lv.mean, yerr=lv.std, fmt="o", capsize=3, label="binned mean ± std"
    )
    grid = np.linspace(lv.centres.min(), lv.centres.max(), 100)
    levels.plot(grid, lv.fitted(grid), color="tab:red", label="quadratic fit")
    levels.set(title="residual vs level", xlabel="level (°C)", ylabel="residual (°C)")
    levels.legend(fontsize=8)
    for ax in (errors, taus, bands, levels):
        ax.grid(alpha=0.3)
    return figure


def _staircase_figure(steps: Sequence[ModelFit]) -> Figure:
    figure = Figure(figsize=(max(5.0, 1.6 * len(steps) + 2.0), 3.5), layout="constrained")
    ax = figure.subplots()
    labels = ["base", *(f"+ {step.effects[-1]}" for step in steps[1:])]
    values = [step.error_pct for step in steps]
    ax.bar(range(len(steps)), values, color="tab:blue")
    for k, value in enumerate(values):
        ax.annotate(_num(value, ".3g"), (k, value), ha="center", va="bottom", fontsize=9)
    ax.set_xticks(range(len(steps)), labels)
    ax.set(title="error staircase", ylabel="held-out error (%)")
    ax.grid(alpha=0.3, axis="y")
    return figure


def _reconstruction_figure(diagnosis: Diagnosis) -> Figure:
    window = _zoom(diagnosis)
    time = diagnosis.time[window]
    with_ref = diagnosis.ref is not None
    figure = Figure(figsize=(10, 6.5 if with_ref else 4), layout="constrained")
    axes = figure.subplots(2 if with_ref else 1, 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    _plot(ax, time, diagnosis.tc1[window], color="grey", linewidth=0.6, label="tc1 measured")
    _plot(ax, time, diagnosis.tc2[window], color="silver", linewidth=0.6, label="tc2 measured")
    if diagnosis.ref is not None:
        _plot(ax, time, diagnosis.ref[window], color="black", linewidth=1.6, label="reference")
    sigmas = (diagnosis.sigma1, diagnosis.sigma2)
    fits = [diagnosis.base, diagnosis.final] if diagnosis.final.effects else [diagnosis.final]
    fused = [fused_gas(fit, sigmas, diagnosis.dt) for fit in fits]
    names = [f"gas, {_label(fit)} (fused)" for fit in fits]
    for gas, name in zip(fused, names, strict=True):
        _plot(ax, time, gas[window], linewidth=0.8, label=name)
    ax.set(title="gas temperature: first order and the final model")
    ax.set_ylabel("temperature (°C)")
    if diagnosis.ref is not None:
        # gas[k] holds over [t_k, t_k+1): the reference halfway through it.
        ref = diagnosis.ref
        halfway = np.append(0.5 * (ref[:-1] + ref[1:]), ref[-1])
        for gas, name in zip(fused, names, strict=True):
            _plot(axes[1], time, (gas - halfway)[window], linewidth=0.8, label=name)
        axes[1].set(title="gas less the reference")
        axes[1].set_ylabel("error (°C)")
    axes[-1].set_xlabel("time (s)")
    for item in axes:
        item.grid(alpha=0.3)
        item.legend(fontsize=8)
    return figure


# -- sections -----------------------------------------------------------------------------------


def _winner_text(diagnosis: Diagnosis) -> str:
    if diagnosis.verdict in diagnosis.default_path_reasons:
        return f"Why {diagnosis.verdict}: {diagnosis.default_path_reasons[diagnosis.verdict]}"
    chosen = [s for s in diagnosis.suspects if s.effect == diagnosis.verdict]
    if chosen:
        return f"Why {chosen[0].effect}: {chosen[0].signature}"
    if diagnosis.suspects:
        best = diagnosis.suspects[0]
        return (
            "No effect lowered the held-out error significantly; the best suspect was "
            f"{best.effect}: {best.signature}"
        )
    return "No effect was tried."


def _summary(diagnosis: Diagnosis) -> str:
    d = diagnosis
    fits = [("base", d.base), (f"final ({_label(d.final)})", d.final)]
    return _section(
        "Summary",
        f"<p>Source: {escape(d.source)}; {d.time.size} samples at {_num(1 / d.dt, '.6g')} Hz; "
        f"tc{d.slow} (the slower) is simulated from tc{3 - d.slow}. Noise: sigma1 = "
        f"{escape(_num(d.sigma1, '.3g'))} °C, sigma2 = {escape(_num(d.sigma2, '.3g'))} °C "
        f"(phi = {escape(_num(d.phi, '.3g'))}).</p>",
        f'<p class="verdict">Verdict: {escape(d.verdict)}</p>',
        _table(
            [
                "model",
                "tau1 (s)",
                "tau2 (s)",
                "held-out error (%)",
                "raw (%)",
                "noise floor (%)",
                "on estimation blocks (%)",
            ],
            [
                [
                    name,
                    f.tau1,
                    f.tau2,
                    f.error_pct,
                    f.raw_error_pct,
                    f.noise_floor_pct,
                    f.train_error_pct,
                ]
                for name, f in fits
            ],
        ),
        "<p>Held-out error: 100 rms(simulated − measured) / std(measured) of the slow sensor "
        "simulated from the fast one, both low-passed at "
        f"{escape(_num(d.eval_cutoff_hz, '.4g'))} Hz, on the validation blocks the fit never "
        "saw, with the sensors' noise floor taken out in quadrature (0 is a perfect model); "
        "the raw error keeps the noise in.</p>",
        "<p>Where the base model fails:</p>",
        _list(d.failure.findings),
        f"<p>{escape(_winner_text(d))}</p>",
        f"<p><b>Unexplained:</b> {escape(d.unexplained)}</p>" if d.unexplained else "",
        ("<p>What the two signals cannot fix:</p>" + _list(d.identifiability))
        if d.identifiability
        else "",
        _intervals(d.final),
    )


def _intervals(fit: ModelFit) -> str:
    """The final model's parameters with their 95 % intervals and bound flags."""
    if not fit.intervals:
        return ""
    rows = [
        [
            name,
            fit.params[name],
            low,
            high,
            "at its physical bound" if name in fit.at_bound else "",
        ]
        for name, (low, high) in fit.intervals.items()
    ]
    return "<p>Final model parameters:</p>" + _table(
        ["parameter", "value", "95 % low", "95 % high", ""], rows
    )


def _comparison(diagnosis: Diagnosis) -> str:
    return _section(
        "Model vs measurement",
        "<p>The slow sensor against its free-run simulation from the fast one; held-out "
        "blocks shaded.</p>",
        _image(_comparison_figure(diagnosis), "measured slow sensor and free-run simulations"),
    )


def _p_value(acf: Autocorrelation) -> str:
    return "p < 1e-6" if acf.p_value < 1e-6 else f"p = {_num(acf.p_value, '.2g')}"


def _residuals(diagnosis: Diagnosis) -> str:
    acf, ccf = diagnosis.failure.acf, diagnosis.failure.ccf_input
    return _section(
        "Residuals",
        f"<p>Ljung-Box Q = {escape(_num(acf.ljung_box_q, '.4g'))}, {escape(_p_value(acf))}; "
        f"{escape(_num(100 * acf.fraction_outside, '.0f'))} "
        "% of the autocorrelation lags lie outside the white-noise bound. The cross-correlation "
        "bound uses Bartlett's formula for autocorrelated series; its peak is "
        f"{escape(_num(ccf.peak, '.2f'))} at {escape(_num(1e3 * ccf.peak_lag_s, '.3g'))} ms "
        f"({'significant' if ccf.significant else 'not significant'}).</p>",
        _image(_residual_figure(diagnosis), "residual autocorrelation and cross-correlation"),
    )


def _where(diagnosis: Diagnosis) -> str:
    candidates = diagnosis.failure.candidates
    return _section(
        "Where it fails",
        _image(_where_figure(diagnosis), "error over time, tau over time, bands and levels"),
        "<p>Zero-lag correlation of the residual with candidate signals (bound for "
        "uncorrelated autocorrelated series):</p>",
        _table(
            ["signal", "correlation", "bound", "z"],
            [[c.name, c.correlation, c.bound, c.z] for c in candidates],
        ),
    )


def _suspect_rows(suspects: Sequence[Suspect]) -> list[list[object]]:
    return [
        [
            s.effect,
            s.error_pct,
            s.evidence,
            "yes" if s.significant else f"no: {s.refusal}" if s.refusal else "no",
            s.signature,
        ]
        for s in suspects
    ]


def _suspects(diagnosis: Diagnosis) -> str:
    header = ["effect", "held-out error (%)", "evidence", "significant (or why not)", "signature"]
    parts = []
    for number, suspects in enumerate(diagnosis.rounds, start=1):
        parts.append(f"<h3>Round {number} (best first)</h3>")
        parts.append(_table(header, _suspect_rows(suspects)))
    if not parts:
        parts.append("<p>No effect was tried.</p>")
    return _section("Suspects", *parts)


def _staircase(diagnosis: Diagnosis) -> str:
    steps = diagnosis.steps
    return _section(
        "Error staircase",
        _image(_staircase_figure(steps), "held-out error of each model of the staircase"),
        _table(
            ["model", "tau1 (s)", "tau2 (s)", "held-out error (%)", "raw (%)", "parameters"],
            [[_label(s), s.tau1, s.tau2, s.error_pct, s.raw_error_pct, s.n_params] for s in steps],
        ),
    )


def _reconstructions(diagnosis: Diagnosis) -> str:
    parts = [_image(_reconstruction_figure(diagnosis), "reconstructed gas temperature (zoom)")]
    if diagnosis.ref_error_pct:
        parts.append(
            "<p>Reference against each reconstruction of the final model and the first-order "
            "fused one, rms in % of its spread (both low-passed at the comparison band edge). "
            "<code>tcomp reconstruct --effects auto</code> and <code>tcomp process --effects "
            "auto</code> publish the gas compensated with the final model.</p>"
        )
        parts.append(
            _table(
                ["reconstruction", "error (%)"],
                [[name, float(value)] for name, value in diagnosis.ref_error_pct.items()],
            )
        )
    return _section("Reconstructions", *parts)


def _html(diagnosis: Diagnosis) -> str:
    body = "\n".join(
        (
            _summary(diagnosis),
            _comparison(diagnosis),
            _residuals(diagnosis),
            _where(diagnosis),
            _suspects(diagnosis),
            _staircase(diagnosis),
            _reconstructions(diagnosis),
            _section("Notes", _list(diagnosis.notes)),
        )
    )
    return _page(f"tcomp diagnosis: {diagnosis.source}", body)


def _windows_figure(result: WindowedDiagnosis) -> Figure:
    """τ1 and τ2 per window (95 % intervals, the whole record's medians) and the error."""
    rows = [row for row in result.windows if row.verdict is not None]
    figure = Figure(figsize=(9.0, 7.0), layout="constrained")
    tau1_axes, tau2_axes, errors = figure.subplots(3, 1, sharex=True)
    middle = np.array([row.start_s + 0.5 * row.length_s for row in rows])
    whole = result.whole
    for axes, name, color, median in (
        (tau1_axes, "tau1", "C0", whole.tau1),
        (tau2_axes, "tau2", "C1", whole.tau2),
    ):
        values = np.array([getattr(row, name) for row in rows])
        bounds = [
            getattr(row, f"{name}_95") or (v, v) for row, v in zip(rows, values, strict=True)
        ]
        spread = np.abs(np.array(bounds).T - values) if rows else None
        axes.errorbar(
            middle,
            values,
            yerr=spread,
            fmt="o",
            color=color,
            capsize=3,
            label="window (95 % interval)",
        )
        axes.axhline(median, color="0.3", linestyle="--", label=f"median {median:.4g} s")
        axes.set_ylabel(f"{name}, s")
        axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    errors.plot(middle, [row.error_pct for row in rows], "o", color="C2")
    for row, x in zip(rows, middle, strict=True):
        errors.annotate(
            str(row.verdict),
            (x, row.error_pct),
            fontsize=8,
            textcoords="offset points",
            xytext=(0, 4),
            ha="center",
        )
    for axes in (tau1_axes, tau2_axes, errors):
        for row in result.windows:
            if row.verdict is None:
                axes.axvspan(row.start_s, row.start_s + row.length_s, color="0.88")
    errors.set_ylabel("held-out error, %")
    errors.set_xlabel("time from the record's start, s (grey: windows not diagnosed)")
    return figure


def _windowed_html(result: WindowedDiagnosis) -> str:
    whole = result.whole
    summary = (
        f'<p class="verdict">verdict: {escape(whole.verdict)} (the verdict of {whole.agree} of '
        f"{whole.voting} windows)</p><p>tau1 = {_num(whole.tau1, '.5g')} s, tau2 = "
        f"{_num(whole.tau2, '.5g')} s: medians over those windows (ranges "
        f"{_num(whole.tau1_range[0])} .. {_num(whole.tau1_range[1])} s and "
        f"{_num(whole.tau2_range[0])} .. {_num(whole.tau2_range[1])} s). Windows of "
        f"{_num(result.window_s, 'g')} s, each diagnosed on its own; the verdict is the one "
        "most windows give (a last window shorter than half a window does not vote, a found "
        "effect goes first on a tie).</p>"
    )

    def interval(value: tuple[float, float] | None) -> str:
        return "" if value is None else f"{_num(value[0])} .. {_num(value[1])}"

    table = _table(
        [
            "window",
            "start s",
            "samples",
            "tau1 s",
            "95 %",
            "tau2 s",
            "95 %",
            "error %",
            "verdict",
            "effects or problem",
        ],
        (
            [
                row.index + 1,
                float(row.start_s),
                row.samples,
                float(row.tau1),
                interval(row.tau1_95),
                float(row.tau2),
                interval(row.tau2_95),
                float(row.error_pct),
                row.verdict or "not diagnosed",
                row.problem or ", ".join(row.effects) or "-",
            ]
            for row in result.windows
        ),
    )
    notes = [f"window {row.index + 1}: {note}" for row in result.windows for note in row.notes]
    body = "\n".join(
        (
            _section("Summary", summary),
            _section(
                "Windows", _image(_windows_figure(result), "tau and error per window"), table
            ),
            _section("Notes", _list(notes)),
        )
    )
    return _page(f"tcomp diagnosis in windows: {result.source}", body)


def _write_page(page: str, directory: str | Path, overwrite: bool, inputs: Iterable[Path]) -> Path:
    """Write ``directory/index.html`` whole under a temporary name, then rename it."""
    from .io import atomic_output

    target = Path(directory)
    with atomic_output(target, overwrite, inputs, directory=True) as temporary:
        temporary.mkdir()
        (temporary / "index.html").write_text(page, encoding="utf-8")
    return target / "index.html"


def write_windowed_report(
    result: WindowedDiagnosis,
    directory: str | Path,
    *,
    overwrite: bool = False,
    inputs: Iterable[Path] = (),
) -> Path:
    """Write a diagnosis in windows as one self-contained ``index.html``.

    Sections: the whole record's verdict and τ, a figure of τ1 and τ2 per window (95 %
    intervals, the medians) and of the held-out error with each window's verdict, the
    windows' table, their notes. Parameters and return as :func:`write_report`.
    """
    return _write_page(_windowed_html(result), directory, overwrite, inputs)


def write_report(
    diagnosis: Diagnosis,
    directory: str | Path,
    *,
    overwrite: bool = False,
    inputs: Iterable[Path] = (),
) -> Path:
    """Write the diagnosis as one self-contained ``index.html``.

    Parameters
    ----------
    diagnosis : Diagnosis
        What :func:`tcomp_core.diagnose.diagnose` found.
    directory : str or Path
        Where to write: a directory of its own, written whole under a temporary name and
        renamed (:func:`tcomp_core.io.atomic_output`).
    overwrite : bool
        Replace an existing report directory.
    inputs : iterable of Path
        The data the diagnosis read: the report may not overlap them.

    Returns
    -------
    Path
        The path of ``index.html``. Sections: summary, model vs measurement, residuals, where
        it fails, suspects, error staircase, reconstructions, notes.
    """
    return _write_page(_html(diagnosis), directory, overwrite, inputs)
