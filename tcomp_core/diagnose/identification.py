"""Whether the data pin down what a fitted model would change in the gas temperature.

Two sensors identify only the ratio of their transfer functions, so a lower model error does not
prove a better gas: a parameter can lower the error while the data leave it free to trade with
τ, and a model of the wrong form can fit the ratio with a common part the data never saw.
Before a fitted model is applied to the published gas (:mod:`tcomp_core.compensation.plan`),
each of its effects' parameters is checked, from the fit's covariance
(:func:`~tcomp_core.diagnose.uncertainty.parameter_covariance`):

* **determined**: the covariance exists (the Jacobian of the fit is not singular);
* **not on a bound**: a fit that ends on a bound of a parameter's physical range wanted more than
  physics allows;

and its correlation with τ1 and τ2 is reported (radiation's ρ correlates with τ by its very
form, τ/(1 + ρ) being what the dynamics see, so a correlation alone refuses nothing: the band
below carries it). A parameter that passes both is **pinned down** only when its 95 % interval
is narrower than the physics allows anyway: an interval that reaches a bound of the physical
range (a radiative ratio whose interval reaches 0) or spans :data:`LOOSE_SHARE` of the range
or more (a property exponent of −1.5 .. 1.5; in the search coordinates, the logarithm for a
time constant) is **loose**, and the report says so. Reaching a bound refuses nothing by
itself (a thin wire's radiative ratio may well be 0 while the thick one's is not); an effect
the gas would undo with all its parameters (:mod:`tcomp_core.compensation.plan`) is not
applied when one of them is **free**, its interval spanning :data:`FREE_SHARE` of its range or
more, and the gas moves across that interval (along the fit's valley, the other parameters
following it) in its fluctuation by as much as the band, or in all by as much as the change
the model makes: the data say nothing of it and it decides the gas (conduction on a mixing
rig with a hidden speed drift, the supports' lag and temperatures spanning 95–100 % of their
ranges, moved the gas's fluctuation by ±14 °C rms against a band of ±8 °C, and made the gas
8 → 58 % off). A free parameter that moves only the gas's level, by less than the change, is
part of the published band instead (:meth:`Identification.output_band_c`): the level is known
no better than the sensors' tolerance anyway. A hot radiating pair, whose level difference
the sensors' class-2 tolerance may share, has its wall temperature anywhere in its range,
which moves the gas level by ±13 °C rms (its fluctuation by ±0.3 °C) where radiation corrects
it by 21 °C: the gas error falls 41 → 4 %. A **wide** parameter, its interval spanning
:data:`LOOSE_SHARE` of its range or more, refuses the effect when the gas moves across it by
as much as the change (conduction read into a radiating exhaust, campaign draw 408: the
supports' temperatures spanning 74 % of their range moved the gas by ±87 °C rms against a
change of 17 °C, which had put the gas 12.5 °C further off); short of that its fluctuation
is the band's business, the covariance overstating some intervals (a true radiation's ρ1
spans 51–59 % of 0 .. 0.2 and moves the gas's fluctuation by ±3.6 °C rms, where fits on new
noise spread 4 times less).
A level the data do not fix moves the gas by nothing when it is not applied (a wall
temperature anywhere in −73 .. 509 °C behind a radiative ratio near 0).

And the model as a whole: the **95 % band** on the gas must be narrower than the **change** its
effects make to the gas, against the first-order model at the fit's own τ (a τ that moves is
the first-order path's business: its gas is what a refused model falls back to), both in the
diagnosis's comparison band (low-passed where the model, not the noise, decides) as rms values
over the record. A change smaller than its own uncertainty is not a correction. (Against the
first-order model at the initial τ, the change also carried the τ's own move: on a noise-ratio
draw at 5 kHz a conduction moved the gas level by 20 °C, within a band of ±33 °C, and passed as
a "change" of 101 °C, most of it the τ; its gas was 5 times worse than first order's.) The
band is a delete-a-block jackknife (:data:`JACKKNIFE_BLOCKS` refits of the model, each leaving one
contiguous stretch of the record out, warm-started at the fit): it measures how far the gas
moves when the data change, which a covariance from the curvature of the criterion cannot do for
a model of the wrong form (on the effect simulator's radiation the sandwich covariance puts ρ's
95 % interval at ±0.07 where fits on new noise spread by ±0.016), and it takes the model's
nonlinearity as it is. It cannot do so for **local parameters**
(:attr:`~tcomp_core.effects.base.Effect.local_parameters`: a varying speed's spline, each
coefficient decided by a few seconds of the record): the refit without a stretch only
interpolates them across it, and the jackknife counts that interpolation, n − 1 times over, as
the fit's uncertainty (campaign draw 2244, the speed swinging ±23 % on a rotating disk: ±4.8 °C
rms, ±4.3 of it from each stretch's own refit, against a change of 2.7 °C that took the gas
10.6 → 1.8 % off; it was refused). With local parameters each stretch's variance comes from the
refits that kept it (what the rest of the record does to τ), and the local parameters' own
covariance adds theirs by the delta method: ±1.3 °C there.

Nor may the change be more than :data:`MAX_CHANGE_PER_EVIDENCE` times the **evidence**, the
rms disagreement of the two sensors' first-order reconstructions (the smallest of those at the
initial τ, unless an effect of the model hides there
(:attr:`~tcomp_core.effects.base.Effect.evidence_at_start`: a delay), at the fit's own and at
the default path's: a τ far off inflates it, 245 °C rms on
steps where the fit's own τ leave 9 °C; on a step record with a mains line whose first-order
fit put τ1 on its 6 s bound, a delay then fitted with the two τ in swapped order, 0.26 and
0.007 s, left 112 °C at both its own and the initial τ, and 4.5 °C at the default path's,
0.029 and 0.074 s: its change of 37 °C was the swap, and its gas 31 % off where the default
path's was 5.8 %): every correction is inferred from that disagreement, and a correction many
times larger is carried by the model's form (a common part both sensors would share, which the
two signals cannot see).

The **form** of an effect is one reading of the literature, and the data may not tell it from
another (:attr:`~tcomp_core.effects.base.Effect.alternative_forms`: a property's τ at the film
or the junction temperature, or following one wire only). The model is refitted in each other
form (its output-error parameters searched again); a form the held-out blocks rule out (the
fit beats it clearly, :func:`~tcomp_core.diagnose.ranking.beats_clearly`) counts no further.
Each remaining form adds its move of the gas to the band (the largest, in quadrature), and the
change that counts is the smallest any form makes: a correction is established only if every
form the data allow finds it (campaign draw 2060: the shared exponent changed the gas by
6.2 °C rms, the slower wire alone, which explained the held-out blocks as well, by 0.6; the
change applied had put the gas 1.0 → 3.2 % off).
So does a **rival** effect: one the round that took the model's last effect found significant
too and the one taken does not beat clearly on the held-out blocks. The model with it in
place of the last effect, refitted on the whole record, is one more explanation the data
allow, and its move and change count as a form's (campaign draw 3402, conduction to lagging
supports behind a mains line: a calibration with tc2's gain at 0.83 was taken, a conduction
did as well on the held-out blocks, and the calibration's τ had put the gas 7.40 → 9.00 % off;
with the conduction's move the band is ±2.3 °C against a change of 1.5, and the default path's
gas is kept).

Given the τ the default first-order path publishes (``published_taus``), the change is also
measured against first order there (:attr:`Identification.published_change_c`): what applying
the model changes for a user. It decides only where that default first order demonstrably fails
the record (:mod:`tcomp_core.compensation.plan`); elsewhere a τ the model moves stays the
first-order path's business, as above.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..effects import FitContext, Model
from ..effects.base import ParamSpec
from ..effects.model import LEVEL
from ..errors import EstimationError
from ..lines import ForeignLine, line_free_pair
from .uncertainty import Z95, ParameterCovariance

__all__ = [
    "FREE_SHARE",
    "JACKKNIFE_BLOCKS",
    "LOOSE_SHARE",
    "MAX_CHANGE_PER_EVIDENCE",
    "Identification",
    "ParameterCheck",
    "held_edges",
    "identify",
]

#: Contiguous stretches of the record the jackknife leaves out one at a time.
JACKKNIFE_BLOCKS = 5
#: Largest change to the gas per degree of the sensors' first-order disagreement. An effect
#: that acts on both wires by their physics (radiation, conduction, a varying speed) differs
#: between them by the ratio r of its strength on the two; the correction it makes is about
#: 1/(r − 1) times their disagreement. Wires chosen for two-thermocouple work are 1.8 times
#: apart or more in diameter, so r ≥ 1.8^0.5 ≈ 1.34 (a loss per convective conductance grows
#: at least as √d) and the ratio stays below 3; beyond 4 the correction rests on the model's
#: form, not on anything the two signals show.
MAX_CHANGE_PER_EVIDENCE = 4.0
#: Share of a parameter's range (its search bounds) at or beyond which its 95 % interval is
#: loose: the data then bound it little better than the range does.
LOOSE_SHARE = 0.5
#: Share at or beyond which the parameter is free: the data say nothing of it.
FREE_SHARE = 0.9
#: :attr:`ParameterCheck.reason` of a parameter the fit left on a bound of its range.
ON_BOUND = "on a bound of its physical range"


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
    reason : str
        Why the fit does not determine it, which refuses the model ('' when determined and
        off its bounds).
    loose : str
        Why its interval is too wide to pin it down although it is determined ('' when
        narrow; module notes).
    range_share : float
        Share of its range (search bounds, in the search coordinates) its 95 % interval
        spans (NaN when not determined).
    gas_move_c : float
        rms 95 % half-width of the gas when the parameter goes to the ends of its interval
        along the fit's valley (the other parameters following it by their covariance),
        degrees C; for a parameter on a bound, the larger move of an end from the fit's gas.
        NaN when not computed (neither wide nor on a bound, or no covariance).
    gas_shape_move_c : float
        The same with the move's mean over the record removed: what the parameter moves in
        the gas's fluctuation rather than its level, degrees C.
    """

    effect: str
    name: str
    value: float
    low: float
    high: float
    tau_correlation: float
    at_bound: bool
    reason: str = ""
    loose: str = ""
    range_share: float = math.nan
    gas_move_c: float = math.nan
    gas_shape_move_c: float = math.nan

    @property
    def wide(self) -> bool:
        """Whether its interval spans :data:`LOOSE_SHARE` of its range or more."""
        return bool(self.range_share >= LOOSE_SHARE)

    @property
    def free(self) -> bool:
        """Whether its interval spans :data:`FREE_SHARE` of its range or more."""
        return bool(self.range_share >= FREE_SHARE)

    @property
    def determined(self) -> bool:
        """Whether the fit determines the parameter (covariance exists, off its bounds)."""
        return not self.reason

    @property
    def pinned(self) -> bool:
        """Whether the data pin the parameter down: determined, with a narrow interval."""
        return not (self.reason or self.loose)

    def summary(self) -> dict[str, Any]:
        """JSON-ready form (NaN as None)."""
        return {
            "effect": self.effect,
            "name": self.name,
            "value": _finite(self.value),
            "interval_95": [_finite(self.low), _finite(self.high)],
            "tau_correlation": _finite(self.tau_correlation),
            "at_bound": self.at_bound,
            "determined": self.determined,
            "pinned": self.pinned,
            "reason": self.reason,
            "loose": self.loose,
            "range_share": _finite(self.range_share),
            "gas_move_c": _finite(self.gas_move_c),
            "gas_shape_move_c": _finite(self.gas_shape_move_c),
        }

    def describe(self) -> str:
        """One line: value, interval, correlation, verdict."""
        if self.reason:
            state = f"NOT pinned down: {self.reason}"
        elif self.loose:
            state = f"NOT pinned down: {self.loose}"
        else:
            state = "pinned down"
        if math.isfinite(self.gas_move_c):
            state += (
                f"; across it the gas moves +-{self.gas_move_c:.3g} degC rms, "
                f"+-{self.gas_shape_move_c:.3g} of it in its fluctuation"
            )
        return (
            f"{self.name} = {self.value:.4g} (95 % {self.low:.4g} .. {self.high:.4g}; "
            f"|corr. with tau| {self.tau_correlation:.3f}): {state}"
        )


@dataclass(frozen=True)
class Identification:
    """The identification checks of a fitted model.

    Attributes
    ----------
    checks : tuple of ParameterCheck
        One per searched parameter of the model's effects.
    band_c : float
        rms 95 % half-width of the gas band (jackknife over :data:`JACKKNIFE_BLOCKS` refits),
        degrees C; inf when a refit failed.
    change_c : float
        rms change the model's effects make to the gas against the first-order model at the
        fit's own τ, degrees C.
    evidence_c : float
        rms disagreement of the two sensors' first-order reconstructions (the smallest of those
        at the initial τ unless an effect hides there, the fit's own and the default path's
        when given), degrees C: all the data say about anything the first-order model lacks.
    band_note : str
        Why the band is infinite ('' otherwise).
    form_c : float
        rms move of the gas when the model is refitted in each of its effects' other forms
        (:attr:`~tcomp_core.effects.base.Effect.alternative_forms`) or with a rival effect
        the held-out data do not rule out in place of the last one taken, the largest,
        degrees C; part of ``band_c`` (in quadrature with the jackknife's); 0 without either.
    form_note : str
        Which of them moved the gas most and by how much ('' without either).
    level_split_c : float
        The level difference the effects put between the two sensors, degrees C
        (:func:`level_split_c`).
    published_change_c : float
        rms change the model makes to the gas against the first-order model at the time
        constants the default path publishes (``published_taus`` of :func:`identify`), degrees
        C; nan when they were not given. What applying the model changes for a user: when the
        default path's first order demonstrably fails the record
        (:func:`tcomp_core.fusion.first_order_adequacy`), the model is applied if this change,
        not only its effects', stands beyond the band (:mod:`tcomp_core.compensation.plan`).
    """

    checks: tuple[ParameterCheck, ...]
    band_c: float
    change_c: float
    evidence_c: float = math.nan
    band_note: str = ""
    published_change_c: float = math.nan
    form_c: float = 0.0
    form_note: str = ""
    level_split_c: float = math.nan

    def undetermined(self, effects: tuple[str, ...] | None = None) -> tuple[ParameterCheck, ...]:
        """The parameters the fit does not determine (singular, or on a bound).

        Of ``effects`` (None: all); any of them refuses the model.
        """
        return tuple(
            check
            for check in self.checks
            if not check.determined and (effects is None or check.effect in effects)
        )

    def output_band_c(self, effects: tuple[str, ...]) -> float:
        """The rms 95 % half-width of the published gas when ``effects`` are applied, degrees C.

        The jackknife band with, in quadrature, the move across each free or on-bound parameter
        of those effects (:attr:`ParameterCheck.gas_move_c`): the refits share the fit's priors, so
        they cannot see what only a prior decides (a wall temperature behind the sensors'
        level difference).
        """
        moves = [
            check.gas_move_c
            for check in self.checks
            if check.effect in effects
            and (check.free or check.at_bound)
            and math.isfinite(check.gas_move_c)
        ]
        return math.sqrt(self.band_c**2 + sum(move**2 for move in moves))

    @property
    def band_exceeds_change(self) -> bool:
        """Whether the gas band is at least as wide as the change (or either is unknown)."""
        return not (self.band_c < self.change_c)

    @property
    def band_exceeds_published_change(self) -> bool:
        """Whether the band is at least as wide as the change against the published first order."""
        return not (self.band_c < self.published_change_c)

    @property
    def extrapolates(self) -> bool:
        """Whether the change exceeds :data:`MAX_CHANGE_PER_EVIDENCE` times the evidence."""
        return bool(self.change_c > MAX_CHANGE_PER_EVIDENCE * self.evidence_c)

    def summary(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "gas_band_c": _finite(self.band_c),
            "gas_change_c": _finite(self.change_c),
            "gas_change_against_published_c": _finite(self.published_change_c),
            "evidence_c": _finite(self.evidence_c),
            "band_note": self.band_note,
            "gas_form_move_c": _finite(self.form_c),
            "form_note": self.form_note,
            "level_split_c": _finite(self.level_split_c),
            "parameters": [check.summary() for check in self.checks],
        }


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def held_edges(gas: NDArray[np.float64]) -> NDArray[np.float64]:
    """``gas`` with its non-finite edges (a delay's shift) held at the nearest finite value."""
    finite = np.flatnonzero(np.isfinite(gas))
    if finite.size == 0:
        return gas
    gas = gas.copy()
    gas[: finite[0]] = gas[finite[0]]
    gas[finite[-1] + 1 :] = gas[finite[-1]]
    return gas


def level_split_c(
    model: Model,
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    context: FitContext,
    keep: NDArray[np.bool_],
) -> float:
    """The level difference the model's effects put between the two sensors, degrees C.

    Each sensor's reconstruction under the model (its sensor offset ``level_c`` left out)
    less its first-order reconstruction at the model's τ is what the effects move that
    sensor's gas by; the difference of the two moves' means over ``keep`` (shape (N - 1,)) is
    the part of the sensors' level difference the effects explain. NaN when not finite.
    """
    params = dict(model.params)
    params.pop(LEVEL, None)
    gas1, gas2 = _gas_pair(Model(model.effects, params), readings, context)
    first1, first2 = _gas_pair(
        Model((), {"tau1": model.tau1, "tau2": model.tau2}), readings, context
    )
    split = float(np.nanmean((gas1 - first1)[keep]) - np.nanmean((gas2 - first2)[keep]))
    return split if math.isfinite(split) else math.nan


def _gas_pair(
    model: Model,
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    context: FitContext,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each sensor's reconstruction under ``model``, edges held, shape (N - 1,) each.

    Each on its own scale, as an output is (:meth:`Model.without_level`).
    """
    gas1, gas2 = model.without_level().reconstruct(*readings, context)
    return held_edges(gas1), held_edges(gas2)


def _rms(values: NDArray[np.float64], keep: NDArray[np.bool_]) -> float:
    kept = values[keep]
    kept = kept[np.isfinite(kept)]
    return float(np.sqrt(np.mean(kept**2))) if kept.size else math.nan


def _jackknife_band(
    gas_of: Callable[[Model], NDArray[np.float64]],
    refit: Callable[[NDArray[np.bool_]], Model],
    n_rows: int,
    keep: NDArray[np.bool_],
    level_free: bool,
    local: bool = False,
) -> tuple[NDArray[np.float64] | None, str]:
    """The gas's variance from delete-a-block refits, shape (N - 1,), and why it is None.

    With ``local`` parameters, each block's variance comes from the refits that kept it: the
    refit without a block only interpolates its local parameters there.
    """
    edges = np.linspace(0, n_rows, JACKKNIFE_BLOCKS + 1).astype(int)
    gases = []
    for start, stop in itertools.pairwise(edges):
        rows = np.ones(n_rows, dtype=bool)
        rows[start:stop] = False
        try:
            gas = gas_of(refit(rows))
        except (EstimationError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            return None, f"a refit without samples {start}..{stop} failed: {exc}"
        if level_free:
            gas = gas - np.mean(gas[keep])
        gases.append(gas)
    stacked = np.stack(gases)
    if not np.all(np.isfinite(stacked[:, keep])):
        return None, "a refit's gas is not finite"

    def spread(values: NDArray[np.float64]) -> NDArray[np.float64]:
        count = values.shape[0]
        return (count - 1) / count * np.sum((values - values.mean(axis=0)) ** 2, axis=0)

    if not local:
        return spread(stacked), ""
    variance = np.empty(n_rows)
    for block, (start, stop) in enumerate(itertools.pairwise(edges)):
        variance[start:stop] = spread(np.delete(stacked[:, start:stop], block, axis=0))
    return variance, ""


def _from_search(name: str, value: float) -> float:
    """A parameter's value from its search coordinate (the logarithm for a time constant)."""
    return math.exp(value) if name.startswith("tau") else float(value)


def _local_variance(
    model: Model,
    covariance: ParameterCovariance,
    names: Sequence[str],
    gas_of: Callable[[Model], NDArray[np.float64]],
    keep: NDArray[np.bool_],
    level_free: bool,
) -> NDArray[np.float64] | None:
    """The gas's variance from the covariance of the local parameters ``names``, shape (N - 1,).

    The delta method with secants: each parameter stepped by ± its standard deviation (clipped
    to its bounds), the gas's half difference D_j, and var(gas) = D R Dᵀ with R their
    correlation. The covariance is the noise floor's
    (:attr:`~tcomp_core.diagnose.uncertainty.ParameterCovariance.noise_matrix`) where there is
    one: the lines a misfit leaves at the signal's frequencies are no noise, and counted as
    noise they put a varying speed's band 3-5 times wider than fits on new noise spread; the
    misfit is the refits' to show (:func:`_jackknife_band`). None when the covariance does not
    give it.
    """
    matrix = covariance.matrix if covariance.noise_matrix is None else covariance.noise_matrix
    if matrix is None:
        return None
    index = [covariance.names.index(name) for name in names if name in covariance.names]
    if not index:
        return np.zeros(keep.size)
    sub = matrix[np.ix_(index, index)]
    sigma = np.sqrt(np.clip(np.diag(sub), 0.0, None))
    columns = []
    for position, deviation in zip(index, sigma, strict=True):
        ends = []
        for sign in (-1.0, 1.0):
            params = dict(model.params)
            stepped = covariance.x[position] + sign * deviation
            low, high = covariance.lower[position], covariance.upper[position]
            name = covariance.names[position]
            params[name] = _from_search(name, float(np.clip(stepped, low, high)))
            try:
                ends.append(gas_of(Model(model.effects, params)))
            except (EstimationError, ValueError, ArithmeticError):
                return None
        half = 0.5 * (ends[1] - ends[0])
        columns.append(half - np.mean(half[keep]) if level_free else half)
    steps = np.stack(columns, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = sub / np.outer(sigma, sigma)
    correlation = np.where(np.isfinite(correlation), correlation, 0.0)
    return np.clip(np.einsum("tj,jk,tk->t", steps, correlation, steps), 0.0, None)


def _alternatives_band(
    gas: NDArray[np.float64],
    gas_of: Callable[[Model], NDArray[np.float64]],
    change_of: Callable[[Model], float],
    alternatives: Sequence[tuple[str, Callable[[], Model | None]]],
    keep: NDArray[np.bool_],
    level_free: bool,
) -> tuple[float, float, str]:
    """What the explanations the data do not rule out do to the gas: largest move, smallest change.

    Each alternative is ``(what it is, in words; its refit)``: the model in another of its
    effects' forms, or with a rival effect in place of the last one taken; a refit that gives
    None was ruled out by the held-out data. Its move is its gas less the fit's ``gas``, rms
    over ``keep`` (the mean removed when ``level_free``); its change is ``change_of`` it
    (against first order at its own τ). Returns the largest move (inf when a refit fails: its
    change cannot be bounded), the smallest change (inf without alternatives) and which
    alternative moved the gas most.
    """
    worst, smallest, note = 0.0, math.inf, ""
    for label, refit in alternatives:
        try:
            other = refit()
            if other is None:  # the held-out data tell it from the fit
                continue
            move = gas_of(other) - gas
            change = change_of(other)
        except (EstimationError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            return math.inf, math.nan, f"the refit with {label} failed: {exc}"
        if level_free:
            move = move - np.mean(move[keep])
        size = _rms(move, keep)
        if not math.isfinite(size):
            return math.inf, math.nan, f"the refit with {label} is not finite"
        smallest = min(smallest, change)
        if size >= worst:
            worst = size
            note = (
                f"{label} moves the gas {size:.3g} degC rms and changes it by {change:.3g} "
                "against its first order"
            )
    return worst, smallest, note


def _form_alternatives(
    model: Model, refit_form: Callable[[str, dict[str, float]], Model | None]
) -> list[tuple[str, Callable[[], Model | None]]]:
    """The model's effects' other forms as alternatives for :func:`_alternatives_band`."""
    return [
        (
            f"{effect.name} in its other form ("
            + ", ".join(f"{name} = {value:g}" for name, value in settings.items())
            + ")",
            partial(refit_form, effect.name, dict(settings)),
        )
        for effect in model.instances
        for settings in effect.alternative_forms
    ]


def _valley_move(
    model: Model,
    covariance: ParameterCovariance,
    name: str,
    gas_of: Callable[[Model], NDArray[np.float64]],
    keep: NDArray[np.bool_],
    level_free: bool,
    from_fit: bool = False,
) -> tuple[float, float]:
    """The rms 95 % half-width of the gas as ``name`` crosses its interval along the valley.

    The searched parameters move by ±1.96 times the covariance's column of ``name`` over its
    standard deviation (the others follow it as the fit lets them), clipped to their bounds;
    the gas at both ends, half their difference, rms over ``keep`` (its mean removed when
    ``level_free``), and the same with its mean removed. With ``from_fit``, for a parameter on
    a bound, where one end is clipped to the fit itself: the larger move of an end from the
    fit's gas instead of the half difference. NaN when the covariance does not give it.
    """
    matrix = covariance.matrix
    index = covariance.names.index(name)
    if matrix is None or not matrix[index, index] > 0.0:
        return math.nan, math.nan
    step = Z95 * matrix[:, index] / math.sqrt(matrix[index, index])
    ends = []
    for sign in (-1.0, 1.0):
        x = np.clip(covariance.x + sign * step, covariance.lower, covariance.upper)
        params = dict(model.params)
        for key, value in zip(covariance.names, x, strict=True):
            params[key] = _from_search(key, value)
        try:
            ends.append(gas_of(Model(model.effects, params)))
        except (EstimationError, ValueError, ArithmeticError):
            return math.inf, math.inf
    if from_fit:
        centre = gas_of(model)
        moves = [_moves(end - centre, keep, level_free) for end in ends]
        return max(move[0] for move in moves), max(move[1] for move in moves)
    return _moves(0.5 * (ends[1] - ends[0]), keep, level_free)


def _moves(
    difference: NDArray[np.float64], keep: NDArray[np.bool_], level_free: bool
) -> tuple[float, float]:
    """The rms over ``keep`` of a gas difference, and of it with its mean removed.

    The first has its mean removed too when ``level_free``.
    """
    shape = difference - np.nanmean(difference[keep])
    return _rms(shape if level_free else difference, keep), _rms(shape, keep)


def _looseness(spec: ParamSpec, low: float, high: float) -> tuple[str, float]:
    """Why the 95 % interval ``low .. high`` is too wide to pin ``spec`` down, and its share.

    ('' when narrow.) The share is of the range, in the search coordinates (the logarithm for
    a time constant). The interval is clipped to the bounds, so reaching a physical bound
    shows as equality.
    """
    if not (math.isfinite(low) and math.isfinite(high)):
        return "", math.nan
    scale = math.log if spec.name.startswith("tau") else float
    share = (scale(high) - scale(low)) / (scale(spec.upper) - scale(spec.lower))
    if share >= LOOSE_SHARE:
        return (
            f"its 95 % interval spans {100.0 * share:.0f} % of its range "
            f"{spec.lower:.4g} .. {spec.upper:.4g}"
        ), share
    if spec.physical:
        for bound in (spec.lower, spec.upper):
            if (low <= bound <= high) or math.isclose(bound, low) or math.isclose(bound, high):
                reach = f"its 95 % interval reaches {bound:.4g}, a bound of its physical range"
                return reach, share
    return "", share


def identify(
    model: Model,
    covariance: ParameterCovariance,
    base_taus: tuple[float, float],
    readings: tuple[NDArray[np.float64], NDArray[np.float64]],
    context: FitContext,
    lowpass: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    keep: NDArray[np.bool_],
    refit: Callable[[NDArray[np.bool_]], Model],
    *,
    level_free: bool = False,
    published_taus: tuple[float, float] | None = None,
    published_lines: Sequence[ForeignLine] = (),
    refit_form: Callable[[str, dict[str, float]], Model | None] | None = None,
    rivals: Sequence[tuple[str, Callable[[], Model | None]]] = (),
    level_split: float | None = None,
) -> Identification:
    """Check a fitted model's effect parameters and its gas band (see the module docstring).

    Parameters
    ----------
    model : Model
        The fitted model.
    covariance : ParameterCovariance
        Its parameters' covariance.
    base_taus : (float, float)
        τ1, τ2 of the first-order model of the same record (its initial estimate), s.
    readings : (ndarray, ndarray)
        tc1, tc2 at the fit's working rate, shape (N,) each, degrees C.
    context : FitContext
    lowpass : callable
        The diagnosis's comparison low-pass.
    keep : ndarray of bool, shape (N - 1,)
        Samples that count (start-up transient and edges left out).
    refit : callable
        Rows (ndarray of bool, shape (N - 1,)) → the model refitted on those rows only, from
        its fitted values.
    level_free : bool
        Compare the change and the band with their means removed (the level stays first
        order's, as for a calibration).
    published_taus : (float, float), optional
        τ1, τ2 the default first-order path publishes for the same record, s: the change is
        measured against first order there too (:attr:`Identification.published_change_c`),
        and the sensors' disagreement there is one more measure of the evidence.
    published_lines : sequence of ForeignLine
        The lines the default path takes off the channel that carries one
        (:attr:`tcomp_core.estimators.Estimate.lines`): its first order is measured on readings
        without them, as it publishes its gas (with a 3 °C mains line on a 66 ms wire,
        amplified 25 times by the inverse lag, the change came out 39 °C rms, of which 24
        were the model's).
    refit_form : callable, optional
        ``(effect name, settings)`` → the model refitted on all rows with that effect in the
        form the settings give, or None when the held-out data rule that form out: the
        effects' other forms (:attr:`~tcomp_core.effects.base.Effect.alternative_forms`) are
        tried with it and what they change in the gas joins the band. None: not tried.
    rivals : sequence of (str, callable)
        Rival explanations: in words, and a callable giving the model with a rival effect in
        place of the last one taken, refitted on all rows (None when the held-out data rule
        it out). What they change in the gas joins the band as the other forms' does.
    level_split : float, optional
        :func:`level_split_c` of the model when the caller has it already (degrees C).
    """

    def gas_of(fitted: Model) -> NDArray[np.float64]:
        gas1, gas2 = _gas_pair(fitted, readings, context)
        return lowpass(0.5 * (gas1 + gas2))

    gas = gas_of(model)

    def first_order(taus: tuple[float, float]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return _gas_pair(Model((), {"tau1": taus[0], "tau2": taus[1]}), readings, context)

    def change_against(
        first1: NDArray[np.float64], first2: NDArray[np.float64], of: NDArray[np.float64] = gas
    ) -> float:
        """The gas ``of`` (the model's) less the first-order gas ``first1``, ``first2``: rms."""
        change = of - lowpass(0.5 * (first1 + first2))
        return _rms(change - np.mean(change[keep]) if level_free else change, keep)

    def change_of(other: Model) -> float:
        """The change ``other`` makes to the gas against first order at its own τ."""
        return change_against(*first_order((other.tau1, other.tau2)), of=gas_of(other))

    own = first_order((model.tau1, model.tau2))
    first_orders = [own]
    if all(effect.evidence_at_start for effect in model.instances):
        first_orders.append(first_order(base_taus))
    published_change_c = math.nan
    if published_taus is not None:  # as the default path publishes its gas: lines taken off
        line_free = line_free_pair(*readings, context.dt, published_lines, published_taus)
        published = _gas_pair(
            Model((), {"tau1": published_taus[0], "tau2": published_taus[1]}), line_free, context
        )
        published_change_c = change_against(*published)
        first_orders.append(published)
    disagreements = [lowpass(pair[0] - pair[1]) for pair in first_orders]
    if level_free:
        disagreements = [values - np.mean(values[keep]) for values in disagreements]
    change_c = change_against(*own)  # at the fit's own τ: what its effects change
    evidence_c = min(_rms(values, keep) for values in disagreements)
    local = [
        spec.name
        for effect in model.instances
        if effect.local_parameters
        for spec in effect.specs(context)
    ]
    variance, band_note = _jackknife_band(gas_of, refit, keep.size, keep, level_free, bool(local))
    if variance is not None and local:
        local_variance = _local_variance(model, covariance, local, gas_of, keep, level_free)
        if local_variance is None:
            variance = None
            band_note = (
                "the local parameters' covariance gives no band (singular, or a step failed)"
            )
        else:
            variance = variance + local_variance
    band_c = math.inf if variance is None else Z95 * math.sqrt(float(np.mean(variance[keep])))
    form_c, form_note = 0.0, ""
    alternatives = [*(_form_alternatives(model, refit_form) if refit_form else []), *rivals]
    if alternatives:
        form_c, smallest, form_note = _alternatives_band(
            gas, gas_of, change_of, alternatives, keep, level_free
        )
        if form_c > 0.0:  # the alternative's move and the data's, independent: in quadrature
            band_c = math.sqrt(band_c**2 + form_c**2)
        if not math.isfinite(form_c) and not band_note:
            band_note = form_note
        # A correction is established only if every explanation the data allow finds it.
        change_c = min(change_c, smallest) if math.isfinite(smallest) else change_c
    owned = {
        spec.name: (effect.name, spec)
        for effect in model.instances
        for spec in effect.specs(context)
    }
    intervals = covariance.intervals()
    checks = []
    for name in covariance.names:
        if name not in owned:
            continue
        effect, spec = owned[name]
        low, high = intervals[name]
        with_tau = [abs(covariance.correlation(name, f"tau{i}")) for i in (1, 2)]
        finite = [value for value in with_tau if math.isfinite(value)]
        reason = ""
        if covariance.matrix is None:
            reason = "the data do not determine it (singular fit)"
        elif name in covariance.at_bound:
            reason = ON_BOUND
        loose, share = ("", math.nan) if reason else _looseness(spec, low, high)
        move = shape_move = math.nan
        if share >= LOOSE_SHARE:  # wide: what it moves decides (compensation.plan)
            move, shape_move = _valley_move(model, covariance, name, gas_of, keep, level_free)
        elif name in covariance.at_bound and covariance.matrix is not None:
            # On a bound, the interval's far end against the fit: a move the gas does not
            # notice leaves the parameter harmless to it (compensation.plan).
            move, shape_move = _valley_move(
                model, covariance, name, gas_of, keep, level_free, from_fit=True
            )
        checks.append(
            ParameterCheck(
                effect=effect,
                name=name,
                value=float(model.params[name]),
                low=low,
                high=high,
                tau_correlation=max(finite) if finite else math.nan,
                at_bound=name in covariance.at_bound,
                reason=reason,
                loose=loose,
                range_share=share,
                gas_move_c=move,
                gas_shape_move_c=shape_move,
            )
        )
    return Identification(
        checks=tuple(checks),
        band_c=band_c,
        change_c=change_c,
        evidence_c=evidence_c,
        band_note=band_note,
        published_change_c=published_change_c,
        form_c=form_c,
        form_note=form_note,
        level_split_c=(
            level_split_c(model, readings, context, keep) if level_split is None else level_split
        ),
    )
