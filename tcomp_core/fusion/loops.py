"""The inner loops of the Kalman likelihood and of the causal filter's start, compiled.

A signal model's maximum-likelihood fit (:mod:`tcomp_core.fusion.fitting`) evaluates the
innovation likelihood a few hundred times on a few thousand samples. As numpy and scipy calls an
evaluation took about 2 ms, most of it per-call overhead: scipy's Riccati solver validates,
balances and orders a QZ decomposition of a pencil twice the state's size, and the filter ran
one ``lfilter`` per mode and another per eigenvalue. Here they are loops compiled by
:func:`tcomp_core.compiled.compile_loops`, with a fourth for the causal filter:

* the steady-state Riccati equation by the structure-preserving doubling algorithm;
* the steady-state filter's whitened innovations, mode by mode in the closed loop's eigenbasis;
* the discounted sums ``Σ_k λ̄^k w_k`` of the initial state's normal equations;
* the causal filter's time-varying start (:class:`tcomp_core.fusion.causal.ExactSchedule`),
  up to 4 096 covariance steps of a few-state filter, 80 ms per model as numpy calls.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..compiled import compile_loops

__all__ = [
    "DOUBLING_STEPS",
    "discounted_sums",
    "exact_schedule",
    "modal_innovations",
    "riccati_by_doubling",
]

#: Most doubling steps: the error falls as ρ^(2^k) with ρ the closed loop's spectral radius, so
#: 64 steps reach double precision for any ρ below 1 − 1e-16 (a slower loop is left to scipy).
DOUBLING_STEPS = 64
#: Doubling stops once a step changes the solution by less than this, relative to its largest
#: entry.
DOUBLING_TOLERANCE = 1e-15
#: Largest residual of the Riccati equation, relative to the solution's largest entry, for which
#: the doubled solution is taken. On a badly scaled model (a noise-free record: R near 1e-10
#: against Q near 1e6) the iteration can settle on a matrix that is no solution at all;
#: scipy's balanced QZ then solves it.
DOUBLING_RESIDUAL = 1e-10
_EPS = float(np.finfo(np.float64).eps)


def _doubling(
    a: NDArray[np.float64],
    g: NDArray[np.float64],
    h: NDArray[np.float64],
    tolerance: float,
    max_steps: int,
) -> tuple[NDArray[np.float64], int]:
    # X = aᵀ X (I + G X)⁻¹ a + H by doubling (Chu, Fan & Lin 2005):
    # W = I + G_k H_k, a_{k+1} = a_k W⁻¹ a_k, G_{k+1} = G_k + a_k W⁻¹ G_k a_kᵀ,
    # H_{k+1} = H_k + a_kᵀ H_k W⁻¹ a_k; H_k → X. Returns (X, steps), steps -1 if not converged.
    # Loops rather than slice assignment and np.linalg.solve, which take numba seconds to
    # compile.
    n = a.shape[0]
    solved = np.empty((n, 2 * n))  # W⁻¹ [a | G]
    transposed = np.empty((n, n))
    for step in range(max_steps):
        w = g @ h
        for i in range(n):
            w[i, i] += 1.0
            for j in range(n):
                solved[i, j] = a[i, j]
                solved[i, n + j] = g[i, j]
                transposed[i, j] = a[j, i]
        # Gaussian elimination with partial pivoting, W destroyed.
        for col in range(n):
            pivot = col
            for row in range(col + 1, n):
                if abs(w[row, col]) > abs(w[pivot, col]):
                    pivot = row
            if pivot != col:
                for j in range(n):
                    w[col, j], w[pivot, j] = w[pivot, j], w[col, j]
                for j in range(2 * n):
                    solved[col, j], solved[pivot, j] = solved[pivot, j], solved[col, j]
            for row in range(col + 1, n):
                factor = w[row, col] / w[col, col]
                for j in range(col + 1, n):
                    w[row, j] -= factor * w[col, j]
                for j in range(2 * n):
                    solved[row, j] -= factor * solved[col, j]
        for col in range(n - 1, -1, -1):
            for j in range(2 * n):
                total = solved[col, j]
                for k in range(col + 1, n):
                    total -= w[col, k] * solved[k, j]
                solved[col, j] = total / w[col, col]
        on_a = np.ascontiguousarray(solved[:, :n])
        on_g = np.ascontiguousarray(solved[:, n:])
        following = h + transposed @ (h @ on_a)
        g = g + (a @ on_g) @ transposed
        a = a @ on_a
        change = 0.0
        largest = 0.0
        for i in range(n):
            for j in range(n):
                change = max(change, abs(following[i, j] - h[i, j]))
                largest = max(largest, abs(following[i, j]))
        h = following
        if change <= tolerance * largest:
            return h, step + 1
    return h, -1


def _modal_innovations(
    poles: NDArray[np.complex128],
    drive: NDArray[np.complex128],
    read: NDArray[np.complex128],
    y: NDArray[np.float64],
    l00: float,
    l10: float,
    l11: float,
    whitened: NDArray[np.float64],
) -> float:
    # Modes z_(k+1) = λ z_k + drive y_k from z_0 = 0; the sensors' prediction Re(read z_k);
    # innovations whitened by L⁻¹ (L L' the innovation covariance). Returns Σ w².
    modes = poles.size
    z = np.zeros(modes, dtype=np.complex128)
    total = 0.0
    for k in range(y.shape[1]):
        first = 0.0
        second = 0.0
        for i in range(modes):
            first += read[0, i].real * z[i].real - read[0, i].imag * z[i].imag
            second += read[1, i].real * z[i].real - read[1, i].imag * z[i].imag
        y0 = y[0, k]
        y1 = y[1, k]
        w0 = (y0 - first) / l00
        w1 = ((y1 - second) - l10 * w0) / l11
        whitened[0, k] = w0
        whitened[1, k] = w1
        total += w0 * w0 + w1 * w1
        for i in range(modes):
            z[i] = poles[i] * z[i] + drive[i, 0] * y0 + drive[i, 1] * y1
    return total


def _discounted(
    values: NDArray[np.float64],
    poles: NDArray[np.complex128],
    reach: NDArray[np.int64],
    out: NDArray[np.complex128],
) -> None:
    # out[:, i] = Σ_(k < reach_i) pole_i^k values[:, k]
    for i in range(poles.size):
        power = 1.0 + 0.0j
        first = 0.0j
        second = 0.0j
        for k in range(reach[i]):
            first += power * values[0, k]
            second += power * values[1, k]
            power *= poles[i]
        out[0, i] = first
        out[1, i] = second


def _exact_steps(
    f: NDArray[np.float64],
    noise: NDArray[np.float64],
    covariance: NDArray[np.float64],
    c: NDArray[np.float64],
    predicted: NDArray[np.float64],
    target: NDArray[np.float64],
    tolerance: float,
    gains: NDArray[np.float64],
    stds: NDArray[np.float64],
    inverses: NDArray[np.float64],
    log_dets: NDArray[np.float64],
    predicted_var: NDArray[np.float64],
) -> int:
    # The time-varying Kalman filter's covariances from ``predicted`` (P_0|-1, overwritten),
    # the readings being the state's last two entries (H = [0 | I]). Per step:
    # S = H P Hᵀ + R, K = P Hᵀ S⁻¹, P_k|k = (I − K H) P (I − K H)ᵀ + K R Kᵀ (Joseph form),
    # P_k+1|k = F P_k|k Fᵀ + Q, symmetrised. Stops after the first step whose gain is within
    # ``tolerance`` of ``target``; returns the steps taken (the outputs' rows filled).
    n = f.shape[0]
    r = n - 2
    update = np.empty((n, n))
    scratch = np.empty((n, n))
    filtered = np.empty((n, n))
    steps = gains.shape[0]
    for step in range(steps + 1):
        variance = 0.0  # c P_k|k-1 c
        for i in range(n):
            row = 0.0
            for j in range(n):
                row += predicted[i, j] * c[j]
            variance += c[i] * row
        predicted_var[step] = variance
        if step == steps:
            break
        s00 = predicted[r, r] + noise[0, 0]
        s01 = predicted[r, r + 1] + noise[0, 1]
        s10 = predicted[r + 1, r] + noise[1, 0]
        s11 = predicted[r + 1, r + 1] + noise[1, 1]
        determinant = s00 * s11 - s01 * s10
        i00, i01 = s11 / determinant, -s01 / determinant
        i10, i11 = -s10 / determinant, s00 / determinant
        inverses[step, 0, 0], inverses[step, 0, 1] = i00, i01
        inverses[step, 1, 0], inverses[step, 1, 1] = i10, i11
        log_dets[step] = math.log(determinant)
        far = 0.0
        for i in range(n):
            k0 = predicted[i, r] * i00 + predicted[i, r + 1] * i10
            k1 = predicted[i, r] * i01 + predicted[i, r + 1] * i11
            gains[step, i, 0], gains[step, i, 1] = k0, k1
            far = max(far, abs(k0 - target[i, 0]), abs(k1 - target[i, 1]))
            for j in range(n):
                update[i, j] = 1.0 if i == j else 0.0
            update[i, r] -= k0
            update[i, r + 1] -= k1
        for i in range(n):  # scratch = (I − K H) P
            for j in range(n):
                total = 0.0
                for m in range(n):
                    total += update[i, m] * predicted[m, j]
                scratch[i, j] = total
        for i in range(n):  # filtered = scratch (I − K H)ᵀ + K R Kᵀ
            left0 = gains[step, i, 0] * noise[0, 0] + gains[step, i, 1] * noise[1, 0]
            left1 = gains[step, i, 0] * noise[0, 1] + gains[step, i, 1] * noise[1, 1]
            for j in range(n):
                total = 0.0
                for m in range(n):
                    total += scratch[i, m] * update[j, m]
                filtered[i, j] = total + (left0 * gains[step, j, 0] + left1 * gains[step, j, 1])
        variance = 0.0  # c P_k|k c
        for i in range(n):
            row = 0.0
            for j in range(n):
                row += filtered[i, j] * c[j]
            variance += c[i] * row
        stds[step] = math.sqrt(max(variance, 0.0))
        for i in range(n):  # scratch = F P_k|k
            for j in range(n):
                total = 0.0
                for m in range(n):
                    total += f[i, m] * filtered[m, j]
                scratch[i, j] = total
        for i in range(n):  # predicted = scratch Fᵀ + Q
            for j in range(n):
                total = 0.0
                for m in range(n):
                    total += scratch[i, m] * f[j, m]
                predicted[i, j] = total + covariance[i, j]
        for i in range(n):
            for j in range(i):
                value = 0.5 * (predicted[i, j] + predicted[j, i])
                predicted[i, j] = value
                predicted[j, i] = value
        if far <= tolerance:
            steps = step + 1  # the next pass records the last predicted variance and stops
    return steps


@functools.cache
def _kernels() -> tuple[Callable[..., Any], ...]:
    """The loops, compiled where numba is installed (once per process, cached on disk)."""
    return compile_loops(_doubling, _modal_innovations, _discounted, _exact_steps)


def riccati_by_doubling(
    transition: NDArray[np.float64],
    observation: NDArray[np.float64],
    covariance: NDArray[np.float64],
    noise: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """The filter's steady prediction covariance P, or None where doubling does not solve it.

    P solves ``P = F P Fᵀ − F P Hᵀ (H P Hᵀ + R)⁻¹ H P Fᵀ + Q``, written (Woodbury) as
    ``P = F P (I + G P)⁻¹ Fᵀ + Q`` with ``G = Hᵀ R⁻¹ H``: scipy's
    ``solve_discrete_are(Fᵀ, Hᵀ, Q, R)``, to within its own rounding. None when the doubling
    does not converge in :data:`DOUBLING_STEPS` or its result leaves a residual above
    :data:`DOUBLING_RESIDUAL`.

    Parameters
    ----------
    transition : ndarray, shape (n, n)
        F.
    observation : ndarray, shape (2, n)
        H.
    covariance : ndarray, shape (n, n)
        Q, process noise per step.
    noise : ndarray, shape (2, 2)
        R, measurement noise.

    Returns
    -------
    ndarray, shape (n, n) or None
        P, symmetric.
    """
    coupling = observation.T @ np.linalg.solve(noise, observation)
    try:
        solution, steps = _kernels()[0](
            np.ascontiguousarray(transition.T, dtype=np.float64),
            np.ascontiguousarray(coupling, dtype=np.float64),
            np.ascontiguousarray(covariance, dtype=np.float64),
            DOUBLING_TOLERANCE,
            DOUBLING_STEPS,
        )
    except ZeroDivisionError:  # a zero pivot: I + G H singular in rounding (it cannot be else)
        return None
    if steps < 0 or not np.all(np.isfinite(solution)):
        return None
    solution = 0.5 * (solution + solution.T)
    n = solution.shape[0]
    try:
        right = np.linalg.solve(np.eye(n) + coupling @ solution, transition.T)
    except np.linalg.LinAlgError:
        return None
    residual = transition @ solution @ right + covariance - solution
    if not np.max(np.abs(residual)) <= DOUBLING_RESIDUAL * np.max(np.abs(solution)):
        return None
    return np.asarray(solution, dtype=np.float64)


def modal_innovations(
    poles: NDArray[Any],
    drive: NDArray[Any],
    read: NDArray[Any],
    y: NDArray[np.float64],
    cholesky: tuple[float, float, float],
) -> tuple[NDArray[np.float64], float]:
    """Whitened innovations of a steady-state filter run mode by mode from a zero state.

    The prediction recursion ``x_(k+1) = A x_k + B y_k`` (A the closed loop, B = F K) in the
    eigenbasis of A: mode i follows ``z_(k+1) = λ_i z_k + drive_i y_k`` and the sensors'
    prediction is ``Re(read z_k)`` (one mode of each conjugate pair, its partner in the
    doubled real part).

    Parameters
    ----------
    poles : ndarray, shape (m,)
        The modes' eigenvalues λ (complex, or real where all are).
    drive : ndarray, shape (m, 2)
        ``(V⁻¹ B)`` for those modes.
    read : ndarray, shape (2, m)
        The sensors' rows of V for those modes, doubled for a conjugate pair.
    y : ndarray, shape (2, N)
        Readings (less their level), degrees C.
    cholesky : (float, float, float)
        L[0, 0], L[1, 0], L[1, 1] of the innovation covariance's Cholesky factor L, °C.

    Returns
    -------
    whitened : ndarray, shape (2, N)
        ``L⁻¹ e_k`` with ``L Lᵀ`` the innovation covariance.
    total : float
        Their sum of squares.
    """
    l00, l10, l11 = cholesky
    whitened = np.empty(y.shape)
    total = _kernels()[1](
        np.ascontiguousarray(poles, dtype=np.complex128),
        np.ascontiguousarray(drive, dtype=np.complex128),
        np.ascontiguousarray(read, dtype=np.complex128),
        np.ascontiguousarray(y, dtype=np.float64),
        l00,
        l10,
        l11,
        whitened,
    )
    return whitened, float(total)


def discounted_sums(values: NDArray[np.float64], poles: NDArray[Any]) -> NDArray[np.complex128]:
    """``Σ_k pole^k values[:, k]`` for each pole, shape (2, P), over the terms that count.

    A term k is below ``|values|·ε`` once ``|pole|^k ≤ ε (1 − |pole|)`` (the tail after it sums
    to less): a closed-loop mode decays long before the end of a long record, and summing only
    its first samples makes the likelihood of a 20 kHz record several times cheaper.

    Parameters
    ----------
    values : ndarray, shape (2, N)
    poles : ndarray, shape (P,)
    """
    count = values.shape[1]
    reach = np.full(poles.size, count, dtype=np.int64)
    for i, radius in enumerate(np.abs(poles).tolist()):
        if radius < 1.0 - 1e-12:
            floor = _EPS * (1.0 - radius)
            terms = math.log(floor) / math.log(radius) if radius > 0.0 else 1.0
            reach[i] = min(count, math.ceil(terms) + 1)
    out = np.empty((2, poles.size), dtype=np.complex128)
    _kernels()[2](
        np.ascontiguousarray(values, dtype=np.float64),
        np.ascontiguousarray(poles, dtype=np.complex128),
        reach,
        out,
    )
    return out


def exact_schedule(
    transition: NDArray[np.float64],
    covariance: NDArray[np.float64],
    noise: NDArray[np.float64],
    output: NDArray[np.float64],
    prior: NDArray[np.float64],
    target: NDArray[np.float64],
    tolerance: float,
    max_steps: int,
) -> tuple[NDArray[np.float64], ...]:
    """The time-varying Kalman filter's gains and covariances from a prior, step by step.

    The readings are the state's last two entries. Runs until a step's gain is within
    ``tolerance`` of ``target`` (that step included) or for ``max_steps`` steps.

    Parameters
    ----------
    transition : ndarray, shape (n, n)
        F.
    covariance : ndarray, shape (n, n)
        Q, process noise per step.
    noise : ndarray, shape (2, 2)
        R, measurement noise, °C².
    output : ndarray, shape (n,)
        c, the row that reads the gas out of the state.
    prior : ndarray, shape (n, n)
        The first prediction's covariance.
    target : ndarray, shape (n, 2)
        The steady-state gain.
    tolerance : float
        Largest entry-wise distance from ``target`` at which to stop.
    max_steps : int
        Most steps.

    Returns
    -------
    gains : ndarray, shape (L, n, 2)
        Kalman gain of each step.
    std : ndarray, shape (L,)
        c P_k|k c, square-rooted, °C.
    inverse : ndarray, shape (L, 2, 2)
        Inverse innovation covariance of each step.
    log_det : ndarray, shape (L,)
        Log-determinant of each step's innovation covariance.
    predicted_var : ndarray, shape (L + 1,)
        c P_k|k-1 c before each step and after the last, °C².
    """
    n = transition.shape[0]
    gains = np.empty((max_steps, n, 2))
    std = np.empty(max_steps)
    inverse = np.empty((max_steps, 2, 2))
    log_det = np.empty(max_steps)
    predicted_var = np.empty(max_steps + 1)
    steps = _kernels()[3](
        np.ascontiguousarray(transition, dtype=np.float64),
        np.ascontiguousarray(noise, dtype=np.float64),
        np.ascontiguousarray(covariance, dtype=np.float64),
        np.ascontiguousarray(output, dtype=np.float64),
        np.array(prior, dtype=np.float64, order="C"),
        np.ascontiguousarray(target, dtype=np.float64),
        float(tolerance),
        gains,
        std,
        inverse,
        log_det,
        predicted_var,
    )
    return (
        gains[:steps],
        std[:steps],
        inverse[:steps],
        log_det[:steps],
        predicted_var[: steps + 1],
    )
