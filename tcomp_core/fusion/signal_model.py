"""Signal models of the gas temperature and the augmented state-space model of both sensors.

Each signal model is a continuous-time linear system driven by white noise (random walk,
integrated random walk, Butterworth band-limited process, wandering periodic line), discretised
exactly (Van Loan) and augmented with the two first-order sensors (Eqs. 4–6 of the paper):
``s_k = [x_{k-1}, T_1(k), T_2(k)]``. See :mod:`tcomp_core.fusion` for the equations.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ..choices import MODELS, ModelChoice, ModelKind
from ..models import tau_to_pole
from ..validation import check_sample_interval

__all__ = [
    "DIFFUSE_STD",
    "MODELS",
    "FusionModel",
    "ModelChoice",
    "ModelKind",
    "StateSpace",
    "butterworth_dynamics",
    "butterworth_unit_variance",
]

#: Prior standard deviation of the gas (or level) state in the causal filter, degrees C.
DIFFUSE_STD = 1e3


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
    ar : tuple of float
        Coefficients φ_1..φ_p of the autoregressive model of the gas's sample-to-sample
        change (``autoregressive``: d_k = Σ φ_j d_(k-j) + e_k, g_k = g_(k-1) + d_k, e_k of
        variance ``q`` in °C² per sample); stationary (all roots of 1 - Σ φ_j z^-j inside the
        unit circle).
    misfit_c : float
        The sensors' first-order disagreement beyond their noise on the record the model was
        fitted on, degrees C (:func:`~tcomp_core.fusion.adequacy.first_order_misfit`): model
        error no signal model can remove, added in quadrature to every std the model gives.
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
    ar: tuple[float, ...] = ()
    misfit_c: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ValueError(f"kind={self.kind!r} is not one of {', '.join(MODELS)}")
        check_sample_interval(self.dt)
        for name in self._positive_fields():
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}={value!r} must be finite and > 0")
        if not (math.isfinite(self.misfit_c) and self.misfit_c >= 0.0):
            raise ValueError(f"misfit_c={self.misfit_c!r} must be finite and >= 0")
        if self.freq_hz >= 0.5 / self.dt:
            raise ValueError(f"freq_hz={self.freq_hz!r} must lie below the Nyquist frequency")
        if self.order not in range(1, 9):
            raise ValueError(f"order={self.order!r} must be an integer from 1 to 8")
        if self.kind == "autoregressive":
            roots = np.roots(np.concatenate(([1.0], -np.asarray(self.ar, dtype=np.float64))))
            if not (len(self.ar) >= 1 and np.all(np.abs(roots) < 1.0)):
                raise ValueError(f"ar={self.ar!r} must hold the coefficients of a stationary AR")

    def _positive_fields(self) -> tuple[str, ...]:
        names = ("tau1", "tau2", "sigma1", "sigma2", "q")
        if self.kind in ("band-limited", "periodic"):
            return (*names, "freq_hz", "level_q")
        return names

    @property
    def n_hyperparameters(self) -> int:
        """Number of hyper-parameters fitted by maximum likelihood."""
        if self.kind == "autoregressive":
            return len(self.ar) + 1
        return 3 if self.kind in ("band-limited", "periodic") else 1

    def discrete_signal(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray]:
        """Discrete ``autoregressive`` signal model ``x_k = F x_(k-1) + w_k``, ``g = c · x``.

        State ``x_k = [g_k, d_k, d_(k-1), ..., d_(k-p+1)]``: the gas and its last p changes.

        Returns
        -------
        transition, covariance : ndarray, shape (p + 1, p + 1)
            F and the covariance of w per sample (°C²).
        output : ndarray, shape (p + 1,)
            c.
        prior_std : ndarray, shape (p + 1,)
            Diffuse prior standard deviations of x.
        """
        coefficients = np.asarray(self.ar, dtype=np.float64)
        p = coefficients.size
        transition = np.zeros((p + 1, p + 1))
        transition[0, 0] = 1.0
        transition[0, 1:] = coefficients
        transition[1, 1:] = coefficients
        transition[2:, 1:-1] = np.eye(p - 1)
        drive = np.zeros(p + 1)
        drive[:2] = 1.0
        output = np.zeros(p + 1)
        output[0] = 1.0
        return transition, self.q * np.outer(drive, drive), output, np.full(p + 1, DIFFUSE_STD)

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
        if self.kind == "autoregressive":
            raise ValueError("the autoregressive model is discrete: see discrete_signal()")
        if self.kind == "random-walk":
            return np.zeros((1, 1)), np.full((1, 1), self.q), np.ones(1), np.full(1, DIFFUSE_STD)
        if self.kind == "integrated-random-walk":
            dynamics = np.array([[0.0, 1.0], [0.0, 0.0]])
            prior = np.array([DIFFUSE_STD, DIFFUSE_STD / self.tau1])
            return dynamics, np.diag([0.0, self.q]), np.array([1.0, 0.0]), prior
        omega = 2.0 * math.pi * self.freq_hz
        # The level's random walk, then the signal's block: [[0, 0], [0, block]].
        size = 1 + (self.order if self.kind == "band-limited" else 2)
        dynamics = np.zeros((size, size))
        intensity = np.zeros((size, size))
        intensity[0, 0] = self.level_q
        output = np.zeros(size)
        output[:2] = 1.0
        if self.kind == "band-limited":
            dynamics[1:, 1:] = butterworth_dynamics(self.order, omega)
            intensity[-1, -1] = self.q
        else:
            dynamics[1, 2], dynamics[2, 1] = -omega, omega
            intensity[1, 1] = intensity[2, 2] = self.q
        return dynamics, intensity, output, np.full(size, DIFFUSE_STD)

    def state_space(self) -> StateSpace:
        """The augmented discrete model ``s_k = [x_{k-1}, T_1(k), T_2(k)]`` (module docstring)."""
        if self.kind == "autoregressive":
            f_s, q_s, c_s, prior = self.discrete_signal()
        else:
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
    return omega * _unit_butterworth_dynamics(order)


@functools.cache
def _unit_butterworth_dynamics(order: int) -> NDArray[np.float64]:
    """:func:`butterworth_dynamics` at ω = 1 rad/s (read-only: one array per order)."""
    angles = np.pi / 2.0 + np.pi * (2.0 * np.arange(order) + 1.0) / (2.0 * order)
    coefficients = np.real(np.poly(np.exp(1j * angles)))  # s^n + c_1 s^(n-1) + ..., ω = 1
    dynamics = np.zeros((order, order))
    dynamics[:-1, 1:] = np.eye(order - 1)
    dynamics[-1] = -coefficients[:0:-1]
    dynamics.flags.writeable = False
    return dynamics


def butterworth_unit_variance(order: int, omega: float) -> float:
    """Stationary variance of the Butterworth process's output per unit drive intensity.

    The output of :func:`butterworth_dynamics` is the drive through ``1 / (ω B(s/ω))`` (B the
    unit Butterworth polynomial, ``|B(jν)|² = 1 + ν^2n``), so the variance is
    ``(1/2π) ∫ dν / (ω² (1 + (ν/ω)^2n)) = 1 / (2 n ω sin(π/2n))``: the solution of the
    Lyapunov equation ``A P + P Aᵀ + e_n e_nᵀ = 0``'s first element, in closed form.
    """
    return 1.0 / (2.0 * order * omega * math.sin(math.pi / (2.0 * order)))


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
