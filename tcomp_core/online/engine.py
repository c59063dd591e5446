"""The online engine: pair matcher, compensator and health, composed once for node and ``process``.

:class:`Engine` takes the samples of each input as they come (:meth:`Engine.add_samples`),
pairs them (:class:`~.pairing.PairMatcher`), reconstructs the gas temperature of the new pairs
(:meth:`Engine.reconstruct`, :class:`~.compensator.OnlineCompensator`), re-estimates τ on
demand (:meth:`Engine.update_estimate`) and reports its health (:meth:`Engine.report`,
:mod:`.health`). Every method that depends on time takes ``now`` in seconds: the compensator
node passes its clock, ``tcomp process`` the stamp time (:mod:`.schedule`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from ..workers import JobRunner
from .compensator import OnlineCompensator
from .config import EstimateStatus, OnlineConfig
from .diagnosis import DiagnosisPolicy
from .extended import RecentPairs
from .health import NO_LATENCY, Health, HealthMonitor, Level
from .pairing import PairCounters, PairMatcher, Pairs
from .reconstructors import GasBatch

__all__ = ["DIAGNOSTICS_PERIOD_S", "Engine", "stale_after_s"]

#: Period of the diagnostics, seconds (as diagnostic_updater's default); the node's timer and
#: the offline schedule's report cadence.
DIAGNOSTICS_PERIOD_S = 1.0
#: Consecutive samples of one input stamped ``discontinuity_s`` behind the last matched stamp
#: that make a discontinuity (one late message is only out of order).
DISCONTINUITY_SAMPLES = 5


def stale_after_s(update_period_s: float) -> float:
    """Age (s) beyond which an accepted estimate is STALE: three updates and a report."""
    return 3.0 * update_period_s + DIAGNOSTICS_PERIOD_S


class Engine:
    """Pairing, compensation and health of one thermocouple pair.

    Parameters
    ----------
    config : OnlineConfig
        The compensator's settings (pairing, timing, estimation, reconstruction).
    runner : JobRunner, optional
        Where the Kalman filter and output models are built (inline by default; the node
        passes a worker process, see :class:`~.compensator.OnlineCompensator`).
    diagnosis_runner : JobRunner, optional
        Where the background diagnoses run (:class:`~.diagnosis.DiagnosisPolicy`; a worker
        process by default, spawned on the first job).
    estimate_runner : JobRunner, optional
        Where τ1, τ2 are re-estimated (inline by default, so an estimate lands at the stamp
        it was asked at; the node passes a :class:`~tcomp_core.workers.ThreadRunner`).
    """

    def __init__(
        self,
        config: OnlineConfig,
        *,
        runner: JobRunner | None = None,
        diagnosis_runner: JobRunner | None = None,
        estimate_runner: JobRunner | None = None,
    ) -> None:
        self.compensator = OnlineCompensator(
            config, runner=runner, estimate_runner=estimate_runner
        )
        #: When the background diagnosis runs and what becomes of its output models.
        self.diagnosis = DiagnosisPolicy(config, diagnosis_runner)
        self.matcher = self._new_matcher(config)
        self._behind = [0, 0]  # per input: trailing samples far behind the last matched stamp
        #: Why the latest message of each input could not be decoded ('' when none failed).
        self.last_malformed = ["", ""]
        self.monitor = HealthMonitor(
            config.silence_timeout_s, stale_after_s(config.update_period_s)
        )
        self._pairs: list[Pairs] = []
        #: Gas samples reconstructed so far.
        self.published = 0

    @staticmethod
    def _new_matcher(config: OnlineConfig) -> PairMatcher:
        return PairMatcher(
            slop_ns=config.slop_ns, queue_size=config.queue_size, valid_range=config.valid_range
        )

    @property
    def config(self) -> OnlineConfig:
        """The engine's settings."""
        return self.compensator.config

    @property
    def recent(self) -> RecentPairs:
        """The newest pairs taken, with their stamps (the compensator's)."""
        return self.compensator.recent

    @property
    def counters(self) -> PairCounters:
        """The pair matcher's counters."""
        return self.matcher.counters

    @property
    def last_status(self) -> EstimateStatus | None:
        """The latest re-estimation."""
        return self.compensator.last_status

    def reconfigure(self, config: OnlineConfig) -> None:
        """Apply new settings: the pair matcher (its counters kept), timing and compensator.

        A new slop, queue size or physical range starts the matcher's queues afresh.
        """
        old = self.compensator.config
        if (config.slop_ns, config.queue_size, config.valid_range) != (
            old.slop_ns,
            old.queue_size,
            old.valid_range,
        ):
            counters = self.matcher.counters
            self.matcher = self._new_matcher(config)
            self.matcher.counters = counters
        self.monitor.stale_after_s = stale_after_s(config.update_period_s)
        self.monitor.silence_timeout_s = config.silence_timeout_s
        self.compensator.reconfigure(config)
        self.diagnosis.reconfigure(config, self.compensator)

    def close(self) -> None:
        """Stop the worker processes (abandoning running jobs)."""
        self.diagnosis.close()
        self.compensator.close()

    def periodic_diagnosis(self, now: float) -> bool:
        """The diagnosis period's tick at ``now`` (s): see :meth:`.DiagnosisPolicy.periodic`."""
        return self.diagnosis.periodic(now, self.compensator)

    def poll_diagnosis(self, now: float) -> None:
        """The report's tick at ``now`` (s): see :meth:`.DiagnosisPolicy.poll`."""
        self.diagnosis.poll(now, self.compensator)

    def malformed(self, index: int, reason: str) -> None:
        """Count a message of input ``index`` that could not be decoded, and why."""
        self.matcher.counters.malformed[index] += 1
        self.last_malformed[index] = reason

    def add_samples(self, index: int, stamps_ns: ArrayLike, values: ArrayLike, now: float) -> None:
        """Take samples of input ``index`` (0 = tc1, 1 = tc2) in arrival order, at ``now`` (s).

        Parameters
        ----------
        index : int
        stamps_ns : array_like of int, shape (n,)
            Stamps, ns.
        values : array_like of float, shape (n,)
            Degrees C (non-finite ones are counted and dropped).
        now : float
            Seconds on the caller's clock.
        """
        stamps = np.asarray(stamps_ns)
        vals = np.asarray(values, dtype=np.float64)
        last = self.matcher.last_matched_ns
        if last is not None and stamps.size and stamps.dtype.kind in "iu":
            limit = last - round(self.compensator.config.discontinuity_s * 1e9)
            if int(stamps.min()) < limit:
                behind = stamps.astype(np.int64, copy=False) < limit
                start = self._discontinuity_start(index, behind)
                if start is not None:
                    self._match(index, stamps[:start], vals[:start], now)
                    self._restart(int(stamps[start]))
                    stamps, vals = stamps[start:], vals[start:]
            else:
                self._behind[index] = 0
        self._match(index, stamps, vals, now)

    def _match(self, index: int, stamps: ArrayLike, values: ArrayLike, now: float) -> None:
        received = self.matcher.counters.received[index]
        pairs = self.matcher.add_batch(index, stamps, values)
        if len(pairs):
            self._pairs.append(pairs)
        if self.matcher.counters.received[index] > received:
            self.monitor.heard(index, now)

    def _discontinuity_start(self, index: int, behind: np.ndarray) -> int | None:
        """Where the run of far-behind samples that makes a discontinuity starts, if one does.

        Updates the count of trailing far-behind samples of input ``index`` otherwise.
        """
        run = self._behind[index]
        for position, far_behind in enumerate(behind.tolist()):
            run = run + 1 if far_behind else 0
            if run >= DISCONTINUITY_SAMPLES:
                self._behind = [0, 0]
                # Samples of the run from earlier calls were dropped as out of order already.
                return max(0, position - DISCONTINUITY_SAMPLES + 1)
        self._behind[index] = run
        return None

    def _restart(self, stamp_ns: int) -> None:
        """Start over from ``stamp_ns`` after a discontinuity: matcher, window, reconstruction."""
        self.matcher.restart()
        dropped = sum(len(pairs) for pairs in self._pairs)
        self.compensator.counters["unreconstructed"] += dropped  # stamped after the jump
        self._pairs = []
        self.compensator.restart()
        counters = self.matcher.counters
        counters.discontinuities += 1
        counters.last_discontinuity_ns = stamp_ns

    def take_pairs(self) -> Pairs:
        """The pairs matched since the last call (and hand them over to the caller)."""
        pairs, self._pairs = Pairs.concatenate(self._pairs), []
        return pairs

    def reconstruct(self, pairs: Pairs | None = None) -> GasBatch:
        """Reconstruct the pairs matched since the last call (or ``pairs``).

        Also takes over a filter or output model built meanwhile
        (:meth:`OnlineCompensator.poll_jobs`).

        Raises
        ------
        DataError
            When the compensator refuses the pairs (:meth:`OnlineCompensator.add_pairs`).
        """
        if pairs is None:
            pairs = self.take_pairs()
        if len(pairs):
            out = self.compensator.add_pairs(pairs.stamps_ns, pairs.tc1, pairs.tc2)
        else:  # a build may land, and the pairs held for it go out, without new pairs
            out = self.compensator.poll_jobs()
        self.published += int(out.stamps_ns.size)
        return out

    def update_estimate(self, now: float) -> EstimateStatus | None:
        """Re-estimate τ1, τ2 at ``now`` (seconds).

        Returns the status of this estimate when it runs inline, else the newest that landed
        (None before any); every landed status is recorded at ``now``.
        """
        status = self.compensator.update_estimate()
        self._record_landed(now)
        return status

    def _record_landed(self, now: float) -> None:
        for status in self.compensator.take_landed():
            self.monitor.estimated(status, now)

    def report(
        self,
        now: float,
        extra: Mapping[str, str] = NO_LATENCY,
        *,
        new_period: bool = True,
    ) -> Health:
        """The diagnostic status at ``now`` (seconds), by default starting a new report period.

        Parameters
        ----------
        now : float
            Seconds on the caller's clock.
        extra : mapping of str to str
            Key-values only the node knows: its publish latency and callback errors
            (:data:`~.health.NO_LATENCY` offline).
        new_period : bool
            Start a new report period (rates and invalid samples count from ``now``).
        """
        self._record_landed(now)
        health = self.monitor.report(
            now,
            engine=self.compensator,
            counters=self.matcher.counters,
            published=self.published,
            max_model_error_pct=self.compensator.config.max_model_error_pct,
            malformed_reasons=self.last_malformed,
            extra={**self.diagnosis.values(now), **extra},
            new_period=new_period,
        )
        suspect = health.values.get("top_suspect", "none")
        status = self.last_status
        if health.level == Level.WARN and status and status.poor_fit and suspect != "none":
            return Health(health.level, f"{health.message}; top suspect: {suspect}", health.values)
        return health
