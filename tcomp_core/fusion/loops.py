"""The inner loops of the Kalman likelihood, compiled.

A signal model's maximum-likelihood fit (:mod:`tcomp_core.fusion.fitting`) evaluates the
innovation likelihood a few hundred times on a few thousand samples. As numpy and scipy calls an
evaluation took about 2 ms, most of it per-call overhead: scipy's Riccati solver validates,
balances and orders a QZ decomposition of a pencil twice the state's size, and the filter ran
one ``lfilter`` per mode and another per eigenvalue. Here those three are loops compiled by
:func:`tcomp_core.compiled.compile_loops`:

* the steady-state Riccati equation by the structure-preserving doubling algorithm;
* the steady-state filter's whitened innovations, mode by mode in the closed loop's eigenbasis;
* the discounted sums ``Σ_k λ̄^k w_k`` of the initial state's normal equations.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..compiled import compile_loops

__all__ = ["DOUBLING_STEPS", "discounted_sums", "modal_innovations", "riccati_by_doubling"]

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


@functools.cache
def _kernels() -> tuple[Callable[..., Any], ...]:
    """The three loops, compiled where numba is installed (once per process, cached on disk)."""
    return compile_loops(_doubling, _modal_innovations, _discounted)


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
