"""Pair the samples of two thermocouple streams by stamp: one matcher for the node and ``process``.

:class:`PairMatcher` follows the Python ``ApproximateTimeSynchronizer`` of ROS
``message_filters`` restricted to two inputs: every incoming sample is queued on its input, then
the other input's queue is searched for the stamp closest to it; when that stamp lies within
``slop`` the two samples are emitted as a pair and leave their queues. On top of that it adds
what a compensator, which integrates the pairs in time, needs:

* ``slop_ns == 0`` pairs equal stamps only (``message_filters`` compares ``delta < slop`` and
  so never matches with a zero slop; here a pair needs ``|delta| <= slop``);
* the pairs come out strictly increasing in the tc1 stamp and in the tc2 stamp: once a pair is
  emitted, every queued sample older than its input's matched stamp is evicted, and samples that
  arrive later with a stamp at or before that input's last matched stamp are dropped as
  out of order;
* a tie between two candidates equally far away goes to the older one;
* values that are not finite or lie outside the physical range (``valid_range``: by default
  below absolute zero or above 2 000 °C) are dropped (``invalid_tc1``, ``invalid_tc2``) before
  they reach a queue;
* every sample is accounted for (:class:`PairCounters`).

Two entry points give the same pairs and counters on the same input: :meth:`PairMatcher.add`
takes one sample, :meth:`PairMatcher.add_batch` the samples of one input in arrival order. The
batch path is vectorised (numpy) for the common case of exact stamps (``slop_ns == 0``) arriving
in increasing order, and falls back to :meth:`~PairMatcher.add`, sample by sample, otherwise.
The node drains its inbox through :meth:`~PairMatcher.add_batch` every few milliseconds;
``tcomp process`` feeds it the samples of each stamp-time batch.
"""

from __future__ import annotations

import math
import operator
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import parameters
from ..errors import DataError
from ..io.screening import VALID_RANGE_C, invalid_readings

__all__ = [
    "COUNTER_NAMES",
    "DEFAULT_VALID_RANGE",
    "INPUT_NAMES",
    "Pair",
    "PairCounters",
    "PairMatcher",
    "Pairs",
]

#: Names of the two inputs, in index order.
INPUT_NAMES = ("tc1", "tc2")

#: One matched sample pair: (tc1 stamp in ns, tc1 value, tc2 value).
Pair = tuple[int, float, float]

#: The counters of :class:`PairCounters`, as :meth:`PairCounters.as_dict` names them (the same
#: names in the node's ``/diagnostics``, ``tcomp process`` output and its summary).
COUNTER_NAMES = (
    "received_tc1",
    "received_tc2",
    "matched",
    "unmatched_tc1",
    "unmatched_tc2",
    "out_of_order",
    "duplicates",
    "invalid_tc1",
    "invalid_tc2",
    "malformed_tc1",
    "malformed_tc2",
    "discontinuities",
)

#: Physical range of a thermocouple reading by default, degrees C: the one every reader uses
#: (:data:`tcomp_core.io.screening.VALID_RANGE_C`).
DEFAULT_VALID_RANGE = VALID_RANGE_C


@dataclass
class PairCounters:
    """What became of every sample offered to a :class:`PairMatcher`.

    For each matcher, summed over both inputs, ``sum(received) == 2 * matched + sum(unmatched)
    + out_of_order + duplicates + sum(invalid) + sum(pending())``.

    Attributes
    ----------
    received : list of int, length 2
        Samples offered per input, ``[tc1, tc2]``, whatever became of them.
    matched : int
        Pairs emitted (each uses one sample of each input).
    unmatched : list of int, length 2
        Samples per input evicted without a partner: older than the matched stamp of an
        emitted pair on their input, or the oldest of a queue that grew beyond ``queue_size``
        (and, after :meth:`PairMatcher.discard_pending`, those left queued at the end).
    out_of_order : int
        Samples dropped because their stamp is at or before the last matched stamp on their
        input: they arrived after a later pair had been emitted.
    duplicates : int
        Samples dropped because a sample with the same stamp was already queued on that input.
    invalid : list of int, length 2
        Samples per input dropped because their value is not finite or lies outside the
        matcher's physical range.
    first_dropped : dict of str to int
        Stamp (ns) of the first sample dropped for each reason, keyed by counter name
        (``unmatched_tc1``, ``out_of_order``, ...), for warnings that name it.
    last_invalid_ns : list of int, length 2
        Stamp of the latest invalid sample per input, ns (0 before the first).
    malformed : list of int, length 2
        Messages per input that could not be decoded (counted by the engine's caller; they
        never reach the matcher and are not in ``received``).
    discontinuities : int
        Times the stamps jumped back so far that the engine restarted (:class:`~.engine.Engine`).
    last_discontinuity_ns : int
        Stamp the latest restart resumed from, ns (0 before the first).
    """

    received: list[int] = field(default_factory=lambda: [0, 0])
    matched: int = 0
    unmatched: list[int] = field(default_factory=lambda: [0, 0])
    out_of_order: int = 0
    duplicates: int = 0
    invalid: list[int] = field(default_factory=lambda: [0, 0])
    first_dropped: dict[str, int] = field(default_factory=dict)
    last_invalid_ns: list[int] = field(default_factory=lambda: [0, 0])
    malformed: list[int] = field(default_factory=lambda: [0, 0])
    discontinuities: int = 0
    last_discontinuity_ns: int = 0

    @property
    def total_unmatched(self) -> int:
        """Samples of both inputs evicted without a partner (the diagnostics' ``unmatched``)."""
        return self.unmatched[0] + self.unmatched[1]

    def as_dict(self) -> dict[str, int]:
        """The counters as a flat mapping keyed by :data:`COUNTER_NAMES`."""
        return {
            "received_tc1": self.received[0],
            "received_tc2": self.received[1],
            "matched": self.matched,
            "unmatched_tc1": self.unmatched[0],
            "unmatched_tc2": self.unmatched[1],
            "out_of_order": self.out_of_order,
            "duplicates": self.duplicates,
            "invalid_tc1": self.invalid[0],
            "invalid_tc2": self.invalid[1],
            "malformed_tc1": self.malformed[0],
            "malformed_tc2": self.malformed[1],
            "discontinuities": self.discontinuities,
        }

    def _dropped(self, name: str, stamp: int) -> None:
        if name not in self.first_dropped:
            self.first_dropped[name] = int(stamp)


@dataclass(frozen=True)
class Pairs:
    """Matched pairs in increasing stamp order.

    Attributes
    ----------
    stamps_ns : ndarray of int64, shape (M,)
        Stamp of each pair's tc1 sample, ns.
    tc1, tc2 : ndarray of float64, shape (M,)
        Degrees C.
    """

    stamps_ns: NDArray[np.int64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamps_ns.size)

    @classmethod
    def empty(cls) -> Pairs:
        """No pairs."""
        return cls(np.empty(0, np.int64), np.empty(0), np.empty(0))

    @classmethod
    def from_tuples(cls, pairs: Sequence[Pair]) -> Pairs:
        """Pairs from ``(stamp_ns, tc1, tc2)`` tuples."""
        if not pairs:
            return cls.empty()
        stamps, tc1, tc2 = zip(*pairs, strict=True)
        return cls(
            np.array(stamps, np.int64), np.array(tc1, np.float64), np.array(tc2, np.float64)
        )

    @classmethod
    def concatenate(cls, parts: Sequence[Pairs]) -> Pairs:
        """One :class:`Pairs` of several, in the given order."""
        parts = [part for part in parts if len(part)]
        if len(parts) <= 1:
            return parts[0] if parts else cls.empty()
        return cls(
            np.concatenate([p.stamps_ns for p in parts]),
            np.concatenate([p.tc1 for p in parts]),
            np.concatenate([p.tc2 for p in parts]),
        )


def _integer(name: str, value: Any) -> int:
    try:
        return operator.index(value)  # int, numpy integers; refuses floats and strings
    except TypeError:
        raise DataError(f"{name} must be an integer, got {value!r}") from None


def _check_index(index: object) -> None:
    if index != 0 and index != 1:
        raise DataError(f"input index must be 0 (tc1) or 1 (tc2), got {index!r}")


class PairMatcher:
    """Match the samples of tc1 (input 0) and tc2 (input 1) whose stamps lie within a slop.

    Parameters
    ----------
    slop_ns : int, optional
        Largest stamp difference of a pair, ns, ``>= 0``; 0 (the default) pairs equal stamps
        only.
    queue_size : int, optional
        Unmatched samples kept per input, ``>= 1``; beyond it the oldest is evicted.
    valid_range : (float, float), optional
        Lowest and highest plausible reading, degrees C (the engine passes its configured
        range, :data:`DEFAULT_VALID_RANGE` by default); None: any finite value.

    Raises
    ------
    DataError
        (a ``ValueError``) when ``slop_ns < 0``, ``queue_size < 1`` or either is not an integer.

    Attributes
    ----------
    counters : PairCounters
        Cumulative accounting of every sample offered since construction or :meth:`reset`.

    Notes
    -----
    On each sample of input ``i`` with stamp ``s`` and value ``v``:

    0. ``v`` not finite, or outside ``valid_range`` if given: dropped, counted ``invalid``;
    1. ``s`` at or before the last matched stamp of input ``i``: dropped, counted
       ``out_of_order``;
    2. ``s`` already queued on input ``i``: dropped, counted ``duplicates``;
    3. otherwise queued; the other input's queue is searched for the stamp ``r`` closest to
       ``s`` (ties to the older), and if ``|s - r| <= slop_ns`` the pair is emitted, both samples
       leave their queues and every queued sample older than its input's matched stamp is
       evicted (counted ``unmatched``): it could only pair out of order;
    4. a queue longer than ``queue_size`` loses its oldest sample (counted ``unmatched``).

    Each queue is a sorted Python list of stamps with a parallel list of values, holding only
    stamps after the input's last matched stamp. A batch queued whole by :meth:`add_batch` into
    an empty queue stays a pair of arrays ("parked") until a call needs the lists, so the usual
    exact in-order stream (all tc1 of a drain, then all tc2) pairs array against array. After
    every call no queued tc1 sample lies within the slop of a queued tc2 sample (the later of
    the two would have found the other).

    Complexity: an in-order sample is appended in amortised O(1) and its partner found with one
    bisection, O(log n) for ``n`` queued samples on the other input. :meth:`add_batch` with
    exact stamps in order costs one ``intersect1d`` per call, O((m + n) log(m + n)) in numpy,
    whatever the number of pairs. Memory is O(``queue_size``) per input.

    Examples
    --------
    >>> matcher = PairMatcher(slop_ns=100)
    >>> matcher.add(0, 1_000, 20.5)
    []
    >>> matcher.add(1, 1_040, 21.0)
    [(1000, 20.5, 21.0)]
    >>> matcher.counters.matched
    1
    """

    def __init__(
        self,
        slop_ns: int = 0,
        queue_size: int = int(parameters.default("queue_size")),
        valid_range: tuple[float, float] | None = None,
    ) -> None:
        slop_ns = _integer("slop_ns", slop_ns)
        queue_size = _integer("queue_size", queue_size)
        if slop_ns < 0:
            raise DataError(f"slop_ns must be >= 0 ns, got {slop_ns}")
        if queue_size < 1:
            raise DataError(f"queue_size must be >= 1, got {queue_size}")
        if valid_range is not None:
            low, high = (float(v) for v in valid_range)
            if not -273.15 <= low < high < math.inf:
                raise DataError(
                    f"valid_range={valid_range!r} must be increasing, finite, from -273.15 °C up"
                )
        self._valid_range = valid_range
        self._slop = slop_ns
        self._queue_size = queue_size
        self.counters = PairCounters()
        self._stamps: tuple[list[int], list[int]] = ([], [])
        self._values: tuple[list[float], list[float]] = ([], [])
        # Per input: a whole queue held as (stamps, values) arrays; the lists are empty then.
        self._parked: list[tuple[NDArray[np.int64], NDArray[np.float64]] | None] = [None, None]
        self._last: list[float] = [-math.inf, -math.inf]

    @property
    def slop_ns(self) -> int:
        """Largest stamp difference of a pair, ns."""
        return self._slop

    @property
    def queue_size(self) -> int:
        """Unmatched samples kept per input."""
        return self._queue_size

    # -- one sample ----------------------------------------------------------------------------
    def add(self, index: int, stamp_ns: int, value: float) -> list[Pair]:
        """Offer one sample of input ``index`` (0 = tc1, 1 = tc2).

        Parameters
        ----------
        index : int
            0 for tc1, 1 for tc2.
        stamp_ns : int
            The sample's stamp, ns.
        value : float
            The sample's value, degrees C (passed through untouched when finite).

        Returns
        -------
        list of (int, float, float)
            The pairs completed, as ``(stamp_ns_of_tc1, tc1_value, tc2_value)``: empty or one.

        Raises
        ------
        DataError
            (a ``ValueError``) when ``index`` is neither 0 nor 1.
        """
        _check_index(index)
        self.counters.received[index] += 1
        valid = self._valid_range
        if not (math.isfinite(value) if valid is None else valid[0] <= value <= valid[1]):
            self.counters.invalid[index] += 1
            self.counters.last_invalid_ns[index] = stamp_ns
            self.counters._dropped(f"invalid_{INPUT_NAMES[index]}", stamp_ns)
            return []
        return self._offer(index, stamp_ns, value)

    def _unpark(self) -> None:
        """Turn parked queues into the lists every other path works on."""
        for index, parked in enumerate(self._parked):
            if parked is not None:
                self._stamps[index][:] = parked[0].tolist()
                self._values[index][:] = parked[1].tolist()
                self._parked[index] = None

    def _offer(self, index: int, stamp_ns: int, value: float) -> list[Pair]:
        """Rules 1-4 of the class notes for one finite sample (already counted received)."""
        if self._parked[0] is not None or self._parked[1] is not None:
            self._unpark()
        counters = self.counters
        if stamp_ns <= self._last[index]:
            counters.out_of_order += 1
            counters._dropped("out_of_order", stamp_ns)
            return []
        own = self._stamps[index]
        own_values = self._values[index]
        if not own or stamp_ns > own[-1]:  # in order: the common case
            position = len(own)
            own.append(stamp_ns)
            own_values.append(value)
        else:
            position = bisect_left(own, stamp_ns)
            if own[position] == stamp_ns:
                counters.duplicates += 1
                counters._dropped("duplicates", stamp_ns)
                return []
            own.insert(position, stamp_ns)
            own_values.insert(position, value)

        other = self._stamps[1 - index]
        if other:
            slop = self._slop
            found = bisect_left(other, stamp_ns)  # other[found - 1] < stamp_ns <= other[found]
            match = -1
            if found and stamp_ns - other[found - 1] <= slop:
                match = found - 1
            if (
                found < len(other)
                and other[found] - stamp_ns <= slop
                and (match < 0 or other[found] - stamp_ns < stamp_ns - other[match])
            ):
                match = found
            if match >= 0:
                other_values = self._values[1 - index]
                other_stamp = other[match]
                value_other = other_values[match]
                if position:
                    counters._dropped(f"unmatched_{INPUT_NAMES[index]}", own[0])
                if match:
                    counters._dropped(f"unmatched_{INPUT_NAMES[1 - index]}", other[0])
                del own[: position + 1], own_values[: position + 1]
                del other[: match + 1], other_values[: match + 1]
                counters.unmatched[index] += position
                counters.unmatched[1 - index] += match
                counters.matched += 1
                self._last[index] = stamp_ns
                self._last[1 - index] = other_stamp
                if index == 0:
                    return [(stamp_ns, value, value_other)]
                return [(other_stamp, value_other, value)]

        if len(own) > self._queue_size:
            counters._dropped(f"unmatched_{INPUT_NAMES[index]}", own[0])
            del own[0], own_values[0]
            counters.unmatched[index] += 1
        return []

    def add_many(
        self, index: int, stamps_ns: Sequence[int], values: Sequence[float]
    ) -> list[Pair]:
        """Offer several samples of input ``index``, one by one in the given (arrival) order.

        Parameters
        ----------
        index : int
            0 for tc1, 1 for tc2.
        stamps_ns : sequence of int, shape (n,)
            The samples' stamps, ns; a numpy array must have an integer dtype.
        values : sequence of float, shape (n,)
            The samples' values, degrees C.

        Returns
        -------
        list of (int, float, float)
            The pairs completed, as ``(stamp_ns_of_tc1, tc1_value, tc2_value)`` in increasing
            stamp order.

        Raises
        ------
        DataError
            (a ``ValueError``) when ``index`` is neither 0 nor 1, the lengths differ or the
            stamps are not integers.
        """
        _check_index(index)
        stamps, vals = _as_lists(index, stamps_ns, values)
        pairs: list[Pair] = []
        add = self.add
        for stamp, value in zip(stamps, vals, strict=True):
            completed = add(index, stamp, value)
            if completed:
                pairs.extend(completed)
        return pairs

    # -- a batch -------------------------------------------------------------------------------
    def add_batch(self, index: int, stamps_ns: ArrayLike, values: ArrayLike) -> Pairs:
        """Offer the samples of input ``index`` in arrival order; the same as :meth:`add_many`.

        Vectorised when ``slop_ns == 0`` and the finite samples' stamps increase strictly and
        follow the input's queue; sample by sample otherwise. Pairs, counters, queues and
        :attr:`PairCounters.first_dropped` end up exactly as :meth:`add_many` leaves them.

        Parameters
        ----------
        index : int
            0 for tc1, 1 for tc2.
        stamps_ns : array_like of int, shape (n,)
            Stamps, ns (integers).
        values : array_like of float, shape (n,)
            Degrees C.

        Returns
        -------
        Pairs
            The pairs completed, in increasing stamp order.

        Raises
        ------
        DataError
            (a ``ValueError``) when ``index`` is neither 0 nor 1, the lengths differ or the
            stamps are not integers.
        """
        _check_index(index)
        stamps = np.asarray(stamps_ns)
        vals = np.asarray(values, dtype=np.float64)
        if stamps.size and stamps.dtype.kind not in "iu":
            raise DataError(f"stamps_ns must be integer nanoseconds, got {stamps.dtype}")
        stamps = stamps.astype(np.int64, copy=False)
        if stamps.shape != vals.shape or stamps.ndim != 1:
            raise DataError(f"{INPUT_NAMES[index]}: {stamps.size} stamps but {vals.size} values")
        counters = self.counters
        counters.received[index] += int(stamps.size)
        valid = self._valid_range
        if valid is None:
            some_bad = not np.isfinite(vals).all()
        else:  # min/max are NaN if any value is: an all-good batch costs two reductions
            some_bad = bool(vals.size) and not (valid[0] <= vals.min() and vals.max() <= valid[1])
        if some_bad:
            finite = np.isfinite(vals) if valid is None else ~invalid_readings(vals, valid)
            bad = stamps[~finite]
            counters.invalid[index] += int(bad.size)
            counters.last_invalid_ns[index] = int(bad[-1])
            counters._dropped(f"invalid_{INPUT_NAMES[index]}", int(bad[0]))
            stamps, vals = stamps[finite], vals[finite]
        if stamps.size == 0:
            return Pairs.empty()
        last = self._last[index]
        increasing = bool(np.all(stamps[1:] > stamps[:-1]))
        late = 0
        if increasing and last != -math.inf:
            late = int(np.searchsorted(stamps, last, side="right"))
        parked = self._parked[index]
        queue = self._stamps[index]
        own_last = int(parked[0][-1]) if parked is not None else queue[-1] if queue else None
        rest = stamps[late:]
        in_order = (
            self._slop == 0
            and increasing
            and (own_last is None or rest.size == 0 or int(rest[0]) > own_last)
        )
        if not in_order:
            offer = self._offer
            pairs: list[Pair] = []
            for stamp, value in zip(stamps.tolist(), vals.tolist(), strict=True):
                completed = offer(index, stamp, value)
                if completed:
                    pairs.extend(completed)
            return Pairs.from_tuples(pairs)
        if late:
            counters.out_of_order += late
            counters._dropped("out_of_order", int(stamps[0]))
        return self._add_exact_in_order(index, rest, vals[late:])

    def _add_exact_in_order(
        self, index: int, stamps: NDArray[np.int64], values: NDArray[np.float64]
    ) -> Pairs:
        """Rules 3-4 for strictly increasing stamps after the own queue, with a zero slop."""
        counters = self.counters
        if stamps.size == 0:
            return Pairs.empty()
        parked = self._parked[1 - index]
        own_empty = not self._stamps[index] and self._parked[index] is None
        if (
            own_empty
            and parked is not None
            and parked[0].size == stamps.size
            and np.array_equal(parked[0], stamps)
        ):  # the other input queued exactly these stamps: all pair, nothing is left
            counters.matched += stamps.size
            self._last[index] = self._last[1 - index] = int(stamps[-1])
            self._parked[1 - index] = None
            if index == 0:
                return Pairs(stamps, values, parked[1])
            return Pairs(stamps, parked[1], values)
        if (
            own_empty
            and not self._stamps[1 - index]
            and stamps.size <= self._queue_size
            and (parked is None or int(stamps[0]) > int(parked[0][-1]))
        ):  # nothing can pair (the other queue is empty or wholly older, the slop zero): park
            self._parked[index] = (stamps.copy(), values.copy())
            return Pairs.empty()
        self._unpark()
        name, other_name = INPUT_NAMES[index], INPUT_NAMES[1 - index]
        own, own_values = self._stamps[index], self._values[index]
        other, other_values = self._stamps[1 - index], self._values[1 - index]
        common = np.empty(0, np.int64)
        if other:
            other_array = np.array(other, dtype=np.int64)
            common, at_own, at_other = np.intersect1d(
                stamps, other_array, assume_unique=True, return_indices=True
            )
        if common.size == 0:
            own.extend(stamps.tolist())
            own_values.extend(values.tolist())
        else:
            matched = int(common.size)
            last_own, last_other = int(at_own[-1]), int(at_other[-1])
            # Own samples that leave unmatched: the whole old queue and the batch's samples up
            # to the last match that did not match; the other's, its queue up to that match.
            own_gone = len(own) + last_own + 1 - matched
            other_gone = last_other + 1 - matched
            if own_gone and f"unmatched_{name}" not in counters.first_dropped:
                unpaired = np.setdiff1d(
                    np.concatenate((np.array(own, np.int64), stamps[: last_own + 1])),
                    common,
                    assume_unique=True,
                )
                counters._dropped(f"unmatched_{name}", int(unpaired[0]))
            if other_gone and f"unmatched_{other_name}" not in counters.first_dropped:
                unpaired = np.setdiff1d(other_array[: last_other + 1], common, assume_unique=True)
                counters._dropped(f"unmatched_{other_name}", int(unpaired[0]))
            counters.unmatched[index] += own_gone
            counters.unmatched[1 - index] += other_gone
            counters.matched += matched
            other_picked = np.array(other_values[: last_other + 1], np.float64)[at_other]
            own_picked = values[at_own]
            del other[: last_other + 1], other_values[: last_other + 1]
            own[:] = stamps[last_own + 1 :].tolist()
            own_values[:] = values[last_own + 1 :].tolist()
            self._last[index] = self._last[1 - index] = int(common[-1])
        overflow = len(own) - self._queue_size
        if overflow > 0:
            counters._dropped(f"unmatched_{name}", own[0])
            del own[:overflow], own_values[:overflow]
            counters.unmatched[index] += overflow
        if common.size == 0:
            return Pairs.empty()
        if index == 0:
            return Pairs(common, own_picked, other_picked)
        return Pairs(common, other_picked, own_picked)

    # -- state -----------------------------------------------------------------------------------
    def pending(self) -> tuple[int, int]:
        """Queued, still unmatched samples per input, ``(tc1, tc2)``."""
        return tuple(  # type: ignore[return-value]
            len(queue) if parked is None else int(parked[0].size)
            for queue, parked in zip(self._stamps, self._parked, strict=True)
        )

    def discard_pending(self) -> None:
        """Drop the queued samples, counted ``unmatched``: the end of a record."""
        self._unpark()
        for index, name in enumerate(INPUT_NAMES):
            queue = self._stamps[index]
            if queue:
                self.counters._dropped(f"unmatched_{name}", queue[0])
                self.counters.unmatched[index] += len(queue)
                queue.clear()
                self._values[index].clear()

    @property
    def last_matched_ns(self) -> int | None:
        """Stamp of the newest matched sample of either input, ns (None before the first)."""
        last = max(self._last)
        return None if last == -math.inf else int(last)

    def restart(self) -> None:
        """Start over after a discontinuity of the stamps, keeping the counters.

        The queued samples are counted ``unmatched`` (:meth:`discard_pending`) and the ordering
        forgets the last matched stamps, so samples stamped before them pair again.
        """
        self.discard_pending()
        self._last[:] = [-math.inf, -math.inf]

    def reset(self) -> None:
        """Return to the freshly constructed state: empty queues, no ordering, zero counters.

        For a jump back in time (a replayed bag starting over, for example), after which the
        ordering rule would otherwise drop every sample. The queued samples are discarded
        without being counted, and :attr:`counters` is zeroed in place.
        """
        for queue in (*self._stamps, *self._values):
            queue.clear()
        self._parked[:] = [None, None]
        self._last[:] = [-math.inf, -math.inf]
        vars(self.counters).update(vars(PairCounters()))

    def __repr__(self) -> str:
        return (
            f"PairMatcher(slop_ns={self._slop}, queue_size={self._queue_size}, "
            f"pending={self.pending()}, counters={self.counters.as_dict()})"
        )


def _as_lists(
    index: int, stamps_ns: Sequence[int] | NDArray, values: Sequence[float] | NDArray
) -> tuple[list[int], list[float]]:
    if isinstance(stamps_ns, np.ndarray):
        if stamps_ns.size and stamps_ns.dtype.kind not in "iu":
            raise DataError(f"stamps_ns must be integer nanoseconds, got {stamps_ns.dtype}")
        stamps_ns = stamps_ns.tolist()
    if isinstance(values, np.ndarray):
        values = values.tolist()
    if len(stamps_ns) != len(values):
        raise DataError(f"{INPUT_NAMES[index]}: {len(stamps_ns)} stamps but {len(values)} values")
    return list(stamps_ns), list(values)
