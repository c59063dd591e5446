"""Every effect by name: the one place that maps an effect name to its class.

:mod:`tcomp_core.effects.model` builds its effects from here; the names themselves are defined
in :mod:`tcomp_core.choices` so the command line can offer them without importing this library.
"""

from __future__ import annotations

from collections.abc import Iterable

from ..choices import EFFECT_NAMES, parse_effect_list
from .base import Effect
from .calibration import Calibration
from .conduction import Conduction
from .delay import Delay
from .interference import Interference
from .noise_ratio import NoiseRatio
from .property import Property
from .radiation import Radiation
from .velocity import Velocity

__all__ = ["EFFECTS", "EFFECT_NAMES", "check_effect_names"]

#: Every effect by name, in the order of :data:`EFFECT_NAMES` (the order reports list them;
#: a new effect adds its name there too, ``test/test_cli.py`` checks the two agree).
EFFECTS: dict[str, type[Effect]] = {
    effect.name: effect
    for effect in (
        Conduction,
        Radiation,
        Velocity,
        Property,
        Delay,
        Calibration,
        Interference,
        NoiseRatio,
    )
}


def check_effect_names(names: Iterable[str]) -> tuple[str, ...]:
    """The names as a tuple, each a known effect and none repeated.

    Parameters
    ----------
    names : iterable of str
        Effect names, in the order they are added to a model.

    Returns
    -------
    tuple of str
        The same names.

    Raises
    ------
    ValueError
        Naming the unknown effect (and the known ones) or the repetition.
    """
    parsed = parse_effect_list(tuple(names))
    assert parsed is not None  # "auto" is not allowed here
    return parsed
