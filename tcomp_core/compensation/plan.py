"""Which physics the published gas temperature is compensated with, and why.

The diagnosis's final model (:class:`~tcomp_core.diagnose.Diagnosis`) is turned into an
:class:`OutputModel`: its parameters, the context its effects need (the record's level, the
knot spacing of a velocity, the film cut-off of a property) and one :class:`Piece` per effect
saying how the reconstruction treats it:

``compensated``
    the effect is undone (its stage of the sensor chain inverted);
``prior``
    undone, but a part the two signals cannot fix is set by a stated convention (a delay puts
    the gas on tc1's clock);
``dynamics``
    undone for the dynamics, the level kept at what the same reconstruction gives with the
    effect left first order: a calibration (which sensor's calibration is right cannot be
    seen), a radiation whose ratios rho1, rho2 are both within their 95 % intervals of 0 (the
    data do not fix the radiation level);
``first order``
    left as the first-order model has it: the effect is of ordinary size (the sensors'
    expected physics, below materiality, where compensating would trade a known small bias
    for the fit's uncertainty), or a causal stream cannot apply it (a velocity profile known
    only over the fitted record, a film temperature that needs the gas ahead).

These are the "never worse" rules: no piece the data cannot fix moves from first order
without a stated prior, and every output says which rule each effect followed. Above them, a
fit is not trusted with the gas at all (every piece ``first order``, on the first-order model's
τ) when it is no physical sensor (:meth:`~tcomp_core.effects.Model.implausible`), when a
parameter of an applied effect is not determined by the data (singular, or on a bound of its
physical range), when a parameter of an effect it undoes (``compensated`` or ``prior``) is
wide (its 95 % interval spans half its range or more) and moves the gas across that
interval by as much as the change the model makes, or is free (90 % or more: the data say
nothing of it) and moves the gas's fluctuation by as much as the band, when
the change it makes to the gas is several times the two sensors'
disagreement (the only evidence of what first order lacks), or when the 95 % band on the gas
(refits leaving out one stretch of the record at a time) is as wide as that change
(:mod:`tcomp_core.diagnose.identification`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..choices import parse_effect_list
from ..effects import EFFECTS, FitContext, Model
from ..effects.base import OutputEvidence
from ..effects.chain import SensorChain
from ..effects.model import swapped_sensors
from ..errors import EstimationError
from ..estimators.default import default_estimate
from ..filters import lowpass_sos
from ..lines import NOTCH_Q
from ..sections import zero_phase
from ..tolerance import (
    CLASS2_GAIN,
    CLASS2_MARGIN,
    CLASS2_OFFSET_C,
    class2_level_tolerance_c,
)

if TYPE_CHECKING:
    from ..diagnose import Diagnosis
    from ..diagnose.identification import Identification, ParameterCheck
    from ..diagnose.result import ModelFit
    from ..estimators import Estimate
    from ..io import Record
    from ..lines import ForeignLine

__all__ = [
    "FIRST_ORDER",
    "OutputModel",
    "Piece",
    "default_estimate",
    "default_first_order_failure",
    "default_taus",
    "fit_output_model",
    "output_model_from_diagnosis",
    "output_model_with_fallback",
    "parse_compensate_effects",
    "swapped_sensors",
]

#: How a shorter model's gas is compared with the full fit's (:func:`_stands_in_for`): the
#: order of the zero-phase low-pass at the comparison band, and the slow time constants left
#: out at each end (the reconstructions' start-up).
STANDS_IN_FILTER_ORDER = 4
STANDS_IN_SKIP_TAUS = 3.0
#: ``OutputModel.name`` of the plain first-order model.
FIRST_ORDER = "first-order"
#: A first-order τ whose 95 % interval spans more than this factor is not determined: pure
#: noise gives 0.004..8 s, two sensors in one gas at K = 60 % a factor of 2.
MAX_TAU_INTERVAL_RATIO = 10.0

#: Handlings that undo an effect with all its fitted parameters: none of them may be free
#: (:attr:`~tcomp_core.diagnose.identification.ParameterCheck.free`).
#: ``dynamics`` is already the fallback for a level the data do not fix, and its band decides.
_UNDONE = ("compensated", "prior")

#: Effects a causal stream cannot apply: a velocity's τ(t) is known only over the fitted
#: record; a level-dependent τ's film temperature is a zero-phase low-pass of the gas.
_NOT_CAUSAL = {
    "velocity": "its tau(t) is known only over the fitted record",
    "property": "its film temperature is a zero-phase low-pass of the gas (needs samples ahead)",
}


@dataclass(frozen=True)
class Piece:
    """How the reconstruction treats one effect of the model.

    Attributes
    ----------
    effect : str
    handling : {'compensated', 'prior', 'dynamics', 'first order'}
    reason : str
        Why, in words.
    """

    effect: str
    handling: str
    reason: str

    def summary(self) -> dict[str, str]:
        """JSON-ready form."""
        return {"effect": self.effect, "handling": self.handling, "reason": self.reason}


@dataclass(frozen=True, kw_only=True)
class OutputModel:
    """The model a gas temperature is reconstructed with, and the rules it follows.

    Attributes
    ----------
    effects : tuple of str
        The fitted model's effects (those left at first order included).
    params : mapping of str to float
        Its parameters: ``tau1``, ``tau2`` (s) and the effects' own.
    context : FitContext
        The fit's context at its working rate (level, knot spacing, film cut-off, time base).
    pieces : tuple of Piece
        One per effect: how the reconstruction treats it.
    error_pct : float
        Held-out model error of the fit, % (NaN when unknown).
    base_error_pct : float
        Held-out error of the first-order model on the same record, %.
    origin_s : float
        Time of the fitted record's sample 0 on the caller's time base, s (a stream's
        interference phase is counted from it).
    base_taus : (float, float)
        τ1, τ2 of the first-order model fitted to the same record, s.
    band_hz : float
        Band edge of the diagnosis's comparisons, Hz (NaN when unknown): errors against a
        reference are also given low-passed there, where the model, not the noise, decides.
    notes : tuple of str
        What the data cannot fix and which convention decided it (the diagnosis's
        identifiability).
    at_bound : tuple of str
        Parameters of the fit that ended on a bound of their physical range.
    identification : Identification or None
        Whether the data pin down the fit's effect parameters and its change to the gas
        (:mod:`tcomp_core.diagnose.identification`); None when not checked.
    lines : tuple of ForeignLine
        Spectral lines one sensor carried alone on the fitted record (mains pick-up), as the
        default first-order path found them (:func:`tcomp_core.lines.foreign_lines`): an
        offline reconstruction takes them off the carrying channel unless an applied
        ``interference`` piece takes its line off itself.
    first_order_failure : str
        How the default path's first-order model fails the record (its two sensors'
        reconstructions disagree beyond their noise:
        :func:`tcomp_core.fusion.first_order_adequacy`); '' when it describes the record or
        was not checked.
    refusal : str
        Why the fit may not make the gas, every piece then left first order ('' when it may).
    first_order_taus : (float, float) or None
        τ1, τ2 of the default path's first order on the fitted record (ml-eiv, fitted with the
        sensors' gain), s; None when it was not run or refused the record. With ``lines`` it
        gives the default path's gas, whose level an offline gas keeps where a ``dynamics``
        piece leaves the level to first order (:func:`~.offline.compensate`).
    """

    effects: tuple[str, ...]
    params: Mapping[str, float]
    context: FitContext
    pieces: tuple[Piece, ...] = ()
    error_pct: float = math.nan
    base_error_pct: float = math.nan
    origin_s: float = 0.0
    base_taus: tuple[float, float] = (math.nan, math.nan)
    band_hz: float = math.nan
    notes: tuple[str, ...] = field(default=())
    at_bound: tuple[str, ...] = field(default=())
    identification: Identification | None = None
    lines: tuple[ForeignLine, ...] = ()
    first_order_failure: str = ""
    refusal: str = ""
    first_order_taus: tuple[float, float] | None = None

    @property
    def tau1(self) -> float:
        """Time constant of thermocouple 1 under the model, s."""
        return float(self.params["tau1"])

    @property
    def tau2(self) -> float:
        """Time constant of thermocouple 2 under the model, s."""
        return float(self.params["tau2"])

    def applied(self, causal_stream: bool = False) -> tuple[str, ...]:
        """The effects undone (``compensated`` or ``prior``); a stream drops the non-causal."""
        return tuple(
            piece.effect
            for piece in self.pieces
            if piece.handling != "first order"
            and not (causal_stream and piece.effect in _NOT_CAUSAL)
        )

    def name(self, causal_stream: bool = False) -> str:
        """``first-order`` or ``first-order+effect+...`` (the effects undone)."""
        return "+".join((FIRST_ORDER, *self.applied(causal_stream)))

    def stream_pieces(self) -> tuple[Piece, ...]:
        """The pieces as a causal stream treats them."""
        return tuple(
            Piece(p.effect, "first order", f"not in a causal stream: {_NOT_CAUSAL[p.effect]}")
            if p.effect in _NOT_CAUSAL and p.handling != "first order"
            else p
            for p in self.pieces
        )

    def context_for(self, time: NDArray[np.float64], dt: float) -> FitContext:
        """The fit's context moved to another sampling of the same record (``time`` in s)."""
        time = np.asarray(time, dtype=np.float64) - self.origin_s
        return replace(self.context, dt=dt, time=time, noise_kernel=None)

    def chains(
        self, time: NDArray[np.float64], dt: float, causal_stream: bool = False
    ) -> tuple[SensorChain, SensorChain]:
        """Both sensors' chains with the applied effects, over ``time`` (s, caller's base).

        Each sensor stays on its own scale (the fit's level difference ``level_c`` is not
        applied: :meth:`~tcomp_core.effects.Model.without_level`).

        Raises
        ------
        ValueError
            If a velocity is applied to samples outside the fitted record.
        """
        applied = self.applied(causal_stream)
        if "velocity" in applied:
            relative = np.asarray(time) - self.origin_s
            span = float(self.context.time[-1]) + self.context.dt
            if relative[0] < -dt or relative[-1] > span + dt:
                raise ValueError(
                    "the velocity's tau(t) was fitted on another stretch of the record "
                    f"(0 to {span:.6g} s from its start; these samples span "
                    f"{relative[0]:.6g} to {relative[-1]:.6g} s)"
                )
        return Model(applied, self.params).without_level().chains(self.context_for(time, dt))

    @property
    def keeps_first_order_level(self) -> bool:
        """Whether the gas keeps the first-order level (a ``dynamics`` piece is applied)."""
        return any(piece.handling == "dynamics" for piece in self.pieces)

    def level_reference(self) -> OutputModel:
        """The model with its ``dynamics`` pieces left first order: the level to keep.

        A reconstruction of this model mixes the levels as the first-order one does (each
        reconstruction weighs the sensors its own way: Eq. 7 by its combination weight, the
        Kalman filter by the noise at low frequency), so its mean less the full model's is the
        shift that keeps the first-order level (:func:`~.offline.level_shift_c`).
        """
        pieces = tuple(
            Piece(p.effect, "first order", "level reference") if p.handling == "dynamics" else p
            for p in self.pieces
        )
        return replace(self, pieces=pieces)

    def summary(self, causal_stream: bool = False) -> dict[str, Any]:
        """JSON-ready: name, effects, parameters, pieces, errors, notes."""
        pieces = self.stream_pieces() if causal_stream else self.pieces
        return {
            "name": self.name(causal_stream),
            "effects": list(self.effects),
            "params": {key: float(value) for key, value in self.params.items()},
            "pieces": [piece.summary() for piece in pieces],
            "error_pct": _finite(self.error_pct),
            "base_error_pct": _finite(self.base_error_pct),
            "notes": list(self.notes),
            "identification": (
                None if self.identification is None else self.identification.summary()
            ),
            "first_order_failure": self.first_order_failure,
        }

    def describe(self, causal_stream: bool = False) -> list[str]:
        """One line per piece, for summaries."""
        pieces = self.stream_pieces() if causal_stream else self.pieces
        lines = [f"output model: {self.name(causal_stream)}"]
        lines += [f"  {piece.effect}: {piece.handling} ({piece.reason})" for piece in pieces]
        if self.identification is not None and self.identification.checks:
            found = self.identification
            output_band = found.output_band_c(self.applied(causal_stream))
            with_free = (
                f", +-{output_band:.3g} with its free parameters"
                if output_band > found.band_c
                else ""
            )
            lines.append(
                f"  identified: gas band +-{found.band_c:.3g} degC rms (95 %{with_free}) against "
                f"a change of {found.change_c:.3g} degC rms; the sensors' first-order "
                f"disagreement {found.evidence_c:.3g} degC rms"
            )
            if found.form_note:
                lines.append(f"  also allowed by the data: {found.form_note}")
            if math.isfinite(found.published_change_c):
                lines.append(
                    f"  against the default first-order gas it changes the gas by "
                    f"{found.published_change_c:.3g} degC rms"
                )
            lines += [f"    {check.describe()}" for check in found.checks]
        if self.first_order_failure:
            lines.append(
                f"  the default first order fails this record: {self.first_order_failure}"
            )
        return lines


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _piece(effect: str, expected: bool, fit: OutputEvidence) -> Piece:
    if expected:
        return Piece(
            effect,
            "first order",
            "ordinary size (the sensors' expected physics, below materiality): compensating "
            "would trade a small known bias for the fit's uncertainty",
        )
    handling, reason = EFFECTS[effect]().output_handling(fit)
    return Piece(effect, handling, reason)


def output_model_from_diagnosis(
    diagnosis: Diagnosis,
    origin_s: float = 0.0,
    first_order_taus: tuple[float, float] | None = None,
    first_order_lines: Sequence[ForeignLine] = (),
    first_order_failure: str = "",
) -> OutputModel:
    """The output model of a diagnosis's (or fit's) final model.

    Parameters
    ----------
    diagnosis : Diagnosis
        From :func:`tcomp_core.diagnose.diagnose` or :func:`~tcomp_core.diagnose.fit_effects`.
    origin_s : float
        Time of the diagnosed record's sample 0 on the caller's time base, s.
    first_order_taus : (float, float), optional
        τ1, τ2 of the default first-order path on the same record (ml-eiv, which fits the
        sensors' gain; :func:`fit_output_model` gives them), s: the gas falls back to them when
        the model applies nothing, or when its fit does not determine τ. Without them it falls
        back to the diagnosis's own first-order fit (no gain between the sensors).
    first_order_lines : sequence of ForeignLine
        The lines the default path found one sensor carrying alone (:attr:`OutputModel.lines`).
    first_order_failure : str
        How the default path's first order fails the record ('' when it describes it:
        :func:`default_first_order_failure`). A model whose effects change the gas by less
        than its band is then still applied when its change against the default path's
        first-order gas (:attr:`~tcomp_core.diagnose.identification.Identification.
        published_change_c`, the diagnosis run with ``published_taus``) stands beyond the
        band: the gas a refusal falls back to is known to be wrong, and the model's is known
        to within its band (conduction to lagging supports put the default τ 144 % long and
        its gas 135 % off; the model's τ was within 3 % and its gas 7 % off, its effects'
        own change of 2.8 degC rms inside a band of +-3.6).

    Raises
    ------
    ValueError
        If the diagnosis carries no fit context.
    EstimationError
        If the final fit, or the first-order fit a refused model falls back to, leaves τ1 or
        τ2 undetermined (on a bound of its range, or a 95 % interval wider than
        :data:`MAX_TAU_INTERVAL_RATIO`): nothing fits the record (pure noise, unrelated
        signals), so nothing is compensated, as the first-order path refuses it.
    """
    if diagnosis.context is None:
        raise ValueError(f"{diagnosis.source}: the diagnosis carries no fit context")
    final = diagnosis.final
    loose = _loose_taus(final)
    if first_order_taus is None:
        _check_determined(diagnosis, final, "fit" if final.effects else "first-order fit")
    expected = set(diagnosis.expected_physics)
    base_taus = (float(diagnosis.base.tau1), float(diagnosis.base.tau2))
    params = dict(final.params)
    evidence = OutputEvidence(
        intervals=final.intervals,
        params=final.params,
        effects=tuple(final.effects),
        level_mean_c=diagnosis.context.level_mean_c,
        ordinary=tuple(
            effect
            for effect in final.effects
            if effect in expected or EFFECTS[effect].default_path_covers
        ),
        level_split_c=(
            math.nan if final.identification is None else final.identification.level_split_c
        ),
    )
    pieces = tuple(_piece(effect, effect in expected, evidence) for effect in final.effects)
    pieces = _lines_the_default_takes_off(pieces, params, first_order_lines)
    refusal = _refusal(
        final, pieces, base_taus, diagnosis.context.dt, first_order_failure, first_order_taus
    )
    if loose and not refusal:
        refusal = f"the fit does not determine the time constants ({'; '.join(loose)})"
    if refusal:  # not trusted with the gas: every piece first order, on first order's tau
        if first_order_taus is None:
            _check_determined(diagnosis, diagnosis.base, "first-order fit it falls back to")
        pieces = tuple(Piece(effect, "first order", refusal) for effect in final.effects)
        fallback = base_taus if first_order_taus is None else first_order_taus
        params |= {"tau1": fallback[0], "tau2": fallback[1]}
    elif first_order_taus is not None and all(p.handling == "first order" for p in pieces):
        # Nothing undone: the gas is the default path's, on its τ (fitted with the gain).
        params |= {"tau1": first_order_taus[0], "tau2": first_order_taus[1]}
    return OutputModel(
        effects=tuple(final.effects),
        params=params,
        context=diagnosis.context,
        pieces=pieces,
        error_pct=float(final.error_pct),
        base_error_pct=float(diagnosis.base.error_pct),
        origin_s=origin_s,
        base_taus=base_taus,
        band_hz=float(diagnosis.eval_cutoff_hz),
        notes=tuple(diagnosis.identifiability),
        at_bound=tuple(final.at_bound),
        identification=final.identification,
        lines=tuple(first_order_lines),
        first_order_failure=first_order_failure,
        refusal=refusal,
        first_order_taus=first_order_taus,
    )


def output_model_with_fallback(
    record: Record,
    diagnosis: Diagnosis,
    origin_s: float = 0.0,
    first_order_taus: tuple[float, float] | None = None,
    first_order_lines: Sequence[ForeignLine] = (),
    first_order_failure: str = "",
) -> OutputModel:
    """The output model of a diagnosis, or of its staircase's longest shorter model that passes.

    As :func:`output_model_from_diagnosis` (same arguments; ``record`` is the diagnosed
    record). When the final model is refused and the diagnosis's staircase took it in steps,
    each shorter model of the staircase, longest first, is fitted again on the whole record
    (:func:`~tcomp_core.diagnose.fit_effects`, the effects in the staircase's order) and
    judged by the same rules; the first that passes makes the gas, and the effects it leaves
    out are first order, with the full model's refusal as their reason. One effect the data
    do not pin down took a sound one's correction with it: a delay found beside a conduction
    whose supports' lag spanned its whole range was refused, and the gas stayed the default
    path's, 18.2 % off, where the delay alone makes it 4.6 % off (campaign draw 2423).
    A shorter model stands in only when its gas agrees with the full fit's, within the two
    fits' 95 % bands (:func:`_stands_in_for`): then what it leaves out did not shape the gas.
    """
    from ..diagnose import fit_effects

    judged = partial(
        output_model_from_diagnosis,
        origin_s=origin_s,
        first_order_taus=first_order_taus,
        first_order_lines=first_order_lines,
        first_order_failure=first_order_failure,
    )
    full = judged(diagnosis)
    if not full.refusal:
        return full
    for step in reversed(diagnosis.steps[1:-1]):
        try:
            shorter_fit = fit_effects(
                record,
                step.effects,
                published_taus=first_order_taus,
                published_lines=first_order_lines,
            )
            shorter = judged(shorter_fit)
        except (EstimationError, ValueError):
            continue
        if shorter.refusal or not shorter.applied():
            continue
        if not _stands_in_for(shorter_fit.final, diagnosis):
            continue
        dropped = [effect for effect in full.effects if effect not in shorter.effects]
        reason = (
            f"the model with it, {'+'.join(full.effects)}, is refused ({full.refusal}); "
            f"{'+'.join(shorter.effects)} without it passes"
        )
        left = tuple(Piece(effect, "first order", reason) for effect in dropped)
        return replace(
            shorter, effects=(*shorter.effects, *dropped), pieces=(*shorter.pieces, *left)
        )
    return full


def _stands_in_for(shorter: ModelFit, diagnosis: Diagnosis) -> bool:
    """Whether a shorter model's gas agrees with the full fit's within their 95 % bands.

    Both fits' gas (the mean of the two sensors' reconstructions at the diagnosis's working
    rate, low-passed at its comparison band, their means removed: the level has its own
    rules) are compared over the record less three slow time constants at each end; they
    agree when the rms of the difference is within the two bands in quadrature
    (:attr:`~tcomp_core.diagnose.identification.Identification.band_c`). A shorter model
    whose gas moves beyond them is another explanation of the record, not the sound part of
    the full one: a radiation refitted without the delay the staircase had added beside it
    (fresh campaign draw 3920, exhaust pulses at 5 kHz, the full model refused for its ρ1)
    moved the gas 89 degC rms against bands of +-5.3 and +-14.4, and published 63.6 % off where
    the default path's gas is 18.1 % off; conduction without a calibration (3926) moved it
    5.4 degC against +-4.3 and +-6.1 and cut the default path's 370 % to 20 %, and draw 2423's
    delay without the conduction 108 degC against +-138 and +-1.8. A band that could not be
    computed does not refuse.
    """
    full = diagnosis.final
    bands = [
        fit.identification.band_c if fit.identification is not None else math.nan
        for fit in (full, shorter)
    ]
    if not all(math.isfinite(band) for band in bands):
        return True
    dt = diagnosis.dt
    count = min(full.gas1.size, shorter.gas1.size)
    skip = min(count // 10, math.ceil(STANDS_IN_SKIP_TAUS * max(full.tau1, full.tau2) / dt))
    sos = lowpass_sos(min(diagnosis.eval_cutoff_hz, 0.45 / dt), dt, STANDS_IN_FILTER_ORDER)
    difference = np.zeros(count)
    for fit, sign in ((full, 1.0), (shorter, -1.0)):
        difference += sign * 0.5 * (fit.gas1[:count] + fit.gas2[:count])
    kept = difference[skip : count - skip]
    if kept.size < 16 or not np.all(np.isfinite(kept)):
        return True
    moved = zero_phase(sos, kept - kept.mean())
    return float(np.sqrt(np.mean(moved**2))) <= math.hypot(*bands)


def _lines_the_default_takes_off(
    pieces: tuple[Piece, ...], params: Mapping[str, float], lines: Sequence[ForeignLine]
) -> tuple[Piece, ...]:
    """The pieces, with an interference left to the default path when it takes the line off.

    When an interference is all the model undoes and the default path takes its line off the
    same channel itself, the piece is left first order. The default path notches each line it
    finds on the carrying channel, keeping that channel's gas content there
    (:func:`tcomp_core.lines.line_free_pair`), at the τ of ml-eiv. A model that undoes nothing
    but such a line changes the published gas only by its own τ, fitted without the gain
    between the sensors and beside effects it did not find: a delay missed beside a mains line
    on a 20 kHz exhaust record put the model's τ 10 % short and its gas 9.7 % off where the
    default path's was 2.9 % off.
    """
    applied = [piece for piece in pieces if piece.handling != "first order"]
    if [piece.effect for piece in applied] != ["interference"]:
        return pieces
    frequency = float(params.get("interference_hz", math.nan))
    channel = int(params.get("interference_channel", 0))
    same = [
        line
        for line in lines
        if line.channel == channel and abs(line.frequency_hz - frequency) <= frequency / NOTCH_Q
    ]
    if not same:
        return pieces
    reason = (
        f"the default path takes the {same[0].frequency_hz:.4g} Hz line off tc{channel} "
        "itself, at its own tau: the model would change only the tau"
    )
    return tuple(
        Piece(piece.effect, "first order", reason) if piece.effect == "interference" else piece
        for piece in pieces
    )


def _loose_taus(fit: ModelFit) -> list[str]:
    """τ of ``fit`` the data do not determine (on a bound, or a 95 % interval over a factor)."""
    loose = []
    for name in ("tau1", "tau2"):
        low, high = fit.intervals.get(name, (math.nan, math.nan))
        if name in fit.at_bound or high > MAX_TAU_INTERVAL_RATIO * low:
            loose.append(f"{name} = {fit.params[name]:.3g} s, 95 % interval {low:.3g}..{high:.3g}")
    return loose


def _level_disagreement(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], tried: frozenset[str] = frozenset()
) -> str:
    """The readings' difference in mean level when it lies beyond class 2, else ''.

    ``tried``: the effects the diagnosis already fitted to the record; for those the advice
    is not to run it again (strong conduction to constant supports, a thick wire reading 66 %
    of the gas's swing, was told to compensate with the search that had just failed it).

    Two first-order lags of one gas read the same mean, so a difference beyond what two
    class-2 sensors may show (by :data:`~tcomp_core.tolerance.CLASS2_MARGIN`) is a calibration
    the refused fit had no way to explain, or conduction to supports colder than the gas,
    which pulls each wire's reading toward them by its own share (on six campaign draws of it
    the readings differed by 48-186 °C at 74-248 °C and the message named a calibration only).
    """
    difference = float(np.mean(tc1) - np.mean(tc2))
    level = 0.5 * float(np.mean(tc1) + np.mean(tc2))
    tolerance = class2_level_tolerance_c(level)
    if not abs(difference) > CLASS2_MARGIN * tolerance:
        return ""
    searched = "calibration" in tried and "conduction" in tried
    remedy = (
        "the diagnosis fitted both and neither determines tau: check the probe's wiring and "
        "supports"
        if searched
        else "correct one sensor's calibration, or compensate with --effects calibration or "
        "--effects auto, and rerun"
    )
    return (
        f"; the readings differ by {difference:+.3g} °C in mean level at {level:.4g} °C, "
        f"beyond IEC 60584 class 2 ({tolerance:.2g} °C there): a calibration or conduction to "
        f"supports colder than the gas; {remedy}"
    )


def _check_determined(diagnosis: Diagnosis, fit: ModelFit, what: str) -> None:
    """Refuse to compensate on a fit whose τ the data do not determine (see the caller)."""
    loose = _loose_taus(fit)
    if not loose:
        return
    found = diagnosis.final.params
    calibration = (
        f"; the fit finds the sensors {100.0 * (found['gain'] - 1.0):+.3g} % apart in gain and "
        f"{found['offset_c']:+.3g} °C in level (class 2 allows {100 * CLASS2_GAIN:g} % and "
        f"{CLASS2_OFFSET_C:g} °C): correct "
        "one sensor's calibration and rerun"
        if {"gain", "offset_c"} <= found.keys()
        else _level_disagreement(
            diagnosis.tc1,
            diagnosis.tc2,
            frozenset(suspect.effect for suspect in diagnosis.suspects),
        )
        or " (are both signals thermocouples in one gas?)"
    )
    raise EstimationError(
        f"{diagnosis.source}: the {what} does not determine the time constants "
        f"({'; '.join(loose)}): no first-order pair fits this record, so no gas is "
        f"compensated{calibration}"
    )


def _harmless_on_bound(check: ParameterCheck, found: Identification) -> bool:
    """Whether a parameter on a bound of its range leaves the gas as the model changes it.

    Its 95 % interval's far end, along the fit's valley, moves the gas by less than the
    change the model makes, and its fluctuation by less than the band: what the data do not
    pin down does not decide the gas. A radiation fit whose wall temperature sat on its
    lowest bound (-73 degC) made the gas 1.3 % off where first order is 7.5 % off (campaign
    draw 3308); its wall, emissivities and τ trade along a valley the gas hardly feels.
    """
    from ..diagnose.identification import ON_BOUND

    return (
        check.at_bound
        and check.reason == ON_BOUND
        and check.gas_move_c < found.change_c
        and check.gas_shape_move_c < found.band_c
    )


def _refusal(
    final: ModelFit,
    pieces: tuple[Piece, ...],
    base_taus: tuple[float, float],
    dt: float,
    first_order_failure: str = "",
    published_taus: tuple[float, float] | None = None,
) -> str:
    """Why a fit may not make the gas ('' when it may).

    It may not when it is no physical sensor (:meth:`~tcomp_core.effects.Model.implausible`,
    or a fit that swaps which sensor is the slower against ``published_taus``, the default
    path's τ: :func:`swapped_sensors`), when a parameter of an applied effect is not pinned
    down by the data, or when its change to the gas is within its own uncertainty: the
    change its effects make, or, where the default first order fails the record
    (``first_order_failure``), the change against the default path's gas. The change against
    the default path's gas must stand beyond the band in every case where it is known.
    """
    implausible = Model(tuple(final.effects), dict(final.params)).implausible(
        base_taus, dt, published_taus
    )
    if implausible:
        return f"the fit is no physical sensor: {implausible}"
    found = final.identification
    applied = tuple(piece.effect for piece in pieces if piece.handling != "first order")
    if found is None or not applied:
        return ""
    undetermined = [
        check for check in found.undetermined(applied) if not _harmless_on_bound(check, found)
    ]
    if undetermined:
        listed = "; ".join(f"{check.name} {check.reason}" for check in undetermined)
        return f"not pinned down by the data ({listed}): first order is what they identify"
    undone = tuple(piece.effect for piece in pieces if piece.handling in _UNDONE)
    deciding = [  # wide or free parameters that decide the gas (identification's notes)
        check
        for check in found.checks
        if check.effect in undone
        and check.wide
        and not (
            check.gas_move_c < found.change_c
            and (check.gas_shape_move_c < found.band_c or not check.free)
        )
    ]
    if deciding:
        listed = "; ".join(
            f"{check.name}: {check.loose}, across which the gas moves "
            f"+-{check.gas_move_c:.3g} degC rms (+-{check.gas_shape_move_c:.3g} in its "
            f"fluctuation) against a change of {found.change_c:.3g} and a band of "
            f"+-{found.band_c:.3g}"
            for check in deciding
        )
        return f"not pinned down by the data ({listed}): first order is what they identify"
    if found.extrapolates:
        return (
            f"the model changes the gas by {found.change_c:.3g} degC rms, "
            f"{found.change_c / found.evidence_c:.3g} times the {found.evidence_c:.3g} degC by "
            f"which the two sensors' first-order gas disagree: the correction would rest on the "
            f"model's form, not on the data"
        )
    beyond_default = bool(first_order_failure) and not found.band_exceeds_published_change
    if math.isfinite(found.published_change_c) and found.band_exceeds_published_change:
        # What a user would get instead is the default path's gas: a model whose gas is not
        # told apart from it by its own band adds nothing the data show. On a mains record
        # its line removal, which the default path makes too, carried a false level-dependent
        # τ past the band (change 17.1 against +-16.9; against the default 2.55): 5.3 -> 6.6 %.
        return (
            f"the 95 % band on the gas (+-{found.band_c:.3g} degC rms) is as wide as the "
            f"change the model makes to the default path's gas "
            f"({found.published_change_c:.3g} degC rms): the data do not tell the two apart"
        )
    if found.band_exceeds_change and not beyond_default:
        why = f"; {found.band_note}" if found.band_note else ""
        if found.form_note and math.isfinite(found.form_c):
            why += f"; {found.form_note}"
        return (
            f"the 95 % band on the gas (+-{found.band_c:.3g} degC rms, refits leaving out one "
            f"stretch of the record at a time, and the effects' other forms) is as wide as the "
            f"change the model makes to it ({found.change_c:.3g} degC rms){why}"
        )
    return ""


def parse_compensate_effects(text: str) -> tuple[str, ...] | None:
    """``--effects`` of reconstruct and process: None for ``auto``, else the names.

    ``""`` and ``"none"`` give the empty set (the first-order model).

    Raises
    ------
    ValueError
        On an unknown or repeated effect name.
    """
    return parse_effect_list(text, auto=True)


def fit_output_model(record: Record, effects: tuple[str, ...] | None) -> OutputModel:
    """Fit the output model of a record: the diagnosis's final model, or a chosen set.

    Parameters
    ----------
    record : Record
    effects : tuple of str or None
        None runs the diagnosis (:func:`tcomp_core.diagnose.diagnose`) and takes its final
        model; a tuple fits those effects in order (:func:`~tcomp_core.diagnose.fit_effects`).

    Raises
    ------
    DataError, EstimationError
        As the diagnosis or fit raises them.
    """
    from ..diagnose import diagnose, fit_effects

    plain = default_estimate(record)
    taus = None if plain is None else (float(plain.tau1), float(plain.tau2))
    lines = () if plain is None else plain.lines
    judged: Callable[..., OutputModel] = output_model_from_diagnosis
    if effects is None:
        diagnosis = diagnose(
            record, published_taus=taus, published_lines=lines, published_tried=True
        )
        judged = partial(output_model_with_fallback, record)
    else:
        diagnosis = fit_effects(
            record, effects, published_taus=taus, published_lines=lines, published_tried=True
        )
    return judged(
        diagnosis,
        origin_s=float(record.time[0]),
        first_order_taus=taus,
        first_order_lines=lines,
        first_order_failure=default_first_order_failure(record, plain),
    )


def default_first_order_failure(record: Record, plain: Estimate | None) -> str:
    """How the default path's first order (``plain``) fails ``record``; '' if it does not.

    The two sensors' first-order reconstructions at its τ, tc2 put on tc1's scale by its
    fitted gain, disagree beyond their noise by a material share of the gas's fluctuation, or
    their phase goes beyond what two first-order lags allow
    (:func:`tcomp_core.fusion.first_order_adequacy`). The gain is taken out because a
    calibration is no failure of the dynamics: two sensors 3 % apart in gain disagree by 3 %
    of the signal at any τ (a calibration read as radiation was applied on that ground and put
    the gas 7.5 -> 12.2 % off).
    """
    from ..fusion import first_order_adequacy

    if plain is None:
        return ""
    gain = float(plain.params.get("gain", 1.0))
    scaled = record.tc2 * (gain if math.isfinite(gain) and gain > 0.0 else 1.0)
    try:
        misfit, gas_std_c = first_order_adequacy(
            record.tc1, scaled, record.dt, float(plain.tau1), float(plain.tau2)
        )
    except (ValueError, np.linalg.LinAlgError):
        return ""
    return misfit.describe(gas_std_c) if misfit.material(gas_std_c) else ""


def default_taus(record: Record) -> tuple[float, float] | None:
    """τ1, τ2 of the default first-order path on ``record`` (ml-eiv), s; None if it refuses."""
    found = default_estimate(record)
    return None if found is None else (float(found.tau1), float(found.tau2))
