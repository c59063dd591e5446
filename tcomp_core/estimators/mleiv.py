"""ML errors-in-variables estimator: the cross-relation residual weighted by its own noise.

Each thermocouple's difference equation (Eq. 7) reconstructs the gas temperature,

    u_i[k] = (T_mi(k+1) - a_i T_mi(k)) / (1 - a_i),   k = 0..N-2,

and the two reconstructions agree for the true time constants. Writing c_i = 1/(1 - a_i), their
difference, the cross-relation residual, is affine in the data and in c = (c1, c2):

    e[k] = u1[k] - u2[k] = (T_m1(k) - T_m2(k)) + c1 ΔT_m1(k) - c2 ΔT_m2(k).

With white noise of variances σ1² = φ σ2² and σ2² on the readings, the noise in e at *any* c is
MA(1) with covariance σ2² Σ(c), Σ = φ R1 + R2, R_i tridiagonal with diagonal (1 + a_i²) c_i² and
off-diagonals -a_i c_i². Hence E[e(c)ᵀ Σ(c)⁻¹ e(c)] = (clean part, zero at the truth) + (N-1) σ2²
for every c, and minimising

    J(τ1, τ2) = e ᵀ Σ⁻¹ e

is consistent. A constant offset b between the two readings (a calibration or cold-junction
error; IEC 60584 class 2 allows ±2.5 °C) adds a constant to e and, left in, drags τ to the
edge of the search; it is eliminated at every τ (variable projection,
:meth:`_CrossRelation.projected`) and reported (``offset_c``). A gain g between the readings
(class 2 allows 0.75 %) multiplies one reconstruction: the residual becomes u1 - g u2 - b and
Σ = φR1 + g²R2. Left out, 0.75 % moved τ1 by 7 % on a slow drift around 50 °C (the gain
confounds the second-order term that separates τ1 from τ2), so g is fitted with τ, with the
class-2 tolerance as a Gaussian prior (:data:`GAIN_PRIOR`, a row of the residual): where the
data carry the gain (broadband signals, drifts) they decide; on one sinusoid, which cannot
tell a gain from τ, the prior does and τ's intervals widen by the gain's share (``gain``,
``gain_ci_low``, ``gain_ci_high``).

J is the efficient weighting of the residual: β-GTLS (Eqs. 18–21) weights the same equation
error by its variance alone and ignores the band of Σ; at the paper's conditions
and K = 4 % its τ1 scatters about three times as much.

Σ is tridiagonal Toeplitz, so the whitened residual L⁻¹e (Σ = LLᵀ) has a closed form that
costs one first-order recursive filter (:meth:`_CrossRelation.whiten`);
:func:`scipy.optimize.least_squares` minimises the squared norm of the projected residual over
(log τ1, log τ2, g - 1). Their covariance is the sandwich H⁻¹(σ̂² H + V₄)H⁻¹ of
:mod:`.eiv_noise`, with σ̂² = J_min/(N - 5), J the Jacobian of the projected residual (the
prior's row included), H = JᵀJ less the information the noise in the regressors ΔT_mi adds to
it, and V₄ the score's fourth-order noise variance. At the paper's conditions both corrections
are below 1 % (JᵀJ matched the clean regressors' X_Sᵀ Σ⁻¹ X_S within 0.2 % in Monte Carlo
checks) and the covariance is σ̂² (JᵀJ)⁻¹; on a signal too slow to excite the sensors the
noise makes most of JᵀJ, and σ̂² (JᵀJ)⁻¹ put the intervals 2.5–10 times too narrow. Monte Carlo
coverage of the 95 % intervals: ``bench/bench_accuracy.py``,
``test/test_mleiv_noise_information.py``.

Two consequences of weighting by the noise spectrum. A pre-filter applied to both signals
leaves the noise term tr(Σ⁻¹ F Σ Fᵀ) ≈ tr(FᵀF) independent of c, so the estimate stays
consistent and moves little (a 40 Hz pre-filter changes τ1 by 7e-5 relative on a K = 3 % ramp).
At the paper's conditions the slow sensor's reconstruction dominates Σ, so a wrong φ costs
little: assuming φ = 1 on data with φ = 0.16 (K = 2 %) biases τ1 by +0.2 %, β-GTLS by +48 %.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.optimize import least_squares

from ..errors import DataError, EstimationError, NoExcitationError, TcompError
from ..filters import PREFILTER_ORDER, decimate, lowpass_sos
from ..noise import estimate_noise, median, model_noise
from ..tolerance import CLASS2_GAIN, CLASS2_OFFSET_C
from .beta import MAX_CONDITION, beta_gtls
from .eiv_noise import noise_moments, sandwich_covariance
from .gauss_newton import SearchResult, levenberg_marquardt, normal_matrix, off_edges
from .projection import projected_residual
from .result import Estimate, estimate_from_poles
from .toeplitz import ToeplitzWhitening

__all__ = ["CONFIDENCE", "ml_eiv", "phi_from_data"]

#: Confidence level of the intervals in ``params``.
CONFIDENCE = 0.95
#: Two-sided standard normal quantile of :data:`CONFIDENCE`.
_Z = 1.959963984540054
#: Points per axis of the log-spaced start grid used when β-GTLS gives no physical start.
_GRID_POINTS = 12
#: Noise σ below this fraction of a signal's largest magnitude is rounding, not noise.
_ROUNDING = 1e-10
#: Range of the start grid and of the search, in sample intervals (low) and record lengths (high).
_TAU_LOW_SAMPLES = 0.02
#: Parameters fitted to the residual: τ1, τ2, the offset and the gain between the sensors.
_FITTED = 4
#: Prior standard deviation of the gain between the sensors: the class-2 tolerance.
GAIN_PRIOR = CLASS2_GAIN
#: The noise σ that weights the gain's prior is at least this fraction of tc2's standard
#: deviation: a record without noise still has the prior that makes a gain and τ separable on
#: a single sinusoid (as a record with 0.1 % noise would).
_PRIOR_NOISE_FLOOR = 1e-3
#: σ of a normal distribution per median absolute deviation.
_MAD_TO_SIGMA = 1.482602218505602
#: The search's range of the gain deviation h = g - 1 between the sensors.
_GAIN_RANGE = 0.5
_TAU_HIGH_RECORDS = 10.0
#: Time constants longer than one record (and than :data:`_TAU_RECORD_SAMPLES` samples) are
#: trusted only from a fit that explains the record to its noise: the record's slowest change
#: reaches such a sensor attenuated and about 90° late, as it would reach an integrator, and
#: what tells the lag from an integrator's gain is a term of relative size 1/(ωτ), the first a
#: model error bends. A pure first-order pair at 4.5 record lengths and K = 1 % is found within
#: 5 %; conduction to cold supports, which first order cannot fit, gave 15 and 33 s on a 6 s
#: record (truth 0.04 and 0.16 s) and a gas 4 500 % off.
_TAU_RECORD_SAMPLES = 100.0
#: The noise σ2 the fit implies (from J_min) over tc2's noise measured from the top of its
#: spectrum, beyond which the fit does not explain the record to its noise. Pure first-order
#: records give 0.98-0.99 (sampling spread a few %); conduction to cold supports with τ beyond
#: the record 1.25-7.4.
_MISFIT_RATIO = 1.1
#: The gain deviations h the rival of a fit with τ beyond the record is searched within and
#: started from (a junction's conduction to cold supports scales its reading by 1/(1 + κ),
#: κ up to a few), and the margin of −2 log L within which it fits as well (the 95 % point of
#: χ² with one degree of freedom).
_RIVAL_GAIN_RANGE = (-0.75, 3.0)
_RIVAL_GAIN_STARTS = (-0.4, 0.0, 0.5, 1.0, 2.0)
_RIVAL_MARGIN = 3.84
#: Decimation factors tried in turn for a β-GTLS start when β-GTLS on the record itself gives
#: none (:func:`_decimated_start`), and the fewest samples a decimated record may keep.
_START_DECIMATION = (4, 16, 64)
_START_MIN_SAMPLES = 500
#: Most evaluations of the residual one search may take (least_squares' default is 300 for three
#: parameters). A record the first-order model fits badly (a flow speed drifting through the
#: record: τ itself drifts) has a long flat valley that the search crosses in 600-700.
_MAX_EVALUATIONS = 1500
#: A warm search stops once its next step is shorter than this share of the standard errors
#: (:func:`~.gauss_newton.levenberg_marquardt`'s ``stop_se``): the node's windows at 5 kHz
#: then end after their second Jacobian instead of a third (8 evaluations of the residual
#: instead of 12), each τ within a thousandth of its standard error of where the strict
#: tolerances end (within 9.5e-7 of itself on ``bench/bench_window_estimate.py``'s windows).
_STOP_SE = 1e-3


def phi_from_data(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    taus: tuple[float, float] | None = None,
    unmeasurable: float | None = None,
) -> float:
    """Noise variance ratio φ = σ1²/σ2² measured from the top of the two spectra (or the model).

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Raw (not pre-filtered) thermocouple temperatures, degrees C.
    dt : float
        Sample interval, s.
    taus : (float, float), optional
        Time constants τ1, τ2 (s). When given, the noise levels come from the model
        (:func:`tcomp_core.noise.model_noise`), which removes the gas signal the two spectra
        share; without them, from a low quantile of each spectrum alone
        (:func:`tcomp_core.noise.estimate_noise`), which sharp edges in the gas can fool.
    unmeasurable : float, optional
        φ to return when one signal shows noise and the other none (synthetic or heavily
        quantised data); None raises.

    Returns
    -------
    float
        φ, dimensionless; 1 when neither signal shows any noise (φ then does not matter).

    Raises
    ------
    DataError
        If one signal shows noise and the other none, so that no finite ratio exists.
    """
    if taus is None:
        sigma1, sigma2 = (_noise_sigma(estimate_noise(v, dt).sigma, v) for v in (tc1, tc2))
    else:
        noise1, noise2 = model_noise(tc1, tc2, dt, *taus)
        sigma1, sigma2 = _noise_sigma(noise1.sigma, tc1), _noise_sigma(noise2.sigma, tc2)
    if sigma1 == 0.0 and sigma2 == 0.0:
        return 1.0
    if not (sigma1 > 0.0 and sigma2 > 0.0):
        if unmeasurable is not None:
            return unmeasurable
        raise DataError(
            f"cannot measure the noise ratio: noise σ1 = {sigma1:.3g}, σ2 = {sigma2:.3g}; "
            "pass phi explicitly"
        )
    return (sigma1 / sigma2) ** 2


def _noise_sigma(sigma: float, values: NDArray[np.float64]) -> float:
    """A white-noise σ of a signal, degrees C; 0 when it is at the level of rounding."""
    return 0.0 if sigma <= _ROUNDING * float(np.max(np.abs(values))) else sigma


def _check_phi(phi: float) -> float:
    phi = float(phi)
    if not (math.isfinite(phi) and phi > 0.0):
        raise ValueError(f"{phi=} must be a finite noise variance ratio > 0")
    return phi


@dataclass(frozen=True)
class _CrossRelation:
    """The cross-relation residual e(τ, g) of a record and its whitening.

    The parameters x = (log τ1, log τ2, h) (τ in s) hold the gain g = 1 + h of tc1's reading
    per degree of tc2's; the offset b between the readings is eliminated at every x.

    Attributes
    ----------
    level : ndarray, shape (M,)
        T_m1(k) - T_m2(k), degrees C, M = N - 1.
    step1, step2 : ndarray, shape (M,)
        ΔT_m1(k), ΔT_m2(k), degrees C.
    reading2 : ndarray, shape (M,)
        T_m2(k) minus its mean, degrees C: with ``step2`` it makes tc2's reconstruction about
        its mean, ũ2 = reading2 + c2 ΔT_m2, which the gain multiplies.
    dt : float
        Sample interval, s.
    phi : float
        Noise variance ratio σ1²/σ2².
    gain_weight : float
        w = σ2 / σ_g, degrees C (> 0): the prior on h, N(0, σ_g²), is the row w h of the
        residual, whose other rows are in units of σ2.
    """

    level: NDArray[np.float64]
    step1: NDArray[np.float64]
    step2: NDArray[np.float64]
    reading2: NDArray[np.float64]
    dt: float
    phi: float
    gain_weight: float
    gain_range: tuple[float, float] = (-_GAIN_RANGE, _GAIN_RANGE)
    tau_high_s: float | None = None

    @classmethod
    def from_signals(
        cls,
        tc1: NDArray[np.float64],
        tc2: NDArray[np.float64],
        dt: float,
        phi: float,
        gain_weight: float = 1.0 / CLASS2_GAIN,
    ) -> _CrossRelation:
        """The residual's data terms from readings of shape (N,), degrees C."""
        head2 = tc2[:-1]
        return cls(
            tc1[:-1] - head2,
            np.diff(tc1),
            np.diff(tc2),
            head2 - head2.mean(),
            dt,
            phi,
            gain_weight,
        )

    @property
    def rows(self) -> int:
        """Residual samples M = N - 1."""
        return self.level.size

    def gains(self, x: NDArray[np.float64]) -> tuple[float, float]:
        """c_i = 1/(1 - a_i), i = 1, 2, for x = (log τ1, log τ2, h)."""
        dt = self.dt
        return (
            1.0 / -math.expm1(-dt / math.exp(x[0])),
            1.0 / -math.expm1(-dt / math.exp(x[1])),
        )

    def residual(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """e[k] = u1[k] - g u2[k] up to a constant, shape (M,), degrees C.

        e = level + c1 ΔT_m1 - g c2 ΔT_m2 - h reading2, one product with the stacked data.
        """
        c1, c2 = self.gains(x)
        h = float(x[2])
        return np.asarray(np.array([1.0, c1, -(1.0 + h) * c2, -h]) @ self._data)

    @functools.cached_property
    def _data(self) -> NDArray[np.float64]:
        """level, ΔT_m1, ΔT_m2 and reading2 stacked, shape (4, M)."""
        return np.stack((self.level, self.step1, self.step2, self.reading2))

    def covariance_bands(self, x: NDArray[np.float64]) -> tuple[float, float]:
        """Diagonal d and off-diagonal o (< 0) of the Toeplitz Σ = φR1 + g²R2, in σ2²."""
        c1, c2 = self.gains(x)
        gain2 = (1.0 + x[2]) ** 2
        # (1 + a²) c² = 2c² - 2c + 1 and a c² = c² - c, with a = 1 - 1/c.
        diagonal = self.phi * (2.0 * c1 * c1 - 2.0 * c1 + 1.0) + gain2 * (
            2.0 * c2 * c2 - 2.0 * c2 + 1.0
        )
        off_diagonal = -(self.phi * (c1 * c1 - c1) + gain2 * (c2 * c2 - c2))
        return float(diagonal), float(off_diagonal)

    def noise_responses(
        self, x: NDArray[np.float64], omega: NDArray[np.float64]
    ) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """How each reading's white noise reaches the whitened residual, at ω (rad per sample).

        The noise of e is n1 read through c1 z - (c1 - 1) and n2 through -g (c2 z - (c2 - 1))
        (z the advance); the whitening is, away from the record's start, the causal filter
        1/(√r1 (1 - s z⁻¹)) of :class:`~.toeplitz.ToeplitzWhitening` (Σ(z) = r1 (1 - s z⁻¹)
        (1 - s z)). tc1's response is scaled by √φ, its noise σ relative to tc2's. ``x`` is
        one point (shape (3,)) or several (shape (S, 3)), all taken in one pass.

        Returns
        -------
        tc1, tc2 : ndarray of complex, shape (K,) each, or (S, K) for several points
        """
        points = np.atleast_2d(x)
        scalars = np.empty((5, points.shape[0], 1))  # c1, c2, g, √r1, o/r1 per point
        for i, point in enumerate(points):
            gains = self.gains(point)
            sensor_gain = 1.0 + float(point[2])
            diagonal, off_diagonal = self.covariance_bands(point)
            root = math.sqrt((self.phi + sensor_gain**2) * (diagonal - 2.0 * off_diagonal))
            r1 = 0.5 * (diagonal + root)
            scalars[:, i, 0] = (*gains, sensor_gain, math.sqrt(r1), off_diagonal / r1)
        c1, c2, gain, root_r1, ratio = scalars
        advance = np.exp(1j * omega)
        whitening = 1.0 / (root_r1 * (1.0 + ratio / advance))
        first = math.sqrt(self.phi) * whitening * (c1 * advance - (c1 - 1.0))
        second = -gain * whitening * (c2 * advance - (c2 - 1.0))
        if np.ndim(x) == 1:
            return first[0], second[0]
        return first, second

    def whitened(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """L⁻¹ e with Σ = LLᵀ (Cholesky), shape (M,), in units of σ2 (see :meth:`whiten`)."""
        return self.whiten(x, self.residual(x))

    def projected(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """L⁻¹ (e - b) at the best offset b, and the gain's prior row w h: shape (M + 1,).

        A constant offset of one sensor's reading (calibration, cold junction) adds a constant
        to e; it is a linear parameter, eliminated in closed form at every x (variable
        projection: the whitened residual minus its projection on the whitened constant).
        The squared norm is J plus the prior's term, minimised over b.
        """
        c1, c2 = self.gains(x)
        h = float(x[2])
        result = np.empty(self.rows + 1)
        # One compiled pass: e, its whitening, the constant's and the projection.
        offset = projected_residual(
            self._data, (c1, -(1.0 + h) * c2, -h), self._whitening(x), result
        )
        self._offsets[np.asarray(x, dtype=np.float64).tobytes()] = offset
        result[-1] = self.gain_weight * x[2]
        return result

    def offset(self, x: NDArray[np.float64]) -> float:
        """The best b of :meth:`projected`: tc1's reading minus g × tc2's at tc2's mean, °C.

        Remembered from :meth:`projected` at the same x (the search's end has been evaluated).
        """
        known = self._offsets.get(np.asarray(x, dtype=np.float64).tobytes())
        if known is not None:
            return known
        whitened, constant = self._whitened_with_constant(x)
        return float((constant @ whitened) / (constant @ constant))

    @functools.cached_property
    def _offsets(self) -> dict[bytes, float]:
        """The offset b at every x :meth:`projected` was evaluated at (a search's few dozen)."""
        return {}

    def _whitened_with_constant(
        self, x: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """L⁻¹ e and L⁻¹ 1 (in closed form), each of shape (M,)."""
        whitening = self._whitening(x)
        return whitening.apply(self.residual(x)), whitening.constant()

    def whiten(self, x: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray:
        """L⁻¹ values with Σ = LLᵀ (Cholesky), shape (M,) or (k, M) as ``values``, in σ2.

        Σ is tridiagonal Toeplitz: one first-order recursive filter
        (:class:`~.toeplitz.ToeplitzWhitening`) instead of a banded Cholesky factorisation.
        """
        return self._whitening(x).apply(values)

    def _whitening(self, x: NDArray[np.float64]) -> ToeplitzWhitening:
        """The whitening L⁻¹ of Σ(x)."""
        diagonal, off_diagonal = self.covariance_bands(x)
        # d - 2|o| = φ + g² exactly: the discriminant without cancellation.
        root = math.sqrt((self.phi + (1.0 + x[2]) ** 2) * (diagonal - 2.0 * off_diagonal))
        return ToeplitzWhitening.from_bands(diagonal, off_diagonal, root, self.rows)

    def criterion(self, x: NDArray[np.float64]) -> float:
        """J = (e - b)ᵀ Σ⁻¹ (e - b) + (w h)² at the best offset b, degrees C²."""
        whitened = self.projected(x)
        return float(whitened @ whitened)

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Search range of x: log τ and h.

        τ from a fiftieth of a sample to ten record lengths (or :attr:`tau_high_s`), h within
        :attr:`gain_range` (± 0.5).
        """
        duration = (self.rows + 1) * self.dt
        low = math.log(_TAU_LOW_SAMPLES * self.dt)
        high = math.log(self.tau_high_s or _TAU_HIGH_RECORDS * duration)
        h_low, h_high = self.gain_range
        return np.array([low, low, h_low]), np.array([high, high, h_high])

    def deviance(self, x: NDArray[np.float64]) -> float:
        """The deviance −2 log L at x, σ2 profiled out, up to a constant: M log(J/M) + log det Σ̃.

        J alone falls as the gain grows (Σ = φR1 + g²R2 grows with it); the determinant,
        ≈ r1^M for the tridiagonal Toeplitz Σ̃ (:meth:`whiten`), puts fits of different gains
        on one scale. The gain's prior row is left out: this compares fits, not priors.
        """
        whitened = self.projected(x)[:-1]
        diagonal, off_diagonal = self.covariance_bands(x)
        root = math.sqrt((self.phi + (1.0 + x[2]) ** 2) * (diagonal - 2.0 * off_diagonal))
        r1 = 0.5 * (diagonal + root)
        rows = self.rows
        return rows * math.log(float(whitened @ whitened) / rows) + rows * math.log(r1)


def _grid_starts(problem: _CrossRelation) -> list[NDArray[np.float64]]:
    """Starts from a log-spaced τ grid (equal gains), each of shape (3,).

    The grid's best cell, and its best cell with both τ at least a sample when that is another
    one. Far below a sample the residual hardly depends on τ (c = 1/(1 - a) → 1), so a search
    started there cannot leave: on a step record at 10 kHz with tc1 three times noisier the
    grid's best cell had τ1 = 0.08 samples and the search stalled at a criterion 40 % above
    the optimum it reaches from the second start (τ within 3 % of the truth).
    """
    low, high = problem.bounds()
    axis = np.linspace(low[0], high[0], _GRID_POINTS + 2)[1:-1]
    values = sorted(
        (problem.criterion(np.array([x1, x2, 0.0])), x1, x2)
        for x1 in axis
        for x2 in axis
        if x1 != x2
    )
    sample = math.log(problem.dt)
    starts = [values[0][1:]]
    resolved = [cell[1:] for cell in values if min(cell[1:]) >= sample]
    if resolved and resolved[0] != starts[0]:
        starts.append(resolved[0])
    return [np.array([x1, x2, 0.0]) for x1, x2 in starts]


def _start(
    problem: _CrossRelation,
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    warm: tuple[float, ...] | None = None,
) -> tuple[list[NDArray[np.float64]], str]:
    """Starting x (one or more) and where they came from.

    ``warm`` (τ1, τ2 in s, and the gain g when it has three entries), else β-GTLS with the
    same φ, else β-GTLS on the record decimated (:func:`_decimated_start`), else the grid
    (:func:`_grid_starts`). These starts assume equal gains; a start outside the search range
    is not used.
    """
    low, high = problem.bounds()

    def inside(start: NDArray[np.float64]) -> bool:
        return bool(np.all(np.isfinite(start) & (start > low) & (start < high)))

    if warm is not None:
        values = np.asarray(warm, dtype=np.float64)
        gain = values[2] - 1.0 if values.size == 3 else 0.0
        start = np.append(np.log(values[:2]), gain)
        if inside(start):
            return [start], "warm"
    try:
        first = beta_gtls(tc1, tc2, problem.dt, problem.phi)
    except (TcompError, ValueError):
        pass
    else:
        start = np.array([math.log(first.tau1), math.log(first.tau2), 0.0])
        if inside(start):
            return [start], "beta-gtls"
    decimated = _decimated_start(tc1, tc2, problem.dt, problem.phi)
    if decimated is not None and inside(decimated):
        return [decimated], "decimated"
    return _grid_starts(problem), "grid"


def _decimated_start(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], dt: float, phi: float
) -> NDArray[np.float64] | None:
    """The start x = (log τ1, log τ2, 0) from β-GTLS on the record decimated, or None.

    Sampled far faster than the sensors respond, each step of a reading is mostly noise and
    β-GTLS's regression loses the lag: at 20 kHz and K = 2–3 % its pole left (0, 1) on step
    records and exhaust pulses. Decimated by q (anti-aliased, the noise left white at σ²/q),
    the same record gives each step q times the change, and β-GTLS a start near the
    minimum, where the log-spaced grid (:func:`_grid_starts`) spent 3–7 s on a 4–6 s record at
    20 kHz in 264 evaluations of the criterion. Only a start: the search runs on the record
    itself. The factors of :data:`_START_DECIMATION` are tried in turn while the decimated
    record keeps :data:`_START_MIN_SAMPLES` samples.
    """
    for factor in _START_DECIMATION:
        if tc1.size // factor < _START_MIN_SAMPLES:
            return None
        slow1, slow2 = decimate(tc1, factor), decimate(tc2, factor)
        try:
            found = beta_gtls(slow1, slow2, factor * dt, phi)
        except (TcompError, ValueError):
            continue
        return np.array([math.log(found.tau1), math.log(found.tau2), 0.0])
    return None


def _best(found: Iterable[SearchResult]) -> SearchResult:
    """The converged search of least cost (a failed one only when none converged)."""
    return min(found, key=lambda result: (not result.success, result.cost))


def _inside(x: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64]) -> bool:
    """Whether x lies inside the search range, off its edges (a fit on one fits nothing)."""
    return off_edges(x, low, high, 1e-6)


def _equilibrated_condition(jacobian: NDArray[np.float64]) -> float:
    """2-norm condition number of a two-column Jacobian with unit-norm columns (inf if one is 0).

    For unit columns u, v with cosine c the singular values are √(1 ± |c|), and
    1 ± |c| = ‖u ± sign(c) v‖² / 2, so the condition is ‖u + sv‖ / ‖u - sv‖ (s = sign c):
    the SVD's value, each norm taken directly, without the cancellation of 1 - |c| (a
    condition of 1e7 leaves 1 - |c| at 2e-14), at the cost of two vector sums instead of an
    SVD of the M × 2 matrix.
    """
    norms = np.linalg.norm(jacobian, axis=0)
    if not np.all(norms > 0.0):
        return math.inf
    first, second = jacobian[:, 0] / norms[0], jacobian[:, 1] / norms[1]
    sign = 1.0 if float(first @ second) >= 0.0 else -1.0
    apart = float(np.linalg.norm(first - sign * second))
    if apart == 0.0:
        return math.inf
    return float(np.linalg.norm(first + sign * second)) / apart


def _gain_weight(tc2: NDArray[np.float64]) -> float:
    """The prior row's weight w = σ2 / σ_g (:attr:`_CrossRelation.gain_weight`), °C.

    σ2 is tc2's white noise from the median absolute second difference (var Δ²n = 6σ² for
    white noise; the lagging sensor's signal is smooth from sample to sample, and the median
    ignores its jumps), at least :data:`_PRIOR_NOISE_FLOOR` of tc2's spread. It does not
    depend on the search's start, so neither does the estimate.
    """
    second = np.diff(tc2, 2)
    mad = 0.0
    if second.size:
        np.subtract(second, median(second, overwrite=True), out=second)
        mad = median(np.abs(second, out=second), overwrite=True)
    sigma2 = _MAD_TO_SIGMA * mad / math.sqrt(6.0)
    return max(sigma2, _PRIOR_NOISE_FLOOR * float(np.std(tc2))) / GAIN_PRIOR


def _search(
    problem: _CrossRelation, initial: NDArray[np.float64], warm: bool = False
) -> SearchResult:
    """Minimise the projected residual's squared norm from ``initial`` within the bounds.

    From a ``warm`` start (close to the minimum) a lean Levenberg–Marquardt search
    (:func:`~.gauss_newton.levenberg_marquardt`, the same forward-difference Jacobian and
    tolerances) goes first, at a fraction of ``least_squares``' own cost; the trust region
    reflective search of ``least_squares`` runs when it does not converge inside the bounds,
    and from every other start.
    """
    low, high = problem.bounds()
    if warm:
        quick = levenberg_marquardt(
            problem.projected,
            initial,
            (low, high),
            xtol=1e-12,
            ftol=1e-12,
            max_nfev=_MAX_EVALUATIONS,
            stop_se=_STOP_SE,
        )
        if quick is not None:
            return quick
    found = least_squares(
        problem.projected,
        initial,
        jac="2-point",
        bounds=(low, high),
        xtol=1e-12,
        ftol=1e-12,
        max_nfev=_MAX_EVALUATIONS,
    )
    # A dense array: the "2-point" Jacobian without jac_sparsity (typed as a union).
    jacobian = np.asarray(found.jac, dtype=np.float64)
    return SearchResult(
        found.x,
        float(found.cost),
        jacobian,
        int(found.nfev),
        bool(found.success),
        str(found.message),
    )


def _gain_rival(
    problem: _CrossRelation, slow: NDArray[np.float64], length: float
) -> NDArray[np.float64] | None:
    """A pair with both τ within the record and any gain that fits as well as ``slow``, or None.

    Two sensors whose τ both exceed the record see its changes as integrators do, so their
    relation is a ratio of gains: a fit with τ beyond the record is matched by sensors of
    unequal gain with τ within it (conduction to cold supports scales each junction's
    reading by 1/(1 + κ)), and the data cannot tell the two apart. The rival's search has
    the gain free from :data:`_RIVAL_GAIN_RANGE` and no prior; it fits as well when its
    −2 log L (:meth:`_CrossRelation.deviance`) is within :data:`_RIVAL_MARGIN`
    of the slow fit's.
    """
    rival_problem = dataclasses.replace(
        problem, gain_weight=0.0, gain_range=_RIVAL_GAIN_RANGE, tau_high_s=length
    )
    low, high = rival_problem.bounds()
    starts = [
        np.array([x[0], x[1], h])
        for x in _grid_starts(rival_problem)
        for h in _RIVAL_GAIN_STARTS
        if low[2] < h < high[2]
    ]
    fits = [_search(rival_problem, start) for start in starts]
    inside = [found.x for found in fits if found.success and _inside(found.x, low, high)]
    if not inside:
        return None
    best = min(inside, key=rival_problem.deviance)
    slow_value = problem.deviance(slow)
    if rival_problem.deviance(best) <= slow_value + _RIVAL_MARGIN:
        return best
    return None


def _gain_rival_message(
    problem: _CrossRelation, slow: NDArray[np.float64], rival: NDArray[np.float64], length: float
) -> str:
    """Why a fit with τ beyond the record that a gain between the sensors matches is refused."""
    return (
        f"ml-eiv: the best first-order fit has τ1 = {math.exp(slow[0]):.3g} s, "
        f"τ2 = {math.exp(slow[1]):.3g} s, longer than the {length:.3g} s record, and sensors "
        f"with τ1 = {math.exp(rival[0]):.3g} s, τ2 = {math.exp(rival[1]):.3g} s whose gains "
        f"differ by {100.0 * float(rival[2]):+.3g} % (tc1's reading per degree of tc2's) fit "
        "the record as well: a lag beyond the record is not told from a gain, so no gas is "
        f"reconstructed from it. There the sensors disagree by {problem.offset(rival):+.3g} °C "
        f"in level; IEC 60584 class 2 allows about {CLASS2_OFFSET_C:g} °C or "
        f"{100 * CLASS2_GAIN:g} %. Such a gain is conduction to the supports or a "
        "calibration: fit the physics with --effects auto, or correct one sensor's calibration"
    )


def _gain_params(deviation: float, variance: float) -> dict[str, float]:
    """The gain g = 1 + h of tc1 per degree of tc2, its standard error and 95 % interval."""
    gain, se = 1.0 + float(deviation), math.sqrt(max(float(variance), 0.0))
    return {
        "gain": gain,
        "gain_se": se,
        "gain_ci_low": gain - _Z * se,
        "gain_ci_high": gain + _Z * se,
    }


def record_length_s(samples: int, dt: float) -> float:
    """The τ beyond which a record of ``samples`` readings ``dt`` apart holds no slower change, s.

    Its length, and at least :data:`_TAU_RECORD_SAMPLES` samples.
    """
    return max(samples * dt, _TAU_RECORD_SAMPLES * dt)


def _misfit_ratio(tc2: NDArray[np.float64], dt: float, noise_sigma2: float) -> float:
    """The fit's implied σ2 over tc2's noise measured from its spectrum (inf if none shows)."""
    measured = estimate_noise(tc2, dt).sigma
    return noise_sigma2 / measured if measured > 0.0 else math.inf


def _edge_message(problem: _CrossRelation, x: NDArray[np.float64]) -> str:
    """Why a fit on the edge of the search failed, with the sensors' fitted disagreement."""
    gain = 1.0 + float(x[2])
    where = (
        f"gain {100.0 * (gain - 1.0):+.3g} %, the search's limit"
        if abs(x[2]) >= _GAIN_RANGE - 1e-6
        else f"τ = {math.exp(x[0]):.3g} s, {math.exp(x[1]):.3g} s"
    )
    return _disagreement_message(
        problem,
        x,
        f"the best fit lies at the edge of the search range ({where}): no first-order pair fits",
    )


def _too_slow_message(
    problem: _CrossRelation, x: NDArray[np.float64], length: float, misfit: float
) -> str:
    """Why a fit with a τ longer than the record, which does not fit to the noise, is refused."""
    return _disagreement_message(
        problem,
        x,
        f"the best first-order fit has τ1 = {math.exp(x[0]):.3g} s, τ2 = {math.exp(x[1]):.3g} s, "
        f"longer than the {length:.3g} s record, and it leaves {misfit:.3g} times the noise "
        "unexplained: a lag that long is told from a gain only by what the model misses, so "
        "no first-order pair fits and no gas is reconstructed from it",
    )


def _disagreement_message(problem: _CrossRelation, x: NDArray[np.float64], what: str) -> str:
    """``what`` went wrong, with the sensors' fitted disagreement and what to do about it."""
    gain = 1.0 + float(x[2])
    return (
        f"ml-eiv: {what}. "
        f"There the sensors disagree by {problem.offset(x):+.3g} °C in level and "
        f"{100.0 * (gain - 1.0):+.3g} % in gain; IEC 60584 class 2 allows about "
        f"{CLASS2_OFFSET_C:g} °C or {100 * CLASS2_GAIN:g} %. Beyond that, check that both "
        "columns are thermocouples in the same gas and units, correct one sensor's "
        "calibration, or fit the physics with --effects auto"
    )


#: Largest half-width of a 95 % interval of log τ that :func:`math.exp` can take (e^700 is
#: near the largest double): beyond it the interval is no interval.
_LARGEST_LOG_SPREAD = 700.0


def _covariance(
    problem: _CrossRelation,
    x: NDArray[np.float64],
    jacobian: NDArray[np.float64],
    noise_variance: float,
    prefilter_hz: float | None = None,
) -> NDArray[np.float64]:
    """Covariance of x = (log τ1, log τ2, h), the noise's share of JᵀJ taken out.

    The sandwich of :mod:`.eiv_noise` at the fit's x and σ̂². With the readings pre-filtered
    (:func:`~tcomp_core.filters.prefilter` at ``prefilter_hz``) the residual's noise is no
    longer white: the noise terms carry the filter's response.

    Raises
    ------
    NoExcitationError
        If the noise accounts for all the information on some direction of x.
    """
    response = None
    if prefilter_hz is not None:
        sos = lowpass_sos(prefilter_hz, problem.dt, PREFILTER_ORDER)

        def response(omega: NDArray[np.float64]) -> NDArray[np.float64]:
            # sosfiltfilt's response: |H|² of the sections, real and non-negative.
            return np.abs(signal.sosfreqz(sos, worN=omega)[1]) ** 2

    moments = noise_moments(
        problem.noise_responses,
        x,
        noise_variance,
        problem.rows,
        float(max(problem.gains(x))),
        response,
    )
    return sandwich_covariance(normal_matrix(jacobian), moments)


def _interval_params(tau: NDArray[np.float64], covariance: NDArray) -> dict[str, float]:
    """Standard errors (delta method, s) and 95 % intervals (exp of the log-τ interval, s)."""
    se_log = np.sqrt(np.diag(covariance))
    params: dict[str, float] = {}
    for i in (0, 1):
        name = f"tau{i + 1}"
        params[f"{name}_se"] = float(tau[i] * se_log[i])
        params[f"{name}_ci_low"] = float(tau[i] * math.exp(-_Z * se_log[i]))
        params[f"{name}_ci_high"] = float(tau[i] * math.exp(_Z * se_log[i]))
    return params


def ml_eiv(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    dt: float,
    phi: float | None = None,
    *,
    start: tuple[float, ...] | None = None,
    prefilter_hz: float | None = None,
) -> Estimate:
    """ML errors-in-variables estimate: minimise J = eᵀ Σ⁻¹ e + (w h)² over τ1, τ2, g, b.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
        Thermocouple temperatures, degrees C, validated by the caller (finite, equal lengths,
        excited).
    dt : float
        Sample interval, s.
    phi : float, optional
        Noise variance ratio σ1²/σ2². ``None`` measures it from the data with
        :func:`phi_from_data`.
    start : (float, float) or (float, float, float), optional
        Time constants τ1, τ2 (s) to start the search from, e.g. the previous window's (a warm
        start), and the gain g (tc1's reading per degree of tc2's, 1 when left out); by
        default β-GTLS with the same φ, or a log-spaced grid when β-GTLS fails.
    prefilter_hz : float, optional
        The cut-off of the zero-phase pre-filter (:func:`~tcomp_core.filters.prefilter`) the
        readings went through, Hz: the intervals then account for the noise it colours. It
        does not change τ.

    Returns
    -------
    Estimate
        ``method='ml-eiv'``, ``phi`` the ratio used. ``condition`` is the condition number of
        the column-equilibrated whitened Jacobian. ``params``: ``tau1_se``, ``tau2_se``
        (asymptotic standard errors, s), ``tau1_ci_low``, ``tau1_ci_high``, ``tau2_ci_low``,
        ``tau2_ci_high`` (95 % intervals, s), ``noise_sigma2`` (σ2 implied by J_min, degrees C),
        ``offset_c`` (tc1's reading minus g × tc2's at tc2's mean, degrees C), ``gain``
        (g, tc1's reading per degree of tc2's) with ``gain_se``, ``gain_ci_low`` and
        ``gain_ci_high``,
        ``phi_estimated`` (1.0 if φ was measured), ``start_beta_gtls`` (1.0 if the search
        started from β-GTLS), ``start_warm`` (1.0 if from ``start``), ``start_decimated``
        (1.0 if from β-GTLS on the record decimated) and ``evaluations`` (of
        the residual, not counting the Jacobian's).

    Raises
    ------
    ValueError
        If ``phi`` is not a finite positive number.
    NoExcitationError
        If the data do not determine both time constants (singular Jacobian).
    EstimationError
        If the search fails, its minimum lies on the edge of the search range (no
        first-order pair fits), or a τ is longer than the record
        (:func:`record_length_s`) from a fit that leaves more than the noise unexplained; the
        message gives the sensors' fitted disagreement in level and gain.
    """
    measured = phi is None
    phi = phi_from_data(tc1, tc2, dt) if phi is None else _check_phi(phi)
    problem = _CrossRelation.from_signals(tc1, tc2, dt, phi, _gain_weight(tc2))
    starts, origin = _start(problem, tc1, tc2, start)
    fit = _best(_search(problem, initial, warm=origin == "warm") for initial in starts)
    low, high = problem.bounds()
    if origin == "decimated" and not (fit.success and _inside(fit.x, low, high)):
        # The decimated record's start is an approximation: where its search fails, the grid
        # decides as it did before that start existed.
        fit = _best(_search(problem, initial) for initial in _grid_starts(problem))
    if not fit.success:
        raise EstimationError(f"ml-eiv: the search did not converge ({fit.message})")
    if not _inside(fit.x, low, high):
        raise EstimationError(_edge_message(problem, fit.x))
    jacobian = fit.jac
    condition = _equilibrated_condition(jacobian[:, :2])
    if not condition < MAX_CONDITION:
        raise NoExcitationError(
            f"ml-eiv: the time constants are not separately determined (condition "
            f"{condition:.3g}): the data carry no information on the time constants"
        )
    tau = np.exp(fit.x[:2])
    a1, a2 = np.exp(-dt / tau)
    noise_variance = 2.0 * fit.cost / (problem.rows - _FITTED)
    length = record_length_s(tc1.size, dt)
    if np.any(tau > length):
        misfit = _misfit_ratio(tc2, dt, math.sqrt(noise_variance))
        if not misfit <= _MISFIT_RATIO:
            raise EstimationError(_too_slow_message(problem, fit.x, length, misfit))
        rival = _gain_rival(problem, fit.x, length)
        if rival is not None:
            raise EstimationError(_gain_rival_message(problem, fit.x, rival, length))
    covariance = _covariance(problem, fit.x, jacobian, noise_variance, prefilter_hz)
    se_log = np.sqrt(np.diag(covariance)[:2])
    if not np.all(_Z * se_log < _LARGEST_LOG_SPREAD):
        # The τ columns alone pass the condition check, but with the level and gain fitted
        # beside them τ is not determined: its interval would span beyond floating point.
        raise NoExcitationError(
            "ml-eiv: the time constants are not determined beside the sensors' level and gain "
            f"(standard errors of log tau1, log tau2 {se_log[0]:.3g}, {se_log[1]:.3g}): the "
            "data carry no information on the time constants"
        )
    params = {
        **_interval_params(tau, covariance),
        "noise_sigma2": math.sqrt(noise_variance),
        "offset_c": problem.offset(fit.x),
        **_gain_params(fit.x[2], covariance[2, 2]),
        "phi_estimated": 1.0 if measured else 0.0,
        "start_beta_gtls": 1.0 if origin == "beta-gtls" else 0.0,
        "start_warm": 1.0 if origin == "warm" else 0.0,
        "start_decimated": 1.0 if origin == "decimated" else 0.0,
        "evaluations": float(fit.nfev),
    }
    return estimate_from_poles("ml-eiv", a1, a2, dt, tc1.size, condition, params, phi=phi)
