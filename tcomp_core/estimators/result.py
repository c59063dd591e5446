"""The result every estimator returns, and the conversion from discrete poles to time constants."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from ..lines import ForeignLine
from ..models import pole_to_tau

__all__ = ["MAX_TAU_INTERVAL", "Estimate", "estimate_from_poles"]

#: Largest half-width of an estimate's 95 % interval of τ1 or τ2, relative to it, for the data
#: to pin the time constant down (the online engine accepts no estimate beyond it).
MAX_TAU_INTERVAL = 0.2


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """Time constants of two thermocouples estimated from their signals alone.

    Attributes
    ----------
    method : str
        Estimator name (``'beta-gtls'``, ``'gamma-ls'``...).
    tau1, tau2 : float
        Time constants of thermocouples 1 and 2, seconds.
    a1, a2 : float
        Discrete poles exp(-τ_s/τ) of the ZOH difference equations (Eq. 5).
    dt : float
        Sample interval τ_s, seconds.
    n_samples : int
        Samples of each signal used.
    condition : float
        Conditioning figure, dimensionless, >= 1, larger is worse. For the difference-equation
        methods: the 2-norm condition number of the column-equilibrated regressor matrix of the
        regression actually solved (Eq. 11 or Eq. 14); for TDR-Kee: 1 + the coefficient of
        variation of the per-window time constants.
    params : dict of str to float
        The raw parameters: ``gamma1..3`` (Eq. 10), or ``beta`` and ``b1`` (Eq. 12, 17), plus
        method-specific figures.
    phi : float or None
        Noise variance ratio σ1²/σ2² assumed (β-GTLS only).
    prefilter_hz : float or None
        Bandwidth of the zero-phase pre-filter applied before estimation.
    lines : tuple of ForeignLine
        Spectral lines one sensor carried and the other did not (mains pick-up), notched from
        both signals before the estimate (:func:`tcomp_core.lines.foreign_lines`); empty when
        there were none or the estimate did not look.
    """

    method: str
    tau1: float
    tau2: float
    a1: float
    a2: float
    dt: float
    n_samples: int
    condition: float
    params: dict[str, float] = field(default_factory=dict)
    phi: float | None = None
    prefilter_hz: float | None = None
    lines: tuple[ForeignLine, ...] = ()

    def __post_init__(self) -> None:
        # From to_dict's JSON the lines come back as a list of dicts.
        lines = tuple(
            line if isinstance(line, ForeignLine) else ForeignLine(**line) for line in self.lines
        )
        object.__setattr__(self, "lines", lines)

    @property
    def alpha(self) -> float:
        """Time constant ratio α = τ1/τ2 (Eq. 24)."""
        return self.tau1 / self.tau2

    @property
    def b1(self) -> float:
        """Input gain 1 - a1 of thermocouple 1's difference equation (Eq. 6)."""
        return 1.0 - self.a1

    @property
    def b2(self) -> float:
        """Input gain 1 - a2 of thermocouple 2's difference equation (Eq. 6)."""
        return 1.0 - self.a2

    def wide_interval(self, limit: float = MAX_TAU_INTERVAL) -> str:
        """The first τ whose 95 % interval's half-width exceeds ``limit`` of it, said; or ''.

        Estimators without intervals (``params`` without ``tau1_ci_low``) give ''.
        """
        for i, tau in enumerate((self.tau1, self.tau2), start=1):
            low = self.params.get(f"tau{i}_ci_low", math.nan)
            high = self.params.get(f"tau{i}_ci_high", math.nan)
            half = 0.5 * (high - low) / tau
            if math.isfinite(half) and half > limit:
                return (
                    f"tau{i}'s 95 % interval {low:.4g} .. {high:.4g} s is wider than "
                    f"+-{100 * limit:g} %"
                )
        return ""

    def tau_log_se(self) -> tuple[float, float] | None:
        """Standard errors of log τ1 and log τ2 (σ_τi / τ_i); None for estimators without them.

        From ``params["tau1_se"]``, ``["tau2_se"]`` (ml-eiv's delta-method standard errors, s).
        """
        found = [
            self.params.get(f"tau{i}_se", math.nan) / tau
            for i, tau in ((1, self.tau1), (2, self.tau2))
        ]
        if not all(math.isfinite(value) and value >= 0.0 for value in found):
            return None
        return found[0], found[1]

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dictionary of the estimate, with α added."""
        data = asdict(self)
        data["alpha"] = self.alpha
        return data


def estimate_from_poles(
    method: str,
    a1: float,
    a2: float,
    dt: float,
    n_samples: int,
    condition: float,
    params: dict[str, float],
    **extra: Any,
) -> Estimate:
    """Build an :class:`Estimate` from discrete poles, refusing poles outside (0, 1).

    Raises
    ------
    PhysicalRangeError
        Naming the method, the pole and the raw parameters that produced it.
    """
    shown = ", ".join(f"{key}={value:.6g}" for key, value in params.items())
    try:
        tau1 = pole_to_tau(a1, dt, label=f"{method}: a1")
        tau2 = pole_to_tau(a2, dt, label=f"{method}: a2")
    except ValueError as exc:
        raise type(exc)(f"{exc} (from {shown}; condition {condition:.3g})") from None
    return Estimate(
        method=method,
        tau1=tau1,
        tau2=tau2,
        a1=float(a1),
        a2=float(a2),
        dt=dt,
        n_samples=n_samples,
        condition=float(condition) if math.isfinite(condition) else math.inf,
        params={key: float(value) for key, value in params.items()},
        **extra,
    )
