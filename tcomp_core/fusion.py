"""Fused gas temperature reconstruction: a Kalman filter and RTS smoother on both sensors.

The paper inverts each thermocouple (Eq. 7), averages the two reconstructions and low-passes the
result with a post-filter whose bandwidth the user has to choose. Here the gas temperature is a
stochastic state of a linear Gaussian state-space model, both sensors observe it, and every
setting comes from the data:

    s_k = [x_{k-1}, T_1(k), T_2(k)],           g_{k-1} = c_s · x_{k-1},
    x_k = F_s x_{k-1} + w_k,                   w_k ~ N(0, Q_s),
    T_i(k+1) = a_i T_i(k) + (1 - a_i) g_k,     a_i = exp(-dt/τ_i)   (Eqs. 4–6, exact ZOH),
    y_i(k) = T_i(k) + v_i(k),                  v_i ~ N(0, σ_i²),

with g_k the gas temperature held over ``[t_k, t_{k+1})`` and x the state of a signal model
(:data:`MODELS`), each a continuous-time linear system driven by white noise and discretised
exactly (Van Loan):

``random-walk``
    ``dg/dt = w``, intensity q in °C²/s. Suits steps and jumps.
``integrated-random-walk``
    ``d²g/dt² = w``, q in °C²/s³. Suits ramps and smooth signals.
``band-limited``
    a random-walk level (``level_q``, °C²/s) plus white noise through a Butterworth low-pass
    of order ``order`` (2 or 4, the likelihood chooses) with cut-off ``freq_hz``: flat up to
    the cut-off, falling as f^(-2·order) above it. q (°C²/s) is the intensity of the noise
    driving the highest derivative, scaled to °C (:func:`butterworth_dynamics`). Suits
    broadband signals with a band edge.
``periodic``
    a random-walk level plus an undamped resonator at the frequency ``freq_hz`` of the
    spectrum's strongest line, driven by white noise of intensity q in °C²/s: a sinusoid whose
    amplitude and phase wander. Suits periodic signals. (A damped resonator would make the
    model expect the amplitude to decay between the rare corrections a weak drive allows.)

Hyper-parameters are chosen by maximising the likelihood of the Kalman innovations
(:mod:`scipy.optimize` on their logarithms), and the model by that likelihood less its number
of hyper-parameters (Akaike). The noise levels σ_i come from the spectra
(:func:`tcomp_core.noise.estimate_noise`) unless given.

For a time-invariant model the Kalman gain converges to a constant, found once from the
discrete algebraic Riccati equation; filter and Rauch–Tung–Striebel smoother are then linear
recursions, run in a Schur basis as first-order :func:`scipy.signal.lfilter` calls (no Python
loop over samples). Offline, the unknown initial state is estimated by generalised least squares
from the innovations (a diffuse prior) and its uncertainty is added to the reported standard
deviation. The causal filter starts from a diffuse prior with the exact time-varying Kalman
recursion (a loop over samples) and switches to the steady-state gain once its gain has
converged, or after :data:`MAX_EXACT_SAMPLES` samples.

Output convention: element k of every gas series is the gas temperature held over
``[t_k, t_{k+1})``, as in :func:`tcomp_core.reconstruct.reconstruct`. The causal filter emits it
when sample k+1 arrives (the one-sample latency of Eq. 7); the last element, which no sample
observes, is a one-step prediction with the wider standard deviation that goes with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal, get_args

import numpy as np
import scipy.linalg
import scipy.optimize
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from .models import tau_to_pole
from .noise import estimate_noise
from .reconstruct import Reconstruction, reconstruct
from .validation import check_pair, check_sample_interval

__all__ = [
    "MODELS",
    "CausalFuser",
    "FusionModel",
    "FusionResult",
    "ModelChoice",
    "ModelKind",
    "StateSpace",
    "fit_fusion_model",
    "fuse",
    "linear_recursion",
]

ModelKind = Literal["random-walk", "integrated-random-walk", "band-limited", "periodic"]
ModelChoice = Literal["auto", "random-walk", "integrated-random-walk", "band-limited", "periodic"]
MODELS: tuple[str, ...] = get_args(ModelKind)

#: Smallest noise standard deviation used, as a fraction of the signal's standard deviation:
#: keeps the Riccati equation well posed on noise-free data.
MIN_RELATIVE_SIGMA = 1e-6
#: Search range of log10(q / q_ref) (q_ref = gas variance / dt^order, order 1 or 3), and of
#: the level's intensity likewise.
LOG10_Q_RANGE = (-14.0, 6.0)
#: Search range of log10 of a stationary signal variance relative to the data's.
VARIANCE_RANGE = (-8.0, 4.0)
#: Starting value of log10(q dt / gas variance) of the periodic model's resonator.
PERIODIC_START = -6.0
#: Starting value of log10(level_q dt / gas variance).
LEVEL_START = -10.0
#: Initial simplex edge of the Nelder–Mead searches, in log10 units.
SIMPLEX_STEP = 0.3
#: Cost reported to the optimisers where the likelihood cannot be evaluated.
FAILED_COST = 1e15
#: Half-width of the maximum-likelihood frequency search around the spectral line, in
#: periodogram bins (the least-squares line frequency is much closer than that).
FREQUENCY_SPAN = 0.02
#: Butterworth orders of the band-limited model tried by the maximum-likelihood fit.
BAND_LIMITED_ORDERS = (2, 4)
#: Search range of the band-limited model's cut-off as a fraction of the Nyquist frequency.
CUTOFF_RANGE = (1e-3, 0.9)
#: Prior standard deviation of the gas (or level) state in the causal filter, degrees C.
DIFFUSE_STD = 1e3
#: Relative distance of the time-varying Kalman gain from the steady-state one at which the
#: causal filter switches to the steady-state gain.
GAIN_TOLERANCE = 1e-4
#: Samples after which the causal filter switches to the steady-state gain in any case (a narrow
#: resonator's gain converges over its own time constant, which may be hours).
MAX_EXACT_SAMPLES = 4096
#: Largest condition number of the eigenvectors for which matrix powers come from them.
MAX_EIGENVECTOR_CONDITION = 1e8
#: Relative change of the backward smoothed covariance below which it counts as converged.
COVARIANCE_TOLERANCE = 1e-10

LOG_2PI_SQUARED = 2.0 * math.log(2.0 * math.pi)


@dataclass(frozen=True, kw_only=True)
class FusionModel:
    """A fully specified state-space model of the gas temperature and the two sensors.

    Attributes
    ----------
    kind : {'random-walk', 'integrated-random-walk', 'band-limited', 'periodic'}
        Signal model of the gas temperature (module docstring).
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants of the two sensors, seconds.
    sigma1, sigma2 : float
        White measurement noise standard deviations, degrees C.
    q : float
        Process noise intensity: °C²/s (random walk, band-limited, periodic), °C²/s³
        (integrated random walk).
    freq_hz : float
        Resonator frequency (periodic) or low-pass cut-off (band-limited), Hz.
    level_q : float
        Random-walk intensity of the level, °C²/s (periodic and band-limited).
    order : int
        Butterworth order of the band-limited model's low-pass, 1 to 8.
    """

    kind: ModelKind
    dt: float
    tau1: float
    tau2: float
    sigma1: float
    sigma2: float
    q: float
    freq_hz: float = 0.0
    level_q: float = 0.0
    order: int = 2

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ValueError(f"kind={self.kind!r} is not one of {', '.join(MODELS)}")
        check_sample_interval(self.dt)
        for name in self._positive_fields():
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}={value!r} must be finite and > 0")
        if self.freq_hz >= 0.5 / self.dt:
            raise ValueError(f"freq_hz={self.freq_hz!r} must lie below the Nyquist frequency")
        if self.order not in range(1, 9):
            raise ValueError(f"order={self.order!r} must be an integer from 1 to 8")

    def _positive_fields(self) -> tuple[str, ...]:
        names = ("tau1", "tau2", "sigma1", "sigma2", "q")
        if self.kind in ("band-limited", "periodic"):
            return (*names, "freq_hz", "level_q")
        return names

    @property
    def n_hyperparameters(self) -> int:
        """Number of hyper-parameters fitted by maximum likelihood."""
        return 3 if self.kind in ("band-limited", "periodic") else 1

    def continuous_signal(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray]:
        """Continuous-time signal model ``dx/dt = A x + w``, ``g = c · x``.

        Returns
        -------
        dynamics : ndarray, shape (m, m)
            A, 1/s.
        intensity : ndarray, shape (m, m)
            Spectral density of w (units of x squared per second).
        output : ndarray, shape (m,)
            c.
        prior_std : ndarray, shape (m,)
            Standard deviation of a diffuse prior on x (the causal filter's start).
        """
        if self.kind == "random-walk":
            return np.zeros((1, 1)), np.full((1, 1), self.q), np.ones(1), np.full(1, DIFFUSE_STD)
        if self.kind == "integrated-random-walk":
            dynamics = np.array([[0.0, 1.0], [0.0, 0.0]])
            prior = np.array([DIFFUSE_STD, DIFFUSE_STD / self.tau1])
            return dynamics, np.diag([0.0, self.q]), np.array([1.0, 0.0]), prior
        omega = 2.0 * math.pi * self.freq_hz
        if self.kind == "band-limited":
            block = butterworth_dynamics(self.order, omega)
            noise = np.zeros((self.order, self.order))
            noise[-1, -1] = self.q
            output = np.concatenate(([1.0, 1.0], np.zeros(self.order - 1)))
            prior = np.full(self.order + 1, DIFFUSE_STD)
        else:
            block = np.array([[0.0, -omega], [omega, 0.0]])
            noise = np.diag([self.q, self.q])
            output = np.array([1.0, 1.0, 0.0])
            prior = np.full(3, DIFFUSE_STD)
        dynamics = scipy.linalg.block_diag(np.zeros((1, 1)), block)
        return dynamics, scipy.linalg.block_diag([[self.level_q]], noise), output, prior

    def state_space(self) -> StateSpace:
        """The augmented discrete model ``s_k = [x_{k-1}, T_1(k), T_2(k)]`` (module docstring)."""
        dynamics, intensity, c_s, prior = self.continuous_signal()
        f_s, q_s = _van_loan(dynamics, intensity, self.dt)
        m = c_s.size
        poles = tau_to_pole([self.tau1, self.tau2], self.dt)
        gains = 1.0 - poles
        transition = np.zeros((m + 2, m + 2))
        transition[:m, :m] = f_s
        transition[m:, :m] = np.outer(gains, c_s @ f_s)
        transition[m:, m:] = np.diag(poles)
        loading = np.vstack((np.eye(m), np.outer(gains, c_s)))
        observation = np.zeros((2, m + 2))
        observation[:, m:] = np.eye(2)
        sigmas = np.array([self.sigma1, self.sigma2])
        return StateSpace(
            transition=transition,
            covariance=loading @ q_s @ loading.T,
            observation=observation,
            noise=np.diag(sigmas**2),
            output=np.concatenate((c_s, np.zeros(2))),
            prior_std=np.concatenate((prior, sigmas)),
        )


def butterworth_dynamics(order: int, omega: float) -> NDArray[np.float64]:
    """State matrix of the Butterworth low-pass of ``order`` with cut-off ``omega`` (rad/s).

    State: the output and its first ``order - 1`` derivatives, the j-th scaled by ``omega**-j``
    so that all have the output's units and scale (a companion form in raw derivatives is
    badly scaled); white noise drives the last.

    Returns
    -------
    ndarray, shape (order, order)
        1/s.
    """
    angles = np.pi / 2.0 + np.pi * (2.0 * np.arange(order) + 1.0) / (2.0 * order)
    coefficients = np.real(np.poly(np.exp(1j * angles)))  # s^n + c_1 s^(n-1) + ..., ω = 1
    dynamics = np.zeros((order, order))
    dynamics[:-1, 1:] = np.eye(order - 1)
    dynamics[-1] = -coefficients[:0:-1]
    return omega * dynamics


def _butterworth_unit_variance(order: int, omega: float) -> float:
    """Stationary variance of the Butterworth process's output per unit drive intensity."""
    dynamics = butterworth_dynamics(order, omega)
    drive = np.zeros((order, order))
    drive[-1, -1] = 1.0
    return float(scipy.linalg.solve_continuous_lyapunov(dynamics, -drive)[0, 0])


def _van_loan(
    dynamics: NDArray[np.float64], intensity: NDArray[np.float64], dt: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact discretisation: ``F = exp(A dt)``, ``Q = ∫₀^dt exp(A s) W exp(A s)ᵀ ds``."""
    m = dynamics.shape[0]
    block = np.zeros((2 * m, 2 * m))
    block[:m, :m] = -dynamics
    block[:m, m:] = intensity
    block[m:, m:] = dynamics.T
    exponential = scipy.linalg.expm(block * dt)
    transition = exponential[m:, m:].T
    covariance = transition @ exponential[:m, m:]
    return transition, 0.5 * (covariance + covariance.T)


@dataclass(frozen=True, kw_only=True)
class StateSpace:
    """Matrices of the augmented discrete model (n states, 2 observations).

    Attributes
    ----------
    transition : ndarray, shape (n, n)
    covariance : ndarray, shape (n, n)
        Process noise covariance per sample interval.
    observation : ndarray, shape (2, n)
    noise : ndarray, shape (2, 2)
        Measurement noise covariance, °C².
    output : ndarray, shape (n,)
        Row giving the gas temperature of the previous interval from the state.
    prior_std : ndarray, shape (n,)
        Diffuse prior standard deviations of the state (causal start).
    """

    transition: NDArray[np.float64]
    covariance: NDArray[np.float64]
    observation: NDArray[np.float64]
    noise: NDArray[np.float64]
    output: NDArray[np.float64]
    prior_std: NDArray[np.float64]


@dataclass(frozen=True)
class SteadyState:
    """Steady-state Kalman quantities of a :class:`StateSpace`.

    Attributes
    ----------
    predicted : ndarray, shape (n, n)
        Covariance of the one-step prediction (solution of the Riccati equation).
    filtered : ndarray, shape (n, n)
        Covariance after the measurement update.
    gain : ndarray, shape (n, 2)
        ``x_{k|k} = x_{k|k-1} + gain (y_k - H x_{k|k-1})``.
    innovation : ndarray, shape (2, 2)
        Innovation covariance, °C².
    closed_loop : ndarray, shape (n, n)
        ``F (I - gain H)``, the matrix of the prediction recursion.
    """

    predicted: NDArray[np.float64]
    filtered: NDArray[np.float64]
    gain: NDArray[np.float64]
    innovation: NDArray[np.float64]
    closed_loop: NDArray[np.float64]


def steady_state(model: StateSpace) -> SteadyState:
    """Solve the discrete algebraic Riccati equation for the steady-state Kalman filter.

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        If the Riccati equation has no stabilising solution (scipy's errors).
    """
    f, h = model.transition, model.observation
    predicted = scipy.linalg.solve_discrete_are(f.T, h.T, model.covariance, model.noise)
    predicted = 0.5 * (predicted + predicted.T)
    innovation = h @ predicted @ h.T + model.noise
    gain = scipy.linalg.solve(innovation, h @ predicted, assume_a="pos").T
    filtered = predicted - gain @ innovation @ gain.T
    closed_loop = f @ (np.eye(f.shape[0]) - gain @ h)
    return SteadyState(predicted, 0.5 * (filtered + filtered.T), gain, innovation, closed_loop)


def _apply(matrix: NDArray, array: NDArray) -> NDArray:
    """``matrix`` (a, b) applied along the first axis of ``array`` (b, ...) → (a, ...).

    Written as elementwise sums (einsum for real data) rather than a matrix product: BLAS
    spreads products with long arrays over threads, which on a loaded machine made these
    small-by-long products ten times slower.
    """
    if not (np.iscomplexobj(matrix) or np.iscomplexobj(array)):
        return np.einsum("ij,j...->i...", matrix, array)
    real = np.einsum("ij,j...->i...", matrix.real, array.real)
    imaginary = np.einsum("ij,j...->i...", matrix.imag, array.real)
    if np.iscomplexobj(array):
        real -= np.einsum("ij,j...->i...", matrix.imag, array.imag)
        imaginary += np.einsum("ij,j...->i...", matrix.real, array.imag)
    return real + 1j * imaginary


def linear_recursion(
    matrix: NDArray[np.float64], inputs: NDArray[np.float64], initial: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Run ``x_j = A x_{j-1} + u_j`` for j = 1..M without a Python loop over samples.

    In the Schur basis ``A = U T Uᴴ`` (T upper triangular, U unitary) each component is a
    first-order recursion driven by the inputs and by the components after it, solved by
    :func:`scipy.signal.lfilter` from the last component back to the first.

    Parameters
    ----------
    matrix : ndarray, shape (n, n)
        A; a bounded result needs its eigenvalues inside the unit circle.
    inputs : ndarray, shape (n, M, m)
        u_1..u_M, component first, for m independent columns propagated together.
    initial : ndarray, shape (n, m)
        x_0.

    Returns
    -------
    ndarray, shape (n, M, m)
        x_1..x_M.
    """
    upper, basis = scipy.linalg.schur(matrix, output="complex")
    n = matrix.shape[0]
    drive = _apply(basis.conj().T, inputs)
    start = basis.conj().T @ initial
    states = np.empty_like(drive)
    delayed = np.empty_like(drive)  # z_j[k-1], filled as components are solved
    for i in range(n - 1, -1, -1):
        forcing = drive[i]
        for j in range(i + 1, n):
            if upper[i, j] != 0.0:
                forcing = forcing + upper[i, j] * delayed[j]
        pole = upper[i, i]
        states[i], _ = signal.lfilter(
            [1.0], [1.0, -pole], forcing, axis=0, zi=pole * start[i : i + 1]
        )
        delayed[i, 0] = start[i]
        delayed[i, 1:] = states[i, :-1]
    return _apply(basis, states).real


def _matrix_powers(
    matrix: NDArray[np.float64], count: int, rows: slice = slice(None)
) -> NDArray[np.float64]:
    """``(matrix**k)[rows]`` for k = 0..count-1 as an array (r, count, n).

    From the eigendecomposition ``A = V Λ V⁻¹`` when V is well conditioned (a few elementwise
    products), else by running the recursion on the identity.
    """
    n = matrix.shape[0]
    eigenvalues, vectors = np.linalg.eig(matrix)
    if np.linalg.cond(vectors) > MAX_EIGENVECTOR_CONDITION:
        powers = linear_recursion(matrix, np.zeros((n, count - 1, n)), np.eye(n))
        return np.concatenate((np.eye(n)[:, None], powers), axis=1)[rows]
    inverse = np.linalg.inv(vectors)
    steps = eigenvalues[:, None] ** np.arange(count)  # (n, count)
    left = vectors[rows]
    powers = np.zeros((left.shape[0], count, n), dtype=np.complex128)
    for i in range(n):
        powers += left[:, i, None, None] * steps[i, None, :, None] * inverse[i, None, None, :]
    return powers.real


def _horizon(matrix: NDArray[np.float64], count: int) -> int:
    """Samples after which ``matrix**k`` has decayed below 1e-13 (at most ``count``)."""
    radius = float(np.max(np.abs(np.linalg.eigvals(matrix))))
    if radius >= 1.0 - 1e-12:
        return count
    return int(min(count, math.ceil(math.log(1e-13) / math.log(max(radius, 1e-300))) + 1))


@dataclass(frozen=True)
class _ForwardPass:
    """Steady-state filter run over a record (arrays component first).

    Attributes
    ----------
    predicted : ndarray, shape (n, N+1)
        x_{k|k-1}, k = 0..N, from the given initial state (zero when it was estimated).
    innovations : ndarray, shape (2, N)
        Innovations of ``predicted``.
    log_likelihood : float
        Nats.
    initial : ndarray, shape (n,) or None
        GLS estimate of x_0 when it was estimated: add ``A^k x_0`` to ``predicted``.
    initial_covariance : ndarray, shape (n, n) or None
        Covariance of that estimate.
    """

    predicted: NDArray[np.float64]
    innovations: NDArray[np.float64]
    log_likelihood: float
    initial: NDArray[np.float64] | None = None
    initial_covariance: NDArray[np.float64] | None = None


def _whiten(values: NDArray[np.float64], covariance: NDArray[np.float64]) -> NDArray:
    """``L⁻¹ values`` for ``covariance = L Lᵀ`` (2×2), values of shape (2, ...)."""
    l00 = math.sqrt(covariance[0, 0])
    l10 = covariance[1, 0] / l00
    l11 = math.sqrt(covariance[1, 1] - l10**2)
    first = values[0] / l00
    return np.stack((first, (values[1] - l10 * first) / l11))


def _gaussian_log_likelihood(whitened: NDArray, covariance: NDArray) -> float:
    """Log-likelihood (nats) of Gaussian innovations of covariance (2, 2), whitened (2, N)."""
    _, logdet = np.linalg.slogdet(covariance)
    count = whitened.shape[1]
    return -0.5 * (count * (logdet + 2.0 * math.log(2.0 * math.pi)) + float(np.sum(whitened**2)))


def _forward(
    model: StateSpace, gains: SteadyState, y: NDArray[np.float64], initial: NDArray | None
) -> _ForwardPass:
    """Steady-state Kalman filter over y (2, N); estimates x_0 by GLS when ``initial`` is None.

    With a fixed gain the innovations are affine in the initial state x_0,
    ``e_k = e⁰_k - H A^k x_0`` (A the closed-loop matrix); minimising their whitened sum of
    squares over x_0 maximises the likelihood under a diffuse prior on x_0.
    """
    n = model.transition.shape[0]
    inputs = _apply(model.transition @ gains.gain, y)[:, :, None]
    start = np.zeros(n) if initial is None else initial
    runs = linear_recursion(gains.closed_loop, inputs, start[:, None])[:, :, 0]
    predicted = np.concatenate((start[:, None], runs), axis=1)
    innovations = y - predicted[-2:, :-1]
    whitened = _whiten(innovations, gains.innovation)
    if initial is not None:
        log_likelihood = _gaussian_log_likelihood(whitened, gains.innovation)
        return _ForwardPass(predicted, innovations, log_likelihood)
    normal, projection = _initial_state_equations(gains, whitened)
    covariance = np.linalg.pinv(normal, rcond=1e-13, hermitian=True)
    estimate = covariance @ projection
    # Σ|w - D x̂|² = Σ|w|² - pᵀ x̂ at the least-squares x̂ (p = Dᵀ w).
    log_likelihood = _gaussian_log_likelihood(whitened, gains.innovation)
    log_likelihood += 0.5 * float(projection @ estimate)
    return _ForwardPass(predicted, innovations, log_likelihood, estimate, covariance)


def _initial_state_equations(
    gains: SteadyState, whitened: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normal equations ``DᵀD x_0 = Dᵀ w`` of the initial state, D_k = L⁻¹ H A^k.

    With ``A = V Λ V⁻¹``, ``D_k = Σ_i a_i λ_i^k b_iᵀ`` (a_i = L⁻¹ H V e_i, b_i the i-th row
    of V⁻¹), so ``DᵀD`` is a sum of geometric series and ``Dᵀw`` needs ``Σ_k λ̄_i^k w_k``
    (a backward first-order recursion per eigenvalue): O(N n) work without forming D. Falls
    back to forming D when V is ill conditioned.

    Returns
    -------
    normal : ndarray, shape (n, n)
    projection : ndarray, shape (n,)
    """
    count = whitened.shape[1]
    eigenvalues, vectors = np.linalg.eig(gains.closed_loop)
    if np.linalg.cond(vectors) > MAX_EIGENVECTOR_CONDITION:
        length = _horizon(gains.closed_loop, count)
        powers = _matrix_powers(gains.closed_loop, length, slice(-2, None))  # (2, L, n)
        design = _whiten(powers, gains.innovation)
        normal = np.einsum("rki,rkj->ij", design, design)
        return normal, np.einsum("rki,rk->i", design, whitened[:, :length])
    rows = np.linalg.inv(vectors)
    columns = _whiten(vectors[-2:], gains.innovation)  # a_i as columns, (2, n)
    ratio = eigenvalues.conj()[:, None] * eigenvalues[None, :]
    near_one = np.abs(1.0 - ratio) < 1e-12
    series = np.where(near_one, count, (1.0 - ratio**count) / np.where(near_one, 1.0, 1.0 - ratio))
    inner = (columns.conj().T @ columns) * series
    normal = (rows.conj().T @ inner @ rows).real
    transforms = np.stack(
        [
            signal.lfilter([1.0], [1.0, -pole.conj()], whitened[:, ::-1], axis=1)[:, -1]
            for pole in eigenvalues
        ],
        axis=1,
    )  # Σ_k λ̄_i^k w_k as columns, (2, n)
    projection = (rows.conj().T @ np.sum(columns.conj() * transforms, axis=0)).real
    return 0.5 * (normal + normal.T), projection


def _smooth(
    model: StateSpace, gains: SteadyState, forward: _ForwardPass
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Steady-state RTS smoother: smoothed states (n, N) and their output variances (N,).

    ``x_{k|N} = J x_{k+1|N} + (I - J F) x_{k|k}`` with ``J = P_f Fᵀ P_p⁻¹``, run backwards.
    The variance is the smoothed covariance (``P_f`` at the end of the record, converging
    backwards to its steady state) plus the part due to the GLS estimate of x_0.
    """
    f, h, c = model.transition, model.observation, model.output
    identity = np.eye(f.shape[0])
    count = forward.innovations.shape[1]
    predicted = forward.predicted[:, :-1].copy()
    innovations = forward.innovations.copy()
    if forward.initial is not None:
        response = _matrix_powers(gains.closed_loop, _horizon(gains.closed_loop, count))
        length = response.shape[1]
        correction = np.einsum("ikj,j->ik", response, forward.initial)
        predicted[:, :length] += correction
        innovations[:, :length] -= correction[-2:]
    filtered = predicted + _apply(gains.gain, innovations)
    smoother = gains.filtered @ np.linalg.solve(gains.predicted, f).T
    blend = identity - smoother @ f
    states = _backward(smoother, blend, filtered[:, :, None])[:, :, 0]
    variances = _smoothed_variances(gains, smoother, c, count)
    if forward.initial is not None:
        sensitivity = _apply(identity - gains.gain @ h, response)
        if length < count:  # the response has died out: start from zero there
            sensitivity = np.concatenate((sensitivity, np.zeros_like(sensitivity[:, :1])), 1)
        output = np.einsum("i,ikj->kj", c, _backward(smoother, blend, sensitivity))[:length]
        variances[:length] += np.einsum("ki,ij,kj->k", output, forward.initial_covariance, output)
    return states, variances


def _backward(
    smoother: NDArray[np.float64], blend: NDArray[np.float64], filtered: NDArray[np.float64]
) -> NDArray[np.float64]:
    """RTS pass ``x_{k|N} = J x_{k+1|N} + B x_{k|k}`` backwards over (n, N, m) arrays."""
    inputs = _apply(blend, filtered[:, -2::-1])
    backward = linear_recursion(smoother, inputs, filtered[:, -1])
    return np.concatenate((backward[:, ::-1], filtered[:, -1:]), axis=1)


def _smoothed_variances(
    gains: SteadyState, smoother: NDArray[np.float64], output: NDArray[np.float64], count: int
) -> NDArray[np.float64]:
    """Output variance of the smoothed states (count,), from the end of the record backwards."""
    variances = np.empty(count)
    covariance = gains.filtered
    variances[-1] = output @ covariance @ output
    for k in range(count - 2, -1, -1):
        updated = gains.filtered + smoother @ (covariance - gains.predicted) @ smoother.T
        variances[k] = output @ updated @ output
        change = np.max(np.abs(updated - covariance))
        covariance = updated
        if change <= COVARIANCE_TOLERANCE * np.max(np.abs(updated)):
            variances[:k] = variances[k]
            break
    return variances


def _log_likelihood(model: FusionModel, y: NDArray[np.float64]) -> float:
    """Profile log-likelihood of the innovations, nats (−inf where the Riccati equation fails)."""
    space = model.state_space()
    try:
        gains = steady_state(space)
        value = _forward(space, gains, y, None).log_likelihood
    except (np.linalg.LinAlgError, ValueError):
        return -math.inf
    return value if math.isfinite(value) else -math.inf


def _dominant_frequency(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> float:
    """Frequency of the strongest spectral line relative to the noise floor, Hz.

    The Hann-windowed periodograms' signal-to-noise ratios of the two sensors are summed; the
    peak bin is refined to the frequency of the least-squares sinusoid fitted to the Eq. (7)
    reconstruction (which, unlike the readings, carries no start-up transient of the sensors),
    as a narrow resonator needs it to a small fraction of a bin.
    """
    count = first.size
    freqs = np.fft.rfftfreq(count, base.dt)
    window = np.hanning(count)
    excess = np.zeros(freqs.size)
    for values, sigma in ((first, base.sigma1), (second, base.sigma2)):
        power = np.abs(np.fft.rfft((values - values.mean()) * window)) ** 2
        excess += power / (sigma**2 * np.sum(window**2))
    excess[0] = 0.0
    peak = max(int(np.argmax(excess[: freqs.size - 1])), 1)
    gas = _reconstruction(first, second, base).gas
    time = np.arange(gas.size) * base.dt
    best = scipy.optimize.minimize_scalar(
        lambda frequency: _sinusoid_residual(gas, time, frequency),
        bounds=(freqs[peak - 1], freqs[peak + 1]),
        method="bounded",
        options={"xatol": 1e-7 * freqs[1]},
    )
    return float(best.x)


def _sinusoid_residual(values: NDArray[np.float64], time: NDArray, frequency: float) -> float:
    """Residual sum of squares of ``values`` about a least-squares sinusoid at ``frequency``."""
    phase = 2.0 * np.pi * frequency * time
    basis = np.stack((np.ones_like(time), np.cos(phase), np.sin(phase)))
    normal = np.einsum("ik,jk->ij", basis, basis)
    projection = np.einsum("ik,k->i", basis, values)
    coefficients = np.linalg.solve(normal, projection)
    return float(values @ values - coefficients @ projection)


@dataclass(frozen=True)
class _Fitting:
    """Data and scales shared by the maximum-likelihood fits of one record.

    Attributes
    ----------
    base : FusionModel
        Carries dt, τ and σ.
    y : ndarray, shape (2, N)
        Readings less their mean level, degrees C.
    scale : float
        Gas temperature variance estimated from the Eq. (7) reconstruction less its noise, °C².
    freq_hz : float
        Strongest spectral line, Hz.
    """

    base: FusionModel
    y: NDArray[np.float64]
    scale: float
    freq_hz: float

    def cost(self, model: FusionModel) -> float:
        """Negative log-likelihood, nats (finite, for the optimisers)."""
        return min(-_log_likelihood(model, self.y), FAILED_COST)


def _random_walk_model(fit: _Fitting, kind: str, theta: NDArray) -> FusionModel:
    """θ = log10(q dt^order / scale)."""
    order = 3 if kind == "integrated-random-walk" else 1
    return replace(fit.base, kind=kind, q=float(fit.scale / fit.base.dt**order * 10.0 ** theta[0]))


def _band_limited_model(fit: _Fitting, theta: NDArray, order: int = 2) -> FusionModel:
    """θ = log10 of (variance / scale, cut-off / Nyquist frequency, level_q dt / scale)."""
    cutoff = 0.5 / fit.base.dt * 10.0 ** theta[1]
    unit = _butterworth_unit_variance(order, 2.0 * math.pi * cutoff)
    return replace(
        fit.base,
        kind="band-limited",
        q=float(fit.scale * 10.0 ** theta[0] / unit),
        freq_hz=float(cutoff),
        level_q=float(fit.scale / fit.base.dt * 10.0 ** theta[2]),
        order=order,
    )


def _periodic_model(fit: _Fitting, theta: NDArray) -> FusionModel:
    """θ = log10 of (q dt / scale, level_q dt / scale)."""
    return replace(
        fit.base,
        kind="periodic",
        q=float(fit.scale / fit.base.dt * 10.0 ** theta[0]),
        freq_hz=fit.freq_hz,
        level_q=float(fit.scale / fit.base.dt * 10.0 ** theta[1]),
    )


def _fit_random_walk(fit: _Fitting, kind: str) -> FusionModel:
    """Brent's method on log10 q."""
    best = scipy.optimize.minimize_scalar(
        lambda t: fit.cost(_random_walk_model(fit, kind, [t])),
        bounds=LOG10_Q_RANGE,
        method="bounded",
        options={"xatol": 1e-3},
    )
    return _random_walk_model(fit, kind, [best.x])


def _polish(fit: _Fitting, build, start: NDArray, bounds: list[tuple[float, float]]):
    """Nelder–Mead on the log10 hyper-parameters from ``start``.

    The tolerances (0.1 in log10, 0.05 nats) are far below what changes the estimate.
    """
    simplex = np.vstack((start, start + SIMPLEX_STEP * np.eye(start.size)))
    best = scipy.optimize.minimize(
        lambda theta: fit.cost(build(fit, theta)),
        start,
        method="Nelder-Mead",
        bounds=bounds,
        options={"xatol": 0.1, "fatol": 0.05, "initial_simplex": simplex, "maxfev": 150},
    )
    return build(fit, best.x)


def _fit_band_limited(fit: _Fitting) -> FusionModel:
    """Each order of :data:`BAND_LIMITED_ORDERS` fitted; the likelier kept."""
    return min((_fit_butterworth(fit, order) for order in BAND_LIMITED_ORDERS), key=fit.cost)


def _fit_butterworth(fit: _Fitting, order: int) -> FusionModel:
    """Scan of the cut-off at the data's variance, then all three settings polished."""

    def build(fitting: _Fitting, theta: NDArray) -> FusionModel:
        return _band_limited_model(fitting, theta, order)

    cutoffs = np.linspace(*np.log10(CUTOFF_RANGE), 10)
    costs = [fit.cost(build(fit, [0.0, c, LEVEL_START])) for c in cutoffs]
    start = np.array([0.0, cutoffs[int(np.argmin(costs))], LEVEL_START])
    bounds = [VARIANCE_RANGE, tuple(np.log10(CUTOFF_RANGE)), LOG10_Q_RANGE]
    return _polish(fit, build, start, bounds)


def _fit_periodic(fit: _Fitting) -> FusionModel:
    """Maximum-likelihood settings of the periodic model.

    Drive and level intensities by Nelder–Mead, then the frequency refined by Brent's method
    within a few hundredths of a periodogram bin.
    """
    start = np.array([PERIODIC_START, LEVEL_START])
    bounds = [LOG10_Q_RANGE, LOG10_Q_RANGE]
    model = _polish(fit, _periodic_model, start, bounds)
    span = FREQUENCY_SPAN / (fit.y.shape[1] * fit.base.dt)
    best = scipy.optimize.minimize_scalar(
        lambda frequency: fit.cost(replace(model, freq_hz=frequency)),
        bounds=(model.freq_hz - span, model.freq_hz + span),
        method="bounded",
        options={"xatol": 1e-4 * span},
    )
    return replace(model, freq_hz=float(best.x))


def _fit_kind(fit: _Fitting, kind: str) -> FusionModel:
    if kind == "band-limited":
        return _fit_band_limited(fit)
    if kind == "periodic":
        return _fit_periodic(fit)
    return _fit_random_walk(fit, kind)


def _reconstruction(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> Reconstruction:
    """The paper's inverse-variance weighted Eq. (7) reconstruction (no post-filter)."""
    phi = (base.sigma1 / base.sigma2) ** 2
    return reconstruct(first, second, base.dt, base.tau1, base.tau2, phi=phi)


def _gas_variance(
    first: NDArray[np.float64], second: NDArray[np.float64], base: FusionModel
) -> float:
    """Variance of the gas temperature: the Eq. (7) reconstruction's less its noise, °C²."""
    reconstruction = _reconstruction(first, second, base)
    poles = tau_to_pole([base.tau1, base.tau2], base.dt)
    noise = np.array([base.sigma1, base.sigma2]) ** 2 * (1.0 + poles**2) / (1.0 - poles) ** 2
    weights = np.array([reconstruction.weight1, 1.0 - reconstruction.weight1])
    total = float(np.var(reconstruction.gas))
    return max(total - float(weights**2 @ noise), 1e-6 * total, 1e-12)


def _noise_sigmas(
    first: NDArray[np.float64],
    second: NDArray[np.float64],
    dt: float,
    sigma1: float | None,
    sigma2: float | None,
) -> tuple[float, float]:
    """Noise standard deviations, measured from the spectra unless given, with a floor."""
    sigmas = []
    for values, given in ((first, sigma1), (second, sigma2)):
        sigma = estimate_noise(values, dt).sigma if given is None else float(given)
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"noise standard deviation {sigma!r} must be finite and >= 0")
        floor = MIN_RELATIVE_SIGMA * max(float(np.std(values)), 1e-9)
        sigmas.append(max(sigma, floor))
    return sigmas[0], sigmas[1]


def fit_fusion_model(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    sigma1: float | None = None,
    sigma2: float | None = None,
    model: ModelChoice = "auto",
) -> tuple[FusionModel, float, dict[str, float]]:
    """Choose the signal model and its hyper-parameters by maximum likelihood.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds.
    sigma1, sigma2 : float, optional
        Noise standard deviations, degrees C; measured from the spectra when omitted.
    model : {'auto', 'random-walk', 'integrated-random-walk', 'band-limited', 'periodic'}
        Signal model; 'auto' fits them all and keeps the one with the highest log-likelihood
        less its number of hyper-parameters (Akaike).

    Returns
    -------
    model : FusionModel
    log_likelihood : float
        Of the chosen model, nats.
    candidates : dict of str to float
        Log-likelihood of every model fitted, nats.
    """
    first, second = check_pair(tc1, tc2)
    dt = check_sample_interval(dt)
    if model != "auto" and model not in MODELS:
        raise ValueError(f"model={model!r} is not 'auto' or one of {', '.join(MODELS)}")
    s1, s2 = _noise_sigmas(first, second, dt, sigma1, sigma2)
    base = FusionModel(kind="random-walk", dt=dt, tau1=tau1, tau2=tau2, sigma1=s1, sigma2=s2, q=1)
    level = float(np.mean(first))
    fit = _Fitting(
        base=base,
        y=np.vstack((first - level, second - level)),
        scale=_gas_variance(first, second, base),
        freq_hz=_dominant_frequency(first, second, base),
    )
    kinds = MODELS if model == "auto" else (model,)
    fitted = {kind: _fit_kind(fit, kind) for kind in kinds}
    candidates = {kind: -fit.cost(value) for kind, value in fitted.items()}
    best = max(kinds, key=lambda k: candidates[k] - fitted[k].n_hyperparameters)
    return fitted[best], candidates[best], candidates


@dataclass(frozen=True, kw_only=True)
class FusionResult:
    """Gas temperature fused from two thermocouples.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Start of the interval over which each gas sample holds, seconds.
    gas : ndarray, shape (N,)
        Estimated gas temperature, degrees C. Element N-1 is a one-step prediction.
    std : ndarray, shape (N,)
        Standard deviation of each estimate under the model, degrees C.
    model : FusionModel
        The model used, with its hyper-parameters.
    log_likelihood : float
        Log-likelihood of the innovations under ``model``, nats.
    candidates : dict of str to float
        Log-likelihood of each signal model fitted (empty when the model was given).
    causal : bool
        Whether ``gas`` comes from the forward (causal) filter rather than the smoother.
    """

    time: NDArray[np.float64]
    gas: NDArray[np.float64]
    std: NDArray[np.float64]
    model: FusionModel
    log_likelihood: float
    candidates: dict[str, float] = field(default_factory=dict)
    causal: bool = False

    @property
    def kind(self) -> str:
        """Signal model used."""
        return self.model.kind

    @property
    def q(self) -> float:
        """Process noise intensity of the model (see :class:`FusionModel`)."""
        return self.model.q


def fuse(
    tc1: ArrayLike,
    tc2: ArrayLike,
    dt: float,
    tau1: float,
    tau2: float,
    *,
    sigma1: float | None = None,
    sigma2: float | None = None,
    model: ModelChoice | FusionModel = "auto",
    causal: bool = False,
) -> FusionResult:
    """Fused gas temperature from both thermocouples: RTS smoother or causal Kalman filter.

    Parameters
    ----------
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C, sampled every ``dt``.
    dt : float
        Sample interval, seconds.
    tau1, tau2 : float
        Time constants, seconds.
    sigma1, sigma2 : float, optional
        Noise standard deviations, degrees C; measured from the spectra when omitted.
    model : str or FusionModel
        'auto' or a signal model name, fitted by maximum likelihood
        (:func:`fit_fusion_model`), or a :class:`FusionModel` used as it is (its dt, τ and σ
        then replace the arguments).
    causal : bool
        Run the forward Kalman filter only: element k then depends on samples 0..k+1 alone,
        once the model is fixed. With a model name the hyper-parameters are still fitted on
        the whole record; pass a :class:`FusionModel` for a strictly causal run.

    Returns
    -------
    FusionResult
        Gas estimate and its standard deviation, shape (N,); element k is the gas temperature
        over ``[t_k, t_{k+1})``.
    """
    first, second = check_pair(tc1, tc2)
    if isinstance(model, FusionModel):
        fitted, candidates = model, {}
    else:
        fitted, _, candidates = fit_fusion_model(
            first, second, dt, tau1, tau2, sigma1=sigma1, sigma2=sigma2, model=model
        )
    if causal:
        fuser = CausalFuser(fitted)
        gas, std = fuser.extend(first, second)
        ahead, ahead_std = fuser.predict()
        gas, std = np.append(gas, ahead), np.append(std, ahead_std)
        log_likelihood = fuser.log_likelihood
    else:
        gas, std, log_likelihood = _smoothed_gas(fitted, first, second)
    return FusionResult(
        time=np.arange(first.size) * fitted.dt,
        gas=gas,
        std=std,
        model=fitted,
        log_likelihood=log_likelihood,
        candidates=candidates,
        causal=causal,
    )


def _smoothed_gas(
    model: FusionModel, first: NDArray[np.float64], second: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Smoothed gas temperature (N,), its standard deviation (N,) and the log-likelihood."""
    space = model.state_space()
    gains = steady_state(space)
    level = float(np.mean(first))
    forward = _forward(space, gains, np.vstack((first - level, second - level)), None)
    states, variances = _smooth(space, gains, forward)
    c, f = space.output, space.transition
    # State k holds the gas of interval k-1; the last interval is predicted one step ahead.
    ahead = f @ states[:, -1]
    ahead_variance = c @ gains.predicted @ c + variances[-1] - c @ gains.filtered @ c
    gas = np.append(c @ states[:, 1:], c @ ahead) + level
    std = np.sqrt(np.append(variances[1:], ahead_variance))
    return gas, std, forward.log_likelihood


class CausalFuser:
    """Streaming Kalman filter of the gas temperature, for the online node.

    Each new sample pair k yields the estimate of the gas temperature over the previous
    interval ``[t_{k-1}, t_k)`` (the latency of Eq. 7); the very first pair yields nothing.
    The filter starts from a diffuse prior around the first reading with the exact
    time-varying Kalman recursion (one sample at a time) and switches to the steady-state
    gain, processed in vectorised batches, once the covariance has converged.

    Parameters
    ----------
    model : FusionModel
        A fitted model (:func:`fit_fusion_model`).

    Examples
    --------
    >>> fuser = CausalFuser(model)                      # doctest: +SKIP
    >>> gas, std = fuser.extend(tc1[:100], tc2[:100])   # 99 estimates
    >>> gas, std = fuser.extend(tc1[100:], tc2[100:])   # one per new pair
    """

    def __init__(self, model: FusionModel) -> None:
        self.model = model
        self._space = model.state_space()
        self._gains = steady_state(self._space)
        self._state: NDArray[np.float64] | None = None  # x_{k|k-1}
        self._covariance = np.diag(self._space.prior_std**2)
        self._steady = False
        self._exact_samples = 0
        self.log_likelihood = 0.0

    @property
    def started(self) -> bool:
        """Whether the filter holds a state (it has taken a sample since its last reset)."""
        return self._state is not None

    @property
    def converged(self) -> bool:
        """Whether the filter runs on the steady-state gain."""
        return self._steady

    def reset(self) -> None:
        """Forget the state: the next pair starts afresh from the diffuse prior."""
        self._state = None
        self._covariance = np.diag(self._space.prior_std**2)
        self._steady = False
        self._exact_samples = 0
        self.log_likelihood = 0.0

    def retune(self, model: FusionModel) -> None:
        """Switch to new model settings (e.g. new τ) and keep what the filter knows.

        The state ``[x, T_1, T_2]`` means the same under any model with the same signal state,
        so the estimate carries over without a new diffuse start: a steady filter moves to the
        new steady-state covariance, a converging one keeps its covariance. A model whose
        signal state differs (another kind or order) starts afresh (:meth:`reset`).
        """
        space = model.state_space()
        same_state = (model.kind, model.order) == (self.model.kind, self.model.order)
        self.model, self._space, self._gains = model, space, steady_state(space)
        if not same_state:
            self.reset()
        elif self._steady:
            self._covariance = self._gains.predicted

    def _initial_state(self, y1: float, y2: float) -> NDArray[np.float64]:
        """Sensors at their first readings, the gas (or level) at the faster sensor's."""
        m = self._space.output.size - 2
        state = np.zeros(m + 2)
        state[0] = y1
        state[m:] = (y1, y2)
        return state

    def extend(
        self, tc1: ArrayLike, tc2: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Filter a batch of new sample pairs.

        Parameters
        ----------
        tc1, tc2 : array_like, shape (M,)
            New readings, degrees C.

        Returns
        -------
        gas, std : ndarray, shape (M,) (M-1 for the very first batch)
            Gas temperature over the interval before each new sample and its standard
            deviation, degrees C.
        """
        first, second = check_pair(tc1, tc2, min_samples=0)
        y = np.vstack((first, second))
        count = first.size
        gas, std = np.empty(count), np.empty(count)
        skip = 0
        if self._state is None and count:
            self._state = self._initial_state(first[0], second[0])
            skip = 1
        done = 0
        if not self._steady:
            exact_gas, exact_std = self._exact_batch(y)
            done = exact_gas.size
            gas[:done], std[:done] = exact_gas, exact_std
        if done < count:
            gas[done:], std[done:] = self._steady_batch(y[:, done:])
        return gas[skip:], std[skip:]

    def _exact_batch(
        self, y: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Time-varying Kalman filter over y (2, M) until the gain has converged.

        Returns the filtered gas and its std for the samples processed (possibly fewer than M).
        """
        f, noise, covariance = self._space.transition, self._space.noise, self._space.covariance
        c, target = self._space.output, self._gains.gain
        tolerance = GAIN_TOLERANCE * float(np.max(np.abs(target)))
        state, predicted = self._state, self._covariance
        gas, std = np.empty(y.shape[1]), np.empty(y.shape[1])
        done = 0
        f_t, identity = f.T, np.eye(f.shape[0])
        while done < y.shape[1] and not self._steady:
            (s00, s01), (s10, s11) = predicted[-2:, -2:] + noise
            determinant = s00 * s11 - s01 * s10
            inverse = np.array([[s11, -s01], [-s10, s00]]) / determinant
            gain = predicted[:, -2:] @ inverse
            innovation = y[:, done] - state[-2:]
            state = state + gain @ innovation
            update = identity.copy()
            update[:, -2:] -= gain
            filtered = update @ predicted @ update.T + gain @ noise @ gain.T  # Joseph form
            gas[done], std[done] = c @ state, math.sqrt(max(c @ filtered @ c, 0.0))
            self.log_likelihood -= 0.5 * (
                math.log(determinant) + innovation @ inverse @ innovation + LOG_2PI_SQUARED
            )
            state = f @ state
            predicted = f @ filtered @ f_t + covariance
            predicted = 0.5 * (predicted + predicted.T)
            self._exact_samples += 1
            done += 1
            converged = np.abs(gain - target).max() <= tolerance
            self._steady = converged or self._exact_samples >= MAX_EXACT_SAMPLES
        self._state = state
        self._covariance = self._gains.predicted if self._steady else predicted
        return gas[:done], std[:done]

    def _steady_batch(
        self, y: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        forward = _forward(self._space, self._gains, y, self._state)
        self.log_likelihood += forward.log_likelihood
        self._state = forward.predicted[:, -1]
        filtered = forward.predicted[:, :-1] + _apply(self._gains.gain, forward.innovations)
        c = self._space.output
        std = float(np.sqrt(c @ self._gains.filtered @ c))
        return c @ filtered, np.full(y.shape[1], std)

    def step(self, tc1: float, tc2: float) -> tuple[float, float] | None:
        """Filter one sample pair: the previous interval's gas and its std (None at first)."""
        gas, std = self.extend([tc1], [tc2])
        return (float(gas[0]), float(std[0])) if gas.size else None

    def predict(self) -> tuple[float, float]:
        """Prediction of the gas over the current, not yet observed, interval and its std."""
        if self._state is None:
            raise ValueError("no sample has been filtered yet")
        c = self._space.output
        return float(c @ self._state), float(np.sqrt(c @ self._covariance @ c))
