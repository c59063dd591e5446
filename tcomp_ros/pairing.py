"""Pair the samples of two thermocouple streams by stamp, as ``message_filters`` would.

:class:`PairMatcher` follows the Python ``ApproximateTimeSynchronizer`` of ROS
``message_filters`` restricted to two inputs: every incoming sample is queued on its input, then
the other input's queue is searched for the stamp closest to it; when that stamp lies within
``slop`` the two samples are emitted as a pair and leave their queues. On top of that it adds
what a compensator, which integrates the pairs in time, needs:

* ``slop_ns == 0`` pairs equal stamps only (``message_filters`` compares ``delta < slop`` and
  so never matches with a zero slop; here a pair needs ``|delta| <= slop``);
* the pairs come out strictly increasing in the tc1 stamp and in the tc2 stamp: once a pair is
  emitted, every queued sample older than its input's matched stamp is evicted, and samples that
  arrive later with a stamp at or before that input's last matched stamp are dropped as late;
* a tie between two candidates equally far away goes to the older one;
* every sample is accounted for (:class:`MatchCounters`).

Pure Python (no rclpy) so the matching rules are testable without ROS; the node feeds it the
``header.stamp`` of each ``sensor_msgs/Temperature`` in integer nanoseconds.
"""

from __future__ import annotations

import math
import operator
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from tcomp_core.errors import DataError

__all__ = ["INPUT_NAMES", "MatchCounters", "Pair", "PairMatcher"]

#: Names of the two inputs, in index order.
INPUT_NAMES = ("tc1", "tc2")

#: One matched sample pair: (tc1 stamp in ns, tc1 value, tc2 value).
Pair = tuple[int, float, float]


@dataclass
class MatchCounters:
    """What became of every sample offered to a :class:`PairMatcher`.

    For each matcher, summed over both inputs,
    ``sum(received) == 2 * matched + unmatched + duplicates + late + sum(pending())``.

    Attributes
    ----------
    received : list of int, length 2
        Samples offered per input, ``[tc1, tc2]``, whatever became of them.
    matched : int
        Pairs emitted (each uses one sample of each input).
    unmatched : int
        Samples evicted without a partner: older than the matched stamp of an emitted pair on
        their input, or the oldest of a queue that grew beyond ``queue_size``.
    duplicates : int
        Samples dropped because a sample with the same stamp was already queued on that input.
    late : int
        Samples dropped because their stamp is at or before the last matched stamp on their
        input: they arrived after a later pair had been emitted.
    """

    received: list[int] = field(default_factory=lambda: [0, 0])
    matched: int = 0
    unmatched: int = 0
    duplicates: int = 0
    late: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counters as a flat mapping.

        Returns
        -------
        dict of str to int
            Keys ``received_tc1``, ``received_tc2``, ``matched``, ``unmatched``, ``duplicates``
            and ``late``.
        """
        return {
            "received_tc1": self.received[0],
            "received_tc2": self.received[1],
            "matched": self.matched,
            "unmatched": self.unmatched,
            "duplicates": self.duplicates,
            "late": self.late,
        }


def _integer(name: str, value: object) -> int:
    try:
        return operator.index(value)  # int, numpy integers; refuses floats and strings
    except TypeError:
        raise DataError(f"{name} must be an integer, got {value!r}") from None


class PairMatcher:
    """Match the samples of tc1 (input 0) and tc2 (input 1) whose stamps lie within a slop.

    Parameters
    ----------
    slop_ns : int, optional
        Largest stamp difference of a pair, ns, ``>= 0``; 0 (the default) pairs equal stamps
        only.
    queue_size : int, optional
        Unmatched samples kept per input, ``>= 1``; beyond it the oldest is evicted.

    Raises
    ------
    DataError
        (a ``ValueError``) when ``slop_ns < 0``, ``queue_size < 1`` or either is not an integer.

    Attributes
    ----------
    counters : MatchCounters
        Cumulative accounting of every sample offered since construction or :meth:`reset`.

    Notes
    -----
    On each sample of input ``i`` with stamp ``s``:

    1. ``s`` at or before the last matched stamp of input ``i``: dropped, counted ``late``;
    2. ``s`` already queued on input ``i``: dropped, counted ``duplicates``;
    3. otherwise queued; the other input's queue is searched for the stamp ``r`` closest to
       ``s`` (ties to the older), and if ``|s - r| <= slop_ns`` the pair is emitted, both samples
       leave their queues and every queued sample older than its input's matched stamp is
       evicted (counted ``unmatched``): it could only pair out of order;
    4. a queue longer than ``queue_size`` loses its oldest sample (counted ``unmatched``).

    Each queue is a sorted Python list of stamps with a parallel list of values, holding only
    stamps after the input's last matched stamp. After every call no queued tc1 sample lies
    within the slop of a queued tc2 sample (the later of the two would have found the other).

    Complexity: an in-order sample (the common case) is appended in amortised O(1) and its
    partner found with one bisection, O(log n) for ``n`` queued samples on the other input.
    An out-of-order sample, an eviction or a match far into a queue moves list items, O(n)
    ``memmove`` bounded by ``queue_size``; each sample is evicted at most once. Memory is
    O(``queue_size``) per input.

    Examples
    --------
    >>> matcher = PairMatcher(slop_ns=100)
    >>> matcher.add(0, 1_000, 20.5)
    []
    >>> matcher.add(1, 1_040, 21.0)
    [(1000, 20.5, 21.0)]
    >>> matcher.counters.as_dict()["matched"]
    1
    """

    def __init__(self, slop_ns: int = 0, queue_size: int = 1000) -> None:
        slop_ns = _integer("slop_ns", slop_ns)
        queue_size = _integer("queue_size", queue_size)
        if slop_ns < 0:
            raise DataError(f"slop_ns must be >= 0 ns, got {slop_ns}")
        if queue_size < 1:
            raise DataError(f"queue_size must be >= 1, got {queue_size}")
        self._slop = slop_ns
        self._queue_size = queue_size
        self.counters = MatchCounters()
        self._stamps: tuple[list[int], list[int]] = ([], [])
        self._values: tuple[list[float], list[float]] = ([], [])
        self._last: list[float] = [-math.inf, -math.inf]

    @property
    def slop_ns(self) -> int:
        """Largest stamp difference of a pair, ns."""
        return self._slop

    @property
    def queue_size(self) -> int:
        """Unmatched samples kept per input."""
        return self._queue_size

    def add(self, index: int, stamp_ns: int, value: float) -> list[Pair]:
        """Offer one sample of input `index` (0 = tc1, 1 = tc2).

        Parameters
        ----------
        index : int
            0 for tc1, 1 for tc2.
        stamp_ns : int
            The sample's stamp, ns.
        value : float
            The sample's value (passed through untouched).

        Returns
        -------
        list of (int, float, float)
            The pairs completed, as ``(stamp_ns_of_tc1, tc1_value, tc2_value)`` in increasing
            stamp order: empty or one pair.

        Raises
        ------
        DataError
            (a ``ValueError``) when `index` is neither 0 nor 1.
        """
        if index != 0 and index != 1:
            raise DataError(f"input index must be 0 (tc1) or 1 (tc2), got {index!r}")
        counters = self.counters
        counters.received[index] += 1
        if stamp_ns <= self._last[index]:
            counters.late += 1
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
                del own[: position + 1], own_values[: position + 1]
                del other[: match + 1], other_values[: match + 1]
                counters.unmatched += position + match
                counters.matched += 1
                self._last[index] = stamp_ns
                self._last[1 - index] = other_stamp
                if index == 0:
                    return [(stamp_ns, value, value_other)]
                return [(other_stamp, value_other, value)]

        if len(own) > self._queue_size:
            del own[0], own_values[0]
            counters.unmatched += 1
        return []

    def add_many(
        self, index: int, stamps_ns: Sequence[int], values: Sequence[float]
    ) -> list[Pair]:
        """Offer several samples of input `index`, in the given (arrival) order.

        Parameters
        ----------
        index : int
            0 for tc1, 1 for tc2.
        stamps_ns : sequence of int, shape (n,)
            The samples' stamps, ns; a numpy array must have an integer dtype.
        values : sequence of float, shape (n,)
            The samples' values.

        Returns
        -------
        list of (int, float, float)
            The pairs completed, as ``(stamp_ns_of_tc1, tc1_value, tc2_value)`` in increasing
            stamp order.

        Raises
        ------
        DataError
            (a ``ValueError``) when `index` is neither 0 nor 1, the lengths differ or the
            stamps are not integers.
        """
        if index != 0 and index != 1:
            raise DataError(f"input index must be 0 (tc1) or 1 (tc2), got {index!r}")
        if isinstance(stamps_ns, np.ndarray):
            if stamps_ns.dtype.kind not in "iu":
                raise DataError(f"stamps_ns must be integer nanoseconds, got {stamps_ns.dtype}")
            stamps_ns = stamps_ns.tolist()
        if isinstance(values, np.ndarray):
            values = values.tolist()
        if len(stamps_ns) != len(values):
            raise DataError(
                f"{INPUT_NAMES[index]}: {len(stamps_ns)} stamps but {len(values)} values"
            )
        pairs: list[Pair] = []
        add = self.add
        for stamp, value in zip(stamps_ns, values, strict=True):
            completed = add(index, stamp, value)
            if completed:
                pairs.extend(completed)
        return pairs

    def pending(self) -> tuple[int, int]:
        """Queued, still unmatched samples per input.

        Returns
        -------
        tuple of (int, int)
            ``(tc1, tc2)``.
        """
        return len(self._stamps[0]), len(self._stamps[1])

    def reset(self) -> None:
        """Return to the freshly constructed state: empty queues, no ordering, zero counters.

        For a jump back in time (a replayed bag starting over, for example), after which the
        late rule would otherwise drop every sample. The queued samples are discarded without
        being counted, and :attr:`counters` is zeroed in place.
        """
        for queue in (*self._stamps, *self._values):
            queue.clear()
        self._last[:] = [-math.inf, -math.inf]
        counters = self.counters
        counters.received[:] = [0, 0]
        counters.matched = counters.unmatched = counters.duplicates = counters.late = 0

    def __repr__(self) -> str:
        return (
            f"PairMatcher(slop_ns={self._slop}, queue_size={self._queue_size}, "
            f"pending={self.pending()}, counters={self.counters})"
        )
