"""The effect library: extensions of the first-order two-thermocouple model.

Each effect is one module with its own parameters (:class:`~tcomp_core.effects.base.Effect`);
:class:`Model` composes any set of them with the base model and fits them to data::

    model = Model().with_effect("delay").fit(tc1, tc2, context)
"""

from __future__ import annotations

from collections.abc import Iterable

from .base import Effect, FitContext, ParamSpec
from .calibration import Calibration
from .conduction import Conduction
from .delay import Delay
from .model import Model, make_context
from .noise_ratio import NoiseRatio
from .radiation import Radiation
from .velocity import Velocity

__all__ = [
    "EFFECTS",
    "EFFECT_NAMES",
    "Effect",
    "FitContext",
    "Model",
    "ParamSpec",
    "check_effect_names",
    "make_context",
]

#: Every effect by name, in the order reports list them.
EFFECTS: dict[str, type[Effect]] = {
    effect.name: effect
    for effect in (Conduction, Radiation, Velocity, Delay, Calibration, NoiseRatio)
}
#: The effect names used everywhere (API, CLI, JSON, diagnostics).
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)


def check_effect_names(names: Iterable[str]) -> tuple[str, ...]:
    """The names as a tuple, each a known effect and none repeated.

    Raises
    ------
    ValueError
        Naming the unknown effect (and the known ones) or the repetition.
    """
    names = tuple(names)
    for name in names:
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; choose from {', '.join(EFFECT_NAMES)}")
    if len(set(names)) != len(names):
        raise ValueError(f"effects {', '.join(names)} repeat an effect")
    return names
