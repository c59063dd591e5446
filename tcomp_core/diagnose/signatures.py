"""In words: which residual signature points to an effect, and what its refit found.

Each effect leaves its own mark on the residual of the model it is missing from:

* conduction: a slow residual, its power below the support mode's corner frequency;
* radiation: a residual that curves with the temperature level (T⁴);
* velocity: time constants that drift together over the record;
* property: a residual that follows the rate of change in proportion to the level (τ ∝ T^p);
* delay: a residual correlated with the rate of change of the input at a small lag;
* calibration: a residual offset and a slope against the temperature level;
* interference: a spectral line on one channel that the other does not share;
* noise_ratio: unequal noise floors in the two spectra (φ ≠ 1).

The statistics here are computed on the residual of the model the effect is added to, so they
hold in every round of the staircase.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..effects import Model
from ..effects.base import KELVIN
from ..effects.conduction import Conduction, fin_kappa
from .heldout import Evaluator
from .residuals import band_errors
from .result import ModelFit

__all__ = ["signature"]


def _residual(evaluator: Evaluator, fit: ModelFit) -> tuple[NDArray, NDArray, NDArray]:
    """Low-passed residual, slow reading and fast reading on the scored held-out samples."""
    readings = evaluator.readings
    measured = readings[evaluator.slow - 1]
    residual = evaluator.lowpass(measured - fit.predicted)
    mask = evaluator.data.validation & evaluator.scored_mask(Model(fit.effects, fit.params))
    return residual[mask], measured[mask], readings[2 - evaluator.slow][mask]


def _conduction(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    p = fit.params
    measured = evaluator.slow_lowpassed
    bands = band_errors(measured, evaluator.lowpass(current.predicted), evaluator.data.dt)
    ratio = bands.residual_to_signal
    # Bands where the slow sensor carries signal: the residual's share of it, low vs high.
    carrying = np.flatnonzero(np.isfinite(ratio) & (bands.coherence > 0.5))
    if carrying.size >= 2:
        low, high = carrying[0], carrying[-1]
        edges = bands.edges_hz
        evidence = (
            f"relative to the signal the residual is {ratio[low] / max(ratio[high], 1e-12):.3g} "
            f"times stronger at {edges[low]:.2g}–{edges[low + 1]:.2g} Hz than at "
            f"{edges[high]:.2g}–{edges[high + 1]:.2g} Hz, the mark of a slow mode"
        )
    else:
        evidence = "the residual is slow, the mark of a slow mode"
    ml1, ml2 = Conduction.fin_ml(1, p), Conduction.fin_ml(2, p)
    return (
        f"{evidence}; refit: legs' diffusion time {p['tau_leg']:.3g} s (mL1 = {ml1:.3g}, "
        f"mL2 = {ml2:.3g}: kappa1 = {fin_kappa(ml1):.3g}, kappa2 = {fin_kappa(ml2):.3g}), "
        f"tau_p = {p['tau_p']:.3g} s"
    )


def _level_fit(residual: NDArray, level: NDArray) -> tuple[float, float, float]:
    """Offset, slope and curvature of the residual against the centred level."""
    centred = level - level.mean()
    design = np.column_stack((np.ones_like(centred), centred, centred**2))
    coefficients, *_ = np.linalg.lstsq(design, residual, rcond=None)
    return float(coefficients[0]), float(coefficients[1]), float(coefficients[2])


def _radiation(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    residual, level, _ = _residual(evaluator, current)
    _, slope, curvature = _level_fit(residual, level)
    p = fit.params
    return (
        f"the residual bends with the temperature level (slope {slope:.3g} degC/degC, "
        f"curvature {curvature:.3g} /degC); refit: rho1 = {p['rho1']:.3g}, rho2 = "
        f"{p['rho2']:.3g} (radiative/convective), wall {p['wall_c']:.4g} degC"
    )


def _velocity(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    factor = Model(fit.effects, fit.params).chains(evaluator.context)[0].factor
    low, high = float(np.min(factor)), float(np.max(factor))
    return (
        "the time constants drift together over the record at a constant ratio; refit: "
        f"tau factor s(t) from {low:.2f} to {high:.2f} ({100 * (high - low) / 2:.0f} % swing), "
        f"tau2/tau1 = {fit.tau2 / fit.tau1:.3g}"
    )


def _property(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    residual, level, _ = _residual(evaluator, current)
    # A τ error proportional to the level's excursion leaves (T − T̄) dT/dt in the residual.
    marker = (level - level.mean()) * np.gradient(level)
    correlation = float(np.corrcoef(residual, marker)[0, 1]) if marker.std() > 0 else 0.0
    p = fit.params["property_exponent"]
    kelvin = level + KELVIN
    span = (kelvin.min() / kelvin.mean()) ** p, (kelvin.max() / kelvin.mean()) ** p
    return (
        "the residual follows the rate of change in proportion to the level "
        f"(correlation {correlation:.2f}), the mark of time constants that change with the "
        f"temperature; refit: tau ~ T^{p:.3g} (T in K), tau from {min(span):.3f} to "
        f"{max(span):.3f} times its mean-level value over the record"
    )


def _delay(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    residual, _, fast = _residual(evaluator, current)
    rate = np.gradient(fast)
    max_lag = max(1, round(abs(fit.params["delay_s"]) / evaluator.data.dt) * 3 + 3)
    lags = np.arange(-max_lag, max_lag + 1)
    scale = np.std(residual) * np.std(rate) * residual.size
    correlation = [
        float(np.sum((residual - residual.mean()) * (np.roll(rate, lag) - rate.mean())) / scale)
        for lag in lags
    ]
    best = int(np.argmax(np.abs(correlation)))
    return (
        f"the residual follows the input's rate of change (correlation {correlation[best]:.2f} "
        f"at {1e3 * lags[best] * evaluator.data.dt:.3g} ms); refit: tc2 sees the gas "
        f"{1e3 * fit.params['delay_s']:.3g} ms after tc1"
    )


def _calibration(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    residual, level, _ = _residual(evaluator, current)
    offset, slope, _ = _level_fit(residual, level)
    p = fit.params
    return (
        f"the residual has an offset ({offset:.3g} degC) and a slope against the level "
        f"({slope:.3g} degC/degC); refit: tc2 reads {p['gain']:.4g} T {p['offset_c']:+.3g} degC"
    )


def _interference(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    p = fit.params
    channel = int(p.get("interference_channel", 2))
    amplitude = math.hypot(p["interference_a1"], p["interference_b1"])
    return (
        f"tc{channel} carries a line the other channel does not share; refit: "
        f"{p['interference_hz']:.5g} Hz, {amplitude:.3g} degC at the fundamental, on tc{channel}"
    )


def _noise_ratio(evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    data = evaluator.data
    return (
        f"the noise floors differ: sigma1 = {data.noise1.sigma:.3g} degC, sigma2 = "
        f"{data.noise2.sigma:.3g} degC (from the {data.noise_source}, "
        f"phi = {data.phi_hat:.3g}), so "
        f"GTLS with phi = 1 weights them wrongly; refit with phi: tau1 {current.tau1:.4g} -> "
        f"{fit.tau1:.4g} s, tau2 {current.tau2:.4g} -> {fit.tau2:.4g} s"
    )


_SIGNATURES: dict[str, Callable[[Evaluator, ModelFit, ModelFit], str]] = {
    "conduction": _conduction,
    "radiation": _radiation,
    "velocity": _velocity,
    "property": _property,
    "delay": _delay,
    "calibration": _calibration,
    "interference": _interference,
    "noise_ratio": _noise_ratio,
}


def signature(name: str, evaluator: Evaluator, current: ModelFit, fit: ModelFit) -> str:
    """One sentence: the residual evidence for effect ``name`` and what its refit found."""
    return (
        f"{_SIGNATURES[name](evaluator, current, fit)}; held-out error "
        f"{current.error_pct:.3g} -> {fit.error_pct:.3g} %"
    )
