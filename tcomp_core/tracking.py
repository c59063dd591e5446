"""Tracking time constants that change with the flow: β-GTLS on an exponentially forgotten scatter.

The time constants fall as the gas velocity rises (Eq. 3, τ ∝ v^-m) while their ratio
α = τ1/τ2 stays put: it depends on the two wire diameters only. Both facts are used here.

Every β estimator needs only the 3×3 scatter of the regression rows ``[x1, x2, y]`` of Eq. (14)
(:func:`tcomp_core.estimators.scatter.beta_rows`). Forgetting old rows exponentially,

    S_k = λ S_{k-1} + z_kᵀ z_k,     λ = exp(-dt / memory_s),

gives a scatter that describes the last ``memory_s`` seconds, at O(1) cost per sample. Solving
it with β-GTLS (Eqs. 18–21) tracks both time constants freely. With ``constrain_ratio`` the
ratio α is instead estimated over the long term (the whole record offline, a long or unlimited
memory online) and only the common scale over the short memory: the constrained GTLS
minimises the same Rayleigh quotient ``vᵀ S v / vᵀ C0 v`` along the one-parameter curve
``v(τ2) = [β, b2, -1]`` with ``b_i = 1 - exp(-dt/τ_i)``, ``τ1 = α τ2``, ``β = b2/b1``. One
parameter instead of two roughly halves the variance.

A causal (one-sided) memory lags a changing τ by about ``memory_s``; offline the default is a
centred (two-sided) memory, the sum of a forward and a backward forgotten scatter, which has
no lag for a linear trend.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from .errors import DataError
from .estimators.beta import beta_noise_covariance, estimate_beta_from_scatter
from .estimators.result import Estimate, estimate_from_poles
from .estimators.scatter import beta_rows, beta_scatter, equilibrated_condition
from .models import tau_to_pole
from .noise import estimate_noise
from .validation import check_excitation, check_finite, check_pair, check_sample_interval

__all__ = [
    "ForgettingEstimator",
    "TauTrack",
    "solve_scale",
    "track_tau",
    "varying_lag_response",
]

#: Factor either side of the long-term τ2 within which the short-term scale is searched.
SCALE_SEARCH = 4.0
#: Method name carried by the estimates.
METHOD = "beta-gtls-forgetting"


def varying_lag_response(
    gas: ArrayLike, tau: ArrayLike, dt: float, initial: float | None = None
) -> NDArray[np.float64]:
    """Response of a first-order sensor whose time constant changes from sample to sample.

    ``T(k+1) = a_k T(k) + (1 - a_k) T_g(k)``, ``a_k = exp(-dt/τ_k)``: the exact ZOH response
    (Eq. 4) with the time constant held over each sample interval.

    Parameters
    ----------
    gas : array_like, shape (N,)
        Gas temperature held over each interval, degrees C.
    tau : array_like, shape (N,)
        Time constant over each interval, seconds.
    dt : float
        Sample interval, seconds.
    initial : float, optional
        Sensor temperature at sample 0; ``gas[0]`` when omitted.

    Returns
    -------
    ndarray, shape (N,)
        Sensor temperature, degrees C.
    """
    values = check_finite(gas, "gas temperature")
    poles = tau_to_pole(check_finite(tau, "tau"), check_sample_interval(dt))
    if poles.shape != values.shape:
        raise DataError(f"tau has shape {poles.shape}, the gas temperature {values.shape}")
    response = np.empty_like(values)
    current = float(values[0] if initial is None else initial)
    for k, (pole, target) in enumerate(zip(poles.tolist(), values.tolist(), strict=True)):
        response[k] = current
        current = pole * current + (1.0 - pole) * target
    return response


def _rayleigh_quotient(
    scatter: NDArray[np.float64], covariance: NDArray[np.float64], vector: NDArray[np.float64]
) -> float:
    return float(vector @ scatter @ vector) / float(vector @ covariance @ vector)


def _constrained_vector(tau2: float, ratio: float, dt: float) -> NDArray[np.float64]:
    """``[β, b1 β, -1]`` of Eq. (15) for ``τ1 = ratio τ2``."""
    b1 = -math.expm1(-dt / (ratio * tau2))
    b2 = -math.expm1(-dt / tau2)
    return np.array([b2 / b1, b2, -1.0])


def solve_scale(
    scatter: NDArray[np.float64],
    dt: float,
    ratio: float,
    guess_tau2: float,
    phi: float = 1.0,
) -> float:
    """Constrained β-GTLS: τ2 minimising the GTLS cost with τ1 = ratio · τ2.

    Parameters
    ----------
    scatter : ndarray, shape (3, 3)
        β scatter matrix (Eq. 14 rows), possibly forgotten.
    dt : float
        Sample interval, seconds.
    ratio : float
        α = τ1/τ2.
    guess_tau2 : float
        Centre of the search, seconds; τ2 is sought within a factor :data:`SCALE_SEARCH`.
    phi : float
        Noise variance ratio σ1²/σ2².

    Returns
    -------
    float
        τ2 in seconds.
    """
    covariance = beta_noise_covariance(phi)
    best = scipy.optimize.minimize_scalar(
        lambda log_tau: _rayleigh_quotient(
            scatter, covariance, _constrained_vector(math.exp(log_tau), ratio, dt)
        ),
        bounds=(math.log(guess_tau2 / SCALE_SEARCH), math.log(guess_tau2 * SCALE_SEARCH)),
        method="bounded",
        options={"xatol": 1e-6},
    )
    return float(math.exp(best.x))


def _constrained_estimate(
    scatter: NDArray[np.float64],
    dt: float,
    ratio: float,
    guess_tau2: float,
    phi: float,
    n_samples: int,
) -> Estimate:
    """An :class:`Estimate` from the constrained solution."""
    tau2 = solve_scale(scatter, dt, ratio, guess_tau2, phi)
    a1, a2 = tau_to_pole([ratio * tau2, tau2], dt)
    return estimate_from_poles(
        METHOD,
        float(a1),
        float(a2),
        dt,
        n_samples,
        equilibrated_condition(scatter[:2, :2]),
        {"beta": (1.0 - a2) / (1.0 - a1), "b1": 1.0 - a1, "ratio": ratio},
        phi=phi,
    )


@dataclass(frozen=True, kw_only=True)
class TauTrack:
    """Time constants tracked through a record.

    Attributes
    ----------
    time : ndarray, shape (M,)
        Times the estimates refer to, seconds from the first sample.
    tau1, tau2 : ndarray, shape (M,)
        Time constants, seconds (NaN where no estimate could be made).
    ratio : float
        Long-term α = τ1/τ2 imposed on the track (NaN when unconstrained).
    memory_s : float
        Forgetting time constant, seconds.
    centered : bool
        Whether the memory is two-sided (no lag) or causal (lags by about ``memory_s``).
    """

    time: NDArray[np.float64]
    tau1: NDArray[np.float64]
    tau2: NDArray[np.float64]
    ratio: float
    memory_s: float
    centered: bool


def _block_scatters(
    rows: NDArray[np.float64], ends: NDArray[np.intp], decay: float
) -> NDArray[np.float64]:
    """Forgotten scatter after each block of rows: ``S(e) = Σ_{k<e} λ^{e-1-k} z_kᵀ z_k``.

    Parameters
    ----------
    rows : ndarray, shape (R, 3)
    ends : ndarray of int, shape (M,)
        Increasing row counts at which the scatter is wanted.
    decay : float
        λ per row.

    Returns
    -------
    ndarray, shape (M, 3, 3)
    """
    scatters = np.empty((ends.size, 3, 3))
    current, start = np.zeros((3, 3)), 0
    for index, end in enumerate(ends.tolist()):
        block = rows[start:end]
        weights = decay ** np.arange(block.shape[0] - 1, -1, -1, dtype=np.float64)
        current = decay ** block.shape[0] * current + np.einsum(
            "k,ki,kj->ij", weights, block, block
        )
        scatters[index], start = current, end
    return scatters


def _scatters_at(
    rows: NDArray[np.float64], ends: NDArray[np.intp], decay: float, centered: bool
) -> NDArray[np.float64]:
    """Forgotten scatters at the row counts ``ends``, one-sided or centred."""
    forward = _block_scatters(rows, ends, decay)
    if not centered:
        return forward
    # Rows after each end, forgotten towards it: the forward pass over the reversed rows.
    backward = _block_scatters(rows[::-1], (rows.shape[0] - ends)[::-1], decay)[::-1]
    return forward + decay * backward


def track_tau(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    *,
    memory_s: float,
    step_s: float,
    phi: float | None = None,
    constrain_ratio: bool = True,
    centered: bool = True,
) -> TauTrack:
    """Track τ1(t), τ2(t) through a record with a forgetting β-GTLS estimator.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    memory_s : float
        Forgetting time constant, seconds: shorter follows faster changes, longer is quieter.
    step_s : float
        Interval between estimates, seconds.
    phi : float, optional
        Noise variance ratio σ1²/σ2²; measured from the spectra when omitted.
    constrain_ratio : bool
        Impose the whole record's α = τ1/τ2 and track the common scale only.
    centered : bool
        Two-sided memory (no lag; offline only) rather than a causal one.

    Returns
    -------
    TauTrack
        One estimate every ``step_s`` from the first full memory on (one-sided) or across the
        record (centred).
    """
    first, second = check_pair(tc1, tc2)
    check_excitation(first, second)
    dt = check_sample_interval(dt)
    if not (memory_s > 0.0 and step_s > 0.0):
        raise ValueError(f"{memory_s=} and {step_s=} must be > 0 s")
    if phi is None:
        phi = (estimate_noise(first, dt).sigma / estimate_noise(second, dt).sigma) ** 2
    rows = beta_rows(first, second)
    step = max(1, round(step_s / dt))
    begin = step if centered else min(rows.shape[0], max(step, round(memory_s / dt)))
    ends = np.arange(begin, rows.shape[0] + 1, step)
    scatters = _scatters_at(rows, ends, math.exp(-dt / memory_s), centered)
    overall = estimate_beta_from_scatter(beta_scatter(first, second), dt, first.size, phi=phi)
    ratio = overall.tau1 / overall.tau2 if constrain_ratio else math.nan
    tau1, tau2 = np.full(ends.size, np.nan), np.full(ends.size, np.nan)
    for index, scatter in enumerate(scatters):
        tau1[index], tau2[index] = _solve(scatter, dt, ratio, overall.tau2, phi)
    return TauTrack(
        time=ends * dt,
        tau1=tau1,
        tau2=tau2,
        ratio=ratio,
        memory_s=float(memory_s),
        centered=centered,
    )


def _solve(
    scatter: NDArray[np.float64], dt: float, ratio: float, guess_tau2: float, phi: float
) -> tuple[float, float]:
    """(τ1, τ2) from one scatter; NaN when the data carry no usable estimate."""
    try:
        if math.isnan(ratio):
            found = estimate_beta_from_scatter(scatter, dt, 0, phi=phi)
            return found.tau1, found.tau2
        tau2 = solve_scale(scatter, dt, ratio, guess_tau2, phi)
    except (ValueError, ArithmeticError):
        return math.nan, math.nan
    return ratio * tau2, tau2


class ForgettingEstimator:
    """Streaming β-GTLS with exponential forgetting, for the online node.

    Parameters
    ----------
    dt : float
        Sample interval, seconds.
    memory_s : float
        Forgetting time constant of the scale (or of both τ when unconstrained), seconds.
    phi : float
        Noise variance ratio σ1²/σ2².
    constrain_ratio : bool
        Estimate α = τ1/τ2 over the long memory and only the common scale over ``memory_s``.
    ratio_memory_s : float, optional
        Forgetting time constant of the ratio's scatter, seconds; None keeps every row.

    Examples
    --------
    >>> tracker = ForgettingEstimator(0.002, memory_s=0.5)   # doctest: +SKIP
    >>> tracker.extend(tc1_batch, tc2_batch)                  # doctest: +SKIP
    >>> tracker.estimate().tau1                               # doctest: +SKIP
    """

    def __init__(
        self,
        dt: float,
        *,
        memory_s: float,
        phi: float = 1.0,
        constrain_ratio: bool = True,
        ratio_memory_s: float | None = None,
    ) -> None:
        self.dt = check_sample_interval(dt)
        if not memory_s > 0.0:
            raise ValueError(f"{memory_s=} must be > 0 s")
        if ratio_memory_s is not None and not ratio_memory_s > 0.0:
            raise ValueError(f"{ratio_memory_s=} must be > 0 s or None")
        beta_noise_covariance(phi)  # validates φ
        self.phi = float(phi)
        self.memory_s = float(memory_s)
        self.constrain_ratio = constrain_ratio
        self._decay = math.exp(-self.dt / self.memory_s)
        self._long_decay = 1.0 if ratio_memory_s is None else math.exp(-self.dt / ratio_memory_s)
        self._short = np.zeros((3, 3))
        self._long = np.zeros((3, 3))
        self._last: tuple[float, float] | None = None
        self.rows = 0

    def reset(self) -> None:
        """Forget every sample."""
        self._short[:] = 0.0
        self._long[:] = 0.0
        self._last = None
        self.rows = 0

    def mark_gap(self) -> None:
        """The next sample does not follow the last one: no regression row links the two."""
        self._last = None

    def extend(self, tc1: ArrayLike, tc2: ArrayLike) -> None:
        """Add consecutive sample pairs (following the previous batch without a gap).

        Parameters
        ----------
        tc1, tc2 : array_like, shape (M,)
            Temperatures, degrees C.
        """
        first, second = check_pair(tc1, tc2, min_samples=0)
        if first.size == 0:
            return
        if self._last is not None:
            first = np.concatenate(([self._last[0]], first))
            second = np.concatenate(([self._last[1]], second))
        self._last = (float(first[-1]), float(second[-1]))
        if first.size < 2:
            return
        rows = beta_rows(first, second)
        self._short = _forget(self._short, rows, self._decay)
        self._long = _forget(self._long, rows, self._long_decay)
        self.rows += rows.shape[0]

    def estimate(self) -> Estimate:
        """Current time constants.

        Returns
        -------
        Estimate
            Method ``'beta-gtls-forgetting'``; ``n_samples`` is the effective number of rows
            of the memory; with ``constrain_ratio`` the params hold the ``ratio`` used.

        Raises
        ------
        NoExcitationError, PhysicalRangeError
            When the memory holds no usable information (too few rows, no excitation).
        """
        effective = int(min(self.rows, round(self.memory_s / self.dt)))
        overall = estimate_beta_from_scatter(self._long, self.dt, self.rows + 1, phi=self.phi)
        if not self.constrain_ratio:
            found = estimate_beta_from_scatter(self._short, self.dt, effective, phi=self.phi)
            return _renamed(found)
        ratio = overall.tau1 / overall.tau2
        return _constrained_estimate(
            self._short, self.dt, ratio, overall.tau2, self.phi, effective
        )


def _forget(scatter: NDArray[np.float64], rows: NDArray[np.float64], decay: float) -> NDArray:
    """``λ^M S + Σ_k λ^{M-1-k} z_kᵀ z_k`` for M new rows."""
    weights = decay ** np.arange(rows.shape[0] - 1, -1, -1, dtype=np.float64)
    return decay ** rows.shape[0] * scatter + np.einsum("k,ki,kj->ij", weights, rows, rows)


def _renamed(found: Estimate) -> Estimate:
    """The unconstrained estimate under this module's method name."""
    return estimate_from_poles(
        METHOD,
        found.a1,
        found.a2,
        found.dt,
        found.n_samples,
        found.condition,
        found.params,
        phi=found.phi,
    )
