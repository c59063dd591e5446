"""The online compensator: matched pairs in, τ estimates and reconstructed gas samples out.

- Matched sample pairs arrive in batches with their stamps (nanoseconds). The sample period is
  learnt from the first stamps (or given); a step longer than ``gap_factor`` periods is a gap,
  and the regression row straddling it is left out of the window.
- The window (:class:`~.estimation.WindowEstimator`) is re-estimated on demand
  (:meth:`OnlineCompensator.update_estimate`); an accepted estimate drives the reconstruction.
  An estimate is accepted when it is well conditioned and pinned down: its 95 % intervals
  within ±:data:`MAX_TAU_INTERVAL` of it, or, for an estimator without intervals, the first
  one within :data:`FIRST_AGREEMENT` of the attempt before it.
- Each new pair k reconstructs the gas temperature at the previous pair's stamp with the latest
  accepted τ: the causal Kalman filter of both sensors (default; :mod:`.kalman`: its signal
  model fitted by a job off the stream, the filter handed over warm) or Eq. (7), optionally
  smoothed by the causal post-filter; or, once an output model is set, its gas
  (:mod:`.extended`, built by a job too).
- Before the first accepted estimate, one is attempted every :data:`~.config.FIRST_ESTIMATE_ROWS`
  window rows, and the pairs are held (up to one window) to be reconstructed once it lands.
- A learnt sample period that the stamps leave (:data:`RATE_CHANGE_STEPS` steps in a row at
  another, common rate) is relearnt: the window, τ, the reconstruction and an output model
  start afresh, as at start-up, and :attr:`OnlineCompensator.rate_note` says so until an
  estimate at the new rate is accepted (the node's status is WARN meanwhile). A configured
  ``sample_period_s`` is kept and the disagreement noted.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..compensation import OutputModel
from ..errors import DataError
from ..estimators.result import MAX_TAU_INTERVAL
from ..fusion import FusionModel
from ..noise import median
from ..validation import MIN_SAMPLES
from ..workers import InlineRunner, JobRunner
from .config import (
    FIRST_ESTIMATE_ROWS,
    FUSION_FIT_SAMPLES,
    PERIOD_LEARNING_SAMPLES,
    EstimateStatus,
    OnlineConfig,
)
from .estimation import WindowEstimator
from .extended import ExtendedOutput, RecentPairs, build_output
from .kalman import (
    PRIME_PAIRS,
    FilterBuild,
    FilterPolicy,
    FilterRequest,
    KalmanReconstructor,
    build_filter,
    interim_build,
)
from .reconstructors import DifferenceReconstructor, GasBatch, PostFilter

__all__ = ["FIRST_AGREEMENT", "MAX_TAU_INTERVAL", "RECENT_S", "OnlineCompensator"]

_Run = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray, NDArray]
_Pairs = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]

#: An estimator without intervals: its first estimate is accepted only within this relative
#: distance of the attempt before it (on a shorter window).
FIRST_AGREEMENT = 0.1
#: The newest pairs kept, seconds (at least :data:`~.kalman.PRIME_PAIRS`): a built filter or
#: output model catches up through the pairs that came while its job ran, and the background
#: diagnosis fits the newest stretch of them.
RECENT_S = 60.0
#: Landed estimate statuses kept for :meth:`OnlineCompensator.take_landed`.
LANDED_KEPT = 16
#: A learnt sample period is relearnt when this many steps in a row are off it by more than
#: :data:`RATE_TOLERANCE` and agree with each other (a sensor driver switched rate or was
#: restarted at another): a few hundredths of a second at the rates of a test cell.
RATE_CHANGE_STEPS = 64
#: Relative difference of a step from the period that counts as another rate.
RATE_TOLERANCE = 0.25


class OnlineCompensator:
    """Sliding-window τ estimation and causal gas temperature reconstruction.

    Parameters
    ----------
    config : OnlineConfig
    initial_tau : (float, float), optional
        Time constants to reconstruct with before the first accepted estimate, seconds.
    runner : JobRunner, optional
        Where the Kalman filter and the output models are built: inline by default (results
        land at once, as ``tcomp process`` needs); a
        :class:`~tcomp_core.workers.ProcessRunner` keeps the fits off a real-time caller.

    Attributes
    ----------
    counters : dict of str to int
        ``pairs`` taken, ``gaps`` seen, ``reconstructed`` and ``unreconstructed`` pairs.
    last_status : EstimateStatus or None
        The latest re-estimation.
    recent : RecentPairs
        The newest pairs taken (stamps ns, tc1, tc2), :data:`RECENT_S` seconds of them.
    """

    def __init__(
        self,
        config: OnlineConfig | None = None,
        initial_tau: tuple[float, float] | None = None,
        runner: JobRunner | None = None,
        estimate_runner: JobRunner | None = None,
    ) -> None:
        self._config = config or OnlineConfig()
        self._tau = initial_tau
        #: φ the accepted estimate was made with (measured when ``phi`` is 0; None before one).
        self._phi: float | None = None
        self._period: float | None = self._config.sample_period_s or None
        self._estimator: WindowEstimator | None = None
        self._reconstructor: DifferenceReconstructor | KalmanReconstructor | None = None
        self._postfilter: PostFilter | None = None
        # Batches (stamps, tc1, tc2) seen while the sample period is learnt.
        self._learning: list[tuple[NDArray[np.int64], NDArray, NDArray]] = []
        self._previous: tuple[int, float, float] | None = None
        self._newest_stamp = 0
        self._restarted = False  # the next pair need not follow _newest_stamp
        self.last_status: EstimateStatus | None = None
        self._last_attempt: tuple[float, float] | None = None  # before the first acceptance
        self.counters = {"pairs": 0, "gaps": 0, "reconstructed": 0, "unreconstructed": 0}
        # Pairs that arrived before the first τ: (stamps, tc1, tc2, steps_s, contiguous).
        self._backlog: list[_Run] = []
        self._backlog_rows = 0
        self._next_first_attempt = FIRST_ESTIMATE_ROWS
        self._extended: ExtendedOutput | None = None
        # An output model set before the period was known; one being built.
        self._pending_output: tuple[OutputModel, int, _Pairs] | None = None
        self._building_output: tuple[OutputModel, int, _Pairs] | None = None
        self._published_until = np.iinfo(np.int64).min  # newest gas stamp given out
        self._reconstructed_until: int | None = None  # newest pair a reconstructor took
        self.recent = RecentPairs(PRIME_PAIRS)
        # Jobs: the one running ('filter' or 'output') and what waits for the runner.
        self._runner: JobRunner = runner if runner is not None else InlineRunner()
        self._running = ""
        # Re-estimations of τ: inline by default; a thread keeps them off a node's executor.
        self._estimates: JobRunner = (
            estimate_runner if estimate_runner is not None else InlineRunner()
        )
        #: Statuses of the :meth:`update_estimate` jobs that landed since :meth:`take_landed`
        #: (the newest few: a caller that never takes them must not accumulate them).
        self._landed: deque[EstimateStatus] = deque(maxlen=LANDED_KEPT)
        self._asked = False  # whether the running estimate was asked by update_estimate
        self._building_for: KalmanReconstructor | None = None  # of the filter build running
        self._wanted_filter = ""  # 'refit' or 'retune' waiting for the runner
        self._wanted_output: tuple[OutputModel, int, _Pairs] | None = None
        #: Why the published gas is first order although output models were asked for, or
        #: what the caller last decided about the output model ('' when nothing to say).
        self.output_note = ""
        #: The newest steps between pairs (ns), to notice a change of rate.
        self._steps: deque[int] = deque(maxlen=RATE_CHANGE_STEPS)
        #: A change of the inputs' rate not yet followed by an accepted estimate ('' when none).
        self.rate_note = ""
        self.rate_changes = 0
        #: Gas values published with a std widened 2x or more: the readings disagreed with the
        #: filter's model (:mod:`tcomp_core.fusion.consistency`).
        self.widened = 0

    # -- state ---------------------------------------------------------------------------------
    @property
    def config(self) -> OnlineConfig:
        """Current settings."""
        return self._config

    @property
    def held_pairs(self) -> int:
        """Pairs held for the first τ or the first Kalman filter, not reconstructed yet."""
        return self._backlog_rows

    @property
    def period_s(self) -> float | None:
        """Sample period in seconds, once known."""
        return self._period

    @property
    def tau(self) -> tuple[float, float] | None:
        """The accepted first-order estimate (τ1, τ2) in seconds, once known."""
        return self._tau

    @property
    def published_tau(self) -> tuple[float, float] | None:
        """τ1, τ2 (s) of the model that produces the published gas.

        The output model's while one is in use, else the Kalman filter's (built for an
        accepted τ, it follows the estimate within :data:`~.kalman.FUSION_RETUNE_CHANGE`), else
        Eq. (7)'s: the accepted estimate.
        """
        if self._extended is not None:
            return self._extended.tau
        reconstructor = self._reconstructor
        if isinstance(reconstructor, KalmanReconstructor):
            return reconstructor.tau
        return self._tau

    @property
    def reconstruction(self) -> str:
        """What makes the published gas: 'kalman' (a filter is in use) or 'difference'."""
        reconstructor = self._reconstructor
        if self._extended is not None:
            reconstructor = self._extended.reconstructor
        if isinstance(reconstructor, KalmanReconstructor) and reconstructor.model is not None:
            return "kalman"
        return "difference"

    @property
    def fusion_model(self) -> FusionModel | None:
        """The first-order Kalman filter's signal model in use (None without one)."""
        reconstructor = self._reconstructor
        return reconstructor.model if isinstance(reconstructor, KalmanReconstructor) else None

    @property
    def signal_model_name(self) -> str:
        """The signal model of the published gas ('' for Eq. (7); '(interim)' while it is)."""
        reconstructor = self._reconstructor
        if self._extended is not None:
            reconstructor = self._extended.reconstructor
        if not isinstance(reconstructor, KalmanReconstructor) or reconstructor.model is None:
            return ""
        kind = reconstructor.model.kind
        return f"{kind} (interim)" if reconstructor.interim else kind

    @property
    def fusion_note(self) -> str:
        """What the signal model's fit could not do and what is used instead ('' when nothing)."""
        if self._extended is not None:
            return self._extended.note
        reconstructor = self._reconstructor
        return reconstructor.note if isinstance(reconstructor, KalmanReconstructor) else ""

    @property
    def misfit_warning(self) -> str:
        """How far the readings depart from the model whose gas is published, when material.

        '' when they do not, or while Eq. (7) publishes; the Kalman filter's std holds the
        departure (:attr:`~tcomp_core.fusion.FusionModel.misfit_c`).
        """
        if self._extended is not None:
            return self._extended.misfit_warning
        reconstructor = self._reconstructor
        if isinstance(reconstructor, KalmanReconstructor):
            return reconstructor.misfit_warning
        return ""

    @property
    def misfit_c(self) -> float:
        """The published gas's model misfit held in its std, degrees C (0 for Eq. 7)."""
        reconstructor = self._reconstructor
        if self._extended is not None:
            reconstructor = self._extended.reconstructor
        if not isinstance(reconstructor, KalmanReconstructor) or reconstructor.model is None:
            return 0.0
        return reconstructor.model.misfit_c

    @property
    def window_samples(self) -> int:
        """Sample pairs in the estimation window."""
        return 0 if self._estimator is None else self._estimator.samples_held

    @property
    def newest_stamp_ns(self) -> int:
        """Stamp of the newest pair taken, ns (0 before the first)."""
        return self._newest_stamp

    @property
    def output(self) -> ExtendedOutput | None:
        """The extended model the published gas uses (None: first order)."""
        return self._extended

    @property
    def output_model(self) -> OutputModel | None:
        """The output model set: being built or waiting, else in use (None: first order)."""
        for waiting in (self._wanted_output, self._building_output, self._pending_output):
            if waiting is not None:
                return waiting[0]
        return None if self._extended is None else self._extended.model

    @property
    def jobs_idle(self) -> bool:
        """Whether no build runs or waits (a replay can then compare outputs at once)."""
        return not (self._running or self._wanted_filter or self._wanted_output)

    def use_output_model(
        self,
        model: OutputModel | None,
        origin_ns: int = 0,
        record: _Pairs | None = None,
    ) -> None:
        """Publish the gas of ``model`` once it is built (None: first order from the next pair).

        The model's filters are built by a job (inline by default) and run through the
        newest pairs; it takes over at the next :meth:`add_pairs` after the job lands, which
        also returns the gas its catching up completed: no stamp is skipped or repeated. A
        model with the same effects as the one in use (a refit) keeps its ``since_ns``.

        Parameters
        ----------
        model : OutputModel or None
        origin_ns : int
            Stamp of the fitted record's sample 0, ns.
        record : (ndarray, ndarray, ndarray)
            Stamps (ns), tc1, tc2 of the fitted record, gap-free (the Kalman filter's signal
            model is fitted to its equivalent readings).

        Raises
        ------
        ValueError
            Without ``record`` for a model.
        """
        self._wanted_output = self._pending_output = self._building_output = None
        if model is None:
            self._extended = None
            return
        if record is None:
            raise ValueError("an output model needs its fitted record")
        if self._period is None:  # built once the period is learnt
            self._pending_output = (model, origin_ns, record)
        else:
            self._wanted_output = (model, origin_ns, record)

    def close(self) -> None:
        """Stop the job runners (abandoning a running build or estimate)."""
        self._runner.close()
        self._estimates.close()

    def longest_segment(self) -> NDArray[np.float64]:
        """The window's longest gap-free stretch, shape (n, 2): tc1, tc2 in degrees C."""
        if self._estimator is None:
            return np.empty((0, 2))
        return self._estimator.longest_segment()

    def restart(self) -> None:
        """Forget the window and the reconstruction state, keep τ and the sample period.

        After a discontinuity of the stamps (:class:`~.engine.Engine`): the next pair may be
        stamped before the newest one taken, and starts a new window.
        """
        held = sum(run[3].size for run in self._backlog)
        self.counters["unreconstructed"] += int(held)
        self._backlog, self._backlog_rows = [], 0
        self._learning = []
        self._estimator = None
        self._previous = None
        self._postfilter = None
        self._restarted = True
        self._published_until = np.iinfo(np.int64).min  # the stamps start over
        self._reconstructed_until = None
        self.recent = RecentPairs(self.recent.capacity)
        if isinstance(self._reconstructor, DifferenceReconstructor):
            self._reconstructor = None  # Eq. (7) with the kept τ until the next estimate lands
        # A Kalman filter is kept: the next pair does not follow its last, so it restarts.
        if self._extended is not None:
            self._extended.restart(stamps_start_over=True)
            self._extended.published_until_ns = self._published_until

    def reconfigure(self, config: OnlineConfig) -> None:
        """Apply new settings, keeping the window's samples where they still fit."""
        old = self._config
        self._config = config
        if config.sample_period_s and config.sample_period_s != old.sample_period_s:
            self._period = config.sample_period_s
        if self._estimator is not None and self._period is not None:
            self._estimator.reconfigure(config, self._period)
        if (config.postfilter_hz, config.postfilter_order) != (
            old.postfilter_hz,
            old.postfilter_order,
        ):
            self._postfilter = None
        kind_changed = (config.reconstruction, config.signal_model) != (
            old.reconstruction,
            old.signal_model,
        )
        extended = self._extended
        if extended is not None and kind_changed:
            # The same model, rebuilt the new way; it takes over when built.
            self.use_output_model(extended.model, extended.origin_ns, extended.record)
            self._extended = extended
        if self._tau is None or self._period is None:
            return
        reconstructor = self._reconstructor
        if kind_changed or reconstructor is None:
            self._reconstructor = None
            self._set_reconstructor()
        elif isinstance(reconstructor, KalmanReconstructor):
            reconstructor.configure(config)
        else:
            self._reconstructor = DifferenceReconstructor(
                config, self._period, self._tau, self._phi
            )

    # -- jobs ----------------------------------------------------------------------------------
    def _set_reconstructor(self) -> None:
        """The reconstructor the settings name, at the accepted τ (a filter build asked for)."""
        assert self._tau is not None and self._period is not None
        reconstructor = self._reconstructor
        if self._config.reconstruction != "kalman":
            self._wanted_filter = ""
            if isinstance(reconstructor, DifferenceReconstructor):
                reconstructor.retune(self._tau, self._phi)
            else:
                self._reconstructor = DifferenceReconstructor(
                    self._config, self._period, self._tau, self._phi
                )
            return
        if not isinstance(reconstructor, KalmanReconstructor):
            reconstructor = KalmanReconstructor(self._config, self._period, self._tau)
            self._reconstructor = reconstructor
        reconstructor.retune(self._tau, self._phi)
        self._want_filter()

    def _want_filter(self) -> None:
        """Ask for the filter build :class:`~.kalman.FilterPolicy` calls for, if any."""
        reconstructor = self._reconstructor
        if not isinstance(reconstructor, KalmanReconstructor) or self._tau is None:
            return
        if self._running == "filter" and self._building_for is reconstructor:
            # The build that runs was asked for against the filter in use, as this would be: a
            # quick fit's full refit asked again while it runs would fit the same stretch once
            # more. The next accepted estimate asks against the filter that lands.
            return
        assert self._estimator is not None
        wanted = FilterPolicy.wanted(
            reconstructor,
            self._tau,
            self.longest_segment().shape[0],
            self._estimator.capacity,
        )
        if wanted and not (wanted == "retune" and self._wanted_filter == "refit"):
            self._wanted_filter = wanted

    def _drive_jobs(self) -> GasBatch:
        """Take a landed build over, start the next one; the gas a take-over completes.

        With an inline runner a build lands as it starts, so this loops until nothing waits.
        """
        out: list[GasBatch] = []
        while True:
            outcome = self._runner.poll()
            if outcome is not None:
                running, self._running = self._running, ""
                if running == "filter":
                    self._take_filter(outcome.value, outcome.error)
                elif running == "output":
                    out.append(self._take_output(outcome.value, outcome.error))
            if self._runner.busy or not self._submit_next():
                return GasBatch.concatenate(out)

    def _submit_next(self) -> bool:
        """Submit the output model or filter build that waits; whether one was."""
        if self._wanted_output is not None and self._period is not None:
            model, origin_ns, record = self._wanted_output
            args = (model, origin_ns, self._config, self._period, record, self._prime())
            if not self._runner.submit(build_output, *args):
                return False
            self._building_output, self._wanted_output = self._wanted_output, None
            self._running = "output"
            return True
        reconstructor = self._reconstructor
        if not self._wanted_filter or not isinstance(reconstructor, KalmanReconstructor):
            self._wanted_filter = ""
            return False
        assert self._tau is not None and self._period is not None
        if reconstructor.model is not None and self._reconstructed_until is None:
            return False  # the pairs held for the filter that just landed go out first: the
            # next build is primed on them (else it would warm up on the stream, not the worker)
        refit = self._wanted_filter == "refit" or reconstructor.model is None
        self._wanted_filter = ""
        first = reconstructor.model is None or reconstructor.interim
        request = FilterRequest(
            self._period,
            self._tau,
            self._config.signal_model,
            self.longest_segment()[-FUSION_FIT_SAMPLES:] if refit else None,
            None if refit else reconstructor.model,
            self._prime(),
            quick=first and not isinstance(self._runner, InlineRunner),
        )
        if not self._runner.submit(build_filter, request):
            self._wanted_filter = "refit" if refit else "retune"  # the worker is warming up
            return False
        self._running, self._building_for = "filter", reconstructor
        return True

    def _prime(self) -> _Pairs:
        """The newest gap-free pairs already reconstructed, at most PRIME_PAIRS (or none)."""
        until = self._reconstructed_until
        empty = (np.empty(0, np.int64), np.empty(0), np.empty(0))
        if until is None or self._period is None or self.recent.size == 0:
            return empty
        stamps, tc1, tc2 = self.recent.tail(PRIME_PAIRS + self._backlog_rows + 1)[:3]
        keep = stamps <= until
        stamps, tc1, tc2 = stamps[keep], tc1[keep], tc2[keep]
        gaps = np.flatnonzero(np.diff(stamps) * 1e-9 > self._config.gap_factor * self._period)
        start = int(gaps[-1]) + 1 if gaps.size else 0
        return (
            stamps[start:][-PRIME_PAIRS:],
            tc1[start:][-PRIME_PAIRS:],
            tc2[start:][-PRIME_PAIRS:],
        )

    def _catch_up_pairs(self, since_ns: int | None) -> _Pairs:
        """The pairs already reconstructed from ``since_ns`` on (the newest PRIME_PAIRS: None).

        A build that was not primed (asked for before any pair was reconstructed) warms up
        on the newest pairs instead.
        """
        until = self._reconstructed_until
        if until is None or self.recent.size == 0:
            return (np.empty(0, np.int64), np.empty(0), np.empty(0))
        if since_ns is None:
            stamps, tc1, tc2 = self.recent.tail(PRIME_PAIRS + self._backlog_rows + 1)[:3]
        else:
            stamps, tc1, tc2 = self.recent.since(since_ns)[:3]
        keep = stamps <= until
        return stamps[keep], tc1[keep], tc2[keep]

    def _take_filter(self, build: FilterBuild | None, error: str) -> None:
        built_for, self._building_for = self._building_for, None
        reconstructor = self._reconstructor
        if not isinstance(reconstructor, KalmanReconstructor) or reconstructor is not built_for:
            return  # the settings changed meanwhile: a build for them follows
        if error or build is None:
            reconstructor.note = f"filter build failed: {error}"
            return
        reconstructor.use(build, self._catch_up_pairs(build.primed_until_ns))

    def _take_output(self, output: ExtendedOutput | None, error: str) -> GasBatch:
        building, self._building_output = self._building_output, None
        if building is None or output is None or error:  # set aside meanwhile, or failed
            if error:
                self.output_note = f"output model not built: {error}"
            return GasBatch.empty()
        previous = self._extended
        self._extended = output
        if previous is not None and previous.model.name(True) == output.model.name(True):
            output.since_ns = previous.since_ns  # a refit of the same physics
        primed_until = output.published_until_ns  # the last pair it was run through
        output.published_until_ns = self._published_until
        primed = primed_until if primed_until != np.iinfo(np.int64).min else None
        stamps, tc1, tc2 = self._catch_up_pairs(primed)
        start = int(np.searchsorted(stamps, primed_until))
        if start < stamps.size and stamps[start] != primed_until:
            output.restart()  # the pairs it was primed on are gone: it starts afresh
        if stamps.size - start < 2:
            return GasBatch.empty()
        stamps, tc1, tc2 = stamps[start:], tc1[start:], tc2[start:]
        contiguous = np.diff(stamps) * 1e-9 <= self._config.gap_factor * (self._period or 0.0)
        gas = output.reconstruct(stamps, tc1, tc2, contiguous)
        self.counters["reconstructed"] += int(gas.stamps_ns.size)
        return self._published(GasBatch(gas.stamps_ns, self._filter(gas.gas), gas.variance))

    # -- pairs ---------------------------------------------------------------------------------
    def add_pairs(self, stamps_ns: ArrayLike, tc1: ArrayLike, tc2: ArrayLike) -> GasBatch:
        """Take matched pairs in increasing stamp order; return the new reconstructed samples.

        Parameters
        ----------
        stamps_ns : array_like of int, shape (M,)
            Sample stamps, nanoseconds, strictly increasing (also across calls).
        tc1, tc2 : array_like, shape (M,)
            Temperatures, degrees C, finite.

        Returns
        -------
        GasBatch
            Stamps (each reconstructed pair's predecessor, ns), gas (degrees C) and its
            variance (degrees C squared, 0 = unknown), shape (R,) each.

        Raises
        ------
        DataError
            Non-finite values or stamps not increasing; nothing is taken then.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        first = np.asarray(tc1, dtype=np.float64)
        second = np.asarray(tc2, dtype=np.float64)
        if not (stamps.shape == first.shape == second.shape) or stamps.ndim != 1:
            raise DataError("stamps, tc1 and tc2 must be 1-D arrays of one length")
        if stamps.size == 0:
            return GasBatch.empty()
        if not (np.isfinite(first).all() and np.isfinite(second).all()):
            raise DataError("non-finite temperature in a matched pair")
        self._collect_estimate()
        fresh = self._restarted or not self.counters["pairs"]
        previous = stamps[0] - 1 if fresh else self._newest_stamp
        steps = np.diff(stamps, prepend=previous)
        if np.any(steps <= 0):
            index = int(np.flatnonzero(steps <= 0)[0])
            raise DataError(f"pair stamp {int(stamps[index])} ns does not increase")
        self.counters["pairs"] += stamps.size
        self._newest_stamp = int(stamps[-1])
        self._restarted = False
        self._steps.extend((steps[1:] if fresh else steps)[-RATE_CHANGE_STEPS:].tolist())
        head = GasBatch.empty()
        start = self._notice_rate(stamps, steps)
        if start:  # the batch's pairs before the change are the old rate's
            assert self._period is not None  # a change is noticed against a learnt period
            head = self._take(stamps[:start], first[:start], second[:start], self._period)
            self._restart_for_rate()
            stamps, first, second = stamps[start:], first[start:], second[start:]
        elif start == 0:
            self._restart_for_rate()
        if self._period is None:
            self._learning.append((stamps, first, second))
            if sum(batch[0].size for batch in self._learning) < PERIOD_LEARNING_SAMPLES:
                return GasBatch.empty()
            # Stamps stay int64: as float64 they would lose the nanoseconds (2^-52 of 1.7e18).
            stamps, first, second = (
                np.concatenate(parts) for parts in zip(*self._learning, strict=True)
            )
            self._learning = []
            self._period = float(np.median(np.diff(stamps))) * 1e-9
        if not stamps.size:
            return head
        return GasBatch.concatenate([head, self._take(stamps, first, second, self._period)])

    def _notice_rate(self, stamps: NDArray[np.int64], steps: NDArray[np.int64]) -> int | None:
        """Where in this batch the inputs left the learnt period for another common rate.

        ``steps`` (M,) are the batch's stamp steps (the first from the newest pair before it),
        ns. Returns the index of the batch's first pair at the new rate (0 when the change
        began in an earlier batch), or None when the period holds (or is configured: then
        :attr:`rate_note` says the stamps disagree).
        """
        if self._period is None or len(self._steps) < RATE_CHANGE_STEPS:
            return None
        newest = np.fromiter(self._steps, dtype=np.float64, count=len(self._steps))
        period_ns = self._period * 1e9
        new_ns = median(newest)
        off = np.abs(newest - period_ns) > RATE_TOLERANCE * period_ns
        common = np.abs(newest - new_ns) <= RATE_TOLERANCE * new_ns
        if not (off.all() and common.mean() >= 0.9):
            return None
        # The pair the last old-period step reached is the first of the new rate.
        old = np.flatnonzero(np.abs(steps - period_ns) <= RATE_TOLERANCE * period_ns)
        start = int(old[-1]) if old.size else 0
        where = f"at stamp {int(stamps[start]) * 1e-9:.6f} s"
        change = f"sample period {self._period:.6g} s -> about {new_ns * 1e-9:.6g} s {where}"
        self._steps.clear()
        if self._config.sample_period_s:
            self.rate_note = f"stamps disagree with sample_period_s: {change}"
            return None
        self.rate_changes += 1
        self.rate_note = (
            f"inputs changed rate ({change}): window, period, τ and reconstruction restarted"
        )
        return start

    def _restart_for_rate(self) -> None:
        """Start afresh at a new rate: window, period, τ, reconstruction, output model."""
        had_model = self.output_model is not None
        self.restart()
        self._period = None
        self._tau = None
        self._phi = None
        self._reconstructor = None
        self._extended = None
        self._wanted_output = self._pending_output = self._building_output = None
        self._next_first_attempt = FIRST_ESTIMATE_ROWS
        self.recent = RecentPairs(PRIME_PAIRS)
        if had_model:
            self.output_note = "output model dropped: the inputs changed rate"

    def _take(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        period: float,
    ) -> GasBatch:
        """Window the pairs and reconstruct what τ allows."""
        if self.recent.capacity == PRIME_PAIRS:
            self.recent = RecentPairs(max(PRIME_PAIRS, round(RECENT_S / period)))
        if self._pending_output is not None:
            self._wanted_output, self._pending_output = self._pending_output, None
        if self._estimator is None:
            self._estimator = WindowEstimator(self._config, period)
        self.recent.add(stamps, tc1, tc2)
        linked = self._previous is not None
        if self._previous is not None:
            stamps = np.concatenate(([self._previous[0]], stamps))
            tc1 = np.concatenate(([self._previous[1]], tc1))
            tc2 = np.concatenate(([self._previous[2]], tc2))
        steps_s = np.diff(stamps) * 1e-9
        # contiguous[i]: sample i+1 follows sample i without a gap.
        contiguous = steps_s <= self._config.gap_factor * period
        self.counters["gaps"] += int((~contiguous).sum())
        self._estimator.extend(tc1, tc2, contiguous, linked)
        self._previous = (int(stamps[-1]), float(tc1[-1]), float(tc2[-1]))
        if self._tau is None and self._estimator.rows >= self._next_first_attempt:
            self._next_first_attempt = self._estimator.rows + FIRST_ESTIMATE_ROWS
            self.update_estimate(first_attempt=True)
        run: _Run = (stamps, tc1, tc2, steps_s, contiguous)
        if self._tau is None:
            self._hold(run)
            return GasBatch.empty()
        return self._release(run)

    def poll_jobs(self) -> GasBatch:
        """Take over a build that landed, start the next; the gas that completes.

        :meth:`add_pairs` does this first; a caller whose drains bring no pair (a node whose
        sensors went quiet, a replay that ended) calls it so that a build lands anyway and the
        pairs held for it go out.
        """
        self._collect_estimate()
        if self._pending_output is not None and self._period is not None:
            self._wanted_output, self._pending_output = self._pending_output, None
        if self._tau is None or self._estimator is None:
            return self._drive_jobs()
        return self._release(None)

    def _release(self, run: _Run | None) -> GasBatch:
        """Drive the jobs, then reconstruct the held pairs and ``run`` unless a filter is due."""
        assert self._estimator is not None
        if self._awaiting_filter() and not (self._running or self._wanted_filter):
            self._want_filter()  # the first fit waits for enough of a stretch
        taken = self._drive_jobs()
        runs = [*self._backlog, *([] if run is None else [run])]
        if self._awaiting_filter():
            rows = sum(part[3].size for part in runs)
            if rows <= self._estimator.capacity:
                if run is not None:
                    self._hold(run)  # reconstructed with the fitted filter once it lands
                return taken
            self._interim_filter()  # the build is slow: publish with the interim meanwhile
        self._backlog, self._backlog_rows = [], 0
        return GasBatch.concatenate([taken, *(self._reconstruct(*part) for part in runs)])

    def _awaiting_filter(self) -> bool:
        """Whether the first Kalman filter is being built elsewhere and none is in use yet."""
        reconstructor = self._reconstructor
        return (
            isinstance(reconstructor, KalmanReconstructor)
            and reconstructor.model is None
            and not reconstructor.note  # a build that found no model: Eq. (7), say so
            and self._extended is None
        )

    def _interim_filter(self) -> None:
        """While the first filter is being built elsewhere, fit the interim one here (once)."""
        reconstructor = self._reconstructor
        if (
            not isinstance(reconstructor, KalmanReconstructor)
            or reconstructor.model is not None
            or self._tau is None
            or self._period is None
        ):
            return
        reconstructor.use(
            interim_build(self.longest_segment(), self._period, self._tau),
            (np.empty(0, np.int64), np.empty(0), np.empty(0)),
            interim=True,
        )
        if reconstructor.model is None:  # not even a random walk: Eq. (7) until the build
            reconstructor.note = "interim random-walk model not fitted: Eq. (7) meanwhile"

    def _hold(self, run: _Run) -> None:
        """Keep pairs until the first τ, at most one window's worth (the oldest go first)."""
        if run[3].size == 0:
            return
        self._backlog.append(run)
        self._backlog_rows += run[3].size
        capacity = self._estimator.capacity if self._estimator is not None else 0
        while self._backlog_rows > capacity and len(self._backlog) > 1:
            dropped = self._backlog.pop(0)
            self._backlog_rows -= dropped[3].size
            self.counters["unreconstructed"] += int(dropped[3].size)

    def _reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> GasBatch:
        if steps_s.size == 0:
            return GasBatch.empty()
        if self._extended is not None:
            lost, widened = self._extended.lost, self._extended.widened
            out = self._extended.reconstruct(stamps, tc1, tc2, contiguous)
            self.widened += self._extended.widened - widened
            self._reconstructed_until = int(stamps[-1])
            self.counters["reconstructed"] += int(out.stamps_ns.size)
            self.counters["unreconstructed"] += int((~contiguous).sum()) + (
                self._extended.lost - lost
            )
            return self._published(GasBatch(out.stamps_ns, self._filter(out.gas), out.variance))
        if self._reconstructor is None:  # an initial τ: Eq. (7) until an estimate lands
            if self._tau is None or self._period is None:
                raise RuntimeError("pairs are held until the first τ and period")
            self._reconstructor = DifferenceReconstructor(self._config, self._period, self._tau)
        out_stamps = stamps[:-1][contiguous]
        self.counters["reconstructed"] += int(out_stamps.size)
        self.counters["unreconstructed"] += int((~contiguous).sum())
        gas, variance = self._reconstructor.reconstruct(stamps, tc1, tc2, steps_s, contiguous)
        self.widened += self._reconstructor.last_widened
        self._reconstructed_until = int(stamps[-1])
        return self._published(GasBatch(out_stamps, self._filter(gas), variance))

    def _published(self, batch: GasBatch) -> GasBatch:
        if batch.stamps_ns.size:
            self._published_until = int(batch.stamps_ns[-1])
        return batch

    def _filter(self, gas: NDArray[np.float64]) -> NDArray[np.float64]:
        cutoff = self._config.postfilter_hz
        if cutoff <= 0.0 or gas.size == 0 or self._period is None:
            return gas
        if self._postfilter is None:
            self._postfilter = PostFilter(cutoff, self._config.postfilter_order, self._period)
        return self._postfilter(gas)

    # -- estimation ----------------------------------------------------------------------------
    def update_estimate(self, *, first_attempt: bool = False) -> EstimateStatus | None:
        """Re-estimate τ1, τ2 from the window; accept the result when it is sound.

        The estimate runs on the estimate runner (inline by default: its status is returned);
        with a thread it lands later, at a following call or drain (:meth:`take_landed`), and
        the newest landed status is returned (None before any). One runs at a time: a call
        while one runs starts none. ``first_attempt``: asked by the pairs themselves before the
        first τ (its status is not one of :meth:`take_landed`'s).
        """
        if self._estimator is None:
            status = EstimateStatus(
                accepted=False,
                estimate=None,
                reason=f"window holds 0 regression rows; {MIN_SAMPLES - 1} needed",
                stamp_ns=self._newest_stamp,
            )
            self._landed.append(status)
            self.last_status = status
            return status
        self._collect_estimate()
        if not self._estimates.busy:
            self._asked = not first_attempt
            self._estimates.submit(self._estimator.job(self._newest_stamp).run)
            self._collect_estimate()  # an inline runner has finished already
        return self.last_status

    def take_landed(self) -> list[EstimateStatus]:
        """The statuses of the estimates that landed since the last call, oldest first."""
        landed = list(self._landed)
        self._landed.clear()
        return landed

    def _collect_estimate(self) -> None:
        """Adopt an estimate that landed, if any."""
        outcome = self._estimates.poll()
        if outcome is None or self._estimator is None:
            return
        if outcome.error:
            status = EstimateStatus(
                accepted=False,
                estimate=None,
                reason=f"the estimate failed: {outcome.error}",
                stamp_ns=self._newest_stamp,
            )
        else:
            status = outcome.value
            self._estimator.adopt(status)
        status = self._accept(status)
        if self._asked:
            self._landed.append(status)

    def _accept(self, status: EstimateStatus) -> EstimateStatus:
        """Take a landed status: a sound estimate becomes the published τ."""
        if status.accepted:
            status = self._trusted(status)
        if status.accepted and status.estimate is not None and self._period is not None:
            self.rate_note = "" if self._estimator is not None else self.rate_note
            self._tau = (status.estimate.tau1, status.estimate.tau2)
            self._phi = status.estimate.phi
            self._set_reconstructor()
            if self._runner.busy or self._running:
                pass  # the landed build is taken over with the next pairs
            elif self._wanted_filter or self._wanted_output:
                self._submit_next()
        self.last_status = status
        return status

    def _trusted(self, status: EstimateStatus) -> EstimateStatus:
        """``status``, or it refused when the estimate is not pinned down (module notes)."""
        estimate = status.estimate
        assert estimate is not None
        taus = (estimate.tau1, estimate.tau2)
        wide = estimate.wide_interval(MAX_TAU_INTERVAL)
        reason = f"{wide}: the window does not pin it down" if wide else ""
        previous, self._last_attempt = self._last_attempt, taus
        has_intervals = math.isfinite(estimate.params.get("tau1_ci_low", math.nan))
        confirmed = previous is not None and all(
            abs(new / old - 1.0) <= FIRST_AGREEMENT
            for new, old in zip(taus, previous, strict=True)
        )
        if not reason and self._tau is None and not has_intervals and not confirmed:
            reason = (
                "first estimate not yet confirmed: it must agree within "
                f"{100 * FIRST_AGREEMENT:g} % with the attempt before it"
            )
        if not reason:
            return status
        return replace(status, accepted=False, reason=reason)
