"""The published gas temperature from an extended model, causally (issue 16).

:class:`ExtendedOutput` takes the compensator's matched pairs, turns them into the readings
first-order sensors would give (:class:`~tcomp_core.compensation.stream.EquivalentStream`) and
reconstructs those with the compensator's own reconstructor (Eq. 7 or the causal Kalman
filter) at the model's τ, then applies the model's level rule. A delay makes the pairs come
out :attr:`~tcomp_core.compensation.stream.EquivalentStream.latency` samples late, each with its
own stamp; gas already published (by first order, before the switch) is not published again.
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..compensation import OutputModel
from ..compensation.stream import EquivalentStream
from .config import FUSION_FIT_SAMPLES, OnlineConfig
from .kalman import FilterRequest, KalmanReconstructor, build_filter
from .reconstructors import DifferenceReconstructor, GasBatch

__all__ = ["ExtendedOutput", "RecentPairs", "build_output", "longest_stretch"]

_Pairs = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]


def _reconstructor(
    config: OnlineConfig,
    period_s: float,
    taus: tuple[float, float],
    segment: NDArray[np.float64],
) -> DifferenceReconstructor | KalmanReconstructor:
    """The reconstructor ``config`` names at the model's τ, its filter fitted on ``segment``."""
    if config.reconstruction != "kalman":
        return DifferenceReconstructor(config, period_s, taus)
    reconstructor = KalmanReconstructor(config, period_s, taus)
    empty = (np.empty(0, np.int64), np.empty(0), np.empty(0))
    request = FilterRequest(
        period_s, taus, config.signal_model, segment[-FUSION_FIT_SAMPLES:], None, empty
    )
    reconstructor.use(build_filter(request), empty)
    return reconstructor


def build_output(
    model: OutputModel,
    origin_ns: int,
    config: OnlineConfig,
    period_s: float,
    record: _Pairs,
    prime: _Pairs,
) -> ExtendedOutput:
    """An :class:`ExtendedOutput` built and run through the newest pairs ``prime`` (a job).

    Its filters are warm when it takes over; the gas of the priming pairs is not published
    (:attr:`ExtendedOutput.published_until_ns` is the last of them until the caller sets it).
    """
    stamps = prime[0]
    primed_until = int(stamps[-1]) if stamps.size else np.iinfo(np.int64).min
    output = ExtendedOutput(model, origin_ns, config, period_s, record, primed_until)
    if stamps.size >= 2:
        contiguous = np.diff(stamps) * 1e-9 <= config.gap_factor * period_s
        output.reconstruct(*prime, contiguous)
    return output


class ExtendedOutput:
    """Gas temperature of the pairs under an output model.

    Parameters
    ----------
    model : OutputModel
    origin_ns : int
        Stamp of the fitted record's sample 0, ns.
    config : OnlineConfig
        The compensator's settings (``reconstruction``, ``signal_model``, ...).
    period_s : float
        Sample period, s.
    record : (ndarray, ndarray, ndarray)
        Stamps (ns), tc1, tc2 (degrees C) of the fitted record, gap-free: the Kalman filter's
        signal model is fitted to its equivalent readings.
    published_until_ns : int
        Newest gas stamp already published; gas up to it is not published again.

    Attributes
    ----------
    record : (ndarray, ndarray, ndarray)
        The fitted record, as given.
    lost : int
        Pairs dropped at gaps before their equivalent pair was complete.
    since_ns : int or None
        Stamp of the first gas sample published with the model, ns (None before it).
    """

    def __init__(
        self,
        model: OutputModel,
        origin_ns: int,
        config: OnlineConfig,
        period_s: float,
        record: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]],
        published_until_ns: int,
    ) -> None:
        self.model = model
        self.origin_ns = int(origin_ns)
        self.record = record
        self._period = period_s
        self._stream = EquivalentStream(model, period_s, origin_ns)
        stamps, tc1, tc2 = EquivalentStream(model, period_s, origin_ns).push(*record)
        taus = (model.tau1, model.tau2)
        segment = np.column_stack((tc1, tc2))
        self._reconstructor = _reconstructor(config, period_s, taus, segment)
        #: Degrees C added to keep the first-order level (a ``dynamics`` piece; else 0).
        self.level_shift_c = 0.0
        if model.keeps_first_order_level and stamps.size > 10:
            # The same reconstruction of the fitted record with the level-setting effects left
            # first order gives the level to keep (compensation.offline.level_shift_c does
            # the same offline).
            reference = EquivalentStream(model.level_reference(), period_s, origin_ns)
            steps = np.diff(stamps) * 1e-9
            every = np.ones(steps.size, dtype=bool)
            gas = _reconstructor(config, period_s, taus, segment).reconstruct(
                stamps, tc1, tc2, steps, every
            )[0]
            level = _reconstructor(config, period_s, taus, segment).reconstruct(
                stamps, *reference.push(*record)[1:], steps, every
            )[0]
            settled = slice(gas.size // 10, None)  # past the causal filter's start
            self.level_shift_c = float(np.mean(level[settled] - gas[settled]))
        self._previous: tuple[int, float, float] | None = None
        self._last_taken = np.iinfo(np.int64).min
        self._published_until = int(published_until_ns)
        self.lost = 0
        #: Values whose std was widened 2x or more: the readings disagree with the model.
        self.widened = 0
        self.since_ns: int | None = None

    @property
    def published_until_ns(self) -> int:
        """Newest gas stamp published (gas up to it is not published again)."""
        return self._published_until

    @published_until_ns.setter
    def published_until_ns(self, stamp_ns: int) -> None:
        self._published_until = int(stamp_ns)

    @property
    def reconstructor(self) -> DifferenceReconstructor | KalmanReconstructor:
        """The first-order reconstruction of the equivalent readings."""
        return self._reconstructor

    @property
    def tau(self) -> tuple[float, float]:
        """τ1, τ2 (s) of the gas it publishes: the model's."""
        return (self.model.tau1, self.model.tau2)

    @property
    def latency(self) -> int:
        """Samples a gas estimate comes out later than first order's."""
        return self._stream.latency

    @property
    def note(self) -> str:
        """What the Kalman filter's signal model fit could not do ('' when nothing)."""
        reconstructor = self._reconstructor
        return reconstructor.note if isinstance(reconstructor, KalmanReconstructor) else ""

    @property
    def misfit_warning(self) -> str:
        """How far the equivalent readings depart from first order, when material ('' if not)."""
        reconstructor = self._reconstructor
        if isinstance(reconstructor, KalmanReconstructor):
            return reconstructor.misfit_warning
        return ""

    def restart(self, stamps_start_over: bool = False) -> None:
        """Forget the stream: at a gap, or (``stamps_start_over``) a discontinuity of the stamps.

        After a discontinuity the stamps may repeat earlier ones: gas is published again from
        the next pair on.
        """
        self.lost += self._stream.pending
        self._stream.reset()
        self._previous = None
        self._last_taken = np.iinfo(np.int64).min
        if stamps_start_over:
            self._published_until = np.iinfo(np.int64).min

    def reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> GasBatch:
        """Gas of the pairs now complete; ``contiguous[i]``: pair i+1 follows pair i.

        The run may start with the pair taken last time (the compensator links runs so).
        """
        new = np.flatnonzero(stamps > self._last_taken)
        if new.size == 0:
            return GasBatch.empty()
        start = int(new[0])
        if start > 0 and not contiguous[start - 1]:
            self.restart()
        gaps = (np.flatnonzero(~contiguous[start:]) + start + 1).tolist()
        bounds = [start, *gaps, stamps.size]
        parts = []
        for number, (begin, end) in enumerate(itertools.pairwise(bounds)):
            if number:
                self.restart()
            parts.append(self._flush_run(stamps, tc1, tc2, begin, end))
        self._last_taken = int(stamps[-1])
        return GasBatch.concatenate(parts)

    def _flush_run(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        start: int,
        stop: int,
    ) -> GasBatch:
        """Push one gap-free stretch of new pairs and reconstruct what comes out."""
        out_stamps, first, second = self._stream.push(
            stamps[start:stop], tc1[start:stop], tc2[start:stop]
        )
        if out_stamps.size == 0:
            return GasBatch.empty()
        if self._previous is not None:
            out_stamps = np.concatenate(([self._previous[0]], out_stamps))
            first = np.concatenate(([self._previous[1]], first))
            second = np.concatenate(([self._previous[2]], second))
        self._previous = (int(out_stamps[-1]), float(first[-1]), float(second[-1]))
        if out_stamps.size < 2:
            return GasBatch.empty()
        steps_s = np.diff(out_stamps) * 1e-9
        contiguous = np.ones(steps_s.size, dtype=bool)
        gas, variance = self._reconstructor.reconstruct(
            out_stamps, first, second, steps_s, contiguous
        )
        self.widened += self._reconstructor.last_widened
        gas_stamps = out_stamps[:-1]
        fresh = gas_stamps > self._published_until
        if fresh.any():
            self._published_until = int(gas_stamps[fresh][-1])
            if self.since_ns is None:
                self.since_ns = int(gas_stamps[fresh][0])
        return GasBatch(gas_stamps[fresh], gas[fresh] + self.level_shift_c, variance[fresh])


def longest_stretch(columns: Sequence[NDArray], gap_factor: float) -> tuple[NDArray, ...]:
    """The longest run of ``columns`` (stamps first) whose stamp steps are not gaps.

    A gap is a step longer than ``gap_factor`` times the median step.
    """
    steps = np.diff(columns[0])
    if steps.size == 0:
        return tuple(columns)
    breaks = np.flatnonzero(steps > gap_factor * np.median(steps)) + 1
    edges = np.concatenate(([0], breaks, [columns[0].size]))
    longest = int(np.argmax(np.diff(edges)))
    part = slice(int(edges[longest]), int(edges[longest + 1]))
    return tuple(c[part] for c in columns)


class RecentPairs:
    """The newest ``capacity`` pairs with their stamps (and any further columns).

    Parameters
    ----------
    capacity : int
        Pairs kept.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        # Batches of a few pairs each: a deque drops the oldest in O(1).
        self.parts: deque[tuple[NDArray, ...]] = deque()
        self.size = 0

    def add(self, *columns: NDArray) -> None:
        """Append pairs: stamps (ns) then values, shape (M,) each."""
        if not columns[0].size:
            return
        self.parts.append(columns)
        self.size += int(columns[0].size)
        while self.size - self.parts[0][0].size >= self.capacity:
            self.size -= self.parts.popleft()[0].size

    def columns(self) -> list[NDArray]:
        """The kept pairs, oldest first: stamps then the values, shape (n,) each."""
        return [np.concatenate(c)[-self.capacity :] for c in zip(*self.parts, strict=True)]

    def since(self, stamp_ns: int) -> list[NDArray]:
        """The kept pairs stamped at or after ``stamp_ns``, oldest first (columns as above).

        Only the newest batches are joined: the cost follows the pairs asked for, not the
        capacity.
        """
        taken: list[tuple[NDArray, ...]] = []
        for part in reversed(self.parts):
            taken.append(part)
            if part[0][0] <= stamp_ns:
                break
        if not taken:
            return [np.empty(0, np.int64)]
        columns = [np.concatenate(c)[-self.capacity :] for c in zip(*reversed(taken), strict=True)]
        start = int(np.searchsorted(columns[0], stamp_ns))
        return [column[start:] for column in columns]

    def tail(self, count: int) -> list[NDArray]:
        """The newest ``count`` pairs (fewer when fewer are kept), oldest first."""
        count = min(count, self.capacity)
        taken: list[tuple[NDArray, ...]] = []
        held = 0
        for part in reversed(self.parts):
            taken.append(part)
            held += part[0].size
            if held >= count:
                break
        if not taken:
            return [np.empty(0, np.int64)]
        return [np.concatenate(c)[-count:] for c in zip(*reversed(taken), strict=True)]

    def longest(self, gap_factor: float) -> tuple[NDArray, ...]:
        """The longest gap-free stretch (:func:`longest_stretch`)."""
        return longest_stretch(self.columns(), gap_factor)

    def newest(self, gap_factor: float) -> tuple[NDArray, ...]:
        """The stretch after the last gap (all of it without one)."""
        columns = self.columns()
        steps = np.diff(columns[0])
        if steps.size == 0:
            return tuple(columns)
        gaps = np.flatnonzero(steps > gap_factor * np.median(steps))
        start = int(gaps[-1]) + 1 if gaps.size else 0
        return tuple(c[start:] for c in columns)
