"""tcomp_core: two-thermocouple lag compensation (Hung, Irwin, Kee and McLoone 2005).

Pure numerical core: sensor models, simulation, the six time-constant estimators, filtering,
gas temperature reconstruction, metrics, streaming windows and data I/O. Never imports rclpy.
"""

from __future__ import annotations

from .errors import (
    DataError,
    EstimationError,
    NoExcitationError,
    PhysicalRangeError,
    TcompError,
)
from .estimators import METHODS, Estimate, estimate
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
