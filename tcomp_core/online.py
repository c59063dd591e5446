"""Online compensation: sliding-window estimation and causal reconstruction of matched pairs.

This is the numerical engine of the ROS compensator node; the node only turns messages into the
arrays this class takes and publishes what it returns.

- Matched sample pairs arrive in batches with their stamps (nanoseconds). The sample period is
  learnt from the first stamps (or given); a step longer than ``gap_factor`` periods is a gap,
  and the regression row straddling it is left out of the window.
- The window keeps the β scatter matrix up to date in O(1) per sample
  (:class:`~tcomp_core.window.SlidingBetaWindow`); :meth:`OnlineCompensator.update_estimate`
  solves it (β methods) or runs the batch estimator on the window's samples (γ, TDR, or when a
  pre-filter is set). An estimate is accepted when it is physical and well conditioned.
- Each new pair k reconstructs the gas temperature at the previous pair's stamp with the latest
  accepted τ: through Eq. (7) with the actual stamp step for the pole (``'difference'``), or by
  the causal Kalman filter of both sensors (``'kalman'``, :class:`~tcomp_core.fusion.CausalFuser`)
  whose signal model is fitted by maximum likelihood on the window when the first τ is
  accepted, again as the gap-free stretch it is fitted on doubles (up to
  :data:`FUSION_FIT_SAMPLES`) and whenever τ has moved by :data:`FUSION_REFIT_CHANGE` since;
  smaller moves only retune its τ. The filter restarts after a gap. An optional causal
  Butterworth low-pass smooths either result (a forward-backward filter cannot run online).
- With ``tracking_memory_s`` > 0, τ comes from an exponentially forgetting β-GTLS with the
  ratio τ1/τ2 held to its long-term value (:class:`~tcomp_core.tracking.ForgettingEstimator`)
  instead of the sliding window, to follow a τ that changes with the flow velocity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from .errors import DataError, TcompError
from .estimators import METHODS, Estimate, beta_noise_covariance, estimate
from .estimators.beta import estimate_beta_from_scatter
from .estimators.scatter import beta_scatter, solve_gtls
from .filters import prefilter
from .fit import fit_error_percent
from .fusion import MODELS, CausalFuser, FusionModel, fit_fusion_model
from .reconstruct import combination_weight
from .tracking import ForgettingEstimator
from .validation import MIN_SAMPLES
from .window import BETA_METHODS, SlidingBetaWindow

__all__ = [
    "RECONSTRUCTIONS",
    "RECONSTRUCT_FROM",
    "SIGNAL_MODELS",
    "EstimateStatus",
    "OnlineCompensator",
    "OnlineConfig",
    "ReconstructFrom",
]

ReconstructFrom = Literal["fused", "tc1", "tc2"]
RECONSTRUCT_FROM: tuple[str, ...] = get_args(ReconstructFrom)
Reconstruction = Literal["difference", "kalman"]
RECONSTRUCTIONS: tuple[str, ...] = get_args(Reconstruction)
SIGNAL_MODELS: tuple[str, ...] = ("auto", *MODELS)

#: Shortest gap-free segment worth pre-filtering (zero-phase filters need edge padding).
MIN_PREFILTER_SAMPLES = 64
#: Stamps used to learn the sample period when none is configured.
PERIOD_LEARNING_SAMPLES = 64
#: Before the first accepted estimate, one is attempted as soon as the window holds this many
#: rows and again after every further batch of as many: output starts early and the pairs
#: that came before it are reconstructed from the backlog instead of being lost.
FIRST_ESTIMATE_ROWS = 256
#: Relative move of τ1 or τ2 since the Kalman filter's signal model was fitted that makes the
#: next accepted estimate refit it (smaller moves only retune τ).
FUSION_REFIT_CHANGE = 0.1
#: Newest samples of the window's longest gap-free stretch the signal model is fitted on: a
#: random-walk model takes ~0.1 s on as many, 'auto' (all four models) ~1.5 s.
FUSION_FIT_SAMPLES = 4096
#: The long-term ratio τ1/τ2 of the tracking estimator forgets over this many tracking memories
#: (or the window, if longer).
RATIO_MEMORY_FACTOR = 10.0


@dataclass(frozen=True, kw_only=True)
class OnlineConfig:
    """Settings of the online compensator (the node's parameters).

    Attributes
    ----------
    window_s : float
        Length of the estimation window, seconds.
    method : str
        Estimator, one of :data:`tcomp_core.METHODS`.
    phi : float
        Noise variance ratio σ1²/σ2² for β-GTLS and for fusing the reconstructions.
    prefilter_hz : float
        Zero-phase pre-filter applied to the window before estimation, Hz; 0 = off.
    postfilter_hz : float
        Causal Butterworth low-pass on the reconstruction, Hz; 0 = off.
    postfilter_order : int
        Order of that low-pass.
    reconstruct_from : {'fused', 'tc1', 'tc2'}
        Which Eq. (7) reconstruction is output (``'difference'`` only).
    reconstruction : {'difference', 'kalman'}
        Eq. (7) through the difference equation, or the causal Kalman filter of both sensors.
    signal_model : {'auto', 'random-walk', 'integrated-random-walk', 'band-limited', 'periodic'}
        Gas temperature model of the Kalman filter (:mod:`tcomp_core.fusion`).
    tracking_memory_s : float
        Forgetting time constant of the tracking estimator, seconds; 0 = sliding window.
    sample_period_s : float
        Sample period of the pairs, seconds; 0 = learn it from the stamps.
    gap_factor : float
        A step longer than this many periods is a gap.
    max_condition : float
        Estimates whose conditioning figure exceeds this are not accepted.
    max_model_error_pct : float
        Model error (fit error beyond the noise floor) above which the fit counts as poor.
    """

    window_s: float = 2.0
    method: str = "beta-gtls"
    phi: float = 1.0
    prefilter_hz: float = 0.0
    postfilter_hz: float = 0.0
    postfilter_order: int = 2
    reconstruct_from: str = "fused"
    reconstruction: str = "difference"
    signal_model: str = "random-walk"
    tracking_memory_s: float = 0.0
    sample_period_s: float = 0.0
    gap_factor: float = 1.5
    max_condition: float = 1e3
    max_model_error_pct: float = 10.0

    def __post_init__(self) -> None:
        checks = [
            (self.window_s > 0.0, f"window_s={self.window_s!r} must be > 0 s"),
            (self.method in METHODS, f"method={self.method!r} is not one of {METHODS}"),
            (math.isfinite(self.phi) and self.phi > 0.0, f"phi={self.phi!r} must be > 0"),
            (self.prefilter_hz >= 0.0, f"prefilter_hz={self.prefilter_hz!r} must be >= 0"),
            (self.postfilter_hz >= 0.0, f"postfilter_hz={self.postfilter_hz!r} must be >= 0"),
            (1 <= self.postfilter_order <= 8, f"postfilter_order={self.postfilter_order!r}"),
            (
                self.reconstruct_from in RECONSTRUCT_FROM,
                f"reconstruct_from={self.reconstruct_from!r} is not one of {RECONSTRUCT_FROM}",
            ),
            (
                self.reconstruction in RECONSTRUCTIONS,
                f"reconstruction={self.reconstruction!r} is not one of {RECONSTRUCTIONS}",
            ),
            (
                self.signal_model in SIGNAL_MODELS,
                f"signal_model={self.signal_model!r} is not one of {SIGNAL_MODELS}",
            ),
            (
                math.isfinite(self.tracking_memory_s) and self.tracking_memory_s >= 0.0,
                f"tracking_memory_s={self.tracking_memory_s!r} must be >= 0 s",
            ),
            (self.sample_period_s >= 0.0, f"sample_period_s={self.sample_period_s!r} < 0"),
            (self.gap_factor > 1.0, f"gap_factor={self.gap_factor!r} must be > 1"),
            (self.max_condition >= 1.0, f"max_condition={self.max_condition!r} must be >= 1"),
            (self.max_model_error_pct > 0.0, "max_model_error_pct must be > 0"),
        ]
        for holds, message in checks:
            if not holds:
                raise ValueError(message)


@dataclass(frozen=True, kw_only=True)
class EstimateStatus:
    """Outcome of one re-estimation.

    Attributes
    ----------
    accepted : bool
        Whether the estimate now drives the reconstruction.
    estimate : Estimate or None
        The estimate, also when it was not accepted (None when none could be made).
    reason : str
        Why it was not accepted ('' when accepted).
    fit_error_pct : float
        Free-run fit error of tc2 from tc1 over the window (:mod:`tcomp_core.fit`), percent.
    noise_floor_pct : float
        Part of the fit error explained by measurement noise alone, percent.
    model_error_pct : float
        ``sqrt(fit² - floor²)``: the part the model does not explain, percent.
    stamp_ns : int
        Stamp of the newest sample in the window.
    poor_fit : bool
        Whether the model error exceeds ``max_model_error_pct``.
    """

    accepted: bool
    estimate: Estimate | None
    reason: str = ""
    fit_error_pct: float = math.nan
    noise_floor_pct: float = math.nan
    model_error_pct: float = math.nan
    stamp_ns: int = 0
    poor_fit: bool = False


class OnlineCompensator:
    """Sliding-window τ estimation and causal gas temperature reconstruction.

    Parameters
    ----------
    config : OnlineConfig
    initial_tau : (float, float), optional
        Time constants to reconstruct with before the first accepted estimate, seconds.
    """

    def __init__(
        self, config: OnlineConfig | None = None, initial_tau: tuple[float, float] | None = None
    ) -> None:
        self._config = config or OnlineConfig()
        self._tau = initial_tau
        self._window: SlidingBetaWindow | None = None
        self._period: float | None = self._config.sample_period_s or None
        # Batches (stamps, tc1, tc2) seen while the sample period is learnt.
        self._learning: list[tuple[NDArray[np.int64], NDArray, NDArray]] = []
        self._previous: tuple[int, float, float] | None = None
        self._newest_stamp = 0
        self._filter_state: NDArray[np.float64] | None = None
        self._sos: NDArray[np.float64] | None = None
        self.last_status: EstimateStatus | None = None
        self.counters = {"pairs": 0, "gaps": 0, "reconstructed": 0, "unreconstructed": 0}
        # Pairs that arrived before the first τ: (stamps, tc1, tc2, steps_s, contiguous).
        self._backlog: list[tuple[NDArray, ...]] = []
        self._backlog_rows = 0
        self._next_first_attempt = FIRST_ESTIMATE_ROWS
        self._fuser: CausalFuser | None = None
        self._fuser_stamp: int | None = None  # stamp of the last sample the fuser took
        self._fusion_tau: tuple[float, float] | None = None  # τ its signal model was fitted at
        self._fusion_samples = 0  # samples it was fitted on
        self._tracker: ForgettingEstimator | None = None
        #: Why the Kalman filter's signal model could not be fitted ('' when it could).
        self.fusion_error = ""
        #: Variance of each gas sample the last :meth:`add_pairs` returned, °C² (0 = unknown,
        #: as for the difference equation).
        self.last_variance: NDArray[np.float64] = np.empty(0)

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
    def fusion_model(self) -> FusionModel | None:
        """The Kalman filter's model once fitted (``reconstruction='kalman'``)."""
        return None if self._fuser is None else self._fuser.model

    @property
    def window_samples(self) -> int:
        """Sample pairs in the estimation window."""
        return 0 if self._window is None else len(self._window)

    def reconfigure(self, config: OnlineConfig) -> None:
        """Apply new settings, keeping the window's samples where they still fit."""
        old = self._config
        self._config = config
        if config.sample_period_s and config.sample_period_s != old.sample_period_s:
            self._period = config.sample_period_s
        if self._window is not None and (
            config.window_s != old.window_s
            or config.sample_period_s != old.sample_period_s
            or (config.method, config.phi) != (old.method, old.phi)
        ):
            samples = self._window.samples
            self._window = self._new_window()
            self._window.extend(samples[:, 0], samples[:, 1])
        if (config.postfilter_hz, config.postfilter_order) != (
            old.postfilter_hz,
            old.postfilter_order,
        ):
            self._sos = self._filter_state = None
        if (config.reconstruction, config.signal_model) != (old.reconstruction, old.signal_model):
            self._fuser = self._fuser_stamp = self._fusion_tau = None
            self.fusion_error = ""
            if config.reconstruction == "kalman" and self._tau is not None:
                self._update_fuser()
        if (config.tracking_memory_s, config.phi, config.window_s) != (
            old.tracking_memory_s,
            old.phi,
            old.window_s,
        ):
            self._tracker = None
            if self._window is not None:
                self._refill_tracker()

    def _new_tracker(self) -> ForgettingEstimator | None:
        memory = self._config.tracking_memory_s
        if memory <= 0.0 or self._period is None:
            return None
        return ForgettingEstimator(
            self._period,
            memory_s=memory,
            phi=self._config.phi,
            ratio_memory_s=max(self._config.window_s, RATIO_MEMORY_FACTOR * memory),
        )

    def _refill_tracker(self) -> None:
        """A new tracker fed with the window's samples, gap by gap."""
        assert self._window is not None
        self._tracker = self._new_tracker()
        if self._tracker is None:
            return
        for segment in np.split(self._window.samples, self._window.segment_starts):
            self._tracker.mark_gap()
            self._tracker.extend(segment[:, 0], segment[:, 1])

    def _new_window(self) -> SlidingBetaWindow:
        assert self._period is not None  # set before any sample reaches here
        capacity = max(MIN_SAMPLES, round(self._config.window_s / self._period))
        method = self._config.method if self._config.method in BETA_METHODS else "beta-gtls"
        return SlidingBetaWindow(capacity, self._period, method, self._config.phi)

    def add_pairs(
        self, stamps_ns: ArrayLike, tc1: ArrayLike, tc2: ArrayLike
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Take matched pairs in increasing stamp order; return the new reconstructed samples.

        Parameters
        ----------
        stamps_ns : array_like of int, shape (M,)
            Sample stamps, nanoseconds, strictly increasing (also across calls).
        tc1, tc2 : array_like, shape (M,)
            Temperatures, degrees C, finite.

        Returns
        -------
        stamps_ns : ndarray of int64, shape (R,)
            Stamps of the reconstructed samples (each pair's predecessor).
        gas : ndarray, shape (R,)
            Reconstructed gas temperature, degrees C.

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
        self.last_variance = np.empty(0)
        if stamps.size == 0:
            return np.empty(0, dtype=np.int64), np.empty(0)
        if not (np.isfinite(first).all() and np.isfinite(second).all()):
            raise DataError("non-finite temperature in a matched pair")
        previous = self._newest_stamp if self.counters["pairs"] else stamps[0] - 1
        steps = np.diff(stamps, prepend=previous)
        if np.any(steps <= 0):
            index = int(np.flatnonzero(steps <= 0)[0])
            raise DataError(f"pair stamp {int(stamps[index])} ns does not increase")
        self.counters["pairs"] += stamps.size
        self._newest_stamp = int(stamps[-1])
        if self._period is None:
            self._learning.append((stamps, first, second))
            if sum(batch[0].size for batch in self._learning) < PERIOD_LEARNING_SAMPLES:
                return np.empty(0, dtype=np.int64), np.empty(0)
            # Stamps stay int64: as float64 they would lose the nanoseconds (2^-52 of 1.7e18).
            stamps, first, second = (
                np.concatenate(parts) for parts in zip(*self._learning, strict=True)
            )
            self._learning = []
            self._period = float(np.median(np.diff(stamps))) * 1e-9
        out_stamps, gas, self.last_variance = self._take(stamps, first, second)
        return out_stamps, gas

    def _take(
        self, stamps: NDArray[np.int64], tc1: NDArray[np.float64], tc2: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """Window the pairs and reconstruct what τ allows: stamps, gas and its variance."""
        assert self._period is not None  # set before any sample reaches here
        if self._window is None:
            self._window = self._new_window()
            self._tracker = self._new_tracker()
        if self._previous is not None:
            stamps = np.concatenate(([self._previous[0]], stamps))
            tc1 = np.concatenate(([self._previous[1]], tc1))
            tc2 = np.concatenate(([self._previous[2]], tc2))
        steps_s = np.diff(stamps) * 1e-9
        # contiguous[i]: sample i+1 follows sample i without a gap.
        contiguous = steps_s <= self._config.gap_factor * self._period
        self.counters["gaps"] += int((~contiguous).sum())
        if self._previous is not None:
            self._window.extend(tc1[1:], tc2[1:], contiguous)
        else:  # the very first sample has no predecessor to link to
            self._window.extend(tc1, tc2, np.concatenate(([True], contiguous)))
        if self._tracker is not None:
            self._feed_tracker(tc1, tc2, contiguous, linked=self._previous is not None)
        self._previous = (int(stamps[-1]), float(tc1[-1]), float(tc2[-1]))
        if self._tau is None and self._window.rows >= self._next_first_attempt:
            self._next_first_attempt = self._window.rows + FIRST_ESTIMATE_ROWS
            self.update_estimate()
        if self._tau is None:
            self._hold(stamps, tc1, tc2, steps_s, contiguous)
            return np.empty(0, dtype=np.int64), np.empty(0), np.empty(0)
        if self._backlog:
            return self._reconstruct_backlog_and(stamps, tc1, tc2, steps_s, contiguous)
        return self._reconstruct(stamps, tc1, tc2, steps_s, contiguous)

    def _feed_tracker(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
        linked: bool,
    ) -> None:
        """Give the tracker the new samples (all but the first when ``linked``), gap by gap."""
        assert self._tracker is not None
        for start, stop in _gap_free_runs(contiguous):
            if start > 0 or not linked:
                self._tracker.mark_gap()
            begin = 1 if start == 0 and linked else start
            self._tracker.extend(tc1[begin:stop], tc2[begin:stop])

    def _hold(self, *chunk: NDArray) -> None:
        """Keep pairs until the first τ, at most one window's worth (the oldest go first)."""
        if chunk[3].size == 0:
            return
        self._backlog.append(chunk)
        self._backlog_rows += chunk[3].size
        capacity = self._window.capacity if self._window is not None else 0
        while self._backlog_rows > capacity and len(self._backlog) > 1:
            dropped = self._backlog.pop(0)
            self._backlog_rows -= dropped[3].size
            self.counters["unreconstructed"] += int(dropped[3].size)

    def _reconstruct_backlog_and(
        self, *current: NDArray
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """Reconstruct the held pairs and the current ones with the first τ, in stamp order."""
        outputs = [self._reconstruct(*chunk) for chunk in (*self._backlog, current)]
        self._backlog, self._backlog_rows = [], 0
        stamps, gas, variance = zip(*outputs, strict=True)
        return np.concatenate(stamps), np.concatenate(gas), np.concatenate(variance)

    def _reconstruct(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        if steps_s.size == 0:
            return np.empty(0, dtype=np.int64), np.empty(0), np.empty(0)
        assert self._tau is not None  # pairs are held until the first τ
        out_stamps = stamps[:-1][contiguous]
        self.counters["reconstructed"] += int(out_stamps.size)
        self.counters["unreconstructed"] += int((~contiguous).sum())
        if self._config.reconstruction == "kalman" and self._fuser is not None:
            gas, variance = self._kalman(stamps, tc1, tc2, contiguous)
        else:
            gas = self._difference(tc1, tc2, steps_s, contiguous)
            variance = np.zeros(gas.size)
        return out_stamps, self._postfilter(gas), variance

    def _difference(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        steps_s: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """Eq. (7) over each contiguous step, with the actual step for the poles."""
        assert self._tau is not None  # pairs are held until the first τ
        tau1, tau2 = self._tau
        a1 = np.exp(-steps_s / tau1)
        a2 = np.exp(-steps_s / tau2)
        gas1 = (tc1[1:] - a1 * tc1[:-1]) / (1.0 - a1)
        gas2 = (tc2[1:] - a2 * tc2[:-1]) / (1.0 - a2)
        choice = self._config.reconstruct_from
        combine = "inverse-variance" if choice == "fused" else choice
        assert self._period is not None  # set before any sample reaches here
        weight = combination_weight(
            math.exp(-self._period / tau1),
            math.exp(-self._period / tau2),
            self._config.phi,
            combine,  # type: ignore[arg-type]
        )
        gas = weight * gas1 + (1.0 - weight) * gas2
        return gas[contiguous]

    def _kalman(
        self,
        stamps: NDArray[np.int64],
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Causal Kalman estimate over each contiguous step and its variance.

        The filter continues from the last sample it took when this batch starts with it, and
        starts afresh after a gap or a lost one.
        """
        assert self._fuser is not None
        gas, std = [], []
        for start, stop in _gap_free_runs(contiguous):
            begin = start
            if start == 0 and self._fuser.started and self._fuser_stamp == int(stamps[0]):
                begin = 1
            else:
                self._fuser.reset()
            estimates, deviations = self._fuser.extend(tc1[begin:stop], tc2[begin:stop])
            gas.append(estimates)
            std.append(deviations)
        self._fuser_stamp = int(stamps[-1])
        return np.concatenate(gas), np.concatenate(std) ** 2

    def _postfilter(self, gas: NDArray[np.float64]) -> NDArray[np.float64]:
        cutoff = self._config.postfilter_hz
        if cutoff <= 0.0 or gas.size == 0:
            return gas
        assert self._period is not None  # set before any sample reaches here
        nyquist = 0.5 / self._period
        if self._sos is None:
            self._sos = signal.butter(
                self._config.postfilter_order,
                min(cutoff, 0.99 * nyquist),
                output="sos",
                fs=1.0 / self._period,
            )
            self._filter_state = signal.sosfilt_zi(self._sos) * gas[0]
        filtered, self._filter_state = signal.sosfilt(self._sos, gas, zi=self._filter_state)
        return filtered

    def update_estimate(self) -> EstimateStatus:
        """Re-estimate τ1, τ2 from the window; accept the result when it is sound."""
        status = self._estimate_window()
        if status.accepted and status.estimate is not None:
            self._tau = (status.estimate.tau1, status.estimate.tau2)
            if self._config.reconstruction == "kalman":
                self._update_fuser()
        self.last_status = status
        return status

    def _update_fuser(self) -> None:
        """Retune the Kalman filter to the new τ, or refit its signal model on the window."""
        assert self._tau is not None and self._period is not None
        tau1, tau2 = self._tau
        window = self._window
        assert window is not None  # an accepted τ comes from it
        longest = max(np.split(window.samples, window.segment_starts), key=len)
        segment = longest[-FUSION_FIT_SAMPLES:]
        if self._fuser is not None and self._fusion_tau is not None:
            moved = max(
                abs(new / old - 1.0) for new, old in zip(self._tau, self._fusion_tau, strict=True)
            )
            # Early fits see few samples (noise levels from short spectra): refit as the
            # stretch doubles, up to FUSION_FIT_SAMPLES.
            grown = segment.shape[0] >= 2 * self._fusion_samples
            if moved < FUSION_REFIT_CHANGE and not grown:
                self._fuser.retune(replace(self._fuser.model, tau1=tau1, tau2=tau2))
                return
        try:
            model, _, _ = fit_fusion_model(
                segment[:, 0],
                segment[:, 1],
                self._period,
                tau1,
                tau2,
                model=self._config.signal_model,  # type: ignore[arg-type]
            )
        except (TcompError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self.fusion_error = f"signal model not fitted: {exc}"
            if self._fuser is not None:
                self._fuser.retune(replace(self._fuser.model, tau1=tau1, tau2=tau2))
            return
        self.fusion_error = ""
        if self._fuser is None:
            self._fuser = CausalFuser(model)
        else:
            self._fuser.retune(model)
        self._fusion_tau = (tau1, tau2)
        self._fusion_samples = segment.shape[0]

    def _estimate_window(self) -> EstimateStatus:
        window = self._window
        if window is None or window.rows + 1 < MIN_SAMPLES:
            held = 0 if window is None else window.rows
            return EstimateStatus(
                accepted=False,
                estimate=None,
                reason=f"window holds {held} regression rows; {MIN_SAMPLES - 1} needed",
                stamp_ns=self._newest_stamp,
            )
        config = self._config
        samples = window.samples
        try:
            from_window = False
            if self._tracker is not None and self._tracker.rows + 1 >= MIN_SAMPLES:
                result = self._tracker.estimate()
            elif config.method in BETA_METHODS and config.prefilter_hz == 0.0:
                result = window.estimate()
                from_window = True
            else:
                result = self._estimate_segments(window, samples)
        except (TcompError, ValueError) as exc:
            return EstimateStatus(
                accepted=False, estimate=None, reason=str(exc), stamp_ns=self._newest_stamp
            )
        fit = fit_error_percent(
            samples[:, 0], samples[:, 1], result.a1, result.a2, window.segment_starts
        )
        # β-GTLS on the window's own scatter has already found the eigenvalue the floor needs.
        same_problem = from_window and config.method == "beta-gtls"
        eigenvalue = result.params.get("noise_eigenvalue") if same_problem else None
        floor = self._noise_floor_percent(window, samples, eigenvalue)
        model = math.sqrt(max(fit**2 - floor**2, 0.0))
        reason = ""
        if not result.condition <= config.max_condition:
            reason = (
                f"ill-conditioned: condition {result.condition:.3g} exceeds "
                f"{config.max_condition:.3g}"
            )
        return EstimateStatus(
            accepted=not reason,
            estimate=result,
            reason=reason,
            fit_error_pct=fit,
            noise_floor_pct=floor,
            model_error_pct=model,
            stamp_ns=self._newest_stamp,
            poor_fit=model > config.max_model_error_pct,
        )

    def _estimate_segments(
        self, window: SlidingBetaWindow, samples: NDArray[np.float64]
    ) -> Estimate:
        """Batch estimate on the window's gap-free segments (pre-filtered, if configured).

        A pre-filter run across a gap would smear the jump into the regression, so each segment
        is filtered alone; β methods pool the segments' scatter matrices, the others use the
        longest segment.
        """
        config = self._config
        segments = np.split(samples, window.segment_starts)
        prefilter_hz = config.prefilter_hz or None
        phi = config.phi if config.method == "beta-gtls" else 1.0
        if config.method in BETA_METHODS:
            scatter = np.zeros((3, 3))
            used = 0
            for segment in segments:
                if segment.shape[0] <= MIN_PREFILTER_SAMPLES:
                    continue
                first, second = segment[:, 0], segment[:, 1]
                if prefilter_hz is not None:
                    first = prefilter(first, window.dt, prefilter_hz)
                    second = prefilter(second, window.dt, prefilter_hz)
                scatter += beta_scatter(first, second)
                used += segment.shape[0]
            if used < MIN_SAMPLES:
                raise DataError(f"the window's gap-free segments hold only {used} samples")
            result = estimate_beta_from_scatter(scatter, window.dt, used, config.method, phi)
            return result if prefilter_hz is None else replace(result, prefilter_hz=prefilter_hz)
        longest = max(segments, key=len)
        return estimate(
            longest[:, 0],
            longest[:, 1],
            window.dt,
            config.method,  # type: ignore[arg-type]
            phi=phi,
            prefilter_hz=prefilter_hz,
        )

    def _noise_floor_percent(
        self,
        window: SlidingBetaWindow,
        samples: NDArray[np.float64],
        eigenvalue: float | None = None,
    ) -> float:
        """Fit error that tc2's measurement noise alone would cause, percent of std(tc2).

        The smallest generalized eigenvalue of the β scatter with C0(φ) estimates σ2² times the
        number of rows (the row noise covariance is σ2² C0(φ), Eq. 19); ``eigenvalue`` is that
        eigenvalue when the estimate already solved this problem.
        """
        if eigenvalue is None:
            try:
                _, eigenvalues = solve_gtls(
                    window.scatter, beta_noise_covariance(self._config.phi)
                )
            except (ValueError, np.linalg.LinAlgError):
                return math.nan
            eigenvalue = float(eigenvalues[0])
        sigma2 = math.sqrt(max(eigenvalue, 0.0) / max(window.rows, 1))
        spread = float(np.std(samples[:, 1]))
        return 100.0 * sigma2 / spread if spread > 0.0 else math.nan


def _gap_free_runs(contiguous: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(start, stop)`` sample ranges of a batch split at its gaps.

    ``contiguous[i]`` says whether sample i+1 follows sample i without a gap, so a batch of
    ``contiguous.size + 1`` samples splits after every False.
    """
    breaks = (np.flatnonzero(~contiguous) + 1).tolist()
    return list(zip([0, *breaks], [*breaks, contiguous.size + 1], strict=True))
