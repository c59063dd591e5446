"""The option strings of tcomp, defined once, and the defaults its command line shows.

Every name an option can take (estimators, signal kinds, combinations, reconstructions, signal
models, effects) is a :data:`typing.Literal` here with its tuple of values beside it. The
numerical modules import them from here, and so does the command line, which builds its parser
from this module alone: it imports nothing but the standard library, so ``tcomp --help`` starts
without loading numpy or scipy. Keep it that way.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal, get_args

__all__ = [
    "BATCH_RECONSTRUCTIONS",
    "COMBINATIONS",
    "DEFAULT_COLUMNS",
    "DEFAULT_METHOD",
    "DEFAULT_TOPICS",
    "EFFECT_NAMES",
    "METHODS",
    "MODELS",
    "PAPER_DT",
    "PAPER_DURATION",
    "PAPER_METHODS",
    "PAPER_TAU1",
    "PAPER_TAU2",
    "RECONSTRUCTIONS",
    "RECONSTRUCT_FROM",
    "SIGNALS",
    "SIGNAL_MODELS",
    "BatchReconstruction",
    "Combination",
    "EffectName",
    "Method",
    "ModelChoice",
    "ModelKind",
    "OnlineReconstruction",
    "PaperMethod",
    "ReconstructFrom",
    "SignalKind",
    "names_a_saved_diagnosis",
    "parse_effect_list",
]

#: The six estimators of Hung et al. (2005), in the paper's order.
PaperMethod = Literal["tdr-kee", "gamma-ls", "gamma-tls", "beta-ls", "beta-tls", "beta-gtls"]
PAPER_METHODS: tuple[str, ...] = get_args(PaperMethod)
#: Every estimator: the paper's six and the maximum-likelihood errors-in-variables one.
Method = Literal[PaperMethod, "ml-eiv"]
METHODS: tuple[str, ...] = get_args(Method)
#: The estimator used when none is asked for: the only one unbiased without a pre-filter at
#: every sample rate from 0.5 to 20 kHz (see ``bench/bench_accuracy.py``).
DEFAULT_METHOD: Method = "ml-eiv"

#: Gas temperature signals of the simulator.
SignalKind = Literal["sinusoid", "ramp", "multisine", "exhaust"]
SIGNALS: tuple[str, ...] = get_args(SignalKind)

#: How the two Eq. (7) reconstructions are combined into one.
Combination = Literal["inverse-variance", "mean", "tc1", "tc2"]
COMBINATIONS: tuple[str, ...] = get_args(Combination)

#: Gas temperature models of the Kalman reconstructions.
ModelKind = Literal[
    "random-walk", "integrated-random-walk", "band-limited", "periodic", "autoregressive"
]
MODELS: tuple[ModelKind, ...] = get_args(ModelKind)
#: A model, or ``auto``: the most likely one, penalised by its number of settings.
ModelChoice = Literal["auto", ModelKind]
SIGNAL_MODELS: tuple[str, ...] = ("auto", *MODELS)

#: Reconstructions of the online compensator (the node and ``tcomp process``): Eq. (7) or the
#: causal Kalman filter.
OnlineReconstruction = Literal["difference", "kalman"]
RECONSTRUCTIONS: tuple[str, ...] = get_args(OnlineReconstruction)
#: Reconstructions of a whole record (``tcomp reconstruct``): Eq. (7), the Kalman (RTS)
#: smoother, or the causal filter alone as the node runs it.
BatchReconstruction = Literal["difference", "kalman", "kalman-causal"]
BATCH_RECONSTRUCTIONS: tuple[str, ...] = get_args(BatchReconstruction)
#: Which Eq. (7) reconstruction the online compensator outputs.
ReconstructFrom = Literal["fused", "tc1", "tc2"]
RECONSTRUCT_FROM: tuple[str, ...] = get_args(ReconstructFrom)

#: The effect names used everywhere (API, CLI, JSON, diagnostics), in the order reports list
#: them.
EffectName = Literal[
    "conduction",
    "radiation",
    "velocity",
    "property",
    "delay",
    "calibration",
    "interference",
    "noise_ratio",
]
EFFECT_NAMES: tuple[str, ...] = get_args(EffectName)

#: Topics of tc1, tc2 and the optional reference in a bag.
DEFAULT_TOPICS: tuple[str, str, str | None] = (
    "/tc1/temperature",
    "/tc2/temperature",
    "/tref/temperature",
)
#: Columns of tc1, tc2 and the optional reference in a CSV file (besides ``time``).
DEFAULT_COLUMNS: tuple[str, str, str | None] = ("tc1", "tc2", "ref")

#: Paper's simulation conditions (Sec. IV): τ1, τ2, τ_s in seconds, run length 10 s.
PAPER_TAU1 = 0.0238
PAPER_TAU2 = 0.1168
PAPER_DT = 0.002
PAPER_DURATION = 10.0


def names_a_saved_diagnosis(effects: str) -> bool:
    """Whether an ``effects`` value names a file ``tcomp diagnose --json`` wrote (``*.json``).

    Such a value stands for the effects of that diagnosis's final model
    (:func:`tcomp_core.diagnose.saved.saved_diagnosis_effects`).
    """
    return effects.strip().lower().endswith(".json")


def parse_effect_list(
    effects: str | Iterable[str], *, auto: bool = False
) -> tuple[str, ...] | None:
    """The one parser of effect lists (``--effects``, the node's ``effects``, the API).

    Parameters
    ----------
    effects : str or iterable of str
        Names from :data:`EFFECT_NAMES`; a string is split at commas and each name stripped,
        ``""`` and ``"none"`` meaning the base model alone.
    auto : bool
        Whether ``"auto"`` (the diagnosis chooses) is allowed; it gives None.

    Returns
    -------
    tuple of str or None
        The names in the order given; None for ``"auto"``.

    Raises
    ------
    ValueError
        Naming an unknown, empty or repeated name (and the known ones).
    """
    if isinstance(effects, str):
        text = effects.strip()
        if auto and text == "auto":
            return None
        effects = [] if text in ("", "none") else text.split(",")
    names = tuple(name.strip() for name in effects)
    known = ", ".join(EFFECT_NAMES) + (", or auto" if auto else "")
    for name in names:
        if not name:
            raise ValueError(f"an empty effect name in {','.join(names)!r}; choose from {known}")
        if name not in EFFECT_NAMES:
            raise ValueError(f"unknown effect {name!r}; choose from {known}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise ValueError(f"effects {', '.join(names)} repeat {', '.join(repeated)}")
    return names
