"""Ranking the suspects: refit with each effect, keep what lowers the held-out error.

An effect is *significant* when its refit lowers the raw held-out error (noise included, so
that chance near the noise floor cannot pass) by at least :data:`MIN_RELATIVE_FALL` overall
and in at least :data:`MIN_BLOCK_SHARE` of the validation blocks: one lucky block cannot carry
it, and the held-out data, never fitted, guard against an effect that only adds freedom.
Unequal noise (``noise_ratio``) is measured rather than fitted, so a clearly unequal noise
ratio counts by itself when the refit does no harm (:func:`is_significant`).
Suspects are ranked by held-out error; when two are within
:data:`TIE_TOLERANCE` of each other the one with fewer parameters ranks first, except for
radiation against calibration. Linearised, radiation is a relative gain and offset of the two
sensors (with τ shortened by 1 + ρ), so both explain a level-dependent offset about equally
well unless the noise is low. Radiation ranks first only on a hot record
(:data:`RADIATION_MIN_LEVEL_C`; colder, a wire's radiative loss is too small to show), and
there when the residual curves against the level (T⁴ bends it, a gain and offset do not;
:data:`CURVATURE_T`) or when the fit is physical: a wall cooler than the gas and the thicker
(slower) wire radiating relatively more. Otherwise calibration, the simpler model, does. (On a
cold record a residual can curve against the level for other reasons, e.g. a hidden delay on
a signal whose slope depends on its level.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..effects import Model
from ..errors import TcompError
from .heldout import Evaluator
from .residuals import level_errors
from .result import ModelFit, Suspect
from .signatures import signature

__all__ = ["MAX_EFFECTS", "fit_with_effect", "is_significant", "next_round", "pick", "rank"]

#: Least relative fall of the held-out error that counts.
MIN_RELATIVE_FALL = 0.2
#: Least share of validation blocks whose error must fall.
MIN_BLOCK_SHARE = 0.7
#: Suspects within this relative error of each other count as a tie.
TIE_TOLERANCE = 0.03
#: Noise variance ratio φ̂ beyond which (or below its inverse) unequal noise is a finding by
#: itself: the spectral estimate of φ is good to ~10 % on clean records, but a fast sensor whose
#: signal reaches the top of the band (sharp exhaust pulses) reads up to ~1.7 with equal noise.
NOISE_RATIO_FACTOR = 2.0
#: Most effects the staircase adds.
MAX_EFFECTS = 3
#: |t| of the residual's curvature against the level above which radiation beats a tied
#: calibration.
CURVATURE_T = 3.0
#: Mean temperature below which radiation is not preferred to a tied calibration, degrees C
#: (at 250 °C a fine wire's radiative conductance is ~1 % of its convective one).
RADIATION_MIN_LEVEL_C = 250.0
#: Least radiative/convective conductance of the slower sensor that counts as radiation.
RADIATION_MIN_RHO = 0.01


def is_significant(
    current: ModelFit, candidate: ModelFit, effect: str = "", phi_hat: float = 1.0
) -> bool:
    """Whether ``candidate`` lowers the held-out error of ``current`` significantly.

    ``noise_ratio`` is measured, not fitted (φ from the spectra), so it cannot overfit: it is
    also significant when φ̂ lies outside [1/:data:`NOISE_RATIO_FACTOR`,
    :data:`NOISE_RATIO_FACTOR`] and the refit does not raise the held-out error.
    """
    if not (math.isfinite(candidate.raw_error_pct) and math.isfinite(current.raw_error_pct)):
        return False
    if (
        effect == "noise_ratio"
        and abs(math.log(phi_hat)) > math.log(NOISE_RATIO_FACTOR)
        and candidate.raw_error_pct <= (1.0 + TIE_TOLERANCE) * current.raw_error_pct
    ):
        return True
    if candidate.raw_error_pct > (1.0 - MIN_RELATIVE_FALL) * current.raw_error_pct:
        return False
    before, after = current.block_errors_pct, candidate.block_errors_pct
    if before.size == 0 or before.size != after.size:
        return False
    both = np.isfinite(before) & np.isfinite(after)  # blocks that both models scored
    if not both.any():
        return False
    return float(np.mean(after[both] < before[both])) >= MIN_BLOCK_SHARE


def rank(suspects: Sequence[Suspect]) -> list[Suspect]:
    """Best first: by held-out error, fewer parameters first among near-ties."""
    ordered = sorted(suspects, key=lambda s: s.error_pct)
    for i in range(1, len(ordered)):
        j = i
        while j > 0:
            better, worse = ordered[j - 1], ordered[j]
            tied = worse.error_pct <= (1.0 + TIE_TOLERANCE) * better.error_pct
            simpler = (
                worse.fit is not None
                and better.fit is not None
                and worse.fit.n_params < better.fit.n_params
            )
            if not (tied and simpler and worse.significant >= better.significant):
                break
            ordered[j - 1], ordered[j] = worse, better
            j -= 1
    return ordered


def fit_with_effect(evaluator: Evaluator, model: Model, name: str) -> tuple[Model, ModelFit]:
    """Fit ``model`` plus the effect ``name`` and score it; the best of its setting choices.

    An effect with :attr:`~tcomp_core.effects.base.Effect.setting_choices` is fitted once per
    choice and the fit with the lowest held-out error is kept.
    """
    extended = model.with_effect(name)
    choices = extended.instances[-1].setting_choices or ({},)
    best: tuple[Model, ModelFit] | None = None
    for choice in choices:
        fitted = evaluator.fit(Model(extended.effects, {**extended.params, **choice}))
        fit = evaluator.evaluate(fitted)
        if best is None or fit.error_pct < best[1].error_pct:
            best = (fitted, fit)
    assert best is not None
    return best


def next_round(
    evaluator: Evaluator, model: Model, current: ModelFit, candidates: Sequence[str]
) -> list[Suspect]:
    """Refit ``model`` plus each candidate effect; the suspects, best first."""
    suspects = []
    for name in candidates:
        try:
            _, fit = fit_with_effect(evaluator, model, name)
        except (TcompError, ValueError, np.linalg.LinAlgError) as exc:
            suspects.append(
                Suspect(
                    effect=name,
                    error_pct=math.inf,
                    evidence=-math.inf,
                    signature=f"the refit failed: {exc}",
                    significant=False,
                )
            )
            continue
        evidence = 1.0 - fit.error_pct / current.error_pct if current.error_pct > 0 else 0.0
        suspects.append(
            Suspect(
                effect=name,
                error_pct=fit.error_pct,
                evidence=evidence,
                signature=signature(name, evaluator, current, fit),
                significant=is_significant(current, fit, name, evaluator.data.phi_hat),
                fit=fit,
            )
        )
    return _radiation_or_calibration(rank(suspects), evaluator, current)


def _radiation_or_calibration(
    ranked: list[Suspect], evaluator: Evaluator, current: ModelFit
) -> list[Suspect]:
    """Order a near-tie of radiation and calibration at the top (see the module docstring)."""
    if len(ranked) < 2 or {ranked[0].effect, ranked[1].effect} != {"radiation", "calibration"}:
        return ranked
    first, second = ranked[0], ranked[1]
    if second.error_pct > (1.0 + TIE_TOLERANCE) * first.error_pct:
        return ranked
    radiation, calibration = (first, second) if first.effect == "radiation" else (second, first)
    top = [radiation, calibration]
    hot = evaluator.context.level_mean_c >= RADIATION_MIN_LEVEL_C
    if not (hot and (_bent(evaluator, current) or _radiation_plausible(evaluator, radiation))):
        top.reverse()
    return top + ranked[2:]


def _bent(evaluator: Evaluator, current: ModelFit) -> bool:
    """Whether the residual curves against the level (T⁴ bends it; gain and offset do not)."""
    readings = evaluator.readings
    measured = readings[evaluator.slow - 1]
    residual = evaluator.lowpass(measured - current.predicted)
    mask = evaluator.data.validation & evaluator.scored_mask(
        Model(current.effects, current.params)
    )
    return abs(level_errors(residual[mask], measured[mask]).curvature_t) > CURVATURE_T


def _radiation_plausible(evaluator: Evaluator, radiation: Suspect) -> bool:
    """Whether the radiation fit is physical rather than a relabelled calibration.

    To first order radiation *is* a relative gain and offset (and τ shortened by 1 + ρ), so at
    moderate noise both fit alike. Physics then decides: radiation needs a wall cooler than the
    gas and the slower (thicker) wire radiating relatively more (r ∝ d^½), visibly
    (ρ ≥ :data:`RADIATION_MIN_RHO`).
    """
    if radiation.fit is None:
        return False
    p = radiation.fit.params
    slow, fast = evaluator.slow, 3 - evaluator.slow
    return bool(
        p["wall_c"] < evaluator.context.level_mean_c
        and p[f"rho{slow}"] >= p[f"rho{fast}"]
        and p[f"rho{slow}"] >= RADIATION_MIN_RHO
    )


def pick(suspects: Sequence[Suspect]) -> Suspect | None:
    """The best significant suspect, or None."""
    for suspect in suspects:
        if suspect.significant:
            return suspect
    return None
