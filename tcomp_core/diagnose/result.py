"""Results of the model-versus-measurement diagnosis (plain data, no computation)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..effects import FitContext
from .residuals import FailureAnalysis

if TYPE_CHECKING:
    from .identification import Identification

__all__ = ["Diagnosis", "ModelFit", "Suspect", "diagnosis_to_dict"]


def _finite(value: float) -> float | None:
    """A float for JSON, None for inf or NaN (JSON has neither)."""
    return float(value) if np.isfinite(value) else None


@dataclass(frozen=True, kw_only=True)
class ModelFit:
    """One fitted model (the base model or the base plus effects) and its held-out error.

    Attributes
    ----------
    effects : tuple of str
        Effects added to the first-order base model, in the order they were added.
    params : dict of str to float
        Every fitted parameter: ``tau1``, ``tau2`` (s) and the effects' own parameters.
    tau1, tau2 : float
        Time constants of thermocouples 1 and 2, s.
    error_pct : float
        Held-out model error beyond the noise floor, % (see :mod:`tcomp_core.diagnose.heldout`).
    raw_error_pct : float
        Held-out error with the noise left in, % (100 − MATLAB ``compare``'s fit %).
    noise_floor_pct : float
        What the sensors' noise alone contributes to ``raw_error_pct``, %.
    train_error_pct : float
        ``error_pct`` measured on the estimation blocks, %.
    block_errors_pct : ndarray, shape (B,)
        Raw held-out error of each validation block, %; NaN where the model's start-up
        transient leaves the block too few samples.
    predicted : ndarray, shape (N,)
        Free-run simulation of the slow sensor from the fast one, degrees C (working rate).
    gas1, gas2 : ndarray, shape (N,)
        Gas temperature reconstructed from thermocouple 1 and from thermocouple 2, degrees C.
    n_params : int
        Number of fitted parameters.
    intervals : dict of str to (float, float)
        95 % confidence interval of every searched parameter, in its unit
        (:mod:`tcomp_core.diagnose.uncertainty`).
    at_bound : tuple of str
        Parameters the fit left on a bound of their physical range: the fit wanted more than
        physics allows, so the effect is not significant.
    identification : Identification or None
        Whether the data pin down the effects' parameters and the change they make to the gas
        (:mod:`tcomp_core.diagnose.identification`); set on the final model only.
    """

    effects: tuple[str, ...]
    params: dict[str, float]
    tau1: float
    tau2: float
    error_pct: float
    raw_error_pct: float
    noise_floor_pct: float
    train_error_pct: float
    block_errors_pct: NDArray[np.float64]
    predicted: NDArray[np.float64]
    gas1: NDArray[np.float64]
    gas2: NDArray[np.float64]
    n_params: int
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    at_bound: tuple[str, ...] = ()
    identification: Identification | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: effects, tau1, tau2, error_pct and the parameters."""
        return {
            "effects": list(self.effects),
            "tau1": float(self.tau1),
            "tau2": float(self.tau2),
            "error_pct": _finite(self.error_pct),
            "raw_error_pct": _finite(self.raw_error_pct),
            "noise_floor_pct": _finite(self.noise_floor_pct),
            "train_error_pct": _finite(self.train_error_pct),
            "params": {name: float(value) for name, value in self.params.items()},
            "intervals_95": {
                name: [_finite(low), _finite(high)] for name, (low, high) in self.intervals.items()
            },
            "at_bound": list(self.at_bound),
            **(
                {"identification": self.identification.summary()}
                if self.identification is not None
                else {}
            ),
        }


@dataclass(frozen=True, kw_only=True)
class Suspect:
    """One candidate effect, refitted on top of the current model.

    Attributes
    ----------
    effect : str
        Effect name.
    error_pct : float
        Held-out error after adding the effect, %.
    evidence : float
        Relative fall of the held-out error, ``1 - error_pct / previous error_pct`` (higher is
        stronger evidence; negative when the effect made the held-out error worse).
    signature : str
        In words: the residual signature that points to this effect, with its statistic.
    significant : bool
        Whether the fall passes the significance rule (see :mod:`tcomp_core.diagnose.ranking`).
    refusal : str
        Why it was first judged not significant, in words ("" when it was significant): the
        rule that failed with its figures, below materiality, or an implausible fit. A suspect
        that clearly beats a significant one is made significant afterwards; its refusal is
        then not reported (``summary`` gives "").
    fit : ModelFit or None
        The refitted model (None when the refit failed; ``signature`` then says why).
    """

    effect: str
    error_pct: float
    evidence: float
    signature: str
    significant: bool
    refusal: str = ""
    fit: ModelFit | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "effect": self.effect,
            "error_pct": _finite(self.error_pct),
            "evidence": _finite(self.evidence),
            "signature": self.signature,
            "significant": self.significant,
            "refusal": "" if self.significant else self.refusal,
        }


@dataclass(frozen=True, kw_only=True)
class Diagnosis:
    """Everything ``tcomp diagnose`` found.

    Attributes
    ----------
    source : str
        Where the data came from.
    time : ndarray, shape (N,)
        Sample times at the working rate, s from the first sample.
    tc1, tc2 : ndarray, shape (N,)
        Measurements at the working rate, degrees C.
    ref : ndarray, shape (N,) or None
        Reference (true or fast-sensor gas temperature) at the working rate, degrees C.
    dt : float
        Working sample interval, s (the data's, or after decimation).
    slow : int
        1 or 2: the slower thermocouple, the one simulated from the other in the comparison.
    validation : ndarray of bool, shape (N,)
        True on held-out (validation) samples, False on estimation samples.
    eval_cutoff_hz : float
        Low-pass cutoff applied to both compared signals in the held-out error, Hz.
    sigma1, sigma2 : float
        Noise standard deviations, degrees C: from the spectra less the gas signal both
        sensors share (:func:`tcomp_core.noise.model_noise`), or the spectra alone.
    phi : float
        Estimated noise variance ratio ``sigma1**2 / sigma2**2``.
    base : ModelFit
        The first-order model of the paper (β-GTLS, φ = 1).
    failure : FailureAnalysis
        Where the base model fails (residual analysis).
    suspects : list of Suspect
        Every effect refitted on the base model, best first.
    steps : list of ModelFit
        The error staircase: the base model, then one entry per accepted effect.
    rounds : list of list of Suspect
        The suspects of every round of the staircase (``rounds[0] is suspects``).
    verdict : str
        The first accepted effect, or ``"none"``.
    final : ModelFit
        The last model of the staircase, its parameters refitted on the whole record (its
        errors are still the held-out ones). When no effect is added it is the base model.
    ref_error_pct : dict of str to float
        When a reference is present: its rms difference from each reconstruction of the final
        model (``"gas1"``, ``"gas2"``, ``"fused"``) in % of the reference's spread.
    notes : list of str
        Caveats found on the way (narrow-band excitation, decimation, ...).
    unexplained : str
        When the final model stays well above the noise floor, what its residual shows, in
        words (:mod:`tcomp_core.diagnose.unexplained`); ``""`` otherwise. The verdict is
        ``"unexplained"`` when no effect was found at all.
    identifiability : list of str
        Per effect of the final model, what the two signals cannot fix and which prior or
        convention decided it.
    context : FitContext or None
        The fits' context at the working rate (level, knot spacing, film cut-off): what a
        reconstruction with the final model needs besides its parameters.
    expected_physics : list of str
        Effects added to the model as the sensors' ordinary physics, not findings (a ``property``
        of ordinary size: :func:`tcomp_core.diagnose.ranking.is_expected_physics`).
    default_path_reasons : dict of str to str
        Effects found in the record that the default first-order path accounts for by itself,
        so that the model holds no piece for them, each with why in words
        (:meth:`~tcomp_core.effects.base.Effect.found_by_default_path`; the names alone:
        :attr:`default_path_findings`): ``interference`` when
        one channel carries lines the other does not share (mains pick-up), which that path
        notches or subtracts before it estimates τ (the notes name each line),
        ``noise_ratio`` when the measured φ̂ shows the sensors' noise to differ, which that
        path weighs them by. They are findings: the verdict names the first when the model
        found nothing else.
    """

    source: str
    time: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    ref: NDArray[np.float64] | None
    dt: float
    slow: int
    validation: NDArray[np.bool_]
    eval_cutoff_hz: float
    sigma1: float
    sigma2: float
    phi: float
    base: ModelFit
    failure: FailureAnalysis
    suspects: list[Suspect]
    steps: list[ModelFit]
    rounds: list[list[Suspect]]
    verdict: str
    final: ModelFit
    ref_error_pct: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    unexplained: str = ""
    expected_physics: list[str] = field(default_factory=list)
    identifiability: list[str] = field(default_factory=list)
    context: FitContext | None = None
    default_path_reasons: dict[str, str] = field(default_factory=dict)

    @property
    def default_path_findings(self) -> list[str]:
        """The effects of :attr:`default_path_reasons`, in the order found."""
        return list(self.default_path_reasons)


def diagnosis_to_dict(diagnosis: Diagnosis) -> dict[str, Any]:
    """The JSON document of ``tcomp diagnose --json`` and ``tcomp fit --json``.

    Keys: ``source``, ``samples``, ``dt``, ``slow``, ``error_definition``, ``noise``,
    ``base`` {tau1, tau2, error_pct, ...}, ``where`` (findings and statistics), ``suspects``
    (best first) [{effect, error_pct, evidence, signature, significant}], ``verdict`` (an effect,
    ``"none"`` or ``"unexplained"``), ``final`` {effects, tau1, tau2, error_pct, intervals_95,
    at_bound, ...}, ``steps`` (the error staircase), ``rounds``, ``ref_error_pct``, ``notes``,
    ``unexplained`` (the residual's signature in words, or ""), ``expected_physics``,
    ``identifiability``, ``default_path_findings``, ``default_path_reasons``.
    """
    return {
        "source": diagnosis.source,
        "samples": int(diagnosis.time.size),
        "dt": diagnosis.dt,
        "slow": diagnosis.slow,
        "error_definition": (
            "held-out free-run model error: 100 * sqrt(mean((simulated - measured)^2) - "
            "noise floor) / std(measured) of the slow sensor "
            f"(tc{diagnosis.slow}) simulated from the other one, both low-passed at "
            f"{diagnosis.eval_cutoff_hz:.4g} Hz, over the validation blocks; raw_error_pct "
            "keeps the noise in"
        ),
        "noise": {"sigma1": diagnosis.sigma1, "sigma2": diagnosis.sigma2, "phi": diagnosis.phi},
        "base": diagnosis.base.summary(),
        "where": diagnosis.failure.summary(),
        "suspects": [suspect.summary() for suspect in diagnosis.suspects],
        "verdict": diagnosis.verdict,
        "final": diagnosis.final.summary(),
        "steps": [step.summary() for step in diagnosis.steps],
        "rounds": [[suspect.summary() for suspect in round_] for round_ in diagnosis.rounds],
        "ref_error_pct": dict(diagnosis.ref_error_pct),
        "notes": list(diagnosis.notes),
        "unexplained": diagnosis.unexplained,
        "expected_physics": list(diagnosis.expected_physics),
        "identifiability": list(diagnosis.identifiability),
        "default_path_findings": list(diagnosis.default_path_findings),
        "default_path_reasons": dict(diagnosis.default_path_reasons),
    }
