"""tcomp_core: two-thermocouple lag compensation (Hung, Irwin, Kee and McLoone 2005).

Pure numerical core: sensor models, simulation, the six time-constant estimators, filtering,
gas temperature reconstruction, metrics, streaming windows and data I/O. Never imports rclpy.

The names below load their module on first use (PEP 562), so ``import tcomp_core`` (and the
``tcomp`` command line, which imports this package) costs no numpy or scipy until a numerical
name is touched: ``tcomp_core.estimate(...)`` works as an eager import would.
"""

from __future__ import annotations

import os
import sys
from importlib import import_module
from types import ModuleType
from typing import TYPE_CHECKING, Any

from .choices import METHODS
from .errors import (
    DataError,
    EstimationError,
    NoExcitationError,
    PhysicalRangeError,
    TcompError,
)

# The numerical work here is small matrices (Kalman filters of 3 to 35 states, 3x3 scatter
# solves) and long elementwise recursions: BLAS threads only contend for the cores, and on a
# busy 2-core machine they made the signal-model fits 2.5x slower (README, "Performance").
# Set before numpy is first imported; a value the user set is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

if TYPE_CHECKING:
    from .estimators import Estimate, estimate
    from .models import FirstOrderLag
    from .reconstruct import Reconstruction, reconstruct
    from .simulate import SimulatedPair, simulate_pair
    from .window import SlidingBetaWindow

__version__ = "0.1.0"

__all__ = [
    "METHODS",
    "DataError",
    "Estimate",
    "EstimationError",
    "FirstOrderLag",
    "NoExcitationError",
    "PhysicalRangeError",
    "Reconstruction",
    "SimulatedPair",
    "SlidingBetaWindow",
    "TcompError",
    "__version__",
    "estimate",
    "reconstruct",
    "simulate_pair",
]

#: The module defining each lazily loaded name, relative to this package.
_LAZY: dict[str, str] = {
    "Estimate": ".estimators",
    "estimate": ".estimators",
    "FirstOrderLag": ".models",
    "Reconstruction": ".reconstruct",
    "reconstruct": ".reconstruct",
    "SimulatedPair": ".simulate",
    "simulate_pair": ".simulate",
    "SlidingBetaWindow": ".window",
}


class _LazyPackage(ModuleType):
    """The module type of this package: a name shadowing its submodule stays the name.

    Loading the submodule ``tcomp_core.reconstruct`` binds it as the package attribute
    ``reconstruct``; the function of that name is kept there instead, as the eager
    ``from .reconstruct import reconstruct`` of an ordinary ``__init__`` would.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, ModuleType) and _LAZY.get(name) == f".{name}":
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _LazyPackage


def __getattr__(name: str) -> Any:
    """Load a numerical name from its module on first access and keep it here."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's own names and the lazily loaded ones."""
    return sorted({*globals(), *__all__})
