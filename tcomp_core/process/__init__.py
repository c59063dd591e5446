"""Offline processing of recorded bags and CSV files (``tcomp process``).

:func:`process` streams one record through the compensator's engine into a new rosbag2 MCAP bag
or CSV file; :func:`process_many` runs many in worker processes. The bulk Temperature codec,
the chunk reader and the bag writer beneath live in :mod:`tcomp_core.io` (re-exported here:
``TemperatureBatch``, ``decode_payloads``, ``decode_rows``, ``encode``).
"""

from __future__ import annotations

from ..io import TemperatureBatch, decode_payloads, decode_rows, encode
from ..online import EngineStep, ScheduledEngine
from .batch import Outcome, find_inputs, format_summary, process_many, process_one
from .pipeline import ProcessConfig, ProcessResult, process

__all__ = [
    "EngineStep",
    "Outcome",
    "ProcessConfig",
    "ProcessResult",
    "ScheduledEngine",
    "TemperatureBatch",
    "decode_payloads",
    "decode_rows",
    "encode",
    "find_inputs",
    "format_summary",
    "process",
    "process_many",
    "process_one",
]
