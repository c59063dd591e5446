"""Offline processing of recorded bags and CSV files (``tcomp process``).

:func:`process` streams one record through the compensator's engine
(:mod:`tcomp_core.online`) into a new rosbag2 MCAP bag or CSV file; :func:`process_many` runs
many in worker processes. The codec, the chunk reader and the bag writer beneath are those of
:mod:`tcomp_core.io`.
"""

from __future__ import annotations

from .batch import Outcome, find_inputs, format_summary, process_many, process_one
from .pipeline import ProcessConfig, ProcessResult, process

__all__ = [
    "Outcome",
    "ProcessConfig",
    "ProcessResult",
    "find_inputs",
    "format_summary",
    "process",
    "process_many",
    "process_one",
]
