"""Drive :class:`~tcomp_core.online.OnlineCompensator` on a schedule set by the stamps alone.

The schedule (what makes ``tcomp process`` reproducible, and equal to the node fed the same
batches):

- ``t0`` is the stamp of the first matched pair; ``B = round(batch_s * 1e9)`` and
  ``P = round(update_period_s * 1e9)`` nanoseconds.
- Pair ``k`` belongs to batch ``floor((stamp_k - t0) / B)``. Each non-empty batch is given to
  :meth:`~tcomp_core.online.OnlineCompensator.add_pairs` whole, in stamp order, once a later
  pair (or the end of the input) shows it is complete.
- After a batch whose last stamp ``s`` has reached the next update time ``t0 + j P``
  (``j = 1, 2, ...``), :meth:`~tcomp_core.online.OnlineCompensator.update_estimate` is called
  once and the next update time becomes ``t0 + (floor((s - t0) / P) + 1) P``.

With ``B`` dividing ``P`` the estimates fall exactly on the multiples of ``update_period_s``
since the first pair; results then depend on ``batch_s`` only through the attempts the
compensator makes by itself before its first accepted estimate (every 256 window rows, checked
after each batch). The reading chunks never matter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..online import EstimateStatus, OnlineCompensator, OnlineConfig

__all__ = ["EngineStep", "ScheduledEngine"]


@dataclass(frozen=True)
class EngineStep:
    """What one batch produced.

    Attributes
    ----------
    stamps_ns : ndarray of int64, shape (R,)
        Stamps of the reconstructed samples.
    gas : ndarray of float64, shape (R,)
        Gas temperature, degrees C.
    variance : ndarray of float64, shape (R,)
        Its variance, degrees C squared (0 = unknown).
    tau : (float, float) or None
        τ1, τ2 (s) the reconstruction of this batch used.
    status : EstimateStatus or None
        The re-estimation made after the batch, if the schedule called for one.
    last_stamp_ns : int
        Stamp of the batch's last pair.
    """

    stamps_ns: NDArray[np.int64]
    gas: NDArray[np.float64]
    variance: NDArray[np.float64]
    tau: tuple[float, float] | None
    status: EstimateStatus | None
    last_stamp_ns: int


class ScheduledEngine:
    """An :class:`OnlineCompensator` fed batch by batch on the module's schedule.

    Parameters
    ----------
    config : OnlineConfig
        Settings of the compensator.
    update_period_s : float
        Re-estimation period in stamp time, seconds (> 0).
    batch_s : float
        Batch length in stamp time, seconds (> 0).
    """

    def __init__(self, config: OnlineConfig, update_period_s: float, batch_s: float) -> None:
        if not update_period_s > 0.0:
            raise ValueError(f"{update_period_s=} must be > 0 s")
        if not batch_s > 0.0:
            raise ValueError(f"{batch_s=} must be > 0 s")
        self.compensator = OnlineCompensator(config)
        self._update_ns = max(1, round(update_period_s * 1e9))
        self._batch_ns = max(1, round(batch_s * 1e9))
        self._t0: int | None = None
        self._next_update = 0
        self._held: list[tuple[NDArray, NDArray, NDArray]] = []
        self._held_batch = -1
        self.estimates = 0

    def feed(
        self, stamps_ns: NDArray[np.int64], tc1: NDArray[np.float64], tc2: NDArray[np.float64]
    ) -> list[EngineStep]:
        """Take pairs in increasing stamp order; run every batch they complete."""
        if stamps_ns.size == 0:
            return []
        if self._t0 is None:
            self._t0 = int(stamps_ns[0])
            self._next_update = self._t0 + self._update_ns
        batch = (stamps_ns - self._t0) // self._batch_ns
        bounds = np.flatnonzero(np.diff(batch)) + 1
        steps = []
        for begin, end in zip((0, *bounds), (*bounds, stamps_ns.size), strict=True):
            if self._held and int(batch[begin]) != self._held_batch:
                steps.append(self._run_held())
            self._held.append((stamps_ns[begin:end], tc1[begin:end], tc2[begin:end]))
            self._held_batch = int(batch[begin])
        return steps

    def finish(self) -> list[EngineStep]:
        """Run the last, incomplete batch."""
        return [self._run_held()] if self._held else []

    def _run_held(self) -> EngineStep:
        stamps, tc1, tc2 = (np.concatenate(parts) for parts in zip(*self._held, strict=True))
        self._held = []
        out_stamps, gas = self.compensator.add_pairs(stamps, tc1, tc2)
        variance = self.compensator.last_variance
        tau = self.compensator.tau
        last = int(stamps[-1])
        status = None
        if last >= self._next_update:
            assert self._t0 is not None
            status = self.compensator.update_estimate()
            self.estimates += 1
            self._next_update = (
                self._t0 + ((last - self._t0) // self._update_ns + 1) * self._update_ns
            )
        return EngineStep(out_stamps, gas, variance, tau, status, last)
