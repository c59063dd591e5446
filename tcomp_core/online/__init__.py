"""The online engine shared by the compensator node and ``tcomp process``.

One module per job:

- :mod:`.config`: :class:`OnlineConfig` (the node's parameters) and :class:`EstimateStatus`;
- :mod:`.pairing`: :class:`PairMatcher`, approximate-time pair matching (exact stamps with
  ``slop_ns=0``), one sample at a time or vectorised in batches, with :class:`PairCounters`;
- :mod:`.estimation`: the sliding window, the tracking estimator and the grading of an estimate;
- :mod:`.reconstructors`: Eq. (7) and the causal Kalman filter, each returning a
  :class:`GasBatch` of stamps, gas and variance;
- :mod:`.compensator`: :class:`OnlineCompensator`, window and reconstruction of matched pairs;
- :mod:`.health`: one :class:`Level` enum, one rule set, one key-value formatter;
- :mod:`.engine`: :class:`Engine`, all of the above for one thermocouple pair;
- :mod:`.schedule`: :class:`ScheduledEngine`, the engine driven by stamp time (``process``).
"""

from __future__ import annotations

from .compensator import OnlineCompensator
from .config import (
    FIRST_ESTIMATE_ROWS,
    FUSION_FIT_SAMPLES,
    FUSION_REFIT_CHANGE,
    RECONSTRUCT_FROM,
    RECONSTRUCTIONS,
    SIGNAL_MODELS,
    EstimateStatus,
    OnlineConfig,
    ReconstructFrom,
)
from .engine import DIAGNOSTICS_PERIOD_S, Engine
from .health import Health, Level, engine_values, format_value
from .pairing import COUNTER_NAMES, PairCounters, PairMatcher, Pairs
from .reconstructors import GasBatch
from .schedule import EngineStep, ScheduledEngine

__all__ = [
    "COUNTER_NAMES",
    "DIAGNOSTICS_PERIOD_S",
    "FIRST_ESTIMATE_ROWS",
    "FUSION_FIT_SAMPLES",
    "FUSION_REFIT_CHANGE",
    "RECONSTRUCTIONS",
    "RECONSTRUCT_FROM",
    "SIGNAL_MODELS",
    "Engine",
    "EngineStep",
    "EstimateStatus",
    "GasBatch",
    "Health",
    "Level",
    "OnlineCompensator",
    "OnlineConfig",
    "PairCounters",
    "PairMatcher",
    "Pairs",
    "ReconstructFrom",
    "ScheduledEngine",
    "engine_values",
    "format_value",
]
