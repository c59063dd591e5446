"""Drive the :class:`~.engine.Engine` on a schedule set by the stamps alone (``tcomp process``).

The schedule (what makes ``tcomp process`` reproducible, and equal to the node whose clock reads
the stamp time and whose timers fire on it):

- ``t0`` is the smallest tc1/tc2 stamp of the first samples fed; ``B = round(batch_s * 1e9)``,
  ``P = round(update_period_s * 1e9)`` and ``R = round(report_period_s * 1e9)`` nanoseconds
  (``report_period_s`` defaults to the node's diagnostics period, 1 s).
- Sample ``k`` of any input belongs to batch ``floor((stamp_k - t0) / B)`` (a sample whose batch
  has already run joins the next one to run, as a late message joins the node's next drain).
  A batch runs once both thermocouples have delivered a sample of a later batch (or the input
  has ended): like the node's inbox drain, it hands the batch's tc1 samples to the engine in
  arrival order, then its tc2 samples, and reconstructs the pairs they complete. ``now`` is
  the batch's newest tc1/tc2 stamp ``s``.
- After a batch with ``s`` at or past the next update time ``t0 + j P`` (``j = 1, 2, ...``),
  τ is re-estimated once and the next update time becomes ``t0 + (floor((s - t0) / P) + 1) P``;
  then, in the same way on ``R``, the engine reports its health: one ``/diagnostics`` status
  per second of stamp time, as the node publishes one per second of its clock. Everything in
  a status (window, counters, τ, levels) is what the engine held at ``s``.
- Once τ is known (an accepted estimate or an initial τ), the batches up to and including the
  next one that calls for an update or a report are drained together, as one drain of a node
  whose inbox filled over that time: tc1 samples of all of them, then tc2 samples, one
  reconstruction. A group is cut before a batch that would bring more than the matcher's
  ``queue_size`` samples of one input into it (so no sample is lost to a queue a batch-wise
  drain would not overflow). Nothing observable changes but the floating-point rounding of
  the window's running sums (the drains' chunking), and the engine is called once per update
  instead of once per batch: the per-call costs, not the samples, dominate ``tcomp process``.

With ``B`` dividing ``P`` the estimates fall on the multiples of ``update_period_s`` since the
first sample; results then depend on ``batch_s`` only through the attempts the compensator
makes by itself before its first accepted estimate (every 256 window rows, checked after each
batch). The reading chunks never matter. Where the stamps have a gap longer than a batch, no
batch runs in it: the node would report its sensors silent there, the schedule reports at the
next batch after it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .config import EstimateStatus
from .engine import DIAGNOSTICS_PERIOD_S, Engine
from .health import Health
from .pairing import Pairs
from .reconstructors import GasBatch

__all__ = ["REF", "EngineStep", "ScheduledEngine"]

#: Input index of the optional reference sensor: batched alongside, never paired.
REF = 2

_Samples = tuple[NDArray[np.int64], NDArray[np.float64]]
#: A batch ready to run: samples per input and its newest tc1/tc2 stamp (None: no tc sample).
_Ready = tuple[dict[int, _Samples], int | None]


@dataclass(frozen=True)
class EngineStep:
    """What one drain (a batch, or a group of batches once τ is known) produced.

    Attributes
    ----------
    pairs : Pairs
        Pairs matched in the drain.
    ref : (ndarray of int64, ndarray of float64)
        The reference samples of the drain: stamps (ns) and degrees C (empty without one).
    gas : GasBatch
        Stamps, gas temperature and variance reconstructed in the drain.
    tau : (float, float) or None
        τ1, τ2 (s) the reconstruction of this drain used.
    status : EstimateStatus or None
        The re-estimation made after the drain, if the schedule called for one.
    health : Health or None
        The diagnostic status reported after the drain, if the schedule called for one.
    last_stamp_ns : int
        The drain's newest tc1/tc2 stamp, ns (its ``now``; 0 for reference samples alone).
    """

    pairs: Pairs
    ref: _Samples
    gas: GasBatch
    tau: tuple[float, float] | None
    status: EstimateStatus | None
    health: Health | None
    last_stamp_ns: int


class ScheduledEngine:
    """An :class:`~.engine.Engine` drained on the module's schedule.

    Parameters
    ----------
    engine : Engine
    update_period_s : float
        Re-estimation period in stamp time, seconds (> 0).
    batch_s : float
        Batch length in stamp time, seconds (> 0).
    report_period_s : float
        Period of the health reports in stamp time, seconds (> 0).
    """

    def __init__(
        self,
        engine: Engine,
        *,
        update_period_s: float,
        batch_s: float,
        report_period_s: float = DIAGNOSTICS_PERIOD_S,
    ) -> None:
        for name, value in (
            ("update_period_s", update_period_s),
            ("batch_s", batch_s),
            ("report_period_s", report_period_s),
        ):
            if not value > 0.0:
                raise ValueError(f"{name}={value!r} must be > 0 s")
        self.engine = engine
        self._update_ns = max(1, round(update_period_s * 1e9))
        self._batch_ns = max(1, round(batch_s * 1e9))
        self._report_ns = max(1, round(report_period_s * 1e9))
        self._t0: int | None = None
        self._next_update = 0
        self._next_report = 0
        self._next_batch = 0  # the lowest batch that has not run
        self._held: dict[int, list[_Samples]] = {0: [], 1: [], REF: []}
        self._ready: list[_Ready] = []  # complete batches not yet drained
        self._newest_batch: dict[int, int] = {}  # tc input -> batch of its newest stamp
        #: Re-estimations and health reports made so far.
        self.estimates = 0
        self.reports = 0

    def feed(self, samples: Mapping[int, _Samples]) -> list[EngineStep]:
        """Take samples per input (0 = tc1, 1 = tc2, :data:`REF`) in arrival order.

        Parameters
        ----------
        samples : mapping of int to (ndarray of int64, ndarray of float64)
            Stamps (ns) and degrees C per input, each in arrival order.

        Returns
        -------
        list of EngineStep
            One per drain the samples complete, in order.
        """
        if self._t0 is None:
            firsts = [int(s.min()) for i, (s, _) in samples.items() if i != REF and s.size]
            if not firsts:
                for index, part in samples.items():
                    if part[0].size:
                        self._held[index].append(part)
                return []
            self._t0 = min(firsts)
            self._next_update = self._t0 + self._update_ns
            self._next_report = self._t0 + self._report_ns
        for index, (stamps, values) in samples.items():
            if stamps.size == 0:
                continue
            self._held[index].append((stamps, values))
            if index != REF:
                newest = int((int(stamps.max()) - self._t0) // self._batch_ns)
                self._newest_batch[index] = max(self._newest_batch.get(index, newest), newest)
        if len(self._newest_batch) < 2:
            return []
        return self._run_until(min(self._newest_batch.values()))

    def finish(self) -> list[EngineStep]:
        """Run every batch still held (the end of the input)."""
        if self._t0 is None:
            return []
        return self._run_until(None)

    def _run_until(self, stop: int | None) -> list[EngineStep]:
        """Run the batches below ``stop`` (all with None)."""
        assert self._t0 is not None
        groups: dict[int, dict[int, _Samples]] = {}
        newest: dict[int, int] = {}  # batch -> its newest tc1/tc2 stamp
        for index, parts in self._held.items():
            if not parts:
                continue
            stamps = np.concatenate([p[0] for p in parts]) if len(parts) > 1 else parts[0][0]
            values = np.concatenate([p[1] for p in parts]) if len(parts) > 1 else parts[0][1]
            batch = np.maximum((stamps - self._t0) // self._batch_ns, self._next_batch)
            ready = batch < stop if stop is not None else np.ones(batch.size, bool)
            if not ready.all():
                self._held[index] = [(stamps[~ready], values[~ready])]
                stamps, values, batch = stamps[ready], values[ready], batch[ready]
            else:
                self._held[index] = []
            if stamps.size == 0:
                continue
            if batch.size > 1 and np.any(batch[1:] < batch[:-1]):
                order = np.argsort(batch, kind="stable")
                stamps, values, batch = stamps[order], values[order], batch[order]
            begins = np.concatenate(([0], np.flatnonzero(batch[1:] != batch[:-1]) + 1))
            ends = [*begins[1:].tolist(), batch.size]
            maxima = np.maximum.reduceat(stamps, begins).tolist()
            for begin, end, most in zip(begins.tolist(), ends, maxima, strict=True):
                key = int(batch[begin])
                groups.setdefault(key, {})[index] = (stamps[begin:end], values[begin:end])
                if index != REF:
                    newest[key] = max(newest.get(key, most), most)
        if groups:
            self._next_batch = max(groups) + 1
        self._ready += [(groups[key], newest.get(key)) for key in sorted(groups)]
        return self._drain(final=stop is None)

    def _drain(self, final: bool) -> list[EngineStep]:
        """Run the ready batches, grouped as the module says; keep an incomplete group."""
        steps = []
        ready = self._ready
        limit = self.engine.matcher.queue_size
        while ready:
            end = 0 if self.engine.compensator.tau is None else self._group_end(limit)
            if end is None:
                if not final:
                    break
                end = len(ready) - 1
            group, ready[: end + 1] = ready[: end + 1], []
            lasts = [last for _, last in group if last is not None]
            steps.append(
                self._run(_merge([batch for batch, _ in group]), max(lasts, default=None))
            )
        return steps

    def _group_end(self, limit: int) -> int | None:
        """Index of the last ready batch of the next group (None: not complete yet)."""
        count1 = count2 = 0
        due = min(self._next_update, self._next_report)
        for k, (batch, last) in enumerate(self._ready):
            count1 += batch[0][0].size if 0 in batch else 0
            count2 += batch[1][0].size if 1 in batch else 0
            if k and (count1 > limit or count2 > limit):
                return k - 1
            if last is not None and last >= due:
                return k
        return None

    def _run(self, batch: dict[int, _Samples], last: int | None) -> EngineStep:
        """Drain ``batch`` whose newest tc1/tc2 stamp is ``last`` (None: reference alone)."""
        engine = self.engine
        ref = batch.get(REF, (np.empty(0, np.int64), np.empty(0)))
        if last is None:
            return EngineStep(Pairs.empty(), ref, GasBatch.empty(), None, None, None, 0)
        now = last * 1e-9
        for index in (0, 1):
            if index in batch:
                engine.add_samples(index, *batch[index], now)
        pairs = engine.take_pairs()
        gas = engine.reconstruct(pairs)
        tau = engine.compensator.published_tau
        status = health = None
        assert self._t0 is not None
        if last >= self._next_update:
            status = engine.update_estimate(now)
            self.estimates += 1
            self._next_update = self._t0 + ((last - self._t0) // self._update_ns + 1) * (
                self._update_ns
            )
        if last >= self._next_report:
            health = engine.report(now)
            self.reports += 1
            self._next_report = self._t0 + ((last - self._t0) // self._report_ns + 1) * (
                self._report_ns
            )
        return EngineStep(pairs, ref, gas, tau, status, health, last)


def _merge(group: list[dict[int, _Samples]]) -> dict[int, _Samples]:
    """The batches of a group as one: each input's samples in order."""
    if len(group) == 1:
        return group[0]
    merged: dict[int, _Samples] = {}
    for index in (0, 1, REF):
        parts = [batch[index] for batch in group if index in batch]
        if parts:
            merged[index] = (
                np.concatenate([stamps for stamps, _ in parts]),
                np.concatenate([values for _, values in parts]),
            )
    return merged
