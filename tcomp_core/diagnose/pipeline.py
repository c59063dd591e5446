"""``diagnose``: fit the base model, find where it fails, add the missing effects one by one.

1. Prepare the record (working rate, noise, held-out blocks: :mod:`.prepare`).
2. Fit the base model of the paper, β-GTLS with φ = 1, on the estimation blocks, and score its
   free-run simulation of the slow sensor on the held-out blocks (:mod:`.heldout`).
3. Analyse its residuals: where in time, frequency and level it fails (:mod:`.residuals`).
4. Refit the model with each candidate effect in turn and rank them by held-out error
   (:mod:`.ranking`); keep the best while it lowers the held-out error significantly, then
   look for a further effect on top of it. The first round's runner-up is followed too, and
   its staircase is taken when it ends clearly better (:data:`FIRST_ROUND_BRANCHES`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import NDArray

from ..effects import EFFECT_NAMES, EFFECTS, Model, check_effect_names, make_context
from ..effects.chain import fractional_shift
from ..errors import EstimationError, TcompError
from ..estimators.beta import estimate_beta_from_scatter
from ..estimators.default import default_estimate
from ..estimators.scatter import beta_scatter
from ..io import Record
from ..lines import ForeignLine
from .heldout import Evaluator, heldout_error_percent
from .prepare import PreparedData, block_length_s, prepare
from .ranking import (
    MAX_EFFECTS,
    MIN_FALL_PER_FLOOR,
    beats_clearly,
    degenerate_parameters,
    fit_other_form,
    fit_with_effect,
    is_expected_physics,
    is_significant,
    next_round,
    pick,
)
from .residuals import FailureAnalysis, analyse_failure
from .result import Diagnosis, ModelFit, Suspect
from .unexplained import describe_unexplained, is_unexplained

__all__ = ["diagnose", "fit_effects"]

#: The comparison low-pass sits this far above the slow sensor's band edge.
CUTOFF_PER_BAND_EDGE = 1.5
#: The fits' low-pass sits this far above the faster sensor's band edge.
FIT_CUTOFF_PER_BAND_EDGE = 1.5


def _initial_taus(data: PreparedData) -> dict[str, float]:
    """β-GTLS (φ = 1) on the pooled estimation blocks; a coarse grid if it fails."""
    blocks = data.blocks(held_out=False)
    scatter = np.zeros((3, 3))
    for b in blocks:
        scatter = scatter + beta_scatter(data.tc1[b], data.tc2[b])
    n = sum(b.stop - b.start for b in blocks)
    try:
        found = estimate_beta_from_scatter(scatter, data.dt, n, "beta-gtls", 1.0)
        return {"tau1": found.tau1, "tau2": found.tau2}
    except TcompError:
        pass
    context = make_context(data.time, data.tc1, data.tc2, data.dt)
    grid = np.geomspace(2.0 * data.dt, data.time[-1] / 5.0, 16)
    rows = data.training_rows

    def cost(tau1: float, tau2: float) -> float:
        model = Model(params={"tau1": tau1, "tau2": tau2})
        return float(np.sum(model.cross_residual(data.tc1, data.tc2, context)[rows] ** 2))

    tau1, tau2 = min(itertools.product(grid, grid), key=lambda pair: cost(*pair))
    return {"tau1": float(tau1), "tau2": float(tau2)}


def _evaluator(data: PreparedData, taus: dict[str, float]) -> Evaluator:
    slow = 2 if taus["tau2"] >= taus["tau1"] else 1
    context = make_context(
        data.time,
        data.tc1,
        data.tc2,
        data.dt,
        phi_hat=data.phi_hat,
        knot_spacing_s=block_length_s(data.time[-1] + data.dt, data.dt),
        tau_scale_s=max(taus.values()),
        sigma2=max(data.noise2.sigma / np.sqrt(data.decimation), 1e-9 * (1.0 + np.std(data.tc2))),
        base_taus_s=(taus["tau1"], taus["tau2"]),
        film_cutoff_hz=max(data.band_edge_hz),
    )
    nyquist = 0.5 / data.dt
    duration = data.time[-1] + data.dt
    cutoff = CUTOFF_PER_BAND_EDGE * data.band_edge_hz[slow - 1]
    cutoff = float(min(max(cutoff, 10.0 / duration), 0.8 * nyquist))
    fit_cutoff = FIT_CUTOFF_PER_BAND_EDGE * max(data.band_edge_hz)
    return Evaluator(
        data=data,
        context=context,
        slow=slow,
        cutoff_hz=cutoff,
        fit_cutoff_hz=float(fit_cutoff) if fit_cutoff < 0.8 * nyquist else None,
    )


def _fit_base(evaluator: Evaluator, taus: dict[str, float]) -> tuple[Model, Model, ModelFit, bool]:
    """The base model: the cross-relation fit, or the default path's τ where they simulate better.

    The cross-relation criterion is biased by the noise on both readings (an errors-in-variables
    problem its GTLS weighting corrects only for white noise at the working rate): on a clean
    record of engine pulses at 2 kHz with K = 3.3 % (campaign draw 2873) it put τ1 and τ2 10
    and 12 % short, where the default path's ml-eiv, at the Cramér–Rao bound, was within 1 %.
    Every effect is judged against the base model's held-out error (2.24 % there against
    0.09 % at ml-eiv's τ), so a speed varying over the record took the verdict for that bias.
    The default path's τ (:attr:`Evaluator.published_taus_s`) replace the fit's when they
    simulate the slow sensor from the fast one better on the estimation blocks
    (:meth:`Evaluator.training_error`: the held-out blocks stay unseen); the fit's level
    difference between the sensors is kept.

    The effects' fits still start from the cross-relation fit: its basin is the criterion's
    own, and started at the default path's τ the criterion can slide into another (steps with
    a mains line at 5 kHz, campaign draw 3276: τ1 145 times the truth at a third of the
    criterion, every effect's held-out error 20–106 %, and the line went unnamed).

    Returns
    -------
    start : Model
        The cross-relation fit, where the effects' fits start.
    base : Model
        The base model (``start``, or ``start`` at the default path's τ).
    fit : ModelFit
        The base model's scores.
    published : bool
        Whether the base model's τ are the default path's.
    """
    start = evaluator.fit(Model(params=taus))
    published = evaluator.published_taus_s
    if published is not None and all(math.isfinite(t) and t > 0.0 for t in published):
        tau1, tau2 = published
        alternative = Model(params=dict(start.params, tau1=tau1, tau2=tau2))
        if evaluator.training_error(alternative) < evaluator.training_error(start):
            return start, alternative, evaluator.evaluate(alternative, intervals=True), True
    return start, start, evaluator.evaluate(start, intervals=True), False


def _failure(evaluator: Evaluator, fit: ModelFit) -> FailureAnalysis:
    data = evaluator.data
    measured = (data.tc1, data.tc2)[evaluator.slow - 1]
    keep = evaluator.scored_mask(Model(fit.effects, fit.params))
    return analyse_failure(
        data.time,
        data.tc1,
        data.tc2,
        evaluator.lowpass(fit.predicted),
        evaluator.slow_lowpassed,
        measured - fit.predicted,
        dt=data.dt,
        slow=evaluator.slow,
        mask=data.validation & keep,
    )


def fused_gas(fit: ModelFit, sigmas: tuple[float, float], dt: float) -> NDArray[np.float64]:
    """Inverse-variance fusion of a fit's two reconstructions, shape (N,), degrees C.

    A reconstruction's noise grows with τ/dt: the weights are 1/(σ_i τ_i/dt)².
    """
    taus = (fit.tau1, fit.tau2)
    weights = [1.0 / (s * t / dt) ** 2 for s, t in zip(sigmas, taus, strict=True)]
    return (weights[0] * fit.gas1 + weights[1] * fit.gas2) / sum(weights)


def fused_against_reference(
    evaluator: Evaluator, fit: ModelFit
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The fit's fused gas, the reference aligned with it, and the samples that count.

    The fused gas is :func:`fused_gas`; gas[k] is the gas held over [t_k, t_k+1), so the
    reference is read half a sample on.

    Raises
    ------
    ValueError
        If the record has no reference.
    """
    data = evaluator.data
    if data.ref is None:
        raise ValueError(f"{data.source}: no reference to compare the gas temperature with")
    fused = fused_gas(fit, (data.noise1.sigma, data.noise2.sigma), data.dt)
    shifted, _ = fractional_shift(data.ref, 0.5)
    keep = evaluator.scored_mask(Model(fit.effects, fit.params)) & np.isfinite(shifted)
    return fused, np.where(np.isfinite(shifted), shifted, data.ref), keep


def _reference_errors(evaluator: Evaluator, fit: ModelFit, base: ModelFit) -> dict[str, float]:
    """e_Tg of the final fit's reconstructions and of the first-order fused one, %."""
    if evaluator.data.ref is None:
        return {}
    fused, aligned, keep = fused_against_reference(evaluator, fit)
    first = fused_against_reference(evaluator, base)[0]
    reference = evaluator.lowpass(aligned)
    return {
        name: heldout_error_percent(reference, evaluator.lowpass(gas), keep)
        for name, gas in (
            ("gas1", fit.gas1),
            ("gas2", fit.gas2),
            ("fused", fused),
            ("fused first-order", first),
        )
    }


def _notes(data: PreparedData, evaluator: Evaluator) -> list[str]:
    notes = []
    if data.decimation > 1:
        notes.append(
            f"decimated by {data.decimation} to {1 / data.dt:.6g} Hz: the signals carry nothing "
            f"above {max(data.band_edge_hz):.3g} Hz"
        )
    notes.append(
        f"noise from the {data.noise_source}: sigma1 = {data.noise1.sigma:.3g} degC, sigma2 = "
        f"{data.noise2.sigma:.3g} degC (phi = {data.phi_hat:.3g})"
    )
    for sensor, quantisation in enumerate(data.quantisation, start=1):
        if quantisation is not None:
            where = (
                "the codes stick for runs of samples, so the rounding error follows the signal "
                "and is counted in the noise floor and phi as in-band noise of q^2/12"
                if quantisation.in_band
                else "the rounding error is white and already in the spectral noise"
            )
            notes.append(
                f"tc{sensor} is quantised in steps of {quantisation.step_c:.4g} degC (an ADC): "
                f"{where}"
            )
    measured = (data.tc1, data.tc2)[evaluator.slow - 1]
    spectrum = np.abs(np.fft.rfft(measured - measured.mean())) ** 2
    share = np.sort(spectrum)[::-1][:5].sum() / spectrum.sum()
    if share > 0.95:
        notes.append(
            f"the excitation is nearly a single tone ({100 * share:.0f} % of the power in 5 "
            "frequency bins): two time constants already match one tone exactly, so linear "
            "effects (delay, conduction) are hard to tell apart from a change of tau"
        )
    # The default path takes these lines off before it estimates τ: interference the base
    # model then leaves no error for (campaign draw 3276: 60 Hz on tc2) is still said, and it
    # is the verdict when nothing else is found (Diagnosis.default_path_reasons).
    whose = ", and its tau, the base model's, were estimated without it"
    notes.extend(
        f"tc{line.channel} carries a {line.frequency_hz:.4g} Hz line the other does not "
        f"({line.amplitude_c:.3g} degC): the default path notches it"
        f"{whose if evaluator.base_taus_published else ''}"
        for line in evaluator.published_lines
    )
    return notes


#: Significant suspects of the first round that are each followed to the end of a staircase.
#: Adding the best suspect alone (greedy forward selection) can take an effect that imitates
#: two and then refuse the second: a conduction fit absorbs a delay together with a sensor
#: offset of class 2 (held-out error 2.4 % against the delay's 3.4 % in round 1), and the
#: delay then no longer pays for itself, where the delay and the offset together leave 1.0 %.
FIRST_ROUND_BRANCHES = 2


@dataclass(frozen=True)
class Staircase:
    """One error staircase and how it was reached.

    Attributes
    ----------
    steps : list of ModelFit
        The base model first, then one fit per effect added.
    rounds : list of list of Suspect
        The suspects of each round.
    expected : list of str
        The effects added as the sensors' expected physics.
    note : str
        Why it was taken over the greedy staircase ('' when it is the greedy one).
    """

    steps: list[ModelFit]
    rounds: list[list[Suspect]]
    expected: list[str]
    note: str = ""


def _descend(
    evaluator: Evaluator,
    fit: ModelFit,
    first_round: list[Suspect],
    start: Suspect,
    candidates: Sequence[str],
    max_effects: int,
    incumbent: ModelFit | None = None,
) -> Staircase | None:
    """The staircase that takes ``start`` from the first round, then the best at each step.

    With an ``incumbent`` (another staircase's last step) the descent stops, returning None, as
    soon as it can no longer end clearly better than it (:func:`_cannot_end_better`): the
    rounds it would still fit could not change which staircase is taken.
    """
    steps: list[ModelFit] = [fit]
    rounds: list[list[Suspect]] = [first_round]
    expected: list[str] = []
    remaining = list(candidates)
    chosen: Suspect | None = start
    while chosen is not None and chosen.fit is not None:
        if is_expected_physics(chosen, evaluator):
            expected.append(chosen.effect)
        fit = evaluator.with_intervals(chosen.fit)
        steps.append(fit)
        remaining.remove(chosen.effect)
        if incumbent is not None and _cannot_end_better(fit, incumbent, evaluator.data.phi_hat):
            return None
        if not remaining or len(steps) > max_effects + len(expected):
            break
        suspects = next_round(evaluator, Model(fit.effects, fit.params), fit, remaining)
        rounds.append(suspects)
        chosen = pick(suspects)
    return Staircase(steps, rounds, expected)


def _clearly_better(candidate: ModelFit, incumbent: ModelFit, phi_hat: float) -> bool:
    """Whether a staircase's last step beats another's clearly.

    With more effects it must be significant against it (:func:`.ranking.is_significant`);
    otherwise its model error must be clearly lower (:func:`.ranking.beats_clearly`).
    """
    if len(candidate.effects) > len(incumbent.effects):
        return is_significant(incumbent, candidate, phi_hat=phi_hat)
    return beats_clearly(candidate, incumbent, raw=False)


def _cannot_end_better(step: ModelFit, incumbent: ModelFit, phi_hat: float) -> bool:
    """Whether no staircase through ``step`` can end clearly better than ``incumbent``.

    A model error is never negative, so when ``incumbent``'s is below the fall significance
    asks (:data:`.ranking.MIN_FALL_PER_FLOOR` noise floors) no model with more effects can be
    significant against it (:func:`_clearly_better`). A staircase at ``step`` then ends there
    or with more effects: with more effects than ``incumbent`` it cannot win, and with as many
    it wins only if ``step`` itself is clearly better.
    """
    if not incumbent.error_pct < MIN_FALL_PER_FLOOR * incumbent.noise_floor_pct:
        return False
    extra = len(step.effects) - len(incumbent.effects)
    if extra > 0:
        return True
    return extra == 0 and not _clearly_better(step, incumbent, phi_hat)


def _staircase(
    evaluator: Evaluator,
    model: Model,
    fit: ModelFit,
    candidates: Sequence[str],
    max_effects: int,
) -> Staircase:
    """The error staircase, greedy or from the first round's runner-up.

    The runner-up's staircase is taken when it ends clearly better (:func:`_clearly_better`,
    :data:`FIRST_ROUND_BRANCHES`).
    """
    remaining = [name for name in candidates if name not in model.effects]
    if not remaining:
        return Staircase([fit], [], [])
    first = next_round(evaluator, model, fit, remaining)
    starts = [s for s in first if s.significant and s.fit is not None]
    if not starts:
        return Staircase([fit], [first], [])
    greedy_branch = _descend(evaluator, fit, first, starts[0], remaining, max_effects)
    assert greedy_branch is not None  # no incumbent: never abandoned
    best = greedy_branch
    for start in starts[1:FIRST_ROUND_BRANCHES]:
        other = _descend(evaluator, fit, first, start, remaining, max_effects, best.steps[-1])
        if other is not None and _clearly_better(
            other.steps[-1], best.steps[-1], evaluator.data.phi_hat
        ):
            best = other
    if best is greedy_branch:
        return best
    greedy = greedy_branch.steps[-1]
    taken = best.steps[-1]
    note = (
        f"the first round's best suspect, {greedy.effects[0]}, led to "
        f"{'+'.join(greedy.effects)} (held-out error {greedy.error_pct:.3g} %); starting from "
        f"{taken.effects[0]} instead led to {'+'.join(taken.effects)} "
        f"({taken.error_pct:.3g} %), clearly better, and was taken"
    )
    return replace(best, note=note)


#: Why each effect that can be added as ordinary physics is not a finding.
ORDINARY = {
    "property": "time constants vary a little with the level through the gas properties, as "
    "for any real wire",
    "calibration": "a relative calibration within the tolerance of special-limits type K "
    "thermocouples, or the few hundredths of a degree by which the sensors' nonlinear "
    "response rectifies a large swing",
    "radiation": "a radiative loss too small to bias the gas temperature noticeably",
}


def _diagnosis(
    evaluator, base, failure, steps, rounds, verdict, expected=(), note="", handled=None
) -> Diagnosis:
    data = evaluator.data
    handled = handled or {}
    notes = _notes(data, evaluator) + ([note] if note else [])
    notes.extend(f"{name}: {why}" for name, why in handled.items())
    final = Model(steps[-1].effects, steps[-1].params)
    identifiability = [
        text for effect in final.instances if (text := effect.identifiability(final.params))
    ]
    for name in expected:
        notes.append(
            f"{name}: added as the sensors' ordinary physics, not a finding ({ORDINARY[name]})"
        )
    return Diagnosis(
        source=data.source,
        time=data.time,
        tc1=data.tc1,
        tc2=data.tc2,
        ref=data.ref,
        dt=data.dt,
        slow=evaluator.slow,
        validation=data.validation,
        eval_cutoff_hz=evaluator.cutoff_hz,
        sigma1=data.noise1.sigma,
        sigma2=data.noise2.sigma,
        phi=data.phi_hat,
        base=base,
        failure=failure,
        suspects=rounds[0] if rounds else [],
        steps=steps,
        rounds=rounds,
        verdict=verdict,
        final=steps[-1],
        ref_error_pct=_reference_errors(evaluator, steps[-1], base),
        notes=notes,
        unexplained=describe_unexplained(evaluator, steps[-1]),
        expected_physics=list(expected),
        default_path_reasons=dict(handled),
        identifiability=identifiability,
        context=evaluator.context,
    )


def _base_fit(
    record: Record,
    published_taus: tuple[float, float] | None = None,
    published_lines: Sequence[ForeignLine] = (),
    published_tried: bool = False,
) -> tuple[Evaluator, Model, ModelFit, FailureAnalysis]:
    """Prepare the record, fit and score the base model, and say where it fails.

    Returns the evaluator, the model the effects' fits start from (the cross-relation fit: see
    :func:`_fit_base`), the base model's scores and the failure analysis.

    Every effect is then judged against the base model's fitted τ, the record's first-order τ
    (:attr:`~tcomp_core.effects.base.FitContext.base_taus_s`: plausibility, materiality), not
    against the closed-form start the fit began from (:func:`_initial_taus`), which only picks
    the basin: on campaign draws with unequal noise or a class-2 offset the start was 0.5–20
    times the truth where the fit came within 5 %, and with a tc2 three times noisier
    β-GTLS failed and its grid's 1.2 s against a true 0.068 s called every candidate with τ
    right "1/17 of the first-order τ": implausible, and the noise ratio went unnamed. The
    identification still measures the sensors' disagreement at the start as well as at a
    fit's own τ (:attr:`Evaluator.start_taus_s`), as its limit on the change per evidence was
    set with: the base fit's τ minimises that disagreement, and taken instead it refused a
    conduction that halved the gas error (campaign draw 467, 68.6 → 33.4 %).
    """
    if published_taus is None and not published_tried:
        plain = default_estimate(record)
        if plain is not None:
            published_taus, published_lines = (float(plain.tau1), float(plain.tau2)), plain.lines
    data = prepare(record)
    taus = _initial_taus(data)
    evaluator = replace(
        _evaluator(data, taus),
        published_taus_s=published_taus,
        published_lines=tuple(published_lines),
    )
    start_model, model, base, published = _fit_base(evaluator, taus)
    evaluator = replace(evaluator, base_taus_published=published)
    fitted = (float(model.tau1), float(model.tau2))
    if all(math.isfinite(tau) and tau > 0.0 for tau in fitted):
        context = replace(evaluator.context, base_taus_s=fitted)
        start = (taus["tau1"], taus["tau2"])
        evaluator = replace(evaluator, context=context, start_taus_s=start)
    return evaluator, start_model, base, _failure(evaluator, base)


def diagnose(
    record: Record,
    *,
    candidates: Sequence[str] = EFFECT_NAMES,
    max_effects: int = MAX_EFFECTS,
    published_taus: tuple[float, float] | None = None,
    published_lines: Sequence[ForeignLine] = (),
    published_tried: bool = False,
) -> Diagnosis:
    """Compare the first-order model with a record, find where it fails and what is missing.

    Parameters
    ----------
    record : Record
        Two thermocouples (and optionally a reference), e.g. from
        :func:`tcomp_core.io.read_record`.
    candidates : sequence of str
        Effects to consider (default all of :data:`~tcomp_core.effects.EFFECT_NAMES`).
    max_effects : int
        Most effects added on top of the base model.
    published_taus : (float, float), optional
        τ1, τ2 the default first-order path publishes for the record, s: the final model's
        identification measures its change to the gas against first order there too
        (:attr:`~.identification.Identification.published_change_c`), and no fit that makes
        the other sensor the slower is a verdict
        (:func:`~tcomp_core.effects.model.swapped_sensors`). None: estimated here, as
        ``tcomp estimate`` does (not checked where that path refuses the record).
    published_lines : sequence of ForeignLine
        The lines that path takes off the channel carrying one
        (:attr:`tcomp_core.estimators.Estimate.lines`), so that its first order is measured
        as it publishes it (with ``published_taus`` None, those of the estimate made here).
    published_tried : bool
        The caller ran that path already: ``published_taus`` None then means it refused the
        record, and it is not estimated again.

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        If the record is too short.
    EstimationError
        If not even the base model can be fitted.
    """
    candidates = check_effect_names(candidates)
    evaluator, model, base, failure = _base_fit(
        record, published_taus, published_lines, published_tried
    )
    staircase = _staircase(evaluator, model, base, candidates, max_effects)
    staircase = _refit_final(evaluator, staircase)
    steps = staircase.steps
    findings = [effect for effect in steps[-1].effects if effect not in staircase.expected]
    handled = _found_by_the_default_path(evaluator, findings, candidates)
    verdict = (findings or list(handled) or ["none"])[0]
    if verdict == "none" and is_unexplained(steps[-1]):
        verdict = "unexplained"
    return _diagnosis(
        evaluator,
        steps[0],
        failure,
        steps,
        staircase.rounds,
        verdict,
        staircase.expected,
        staircase.note,
        handled,
    )


def _refit_final(evaluator: Evaluator, staircase: Staircase) -> Staircase:
    """The staircase with its last step refitted on the whole record, or dropped if degenerate.

    Held-out blocks chose each step on the estimation blocks, where significance refuses a fit
    that ends on a bound of an effect's physical range (:func:`.ranking.degenerate_parameters`).
    The whole record can still take an effect there (:func:`_on_a_bound`); such a fit found no
    physical explanation, so no verdict rests on it: the last step is dropped, the one before
    refitted in its place, until a fit is physical, and the note says why (campaign draw 3465,
    a level-dependent τ on 1 kHz steps read as radiation whose wall went to −72.85 °C, the
    200 K bound, on the whole record).
    """
    steps, expected, notes = list(staircase.steps), list(staircase.expected), [staircase.note]
    while True:
        rivals = _rivals(replace(staircase, steps=steps))
        steps[-1] = evaluator.refit_whole(steps[-1], partial(fit_other_form, evaluator), rivals)
        bounded = _on_a_bound(steps) if len(steps) > 1 else []
        if not bounded:
            note = "; ".join(filter(None, notes))
            return replace(staircase, steps=steps, expected=expected, note=note)
        added = next(e for e in steps[-1].effects if e not in steps[-2].effects)
        notes.append(
            f"{'+'.join(steps[-1].effects)} was taken on the estimation blocks, but on the "
            "whole record its fit puts "
            + ", ".join(f"{name} = {steps[-1].params[name]:.4g}" for name in bounded)
            + f" on a bound of the physical range: no physical explanation, so {added} is "
            "dropped and the model before it refitted as the final one"
        )
        if added in expected:
            expected.remove(added)
        steps = steps[:-1]


def _on_a_bound(steps: list[ModelFit]) -> list[str]:
    """Parameters of the last step's whole-record fit that make it degenerate.

    Any effect's parameter on a bound of its physical range (the base model's, τ and the
    level, excepted), and a τ the last effect drove onto its bound
    (:func:`.ranking.degenerate_parameters`): campaign draw 3503, mains with a calibration
    read as interference + property, had a line amplitude on its bound and τ1 at 1 % of the
    truth.
    """
    last, base = steps[-1], steps[0]
    own = [name for name in last.at_bound if name not in base.params]
    return sorted(set(own) | set(degenerate_parameters(last, steps[-2])))


def _rivals(staircase: Staircase) -> list[ModelFit]:
    """Fits with another effect in place of the last one taken, which the data allow as well.

    The suspects of the round that took the staircase's last effect that were significant
    too and that the one taken does not beat clearly (:func:`.ranking.beats_clearly`): the
    held-out blocks do not tell the two explanations apart, so the gas may follow either
    (campaign draw 3402, conduction to lagging supports behind a mains line: a calibration
    with tc2's gain at 0.83 took 1.30 → 0.40 %, a conduction 1.30 → 0.51 %, and the
    calibration's τ put the gas 7.40 → 9.00 % off).
    """
    if len(staircase.steps) < 2 or len(staircase.rounds) < len(staircase.steps) - 1:
        return []
    taken = staircase.steps[-1]
    return [
        suspect.fit
        for suspect in staircase.rounds[len(staircase.steps) - 2]
        if suspect.fit is not None
        and suspect.significant
        and suspect.effect not in taken.effects
        and not beats_clearly(taken, suspect.fit)
    ]


def _found_by_the_default_path(
    evaluator: Evaluator, findings: list[str], candidates: Sequence[str]
) -> dict[str, str]:
    """Effects among ``candidates``, not in ``findings``, that the default path accounts for.

    Each effect says, from what that path found (the lines on one channel alone,
    ``evaluator.published_lines``, and the measured noise ratio φ̂), whether it is there and
    why the model needs no piece for it
    (:meth:`~tcomp_core.effects.base.Effect.found_by_default_path`): name → why.
    """
    found = {}
    for name in candidates:
        if name in findings:
            continue
        why = EFFECTS[name]().found_by_default_path(
            evaluator.published_lines, evaluator.data.phi_hat
        )
        if why:
            found[name] = why
    return found


def fit_effects(
    record: Record,
    effects: Sequence[str],
    *,
    published_taus: tuple[float, float] | None = None,
    published_lines: Sequence[ForeignLine] = (),
    published_tried: bool = False,
) -> Diagnosis:
    """Fit the base model plus a chosen set of effects, added in the order given.

    Every step is scored like :func:`diagnose` scores it; ``steps`` holds the base model and
    one fit per effect added, ``suspects`` the same fits as suspects, and ``verdict`` the
    last effect (``"none"`` for an empty set). ``published_taus``, ``published_lines`` and
    ``published_tried`` as for :func:`diagnose`.

    Raises
    ------
    EstimationError
        If a fit fails.
    """
    effects = check_effect_names(effects)
    evaluator, model, base, failure = _base_fit(
        record, published_taus, published_lines, published_tried
    )
    steps, suspects = [base], []
    for name in effects:
        try:
            model, fit = fit_with_effect(evaluator, model, name)
        except (EstimationError, ValueError) as exc:
            raise EstimationError(f"fitting the effect {name!r} failed: {exc}") from exc
        previous = steps[-1].error_pct
        evidence = 1.0 - fit.error_pct / previous if math.isfinite(previous) else 0.0
        suspects.append(
            Suspect(
                effect=name,
                error_pct=fit.error_pct,
                evidence=evidence,
                signature="chosen by the user",
                significant=True,
                fit=fit,
            )
        )
        steps.append(evaluator.with_intervals(fit))
    steps[-1] = evaluator.refit_whole(steps[-1], partial(fit_other_form, evaluator))
    verdict = effects[-1] if effects else "none"
    return _diagnosis(evaluator, steps[0], failure, steps, [suspects] if suspects else [], verdict)
