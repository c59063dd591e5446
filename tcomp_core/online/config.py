"""Settings of the online engine and the outcome of one re-estimation.

Shared by the compensator node (its parameters map onto :class:`OnlineConfig` field for field)
and ``tcomp process``; the tuning constants of the engine live here too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .. import parameters
from ..choices import RECONSTRUCT_FROM, RECONSTRUCTIONS, SIGNAL_MODELS, ReconstructFrom
from ..diagnose.saved import saved_diagnosis_effects
from ..estimators import Estimate
from ..validation import MIN_SAMPLES

__all__ = [
    "ENGINE_PARAMETERS",
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
#: Smallest noise variance ratio ``phi`` that may be fixed (0 measures it from each window).
MIN_FIXED_PHI = 1e-6
#: Bytes the window holds per sample pair (a buffer twice the window of three float64 columns).
WINDOW_BYTES_PER_SAMPLE = 48
#: The node's parameters that configure the engine (fields of :class:`OnlineConfig`).
ENGINE_PARAMETERS = tuple(p.name for p in parameters.PARAMETERS if p.scope == "engine")


def _default(name: str) -> Any:
    """The declared default of parameter ``name`` (:mod:`tcomp_core.parameters`)."""
    return parameters.default(name)


@dataclass(frozen=True, kw_only=True)
class OnlineConfig:
    """Settings of the online engine: the node's parameters but its ROS ones, and two constants.

    Every field but ``postfilter_order`` and ``gap_factor`` is a parameter of the node declared
    in :mod:`tcomp_core.parameters`, which gives its default, range and description; the checks
    here are those ranges and what ties the fields together.

    Attributes
    ----------
    window_s : float
        Length of the estimation window, seconds.
    update_period_s : float
        Re-estimation period, seconds (the node's timer; ``tcomp process``'s stamp-time
        schedule); also sets when an estimate is STALE.
    method : str
        Estimator, one of :data:`tcomp_core.METHODS`.
    phi : float
        Noise variance ratio σ1²/σ2² for ml-eiv, β-GTLS and for fusing the reconstructions;
        0 = measured from each window (:attr:`fixed_phi`).
    prefilter_hz : float
        Zero-phase pre-filter applied to the window before estimation, Hz; 0 = off.
    postfilter_hz : float
        Causal Butterworth low-pass on the reconstruction, Hz; 0 = off.
    postfilter_order : int
        Order of that low-pass (not a parameter).
    sync_slop_s : float
        Largest stamp difference of a tc1/tc2 pair, seconds (0 = exact stamps).
    reconstruction : {'kalman', 'difference'}
        The causal Kalman filter of both sensors (default) or Eq. (7).
    signal_model : {'auto', 'random-walk', 'integrated-random-walk', 'band-limited', \
'periodic', 'autoregressive'}
        Gas temperature model of the Kalman filter (:mod:`tcomp_core.fusion`).
    reconstruct_from : {'fused', 'tc1', 'tc2'}
        Which Eq. (7) reconstruction is output (``'difference'`` only).
    tracking_memory_s : float
        Forgetting time constant of the tracking estimator, seconds; 0 = sliding window.
    sample_period_s : float
        Sample period of the pairs, seconds; 0 = learn it from the stamps.
    silence_timeout_s : float
        A sensor silent this long is an ERROR, seconds.
    gap_factor : float
        A step longer than this many periods is a gap (not a parameter).
    max_condition : float
        Estimates whose conditioning figure exceeds this are not accepted.
    max_model_error_pct : float
        Model error (fit error beyond the noise floor) above which the fit counts as poor.
    queue_size : int
        Unmatched samples kept per input.
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
    effects : str
        Effects the background diagnosis adds to the first-order model (comma-separated,
        ``'none'``), ``'auto'``, or a diagnosis saved by ``tcomp diagnose --json``
        (``*.json``: its final model's effects, read when the config is made).
    compensate_effects : bool
        Publish the gas of an accepted background fit of ``effects``.
    diagnosis_period_s : float
        Period of the background diagnosis, seconds (0 = only when ``effects`` changes).
    """

    window_s: float = _default("window_s")
    update_period_s: float = _default("update_period_s")
    method: str = _default("method")
    phi: float = _default("phi")
    prefilter_hz: float = _default("prefilter_hz")
    postfilter_hz: float = _default("postfilter_hz")
    postfilter_order: int = 2
    sync_slop_s: float = _default("sync_slop_s")
    reconstruction: str = _default("reconstruction")
    signal_model: str = _default("signal_model")
    reconstruct_from: str = _default("reconstruct_from")
    tracking_memory_s: float = _default("tracking_memory_s")
    sample_period_s: float = _default("sample_period_s")
    silence_timeout_s: float = _default("silence_timeout_s")
    gap_factor: float = 1.5
    max_condition: float = _default("max_condition")
    max_model_error_pct: float = _default("max_model_error_pct")
    queue_size: int = _default("queue_size")
    min_temperature_c: float = _default("min_temperature_c")
    max_temperature_c: float = _default("max_temperature_c")
    max_window_samples: int = _default("max_window_samples")
    discontinuity_s: float = _default("discontinuity_s")
    effects: str = _default("effects")
    compensate_effects: bool = _default("compensate_effects")
    diagnosis_period_s: float = _default("diagnosis_period_s")

    @property
    def valid_range(self) -> tuple[float, float]:
        """``(min_temperature_c, max_temperature_c)``."""
        return self.min_temperature_c, self.max_temperature_c

    @property
    def fixed_phi(self) -> float | None:
        """``phi``, or None when it is measured from each window (``phi`` 0)."""
        return self.phi if self.phi > 0.0 else None

    @property
    def slop_ns(self) -> int:
        """``sync_slop_s`` in nanoseconds."""
        return round(self.sync_slop_s * 1e9)

    @property
    def requested_effects(self) -> tuple[str, ...] | None:
        """``effects`` as names (None: ``auto``; empty: the first-order model alone)."""
        from ..compensation import parse_compensate_effects

        return parse_compensate_effects(self.effects)

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> OnlineConfig:
        """The engine's settings among ``values`` (a node's parameters: extra names ignored)."""
        return cls(**{name: values[name] for name in ENGINE_PARAMETERS if name in values})

    def __post_init__(self) -> None:
        if isinstance(self.effects, str):
            # A saved diagnosis is read once, here: the engine holds the names, whatever
            # becomes of the file.
            object.__setattr__(self, "effects", saved_diagnosis_effects(self.effects))
        for name in ENGINE_PARAMETERS:
            parameters.spec(name).check(getattr(self, name))
        checks = [
            (1 <= self.postfilter_order <= 8, f"postfilter_order={self.postfilter_order!r}"),
            (self.gap_factor > 1.0, f"gap_factor={self.gap_factor!r} must be > 1"),
            (
                self.phi == 0.0 or self.phi >= MIN_FIXED_PHI,
                f"phi={self.phi!r} must be 0 (measured from each window) or >= {MIN_FIXED_PHI:g}",
            ),
            (
                self.min_temperature_c < self.max_temperature_c,
                f"min_temperature_c={self.min_temperature_c!r}, max_temperature_c="
                f"{self.max_temperature_c!r}: need min < max",
            ),
            (
                self.max_window_samples >= MIN_SAMPLES,
                f"max_window_samples={self.max_window_samples!r} must be >= {MIN_SAMPLES}",
            ),
            (
                self.diagnosis_period_s == 0.0
                or self.diagnosis_period_s >= parameters.MIN_DIAGNOSIS_PERIOD_S,
                f"diagnosis_period_s={self.diagnosis_period_s!r} must be 0 (no periodic "
                f"diagnosis) or >= {parameters.MIN_DIAGNOSIS_PERIOD_S:g} s",
            ),
        ]
        for holds, message in checks:
            if not holds:
                raise ValueError(message)
        self.requested_effects  # noqa: B018 - raises ValueError on an unknown effect
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
    level_c : float
        Mean temperature of the window's readings, degrees C (nan when none was estimated):
        the level class 2's tolerance is judged at.
    """

    accepted: bool
    estimate: Estimate | None
    reason: str = ""
    fit_error_pct: float = math.nan
    noise_floor_pct: float = math.nan
    model_error_pct: float = math.nan
    stamp_ns: int = 0
    poor_fit: bool = False
    level_c: float = math.nan
