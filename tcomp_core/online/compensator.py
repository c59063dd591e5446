"""The online compensator: matched pairs in, τ estimates and reconstructed gas samples out.

- Matched sample pairs arrive in batches with their stamps (nanoseconds). The sample period is
  learnt from the first stamps (or given); a step longer than ``gap_factor`` periods is a gap,
  and the regression row straddling it is left out of the window.
- The window (:class:`~.estimation.WindowEstimator`) is re-estimated on demand
  (:meth:`OnlineCompensator.update_estimate`); an accepted estimate drives the reconstruction.
- Each new pair k reconstructs the gas temperature at the previous pair's stamp with the latest
  accepted τ (:mod:`.reconstructors`: Eq. 7 or the causal Kalman filter), optionally smoothed by
  the causal post-filter.
- Before the first accepted estimate, one is attempted every :data:`~.config.FIRST_ESTIMATE_ROWS`
  window rows, and the pairs are held (up to one window) to be reconstructed once it lands.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..compensation import OutputModel
from ..errors import DataError
from ..fusion import FusionModel
from ..validation import MIN_SAMPLES
from .config import FIRST_ESTIMATE_ROWS, PERIOD_LEARNING_SAMPLES, EstimateStatus, OnlineConfig
from .estimation import WindowEstimator
from .extended import ExtendedOutput
from .reconstructors import (
    DifferenceReconstructor,
    GasBatch,
    KalmanReconstructor,
    PostFilter,
    make_reconstructor,
)

__all__ = ["OnlineCompensator"]

_Run = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray, NDArray]


class OnlineCompensator:
    """Sliding-window τ estimation and causal gas temperature reconstruction.

    Parameters
    ----------
    config : OnlineConfig
    initial_tau : (float, float), optional
        Time constants to reconstruct with before the first accepted estimate, seconds.

    Attributes
    ----------
    counters : dict of str to int
        ``pairs`` taken, ``gaps`` seen, ``reconstructed`` and ``unreconstructed`` pairs.
    last_status : EstimateStatus or None
        The latest re-estimation.
    """

    def __init__(
        self, config: OnlineConfig | None = None, initial_tau: tuple[float, float] | None = None
    ) -> None:
        self._config = config or OnlineConfig()
        self._tau = initial_tau
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
        self.counters = {"pairs": 0, "gaps": 0, "reconstructed": 0, "unreconstructed": 0}
        # Pairs that arrived before the first τ: (stamps, tc1, tc2, steps_s, contiguous).
        self._backlog: list[_Run] = []
        self._backlog_rows = 0
        self._next_first_attempt = FIRST_ESTIMATE_ROWS
        self._extended: ExtendedOutput | None = None
        self._pending_output: tuple[OutputModel, int, tuple] | None = None
        self._published_until = np.iinfo(np.int64).min  # newest gas stamp given out
        #: Why the published gas is first order although output models were asked for, or
        #: what the caller last decided about the output model ('' when nothing to say).
        self.output_note = ""

    # -- state ---------------------------------------------------------------------------------
    @property
    def config(self) -> OnlineConfig:
        """Current settings."""
        return self._config

    @property
    def period_s(self) -> float | None:
        """Sample period in seconds, once known."""
        return self._period

    @property
    def tau(self) -> tuple[float, float] | None:
        """Time constants (τ1, τ2) in seconds the reconstruction uses, once known."""
        return self._tau

    @property
    def published_tau(self) -> tuple[float, float] | None:
        """τ1, τ2 (s) of the published gas: the output model's while it is in use."""
        if self._extended is not None:
            return (self._extended.model.tau1, self._extended.model.tau2)
        return self._tau

    @property
    def fusion_model(self) -> FusionModel | None:
        """The Kalman filter's model once fitted (``reconstruction='kalman'``)."""
        reconstructor = self._reconstructor
        return reconstructor.model if isinstance(reconstructor, KalmanReconstructor) else None

    @property
    def fusion_error(self) -> str:
        """Why the Kalman filter's signal model could not be fitted ('' when it could)."""
        reconstructor = self._reconstructor
        return reconstructor.error if isinstance(reconstructor, KalmanReconstructor) else ""

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
        """The output model set, in use or waiting for the sample period (None: first order)."""
        if self._extended is not None:
            return self._extended.model
        return None if self._pending_output is None else self._pending_output[0]

    def use_output_model(
        self,
        model: OutputModel | None,
        origin_ns: int = 0,
        record: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None = None,
        prime: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None = None,
    ) -> GasBatch:
        """Publish the gas of ``model`` from the next pair on (None: back to first order).

        A model with the same effects as the one in use (a refit) keeps its ``since_ns``.

        Parameters
        ----------
        model : OutputModel or None
        origin_ns : int
            Stamp of the fitted record's sample 0, ns.
        record : (ndarray, ndarray, ndarray)
            Stamps (ns), tc1, tc2 of the fitted record, gap-free (the Kalman filter's signal
            model is fitted to its equivalent readings).
        prime : (ndarray, ndarray, ndarray), optional
            The newest pairs taken (stamps, tc1, tc2), gap-free: run through the new model
            first, so that its filters are warm and no stamp is skipped at the switch.

        Returns
        -------
        GasBatch
            Gas the priming completed that was not published yet (publish it).

        Before the sample period is known the model waits for it (:attr:`output_model`).

        Raises
        ------
        ValueError
            Without ``record`` for a model.
        """
        previous, self._extended = self._extended, None
        self._pending_output = None
        if model is None:
            return GasBatch.empty()
        if record is None:
            raise ValueError("an output model needs its fitted record")
        if self._period is None:  # built once the period is learnt
            self._pending_output = (model, origin_ns, record)
            return GasBatch.empty()
        self._extended = ExtendedOutput(
            model, origin_ns, self._config, self._period, record, self._published_until
        )
        if previous is not None and previous.model.name(True) == model.name(True):
            self._extended.since_ns = previous.since_ns  # a refit of the same physics
        if prime is None or prime[0].size < 2:
            return GasBatch.empty()
        stamps, tc1, tc2 = prime
        contiguous = np.diff(stamps) * 1e-9 <= self._config.gap_factor * self._period
        out = self._extended.reconstruct(stamps, tc1, tc2, contiguous)
        self.counters["reconstructed"] += int(out.stamps_ns.size)
        return self._published(GasBatch(out.stamps_ns, self._filter(out.gas), out.variance))

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
        self._reconstructor = None  # Eq. (7) with the kept τ until the next estimate lands
        self._restarted = True
        self._published_until = np.iinfo(np.int64).min  # the stamps start over
        if self._extended is not None:
            self._extended.restart(stamps_start_over=True)

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
        extended = self._extended
        if extended is not None and (config.reconstruction, config.signal_model) != (
            old.reconstruction,
            old.signal_model,
        ):  # the same model, reconstructed the new way from the next pair on
            self.use_output_model(extended.model, extended.origin_ns, extended.record)
        if self._tau is None or self._period is None:
            return
        reconstructor = self._reconstructor
        if (config.reconstruction, config.signal_model) != (
            old.reconstruction,
            old.signal_model,
        ) or reconstructor is None:
            self._reconstructor = make_reconstructor(
                config, self._period, self._tau, self.longest_segment()
            )
        elif isinstance(reconstructor, KalmanReconstructor):
            reconstructor.configure(config)
        else:
            self._reconstructor = DifferenceReconstructor(config, self._period, self._tau)

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
        fresh = self._restarted or not self.counters["pairs"]
        previous = stamps[0] - 1 if fresh else self._newest_stamp
        steps = np.diff(stamps, prepend=previous)
        if np.any(steps <= 0):
            index = int(np.flatnonzero(steps <= 0)[0])
            raise DataError(f"pair stamp {int(stamps[index])} ns does not increase")
        self.counters["pairs"] += stamps.size
        self._newest_stamp = int(stamps[-1])
        self._restarted = False
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
        return self._take(stamps, first, second, self._period)

    def _take(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        period: float,
    ) -> GasBatch:
        """Window the pairs and reconstruct what τ allows."""
        if self._pending_output is not None:
            self.use_output_model(*self._pending_output)
        if self._estimator is None:
            self._estimator = WindowEstimator(self._config, period)
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
            self.update_estimate()
        run: _Run = (stamps, tc1, tc2, steps_s, contiguous)
        if self._tau is None:
            self._hold(run)
            return GasBatch.empty()
        runs, self._backlog, self._backlog_rows = [*self._backlog, run], [], 0
        return GasBatch.concatenate([self._reconstruct(*part) for part in runs])

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
            lost = self._extended.lost
            out = self._extended.reconstruct(stamps, tc1, tc2, contiguous)
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
    def update_estimate(self) -> EstimateStatus:
        """Re-estimate τ1, τ2 from the window; accept the result when it is sound."""
        if self._estimator is None:
            status = EstimateStatus(
                accepted=False,
                estimate=None,
                reason=f"window holds 0 regression rows; {MIN_SAMPLES - 1} needed",
                stamp_ns=self._newest_stamp,
            )
        else:
            status = self._estimator.estimate(self._newest_stamp)
        if status.accepted and status.estimate is not None and self._period is not None:
            self._tau = (status.estimate.tau1, status.estimate.tau2)
            kalman = self._config.reconstruction == "kalman"
            if self._reconstructor is None or (
                kalman and not isinstance(self._reconstructor, KalmanReconstructor)
            ):
                self._reconstructor = make_reconstructor(
                    self._config, self._period, self._tau, self.longest_segment()
                )
            else:
                self._reconstructor.retune(self._tau, self.longest_segment)
        self.last_status = status
        return status
