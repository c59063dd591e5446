"""Settings of the online engine and the outcome of one re-estimation.

Shared by the compensator node (its parameters map onto :class:`OnlineConfig` field for field)
and ``tcomp process``; the tuning constants of the engine live here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..choices import RECONSTRUCT_FROM, RECONSTRUCTIONS, SIGNAL_MODELS, ReconstructFrom
from ..estimators import DEFAULT_METHOD, METHODS, Estimate
from ..validation import MIN_SAMPLES

__all__ = [
    "FIRST_ESTIMATE_ROWS",
    "FUSION_FIT_SAMPLES",
    "FUSION_REFIT_CHANGE",
    "MIN_PREFILTER_SAMPLES",
    "PERIOD_LEARNING_SAMPLES",
    "RATIO_MEMORY_FACTOR",
    "RECONSTRUCTIONS",
    "RECONSTRUCT_FROM",
    "SIGNAL_MODELS",
    "EstimateStatus",
    "OnlineConfig",
    "ReconstructFrom",
]

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
#: Bytes the window holds per sample pair (a buffer twice the window of three float64 columns).
WINDOW_BYTES_PER_SAMPLE = 48


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
    min_temperature_c, max_temperature_c : float
        Physical range of a reading, degrees C: samples outside it (or not finite) are invalid,
        counted and left out of estimation and output.
    max_window_samples : int
        Memory budget of the window, in sample pairs (:data:`WINDOW_BYTES_PER_SAMPLE` bytes
        each): a ``window_s`` that needs more at ``sample_period_s`` is refused, and a window
        sized from a learnt period is clipped to it.
    discontinuity_s : float
        Stamps this far (seconds) behind the last matched stamp, several in a row, are a
        discontinuity (a clock reset, a replayed bag starting over): the engine restarts.
    """

    window_s: float = 2.0
    method: str = DEFAULT_METHOD
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
    min_temperature_c: float = -273.15
    max_temperature_c: float = 2000.0
    max_window_samples: int = 500_000
    discontinuity_s: float = 10.0

    @property
    def valid_range(self) -> tuple[float, float]:
        """``(min_temperature_c, max_temperature_c)``."""
        return self.min_temperature_c, self.max_temperature_c

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
            (
                -273.15 <= self.min_temperature_c < self.max_temperature_c < math.inf,
                f"min_temperature_c={self.min_temperature_c!r}, max_temperature_c="
                f"{self.max_temperature_c!r}: need -273.15 <= min < max, both finite",
            ),
            (
                MIN_SAMPLES <= self.max_window_samples <= 10**8,
                f"max_window_samples={self.max_window_samples!r} must lie in [{MIN_SAMPLES}, 1e8]",
            ),
            (
                math.isfinite(self.discontinuity_s) and self.discontinuity_s > 0.0,
                f"discontinuity_s={self.discontinuity_s!r} must be > 0 s",
            ),
        ]
        for holds, message in checks:
            if not holds:
                raise ValueError(message)
        if self.sample_period_s > 0.0:
            needed = self.window_s / self.sample_period_s
            if needed > self.max_window_samples:
                raise ValueError(
                    f"window_s={self.window_s!r} at sample_period_s={self.sample_period_s!r} "
                    f"needs {needed:.3g} samples ({needed * WINDOW_BYTES_PER_SAMPLE / 1e6:.3g} "
                    f"MB), above max_window_samples={self.max_window_samples}"
                )


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
