"""The effect library: extensions of the first-order two-thermocouple model.

Each effect is one module with its own parameters (:class:`~tcomp_core.effects.base.Effect`);
:class:`Model` composes any set of them with the base model and fits them to data::

    model = Model().with_effect("delay").fit(tc1, tc2, context)
"""

from __future__ import annotations

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
    "make_context",
]

#: Every effect by name, in the order reports list them.
EFFECTS: dict[str, type[Effect]] = {
    effect.name: effect
    for effect in (Conduction, Radiation, Velocity, Delay, Calibration, NoiseRatio)
}
#: The effect names used everywhere (API, CLI, JSON, diagnostics).
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)
