"""Sliding-window estimation of τ1, τ2 for the online engine: window, tracker and status.

The window keeps the β scatter matrix up to date in O(1) per sample
(:class:`~tcomp_core.window.SlidingBetaWindow`); :meth:`WindowEstimator.estimate` solves it (β
methods) or runs the batch estimator on the window's gap-free segments (γ, TDR, or when a
pre-filter is set), and grades the result (:class:`~.config.EstimateStatus`): accepted when it is
well conditioned, a poor fit when the model error beyond the noise floor exceeds the limit.
With ``tracking_memory_s`` > 0 the τ comes from an exponentially forgetting β-GTLS with the
ratio τ1/τ2 held to its long-term value (:class:`~tcomp_core.tracking.ForgettingEstimator`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, TcompError
from ..estimators import (
    PHI_METHODS,
    Estimate,
    beta_noise_covariance,
    estimate,
    warm_start,
)
from ..estimators.beta import estimate_beta_from_scatter
from ..estimators.mleiv import phi_from_data
from ..estimators.scatter import beta_scatter, solve_gtls
from ..filters import prefilter_pair, transient_samples
from ..fit import fit_error_percent, rms_about_mean
from ..tracking import ForgettingEstimator
from ..validation import MIN_SAMPLES
from ..window import BETA_METHODS, SlidingBetaWindow
from .config import MIN_PREFILTER_SAMPLES, RATIO_MEMORY_FACTOR, EstimateStatus, OnlineConfig

__all__ = ["EstimationJob", "WindowEstimator", "gap_free_runs"]


class WindowEstimator:
    """The estimation window (and tracker) of the online engine.

    Parameters
    ----------
    config : OnlineConfig
    period_s : float
        Sample period of the pairs, seconds (> 0).
    """

    def __init__(self, config: OnlineConfig, period_s: float) -> None:
        if not period_s > 0.0:
            raise ValueError(f"{period_s=} must be > 0 s")
        self._config = config
        self._period = period_s
        self._window = self._new_window()
        self._tracker = self._new_tracker()
        #: τ1, τ2 (and gain) of the last estimate, the warm start of the next ``ml-eiv`` search.
        self._warm: tuple[float, ...] | None = None
        #: The noise ratio the last estimate measured, the next one's first (None: not measured).
        self._warm_phi: float | None = None

    # -- state ---------------------------------------------------------------------------------
    @property
    def rows(self) -> int:
        """Regression rows in the window (samples minus the links broken by gaps)."""
        return self._window.rows

    @property
    def samples_held(self) -> int:
        """Sample pairs in the window."""
        return len(self._window)

    @property
    def capacity(self) -> int:
        """Sample pairs the window holds at most."""
        return self._window.capacity

    def segments(self) -> list[NDArray[np.float64]]:
        """The window's gap-free stretches, oldest first, each of shape (n, 2), degrees C."""
        return np.split(self._window.samples, self._window.segment_starts)

    def longest_segment(self) -> NDArray[np.float64]:
        """The window's longest gap-free stretch, shape (n, 2): tc1, tc2 in degrees C."""
        return max(self.segments(), key=len)

    def reconfigure(self, config: OnlineConfig, period_s: float) -> None:
        """Apply new settings, keeping the window's samples where they still fit."""
        old, old_period = self._config, self._period
        self._config, self._period = config, period_s
        if (
            config.window_s != old.window_s
            or config.max_window_samples != old.max_window_samples
            or period_s != old_period
            or (config.method, config.phi) != (old.method, old.phi)
        ):
            samples = self._window.samples
            self._window = self._new_window()
            self._window.extend(samples[:, 0], samples[:, 1])
        if (config.tracking_memory_s, config.phi, config.window_s) != (
            old.tracking_memory_s,
            old.phi,
            old.window_s,
        ):
            self._tracker = self._new_tracker()
            if self._tracker is not None:
                for segment in self.segments():
                    self._tracker.mark_gap()
                    self._tracker.extend(segment[:, 0], segment[:, 1])

    def _new_tracker(self) -> ForgettingEstimator | None:
        memory = self._config.tracking_memory_s
        if memory <= 0.0:
            return None
        return ForgettingEstimator(
            self._period,
            memory_s=memory,
            phi=self._config.fixed_phi or 1.0,  # the tracker takes 1 when phi is measured
            ratio_memory_s=max(self._config.window_s, RATIO_MEMORY_FACTOR * memory),
        )

    def _new_window(self) -> SlidingBetaWindow:
        wanted = round(self._config.window_s / self._period)
        capacity = max(MIN_SAMPLES, min(wanted, self._config.max_window_samples))
        method = self._config.method if self._config.method in BETA_METHODS else "beta-gtls"
        return SlidingBetaWindow(capacity, self._period, method, self._config.fixed_phi or 1.0)

    # -- samples -------------------------------------------------------------------------------
    def extend(
        self,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        contiguous: NDArray[np.bool_],
        linked: bool,
    ) -> None:
        """Take a run of samples.

        Parameters
        ----------
        tc1, tc2 : ndarray, shape (n,)
            Degrees C; with ``linked`` the first sample is the last one already taken.
        contiguous : ndarray of bool, shape (n - 1,)
            ``contiguous[i]``: sample i+1 follows sample i without a gap.
        linked : bool
            Whether the first sample is the previous run's last (only its link is new).
        """
        if linked:
            self._window.extend(tc1[1:], tc2[1:], contiguous)
        else:  # the very first sample has no predecessor to link to
            self._window.extend(tc1, tc2, np.concatenate(([True], contiguous)))
        if self._tracker is not None:
            for start, stop in gap_free_runs(contiguous):
                if start > 0 or not linked:
                    self._tracker.mark_gap()
                begin = 1 if start == 0 and linked else start
                self._tracker.extend(tc1[begin:stop], tc2[begin:stop])

    # -- estimation ----------------------------------------------------------------------------
    def estimate(self, stamp_ns: int) -> EstimateStatus:
        """Estimate τ1, τ2 on the window and grade the result (:meth:`job`, run, adopted).

        Parameters
        ----------
        stamp_ns : int
            Stamp of the newest sample in the window, ns (carried into the status).
        """
        status = self.job(stamp_ns).run()
        self.adopt(status)
        return status

    def job(self, stamp_ns: int) -> EstimationJob:
        """The estimate of the window as it is now, to run anywhere (a copy of what it needs).

        The O(1) paths (the tracker, β methods on the window's scatter) are solved here; the
        batch estimators (``ml-eiv``, γ, TDR, or any method with a pre-filter) run in
        :meth:`EstimationJob.run`, which a caller may hand to a thread.
        """
        window = self._window
        config = self._config
        if window.rows + 1 < MIN_SAMPLES:
            refused = EstimateStatus(
                accepted=False,
                estimate=None,
                reason=f"window holds {window.rows} regression rows; {MIN_SAMPLES - 1} needed",
                stamp_ns=stamp_ns,
            )
            return EstimationJob(config=config, stamp_ns=stamp_ns, refused=refused)
        result: Estimate | str | None = None
        try:
            if self._tracker is not None and self._tracker.rows + 1 >= MIN_SAMPLES:
                result = self._tracker.estimate()
            elif (
                config.method in BETA_METHODS
                and config.prefilter_hz == 0.0
                and not (config.method in PHI_METHODS and config.fixed_phi is None)
            ):
                result = window.estimate()  # φ measured needs the samples: the batch path
        except (TcompError, ValueError) as exc:
            result = str(exc)
        from_window = result is not None and self._tracker is None
        return EstimationJob(
            config=config,
            stamp_ns=stamp_ns,
            samples=window.samples,  # a copy: the window moves on while the job runs
            segment_starts=window.segment_starts,
            scatter=window.scatter,  # a copy
            rows=window.rows,
            dt=window.dt,
            warm=self._warm,
            warm_phi=self._warm_phi,
            solved=result,
            same_problem=from_window and config.method == "beta-gtls",
        )

    def adopt(self, status: EstimateStatus) -> None:
        """Take a job's status: its τ, gain and measured φ warm-start the next ``ml-eiv``."""
        estimate = status.estimate
        if estimate is not None and estimate.method == "ml-eiv":
            self._warm = warm_start(estimate)
            self._warm_phi = estimate.phi if estimate.params.get("phi_estimated") else None


@dataclass(frozen=True, kw_only=True)
class EstimationJob:
    """One estimate of a window, self-contained: :meth:`run` may run on another thread.

    Attributes
    ----------
    config : OnlineConfig
    stamp_ns : int
        Stamp of the newest sample, ns (carried into the status).
    refused : EstimateStatus or None
        The status when the window is too short to estimate (then nothing else is set).
    samples : ndarray, shape (n, 2)
        The window's pairs, degrees C (a copy).
    segment_starts : ndarray of int
        Where the window's gap-free segments start (after the first).
    scatter : ndarray, shape (3, 3)
        The window's β scatter matrix.
    rows : int
        Regression rows of the window.
    dt : float
        Sample period, s.
    warm : tuple of float or None
        Start of an ``ml-eiv`` search: τ1, τ2 (s) and the gain
        (:func:`~tcomp_core.estimators.warm_start`).
    warm_phi : float or None
        The noise ratio the last estimate measured: the first fit's when φ is measured
        (``estimate``'s ``phi_start``).
    solved : Estimate or str or None
        The result of an O(1) path, or its error message; None: the batch estimator runs.
    same_problem : bool
        Whether ``solved`` is β-GTLS on this scatter (its eigenvalue gives the noise floor).
    """

    config: OnlineConfig
    stamp_ns: int
    refused: EstimateStatus | None = None
    samples: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 2)))
    segment_starts: NDArray[np.intp] = field(default_factory=lambda: np.empty(0, np.intp))
    scatter: NDArray[np.float64] = field(default_factory=lambda: np.zeros((3, 3)))
    rows: int = 0
    dt: float = math.nan
    warm: tuple[float, ...] | None = None
    warm_phi: float | None = None
    solved: Estimate | str | None = None
    same_problem: bool = False

    def run(self) -> EstimateStatus:
        """Estimate τ1, τ2 and grade the result.

        Accepted when well conditioned; a poor fit when the model error beyond the noise floor
        exceeds ``max_model_error_pct``.
        """
        if self.refused is not None:
            return self.refused
        config, samples, stamp_ns = self.config, self.samples, self.stamp_ns
        try:
            if isinstance(self.solved, str):
                raise DataError(self.solved)
            result = self.solved if self.solved is not None else self._estimate_segments()
        except (TcompError, ValueError) as exc:
            return EstimateStatus(
                accepted=False, estimate=None, reason=str(exc), stamp_ns=stamp_ns
            )
        fit = fit_error_percent(
            samples[:, 0], samples[:, 1], result.a1, result.a2, self.segment_starts
        )
        # β-GTLS on the window's own scatter has already found the eigenvalue the floor needs.
        eigenvalue = result.params.get("noise_eigenvalue") if self.same_problem else None
        floor = self._noise_floor_percent(eigenvalue, result.phi)
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
            stamp_ns=stamp_ns,
            poor_fit=model > config.max_model_error_pct,
            level_c=float(np.mean(samples)),
        )

    def _estimate_segments(self) -> Estimate:
        """Batch estimate on the window's gap-free segments (pre-filtered, if configured).

        A pre-filter run across a gap would smear the jump into the regression, so each segment
        is filtered alone; β methods pool the segments' scatter matrices, the others use the
        longest segment.
        """
        config, dt = self.config, self.dt
        segments = np.split(self.samples, self.segment_starts)
        prefilter_hz = config.prefilter_hz or None
        phi = config.fixed_phi if config.method in PHI_METHODS else 1.0
        longest = max(segments, key=len)
        if config.method in BETA_METHODS:
            if phi is None:  # measured as ``estimate`` first measures it: from the spectra
                phi = phi_from_data(longest[:, 0], longest[:, 1], dt, unmeasurable=1.0)
            scatter = np.zeros((3, 3))
            used = 0
            # A pre-filter's start-up transients are left out at both ends of each segment.
            edge = 0 if prefilter_hz is None else transient_samples(prefilter_hz, dt)
            for segment in segments:
                if segment.shape[0] <= MIN_PREFILTER_SAMPLES + 2 * edge:
                    continue
                first, second = segment[:, 0], segment[:, 1]
                if prefilter_hz is not None:
                    first, second = prefilter_pair(first, second, dt, prefilter_hz)
                scatter += beta_scatter(first, second)
                used += first.size
            if used < MIN_SAMPLES:
                raise DataError(f"the window's gap-free segments hold only {used} samples")
            result = estimate_beta_from_scatter(scatter, dt, used, config.method, phi)
            return result if prefilter_hz is None else replace(result, prefilter_hz=prefilter_hz)
        return estimate(
            longest[:, 0],
            longest[:, 1],
            dt,
            config.method,  # type: ignore[arg-type]
            phi=phi,
            prefilter_hz=prefilter_hz,
            start=self.warm,
            phi_start=self.warm_phi if phi is None else None,
        )

    def _noise_floor_percent(
        self, eigenvalue: float | None = None, phi: float | None = None
    ) -> float:
        """Fit error that tc2's measurement noise alone would cause, percent of std(tc2).

        The smallest generalized eigenvalue of the β scatter with C0(φ) estimates σ2² times the
        number of rows (the row noise covariance is σ2² C0(φ), Eq. 19); ``eigenvalue`` is that
        eigenvalue when the estimate already solved this problem. φ is the estimate's (measured
        or given), else the configured one, else 1.
        """
        if eigenvalue is None:
            ratio = phi or self.config.fixed_phi or 1.0
            try:
                _, eigenvalues = solve_gtls(self.scatter, beta_noise_covariance(ratio))
            except (ValueError, np.linalg.LinAlgError):
                return math.nan
            eigenvalue = float(eigenvalues[0])
        sigma2 = math.sqrt(max(eigenvalue, 0.0) / max(self.rows, 1))
        spread = rms_about_mean(self.samples[:, 1])
        return 100.0 * sigma2 / spread if spread > 0.0 else math.nan


def gap_free_runs(contiguous: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(start, stop)`` sample ranges of a batch split at its gaps.

    ``contiguous[i]`` says whether sample i+1 follows sample i without a gap, so a batch of
    ``contiguous.size + 1`` samples splits after every False.
    """
    breaks = (np.flatnonzero(~contiguous) + 1).tolist()
    return list(zip([0, *breaks], [*breaks, contiguous.size + 1], strict=True))
