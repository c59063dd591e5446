"""Whether the data pin down what a fitted model would change in the gas temperature.

Two sensors identify only the ratio of their transfer functions, so a lower model error does not
prove a better gas: a parameter can lower the error while the data leave it free to trade with
τ. Before a fitted model is applied to the published gas (:mod:`tcomp_core.compensation.plan`),
each of its effects' parameters is checked, from the fit's covariance
(:func:`~tcomp_core.diagnose.uncertainty.parameter_covariance`):

* **determined**: the covariance exists (the Jacobian of the fit is not singular);
* **not on a bound**: a fit that ends on a bound of a parameter's physical range wanted more than
  physics allows;
* **not confounded with τ**: the correlation of its estimate with τ1's or τ2's is below
  :data:`MAX_TAU_CORRELATION` (beyond it the data cannot tell the effect from a change of τ).

And the model as a whole: the **95 % band** its parameters' uncertainty puts on the gas
(propagated through the reconstruction: central differences of the gas along each parameter's
standard deviation, combined with the parameters' correlations) must be narrower than the
**change** the model makes to the gas against the first-order model of the same record, both in
the diagnosis's comparison band (low-passed where the model, not the noise, decides) as rms
values over the record. A change smaller than its own uncertainty is not a correction.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..effects import FitContext, Model
from .uncertainty import Z95, ParameterCovariance

__all__ = [
    "MAX_TAU_CORRELATION",
    "Identification",
    "ParameterCheck",
    "identify",
]

#: Largest |correlation| of an effect parameter's estimate with τ1's or τ2's that still tells
#: the effect from a change of τ.
MAX_TAU_CORRELATION = 0.99
#: Central-difference step along a parameter, in its standard deviations.
_STEP_SD = 0.1


@dataclass(frozen=True)
class ParameterCheck:
    """How well the data pin down one effect parameter.

    Attributes
    ----------
    effect, name : str
    value : float
        The estimate, in the parameter's unit.
    low, high : float
        Its 95 % interval (NaN when not determined).
    tau_correlation : float
        Largest |correlation| with τ1 or τ2 (NaN when unknown).
    at_bound : bool
        On a bound of its physical range.
    gas_band_c : float
        rms 95 % half-width its uncertainty alone puts on the gas (signal band), degrees C.
    reason : str
        Why it is not pinned down ('' when it is).
    """

    effect: str
    name: str
    value: float
    low: float
    high: float
    tau_correlation: float
    at_bound: bool
    gas_band_c: float
    reason: str = ""

    @property
    def pinned(self) -> bool:
        """Whether the data pin the parameter down."""
        return not self.reason

    def summary(self) -> dict[str, Any]:
        """JSON-ready form (NaN as None)."""
        return {
            "effect": self.effect,
            "name": self.name,
            "value": _finite(self.value),
            "interval_95": [_finite(self.low), _finite(self.high)],
            "tau_correlation": _finite(self.tau_correlation),
            "at_bound": self.at_bound,
            "gas_band_c": _finite(self.gas_band_c),
            "pinned": self.pinned,
            "reason": self.reason,
        }

    def describe(self) -> str:
        """One line: value, interval, correlation, band, verdict."""
        state = "pinned down" if self.pinned else f"NOT pinned down: {self.reason}"
        return (
            f"{self.name} = {self.value:.4g} (95 % {self.low:.4g} .. {self.high:.4g}; "
            f"|corr. with tau| {self.tau_correlation:.3f}; gas band +-{self.gas_band_c:.3g} degC)"
            f": {state}"
        )


@dataclass(frozen=True)
class Identification:
    """The identification checks of a fitted model.

    Attributes
    ----------
    checks : tuple of ParameterCheck
        One per searched parameter of the model's effects.
    band_c : float
        rms 95 % half-width of the gas band from all the parameters (τ included), degrees C.
    change_c : float
        rms change the model makes to the gas against the first-order model, degrees C.
    """

    checks: tuple[ParameterCheck, ...]
    band_c: float
    change_c: float

    def unpinned(self, effects: tuple[str, ...] | None = None) -> tuple[ParameterCheck, ...]:
        """The checks that failed, of ``effects`` (None: all)."""
        return tuple(
            check
            for check in self.checks
            if not check.pinned and (effects is None or check.effect in effects)
        )

    @property
    def band_exceeds_change(self) -> bool:
        """Whether the gas band is at least as wide as the change (or either is unknown)."""
        return not (self.band_c < self.change_c)

    def summary(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "gas_band_c": _finite(self.band_c),
            "gas_change_c": _finite(self.change_c),
            "parameters": [check.summary() for check in self.checks],
        }


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _gas(
    model: Model,
    params: dict[str, float],
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    context: FitContext,
) -> NDArray[np.float64]:
    """Mean of the two sensors' reconstructions, edges (a delay's shift) held, shape (N - 1,)."""
    gas1, gas2 = Model(model.effects, params).reconstruct(*readings, context)
    gas = 0.5 * (gas1 + gas2)
    finite = np.flatnonzero(np.isfinite(gas))
    if finite.size == 0:
        return gas
    gas[: finite[0]] = gas[finite[0]]
    gas[finite[-1] + 1 :] = gas[finite[-1]]
    return gas


def _rms(values: NDArray[np.float64], keep: NDArray[np.bool_]) -> float:
    kept = values[keep]
    kept = kept[np.isfinite(kept)]
    return float(np.sqrt(np.mean(kept**2))) if kept.size else math.nan


def identify(
    model: Model,
    covariance: ParameterCovariance,
    base_taus: tuple[float, float],
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    context: FitContext,
    lowpass: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    keep: NDArray[np.bool_],
    *,
    level_free: bool = False,
) -> Identification:
    """Check a fitted model's effect parameters and its gas band (see the module docstring).

    Parameters
    ----------
    model : Model
        The fitted model.
    covariance : ParameterCovariance
        Its parameters' covariance.
    base_taus : (float, float)
        τ1, τ2 of the first-order model of the same record, s.
    readings : (ndarray, ndarray)
        tc1, tc2 at the fit's working rate, shape (N,) each, degrees C.
    context : FitContext
    lowpass : callable
        The diagnosis's comparison low-pass.
    keep : ndarray of bool, shape (N - 1,)
        Samples that count (start-up transient and edges left out).
    level_free : bool
        Compare the change and the band with their means removed (the level stays first
        order's, as for a calibration).
    """
    params = dict(model.params)
    gas = lowpass(_gas(model, params, readings, context))
    first = Model((), {"tau1": base_taus[0], "tau2": base_taus[1]})
    change = gas - lowpass(_gas(first, dict(first.params), readings, context))
    if level_free:
        change = change - np.mean(change[keep])
    change_c = _rms(change, keep)
    names = covariance.names
    matrix = covariance.matrix
    effect_of = {
        spec.name: effect.name for effect in model.instances for spec in effect.specs(context)
    }
    intervals = covariance.intervals()
    sensitivities: dict[str, NDArray[np.float64]] = {}
    if matrix is not None:
        sds = np.sqrt(np.clip(np.diag(matrix), 0.0, None))
        for index, name in enumerate(names):
            if name in covariance.at_bound or not sds[index] > 0.0:
                continue  # held at its bound: no derivative across it
            shifted_gas = []
            for sign in (1.0, -1.0):
                x = covariance.x.copy()
                x[index] += sign * _STEP_SD * sds[index]
                shifted = dict(params)
                shifted[name] = math.exp(x[index]) if name.startswith("tau") else float(x[index])
                shifted_gas.append(lowpass(_gas(model, shifted, readings, context)))
            # per standard deviation of the parameter
            derivative = (shifted_gas[0] - shifted_gas[1]) / (2.0 * _STEP_SD)
            if level_free:
                derivative = derivative - np.mean(derivative[keep])
            sensitivities[name] = derivative
    band_c = math.nan
    if matrix is not None and sensitivities:
        used = [name for name in names if name in sensitivities]
        rows = np.array([names.index(name) for name in used])
        spread = np.sqrt(np.diag(matrix))[rows]
        correlations = matrix[np.ix_(rows, rows)] / np.outer(spread, spread)
        columns = np.stack([sensitivities[name][keep] for name in used], axis=1)
        variance = np.sum((columns @ correlations) * columns, axis=1)
        band_c = Z95 * math.sqrt(float(np.mean(np.clip(variance, 0.0, None))))
    checks = []
    for name in names:
        if name not in effect_of:
            continue
        low, high = intervals[name]
        with_tau = [abs(covariance.correlation(name, f"tau{i}")) for i in (1, 2)]
        finite = [value for value in with_tau if math.isfinite(value)]
        correlation = max(finite) if finite else math.nan
        own_band = Z95 * _rms(sensitivities[name], keep) if name in sensitivities else math.nan
        reason = ""
        if matrix is None:
            reason = "the data do not determine it (singular fit)"
        elif name in covariance.at_bound:
            reason = "on a bound of its physical range"
        elif correlation >= MAX_TAU_CORRELATION:
            reason = f"confounded with tau (|correlation| {correlation:.3f})"
        checks.append(
            ParameterCheck(
                effect=effect_of[name],
                name=name,
                value=float(params[name]),
                low=low,
                high=high,
                tau_correlation=correlation,
                at_bound=name in covariance.at_bound,
                gas_band_c=own_band,
                reason=reason,
            )
        )
    return Identification(checks=tuple(checks), band_c=band_c, change_c=change_c)
