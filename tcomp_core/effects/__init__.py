"""The effect library: extensions of the first-order two-thermocouple model.

Each effect is one module with its own parameters (:class:`~tcomp_core.effects.base.Effect`);
:mod:`~tcomp_core.effects.registry` maps their names to them, and :class:`Model` composes any
set of them with the base model and fits them to data::

    model = Model().with_effect("delay").fit(tc1, tc2, context)

The modules of this package import each other directly, never this ``__init__``, which only
re-exports their public names.
"""

from __future__ import annotations

from .base import Effect, FitContext, ParamSpec
from .model import Model, make_context
from .registry import EFFECT_NAMES, EFFECTS, check_effect_names

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
