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

from .compensator import OnlineCompensator
from .config import EstimateStatus, OnlineConfig
from .extended import RecentPairs
from .health import NO_DIAGNOSIS, NO_LATENCY, Health, HealthMonitor
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
        The compensator's settings.
    slop_ns : int
        Largest stamp difference of a pair, ns (0 = exact stamps).
    queue_size : int
        Unmatched samples kept per input.
    update_period_s : float
        Re-estimation period, seconds (sets when an estimate is STALE).
    silence_timeout_s : float
        A sensor silent this long is an ERROR, seconds.
    """

    def __init__(
        self,
        config: OnlineConfig,
        *,
        slop_ns: int = 0,
        queue_size: int = 2000,
        update_period_s: float = 0.5,
        silence_timeout_s: float = 1.0,
    ) -> None:
        self.compensator = OnlineCompensator(config)
        self.matcher = PairMatcher(
            slop_ns=slop_ns, queue_size=queue_size, valid_range=config.valid_range
        )
        self._behind = [0, 0]  # per input: trailing samples far behind the last matched stamp
        #: Why the latest message of each input could not be decoded ('' when none failed).
        self.last_malformed = ["", ""]
        self.monitor = HealthMonitor(silence_timeout_s, stale_after_s(update_period_s))
        self._pairs: list[Pairs] = []
        #: Gas samples reconstructed so far.
        self.published = 0
        #: The newest pairs with their stamps, when kept (:meth:`keep_recent`).
        self.recent: RecentPairs | None = None

    def keep_recent(self, capacity: int) -> None:
        """Keep the newest ``capacity`` pairs with their stamps (0: keep none)."""
        if capacity <= 0:
            self.recent = None
        elif self.recent is None or self.recent.capacity != capacity:
            self.recent = RecentPairs(capacity)

    @property
    def counters(self) -> PairCounters:
        """The pair matcher's counters."""
        return self.matcher.counters

    @property
    def last_status(self) -> EstimateStatus | None:
        """The latest re-estimation."""
        return self.compensator.last_status

    def set_matching(self, slop_ns: int, queue_size: int) -> None:
        """A new pair matcher (its queues and counters start empty)."""
        self.matcher = PairMatcher(
            slop_ns=slop_ns,
            queue_size=queue_size,
            valid_range=self.compensator.config.valid_range,
        )

    def reconfigure(self, config: OnlineConfig) -> None:
        """Apply new compensator settings (and the physical range of the readings)."""
        if config.valid_range != self.compensator.config.valid_range:
            counters = self.matcher.counters
            self.set_matching(self.matcher.slop_ns, self.matcher.queue_size)
            self.matcher.counters = counters
        self.compensator.reconfigure(config)

    def malformed(self, index: int, reason: str) -> None:
        """Count a message of input ``index`` that could not be decoded, and why."""
        self.matcher.counters.malformed[index] += 1
        self.last_malformed[index] = reason

    def set_timing(self, update_period_s: float, silence_timeout_s: float) -> None:
        """New re-estimation period and silence timeout, seconds."""
        self.monitor.stale_after_s = stale_after_s(update_period_s)
        self.monitor.silence_timeout_s = silence_timeout_s

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

        Raises
        ------
        DataError
            When the compensator refuses the pairs (:meth:`OnlineCompensator.add_pairs`).
        """
        if pairs is None:
            pairs = self.take_pairs()
        if self.recent is not None:
            self.recent.add(pairs.stamps_ns, pairs.tc1, pairs.tc2)
        out = self.compensator.add_pairs(pairs.stamps_ns, pairs.tc1, pairs.tc2)
        self.published += int(out.stamps_ns.size)
        return out

    def update_estimate(self, now: float) -> EstimateStatus:
        """Re-estimate τ1, τ2 at ``now`` (seconds)."""
        status = self.compensator.update_estimate()
        self.monitor.estimated(status, now)
        return status

    def report(
        self,
        now: float,
        extra: Mapping[str, str] = NO_DIAGNOSIS | NO_LATENCY,
        *,
        new_period: bool = True,
    ) -> Health:
        """The diagnostic status at ``now`` (seconds), by default starting a new report period.

        Parameters
        ----------
        now : float
            Seconds on the caller's clock.
        extra : mapping of str to str
            Key-values of the node's background diagnosis and latency (offline: none).
        new_period : bool
            Start a new report period (rates and invalid samples count from ``now``).
        """
        return self.monitor.report(
            now,
            engine=self.compensator,
            counters=self.matcher.counters,
            published=self.published,
            max_model_error_pct=self.compensator.config.max_model_error_pct,
            malformed_reasons=self.last_malformed,
            extra=extra,
            new_period=new_period,
        )
