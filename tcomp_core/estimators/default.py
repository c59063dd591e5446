"""The default first-order path's estimate of a record: what ``tcomp estimate`` gives.

The diagnosis and the compensation both measure against it (the τ it publishes, the lines it
takes off), so it lives below both.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import EstimationError
from . import estimate
from .result import Estimate

if TYPE_CHECKING:
    from ..io import Record

__all__ = ["default_estimate"]


def default_estimate(record: Record) -> Estimate | None:
    """The default first-order path's estimate on ``record``; None if it refuses.

    As ``tcomp estimate`` gives it without options: ml-eiv with the noise ratio φ measured
    and the lines one sensor carries alone notched.
    """
    try:
        return estimate(record.tc1, record.tc2, record.dt, phi=None)
    except (EstimationError, ValueError):
        return None
