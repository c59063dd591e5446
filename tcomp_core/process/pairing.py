"""Streaming exact-stamp pairing of tc1 and tc2 (and an optional reference) for offline runs.

Samples arrive topic by topic in chunks, roughly in stamp order. Each topic's pending samples
are kept sorted; the *horizon* is the newest stamp both thermocouples have reached. Pending
samples up to the horizon are final: a tc1 and a tc2 sample with identical ``header.stamp``
make a pair (as :func:`tcomp_core.io.read_bag` pairs them), the reference value with that
stamp is attached (NaN when there is none), and the rest is counted as unmatched and dropped,
like the node's pair matcher does. A sample at or before a stamp already paired arrives too
late (``out_of_order``), a repeated stamp is a duplicate, a non-finite temperature is invalid;
all are dropped and counted, and the first of each kind is remembered for the warning.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["Pairs", "StampPairer"]

_ROLES = ("tc1", "tc2", "ref")


@dataclass(frozen=True)
class Pairs:
    """Matched samples in increasing stamp order.

    Attributes
    ----------
    stamps_ns : ndarray of int64, shape (M,)
    tc1, tc2 : ndarray of float64, shape (M,)
        Degrees C.
    ref : ndarray of float64, shape (M,)
        Degrees C; NaN where the reference has no sample with that stamp.
    """

    stamps_ns: NDArray[np.int64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    ref: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamps_ns.size)


@dataclass
class _Pending:
    stamps: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))
    values: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    seen: bool = False


class StampPairer:
    """Pair samples of ``tc1`` and ``tc2`` (roles) with identical stamps, chunk by chunk."""

    def __init__(self) -> None:
        self._pending = {role: _Pending() for role in _ROLES}
        self._last = np.iinfo(np.int64).min  # newest stamp handed out
        self.counters = {
            "matched": 0,
            "unmatched_tc1": 0,
            "unmatched_tc2": 0,
            "out_of_order": 0,
            "duplicates": 0,
            "invalid_tc1": 0,
            "invalid_tc2": 0,
        }
        #: First dropped sample of each kind: counter name -> stamp (ns).
        self.first_dropped: dict[str, int] = {}

    def _count(self, name: str, stamps: NDArray[np.int64]) -> None:
        if stamps.size:
            self.counters[name] += int(stamps.size)
            self.first_dropped.setdefault(name, int(stamps[0]))

    def add(self, role: str, stamps_ns: NDArray[np.int64], values: NDArray[np.float64]) -> None:
        """Queue samples of ``role`` ('tc1', 'tc2' or 'ref'): stamps (ns) and degrees C."""
        pending = self._pending[role]
        pending.seen = True
        if stamps_ns.size == 0:
            return
        if role != "ref":
            finite = np.isfinite(values)
            if not finite.all():
                self._count(f"invalid_{role}", stamps_ns[~finite])
                stamps_ns, values = stamps_ns[finite], values[finite]
        late = stamps_ns <= self._last
        if late.any():
            if role != "ref":  # a reference sample too late for its pair is just not attached
                self._count("out_of_order", stamps_ns[late])
            stamps_ns, values = stamps_ns[~late], values[~late]
        stamps = np.concatenate((pending.stamps, stamps_ns))
        merged = np.concatenate((pending.values, values))
        if stamps.size > 1 and np.any(stamps[1:] <= stamps[:-1]):
            order = np.argsort(stamps, kind="stable")
            stamps, merged = stamps[order], merged[order]
            repeated = np.concatenate(([False], stamps[1:] == stamps[:-1]))
            if repeated.any():
                if role != "ref":
                    self._count("duplicates", stamps[repeated])
                stamps, merged = stamps[~repeated], merged[~repeated]
        pending.stamps, pending.values = stamps, merged

    def pop(self, final: bool = False) -> Pairs:
        """The pairs that can no longer change; with ``final`` every pending sample is settled."""
        present = [p for role, p in self._pending.items() if p.seen and role != "ref"]
        if len(present) < 2 and not final:
            return _empty()
        if final:
            horizon = np.iinfo(np.int64).max
        else:
            if not all(p.stamps.size for p in present):
                return _empty()  # a thermocouple with nothing pending holds the horizon back
            horizon = int(min(p.stamps[-1] for p in present))
        taken = {}
        for role, pending in self._pending.items():
            count = int(np.searchsorted(pending.stamps, horizon, side="right"))
            taken[role] = (pending.stamps[:count], pending.values[:count])
            pending.stamps, pending.values = pending.stamps[count:], pending.values[count:]
        (s1, v1), (s2, v2), (sr, vr) = taken["tc1"], taken["tc2"], taken["ref"]
        common, i1, i2 = np.intersect1d(s1, s2, assume_unique=True, return_indices=True)
        for role, stamps, used in (("tc1", s1, i1), ("tc2", s2, i2)):
            if used.size != stamps.size:
                keep = np.ones(stamps.size, bool)
                keep[used] = False
                self._count(f"unmatched_{role}", stamps[keep])
        ref = np.full(common.size, np.nan)
        if sr.size and common.size:
            at = np.clip(np.searchsorted(sr, common), 0, sr.size - 1)
            hit = sr[at] == common
            ref[hit] = vr[at[hit]]
        if common.size:
            self._last = int(common[-1])
        self.counters["matched"] += int(common.size)
        return Pairs(common, v1[i1], v2[i2], ref)


def _empty() -> Pairs:
    return Pairs(np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0))
