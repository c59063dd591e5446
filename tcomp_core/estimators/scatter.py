"""Regression rows, their scatter matrices and the LS / TLS / GTLS solutions from a scatter.

Every difference-equation estimator solves a linear errors-in-variables problem
``X θ ≈ Y``. All it needs from the data is the scatter matrix ``S = Zᵀ Z`` of the augmented rows
``Z = [X Y]`` (3×3 for β, 4×4 for γ): least squares, total least squares and generalized TLS are
all functions of ``S``. Accumulating ``S`` in chunks takes O(N) time and O(1) memory, where the
SVD of the N×3 matrix the paper used (Eq. 20) takes O(N) memory.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

__all__ = [
    "CHUNK_ROWS",
    "accumulate_r_factor",
    "accumulate_scatter",
    "beta_rows",
    "beta_scatter",
    "equilibrated_condition",
    "equilibrated_condition_r",
    "gamma_r_factor",
    "gamma_rows",
    "solve_gtls",
    "solve_gtls_r",
    "solve_ls",
    "solve_ls_r",
]

#: Rows formed at a time when accumulating a scatter matrix: bounds the working memory.
CHUNK_ROWS = 1 << 16


def beta_rows(tc1: NDArray[np.float64], tc2: NDArray[np.float64]) -> NDArray[np.float64]:
    """Augmented rows ``[x1, x2, y]`` of the β model Y = Xθ (Eqs. 13–15).

    ``x1 = T_m1(k) - T_m1(k-1)``, ``x2 = T_m1(k-1) - T_m2(k-1)``, ``y = T_m2(k) - T_m2(k-1)``
    for k = 1..N-1.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)

    Returns
    -------
    ndarray, shape (N-1, 3)
    """
    rows = np.empty((tc1.size - 1, 3))
    np.subtract(tc1[1:], tc1[:-1], out=rows[:, 0])
    np.subtract(tc1[:-1], tc2[:-1], out=rows[:, 1])
    np.subtract(tc2[1:], tc2[:-1], out=rows[:, 2])
    return rows


def gamma_rows(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], offset: float = 0.0
) -> NDArray[np.float64]:
    """Augmented rows ``[T_m2(k-1), T_m1(k), T_m1(k-1), T_m2(k)]`` of the γ model (Eq. 11).

    ``offset`` is subtracted from every temperature first (0 by default, as in the paper).
    Because γ1 + γ2 + γ3 = 1 a common offset leaves the noise-free Eq. (11) unchanged, but it
    changes the regression: the mean level is itself excitation along the unity-gain direction,
    and without it a single sinusoid spans only two of the three regressor dimensions. The γ
    estimators therefore use the raw temperatures, in the units given.

    Returns
    -------
    ndarray, shape (N-1, 4)
    """
    rows = np.empty((tc1.size - 1, 4))
    np.subtract(tc2[:-1], offset, out=rows[:, 0])
    np.subtract(tc1[1:], offset, out=rows[:, 1])
    np.subtract(tc1[:-1], offset, out=rows[:, 2])
    np.subtract(tc2[1:], offset, out=rows[:, 3])
    return rows


def accumulate_scatter(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    rows_of,
    width: int,
    chunk_rows: int = CHUNK_ROWS,
) -> NDArray[np.float64]:
    """Sum ``rowsᵀ rows`` over the record, forming at most ``chunk_rows`` rows at a time.

    Parameters
    ----------
    tc1, tc2 : ndarray, shape (N,)
    rows_of : callable
        Maps two sample slices of length L+1 to their L augmented rows.
    width : int
        Number of columns of a row.
    chunk_rows : int
        Rows per chunk; consecutive chunks overlap by one sample so no row is lost.

    Returns
    -------
    ndarray, shape (width, width)
    """
    scatter = np.zeros((width, width))
    for first, second in _overlapping_chunks(tc1, tc2, chunk_rows):
        rows = rows_of(first, second)
        scatter += rows.T @ rows
    return scatter


def _overlapping_chunks(tc1, tc2, chunk_rows: int):
    """Slices of ``chunk_rows + 1`` samples, each starting at the previous one's last sample."""
    for start in range(0, tc1.size - 1, chunk_rows):
        stop = min(start + chunk_rows + 1, tc1.size)
        yield tc1[start:stop], tc2[start:stop]


def accumulate_r_factor(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    rows_of,
    width: int,
    chunk_rows: int = CHUNK_ROWS,
) -> NDArray[np.float64]:
    """Triangular factor R of the augmented rows (``rowsᵀ rows = Rᵀ R``), one chunk at a time.

    Each chunk is stacked under the current R and re-factorised (a tall-skinny QR), so memory
    stays O(chunk) while R keeps the conditioning of the data matrix itself; the scatter matrix
    squares it. The γ regressors carry the raw temperature levels and can be ill-conditioned
    enough for that to cost digits.

    Returns
    -------
    ndarray, shape (width, width)
        Upper triangular.
    """
    factor = np.zeros((0, width))
    for first, second in _overlapping_chunks(tc1, tc2, chunk_rows):
        # numpy 2.4 types every qr() as a QRResult; mode="r" returns the R factor alone.
        stacked = np.vstack((factor, rows_of(first, second)))
        factor = np.linalg.qr(stacked, mode="r")  # type: ignore[assignment]
    if factor.shape[0] < width:
        factor = np.vstack((factor, np.zeros((width - factor.shape[0], width))))
    return factor


def beta_scatter(
    tc1: NDArray[np.float64], tc2: NDArray[np.float64], chunk_rows: int = CHUNK_ROWS
) -> NDArray[np.float64]:
    """3×3 scatter matrix ``[X Y]ᵀ [X Y]`` of the β model, accumulated in chunks."""
    return accumulate_scatter(tc1, tc2, beta_rows, 3, chunk_rows)


def gamma_r_factor(
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    offset: float = 0.0,
    chunk_rows: int = CHUNK_ROWS,
) -> NDArray[np.float64]:
    """4×4 triangular factor of the γ model rows (see :func:`gamma_rows`), chunk by chunk."""
    return accumulate_r_factor(
        tc1, tc2, lambda first, second: gamma_rows(first, second, offset), 4, chunk_rows
    )


def equilibrated_condition_r(regressor_factor: NDArray[np.float64]) -> float:
    """Like :func:`equilibrated_condition`, from the triangular factor of the regressors."""
    norms = np.linalg.norm(regressor_factor, axis=0)
    if np.any(norms <= 0.0):
        return np.inf
    singular = np.linalg.svd(regressor_factor / norms, compute_uv=False)
    return float(singular[0] / singular[-1]) if singular[-1] > 0.0 else np.inf


def equilibrated_condition(regressor_scatter: NDArray[np.float64]) -> float:
    """2-norm condition number of a regressor matrix X from its scatter ``XᵀX``.

    Columns are first scaled to unit norm, so the figure measures collinearity, not units:
    ``cond(X D) = sqrt(cond(D XᵀX D))`` with ``D = diag(XᵀX)^(-1/2)``.
    """
    if regressor_scatter.shape == (2, 2):
        # Equilibrated, it is [[1, r], [r, 1]] with eigenvalues 1 ± |r|.
        (s11, s12), (_, s22) = regressor_scatter.tolist()
        if not (s11 > 0.0 and s22 > 0.0):
            return np.inf
        r = min(abs(s12) / math.sqrt(s11 * s22), 1.0)
        return math.sqrt((1.0 + r) / (1.0 - r)) if r < 1.0 else np.inf
    diagonal = np.diag(regressor_scatter)
    if np.any(diagonal <= 0.0):
        return np.inf
    scale = 1.0 / np.sqrt(diagonal)
    eigenvalues = np.linalg.eigvalsh(regressor_scatter * np.outer(scale, scale))
    if eigenvalues[0] <= 0.0:
        return np.inf
    return float(np.sqrt(eigenvalues[-1] / eigenvalues[0]))


def solve_ls(scatter: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares θ of ``X θ ≈ Y`` from the augmented scatter (last column is Y).

    ``θ = (XᵀX)⁻¹ XᵀY`` (Eq. 16), solved by Cholesky.
    """
    return scipy.linalg.solve(scatter[:-1, :-1], scatter[:-1, -1], assume_a="pos")


def solve_ls_r(factor: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares θ from the triangular factor R of ``[X Y]``: ``R_xx θ = r_xy``."""
    return scipy.linalg.solve_triangular(factor[:-1, :-1], factor[:-1, -1])


def solve_gtls_r(
    factor: NDArray[np.float64], covariance: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """GTLS θ from the triangular factor R of ``[X Y]`` (TLS when ``covariance`` is omitted).

    The GSVD route of Eqs. (18–21) applied to R instead of the N-row matrix: with
    ``C = Wᵀ W`` (Cholesky), the right singular vector v of ``R W⁻¹`` with the smallest singular
    value gives ``g = W⁻¹ v`` and ``θ = -g[:-1] / g[-1]`` (Eq. 21).

    Returns
    -------
    theta : ndarray, shape (p,)
    eigenvalues : ndarray, shape (p+1,)
        Squared singular values in ascending order (generalized eigenvalues of ``(RᵀR, C)``).
    """
    width = factor.shape[0]
    if covariance is None:
        weight = np.eye(width)
    else:
        weight = scipy.linalg.cholesky(covariance, lower=False)
    weighted = scipy.linalg.solve_triangular(weight, factor.T, trans="T").T  # R W⁻¹
    _, singular, right = np.linalg.svd(weighted)
    direction = scipy.linalg.solve_triangular(weight, right[-1])
    return -direction[:-1] / direction[-1], singular[::-1] ** 2


def solve_gtls(
    scatter: NDArray[np.float64], covariance: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Generalized total least-squares θ of ``X θ ≈ Y`` from the augmented scatter.

    Minimises ``vᵀ S v / vᵀ C v`` over ``v = [θ; -1]``: the generalized eigenvector of
    ``(S, C)`` with the smallest eigenvalue λ (equivalent to the GSVD solution of Eqs. 18–21).
    With ``C = I`` this is ordinary TLS. θ is computed from the first block row of
    ``(S - λ C) v = 0``, i.e. ``(S_xx - λ C_xx) θ = s_xy - λ c_xy``, which is better conditioned
    than normalising the eigenvector when λ is tiny.

    Parameters
    ----------
    scatter : ndarray, shape (p+1, p+1)
        Augmented scatter ``[X Y]ᵀ [X Y]``.
    covariance : ndarray, shape (p+1, p+1), optional
        Row noise covariance up to a scalar (C0); identity when omitted.

    Returns
    -------
    theta : ndarray, shape (p,)
    eigenvalues : ndarray, shape (p+1,)
        Generalized eigenvalues in ascending order (the smallest is the residual noise estimate).
    """
    width = scatter.shape[0]
    covariance = np.eye(width) if covariance is None else covariance
    if not (np.isfinite(scatter).all() and np.isfinite(covariance).all()):
        raise ValueError("the scatter or noise covariance matrix holds non-finite values")
    # Checked above: scipy's own checks cost more than these small problems (the online
    # engine solves one per update).
    eigenvalues = scipy.linalg.eigh(scatter, covariance, eigvals_only=True, check_finite=False)
    smallest = eigenvalues[0]
    lhs = scatter[:-1, :-1] - smallest * covariance[:-1, :-1]
    rhs = scatter[:-1, -1] - smallest * covariance[:-1, -1]
    return np.linalg.solve(lhs, rhs), eigenvalues
