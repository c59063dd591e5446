"""A lean Levenberg–Marquardt search for a few parameters from a start close to the minimum.

:func:`scipy.optimize.least_squares` (trust region reflective) costs about 8 ms of its own per
search of ml-eiv's three parameters on a 2 s window at 5 kHz, more than the 16 evaluations of
the residual it makes (0.4 ms each): an SVD of the M × 3 Jacobian per iteration, scaling,
bookkeeping. From a warm start (the previous window's τ, or the same window's with another
φ) the search needs none of its machinery for bounds: :func:`levenberg_marquardt` solves the
3 × 3 normal equations JᵀJ δ = -Jᵀr (Marquardt's damping when a step fails), with the same
forward-difference Jacobian as ``least_squares(jac="2-point")`` and the same stopping rules
(``ftol``, ``xtol``, ``gtol``), so it stops at the same minimum within those tolerances; it
also stops, without the trial, where the step's predicted lowering of the cost is a thousandth
of ``ftol`` (:data:`PREDICTED_SHARE`), or, when asked (``stop_se``), where the step is shorter
than a given share of the parameters' standard errors.

It returns None, and the caller falls back to ``least_squares``, when it does not converge
within its budget or when its end lies within ``edge`` of a bound: a minimum on the edge is
for the trust region reflective search to find and to report.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["PREDICTED_SHARE", "SearchResult", "levenberg_marquardt", "normal_matrix", "off_edges"]

#: √eps, the relative step of the forward differences (``least_squares``' "2-point").
_ROOT_EPS = float(np.sqrt(np.finfo(np.float64).eps))
#: A search ends before its trial once the Gauss–Newton model lowers the cost by less than
#: this share of ``ftol`` (see :func:`levenberg_marquardt`): the last search step of ml-eiv's
#: windows at 5 kHz, with its Jacobian, a quarter of the evaluations.
PREDICTED_SHARE = 1e-3
#: Damping of the first failed step, relative to the diagonal of JᵀJ, and its growth.
_DAMPING_START = 1e-3
_DAMPING_GROWTH = 10.0
#: Damping beyond which the search gives up (every step so short it no longer moves x).
_DAMPING_LIMIT = 1e12


@dataclass(frozen=True)
class SearchResult:
    """The end of a least-squares search (the fields of ``least_squares``' result used here).

    Attributes
    ----------
    x : ndarray, shape (n,)
        The parameters at the end.
    cost : float
        ½‖r‖² there.
    jac : ndarray, shape (m, n)
        The Jacobian there.
    nfev : int
        Evaluations of the residual, not counting the Jacobian's.
    success : bool
    message : str
    """

    x: NDArray[np.float64]
    cost: float
    jac: NDArray[np.float64]
    nfev: int
    success: bool
    message: str


def forward_jacobian(
    fun: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x: NDArray[np.float64],
    f0: NDArray[np.float64],
    high: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Forward-difference Jacobian, shape (m, n), with ``least_squares``' "2-point" steps.

    h_j = √eps · sign(x_j) · max(1, |x_j|) (sign 0 = +1), taken backwards where x + h would
    pass the upper bound; the step actually taken, (x_j + h_j) - x_j, divides. Stored by
    columns (Fortran order): each column is one contiguous vector for the norms and products
    its users take of it.
    """
    columns = np.empty((x.size, f0.size))
    for j in range(x.size):
        value = float(x[j])
        step = _ROOT_EPS * (1.0 if value >= 0.0 else -1.0) * max(1.0, abs(value))
        if value + step > high[j]:
            step = -step
        moved = x.copy()
        moved[j] += step
        np.subtract(fun(moved), f0, out=columns[j])
        columns[j] /= moved[j] - value
    return columns.T


def normal_matrix(jacobian: NDArray[np.float64]) -> NDArray[np.float64]:
    """JᵀJ, shape (n, n), of a Jacobian of shape (m, n) with few columns and many rows.

    One dot product per pair of columns: for three columns of 10 000 rows stored by columns
    (:func:`forward_jacobian`) a third of the time of ``jacobian.T @ jacobian``, whose
    general matrix product spends more on set-up than on the 60 000 products.
    """
    columns = jacobian.T
    count = columns.shape[0]
    normal = np.empty((count, count))
    for i in range(count):
        for j in range(i, count):
            normal[i, j] = normal[j, i] = float(columns[i] @ columns[j])
    return normal


def levenberg_marquardt(
    fun: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x0: NDArray[np.float64],
    bounds: tuple[NDArray[np.float64], NDArray[np.float64]],
    *,
    ftol: float,
    xtol: float,
    gtol: float = 1e-8,
    max_nfev: int = 100,
    edge: float = 1e-6,
    stop_se: float = 0.0,
) -> SearchResult | None:
    """Minimise ½‖fun(x)‖² from ``x0`` inside ``bounds``, or None (see the module docstring).

    Parameters
    ----------
    fun : callable
        Residual, x of shape (n,) to shape (m,).
    x0 : ndarray, shape (n,)
        Start, strictly inside the bounds.
    bounds : (ndarray, ndarray)
        Lower and upper bounds, each of shape (n,).
    ftol, xtol, gtol : float
        Stop when an accepted step lowers the cost by less than ``ftol`` times it, moves x by
        less than ``xtol (xtol + ‖x‖)``, or when ‖Jᵀr‖∞ < ``gtol`` (as ``least_squares``).
    max_nfev : int
        Evaluations of ``fun`` allowed, the Jacobian's included.
    edge : float
        An end closer than this to a bound is left to ``least_squares`` (None).
    stop_se : float
        Stop before the trial once the Gauss–Newton step is shorter than this many standard
        errors of x (0: never). The length is the step's Mahalanobis length in the metric of
        JᵀJ / σ̂², σ̂² = 2 cost / m the residual's variance per row: with the step's predicted
        lowering of the cost p = ½ δᵀJᵀJδ, its square is p m / cost. For a residual of noise
        the estimate itself scatters by one standard error, so a remaining step of 1e-3 of
        one is none.

    Returns
    -------
    SearchResult or None
        ``jac`` by forward differences at ``x``; None when the search did not converge
        inside the bounds.
    """
    low, high = bounds
    x = np.asarray(x0, dtype=np.float64).copy()
    residual = fun(x)
    cost = 0.5 * float(residual @ residual)
    nfev = used = 1  # evaluations of the residual alone, and with the Jacobian's
    damping = 0.0
    jacobian = None
    while used < max_nfev:
        if jacobian is None:
            jacobian = forward_jacobian(fun, x, residual, high)
            used += x.size
            gradient = jacobian.T @ residual
            normal = normal_matrix(jacobian)
            if float(np.max(np.abs(gradient))) < gtol:
                return _result(x, cost, jacobian, nfev, "gtol")
        scale = np.diag(np.diag(normal))
        try:
            step = np.linalg.solve(normal + damping * scale, -gradient)
        except np.linalg.LinAlgError:
            return None
        if damping == 0.0 and used > x.size + 1:  # after a first step, as least_squares
            # The Gauss–Newton model's lowering of the cost by the step (on ml-eiv's windows at
            # 5 kHz the trials' own lowerings matched it to two digits down to 1e-11 of the
            # cost). Below PREDICTED_SHARE of ftol the trial would end the search on ftol, and
            # its step is, in standard errors of x, at most √(PREDICTED_SHARE ftol M) for a
            # residual of M rows of noise (½ δᵀJᵀJδ = ½ σ² ‖δ/se‖², cost ≈ M σ²/2): 3e-6 on
            # 10 000 rows. It is not taken, nor its Jacobian made.
            predicted = -float(gradient @ step) - 0.5 * float(step @ normal @ step)
            if predicted < PREDICTED_SHARE * ftol * cost and off_edges(x, low, high, edge):
                return _result(x, cost, jacobian, nfev, "ftol, predicted")
            if predicted * residual.size < stop_se**2 * cost and off_edges(x, low, high, edge):
                return _result(x, cost, jacobian, nfev, "step within stop_se")
        trial = np.clip(x + step, low, high)
        moved = trial - x
        trial_residual = fun(trial)
        nfev += 1
        used += 1
        trial_cost = 0.5 * float(trial_residual @ trial_residual)
        # As least_squares: a step shorter than xtol ends the search whether or not it lowered
        # the cost (near the minimum, rounding decides); a lowering below ftol ends it too.
        small_step = float(np.linalg.norm(moved)) < xtol * (xtol + float(np.linalg.norm(x)))
        accepted = trial_cost < cost
        if accepted:
            small_gain = cost - trial_cost < ftol * cost
            x, residual, cost = trial, trial_residual, trial_cost
            damping = damping / _DAMPING_GROWTH if damping > _DAMPING_START else 0.0
            jacobian = None
        else:
            small_gain = False
            damping = _DAMPING_START if damping == 0.0 else damping * _DAMPING_GROWTH
        if small_step or small_gain:
            if not off_edges(x, low, high, edge):
                return None
            if jacobian is None:
                jacobian = forward_jacobian(fun, x, residual, high)
            return _result(x, cost, jacobian, nfev, "xtol" if small_step else "ftol")
        if damping > _DAMPING_LIMIT:
            return None
    return None


def off_edges(
    x: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64], edge: float
) -> bool:
    """Whether x lies at least ``edge`` inside every bound."""
    return bool(np.all(np.minimum(x - low, high - x) >= edge))


def _result(
    x: NDArray[np.float64], cost: float, jacobian: NDArray[np.float64], nfev: int, reason: str
) -> SearchResult:
    return SearchResult(x, cost, jacobian, nfev, True, f"converged ({reason})")
