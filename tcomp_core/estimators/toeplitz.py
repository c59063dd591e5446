"""Whitening by a tridiagonal Toeplitz covariance: L⁻¹ values with Σ = LLᵀ, in O(M).

Σ (M × M) has diagonal d and off-diagonal o < 0. Its leading minors are
D_k = (r1^(k+2) - r2^(k+2)) / (r1 - r2), r1 ≥ r2 the roots of r² - d r + o², so with
s = -o / r1 (s² = q = r2 / r1) the pivots of Σ = L̃ diag(p) L̃ᵀ (L̃ unit lower bidiagonal) are
p_k = r1 D̃_k / D̃_(k-1), D̃_k = D_k / r1^(k+1) = (1 - s^(2k+4)) / (1 - s²). With
w_k = D̃_(k-1) z_k (z = L̃⁻¹e), the recursion z_k = e_k - (o / p_(k-1)) z_(k-1) becomes the
constant-coefficient, stable

    w_k = D̃_(k-1) e_k + s w_(k-1),    (L⁻¹e)_k = w_k / √(r1 D̃_k D̃_(k-1)),

one first-order recursive filter (:func:`scipy.signal.lfilter`) instead of a banded Cholesky
factorisation. For e = 1 the recursion sums in closed form,
w_k = (1 - s^(k+1)) (1 - s^(k+2)) / ((1 - s)(1 - s²)), so

    (L⁻¹1)_k = (1 - s^(k+1)) (1 - s^(k+2)) / ((1 - s)(1 - s²) √(r1 D̃_k D̃_(k-1))),

which costs no filter. Every power enters as s^n - 1 (:func:`powers_minus_one`): one array of
M + 2 values serves the minors (1 - s^(2n) = -(s^n - 1)(s^n + 1)) and the constant.
"""

from __future__ import annotations

import functools
import math
import sys
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from ..errors import EstimationError

__all__ = ["ToeplitzWhitening", "direct_powers", "powers_minus_one"]

#: s^n - 1 is computed directly (``expm1``) below this |n log s|, where the difference would
#: lose digits, and from the product of two powers above it.
_DIRECT_EXPONENT = 0.7
#: Powers s^n beyond the direct ones are built as s^(B j) s^i: B = this many columns.
_POWER_BLOCK = 64


#: log of the smallest positive normal float: s² for a diagonal Σ (s = 0 in the limit).
_LOG_SMALLEST = math.log(sys.float_info.min)


def direct_powers(log_s: float, count: int) -> int:
    """How many of s^n - 1 (n = 1 .. count) :func:`powers_minus_one` takes by ``expm1``."""
    return count if log_s >= 0.0 else min(count, math.ceil(_DIRECT_EXPONENT / -log_s))


def powers_minus_one(log_s: float, count: int) -> NDArray[np.float64]:
    """s^n - 1 for n = 1 .. count, shape (count,), s = exp(log_s) ≤ 1.

    ``expm1`` while |n log s| < :data:`_DIRECT_EXPONENT` (s^n - 1 would cancel there); beyond,
    s^n as the outer product s^(B j) s^i (two roundings) minus one, which cannot cancel
    since s^n < 1/2: the cost of a multiplication per power instead of a transcendental.
    Equal to ``np.expm1(np.arange(1, count + 1) * log_s)`` within a few units in the last
    place.
    """
    exponents = np.arange(1.0, count + 1.0)
    direct = direct_powers(log_s, count)
    if direct >= count:
        return np.expm1(exponents * log_s)
    result = np.empty(count)
    result[:direct] = np.expm1(exponents[:direct] * log_s)
    rest = count - direct
    rows = -(-rest // _POWER_BLOCK)
    inner = np.exp(np.arange(_POWER_BLOCK) * log_s)
    outer = np.exp((direct + 1 + _POWER_BLOCK * np.arange(rows)) * log_s)
    result[direct:] = np.outer(outer, inner).ravel()[:rest]
    result[direct:] -= 1.0
    return result


@dataclass(frozen=True)
class ToeplitzWhitening:
    """L⁻¹ for Σ = LLᵀ tridiagonal Toeplitz of size M (see the module docstring).

    Attributes
    ----------
    r1 : float
        The larger root of r² - d r + o² (> 0), in Σ's units.
    ratio : float
        o / r1 = -s, the recursion's coefficient (``lfilter``'s denominator [1, o/r1]).
    log_s : float
        log s = log(-o / r1) < 0.
    size : int
        M.
    """

    r1: float
    ratio: float
    log_s: float
    size: int

    @classmethod
    def from_bands(
        cls, diagonal: float, off_diagonal: float, root: float, size: int
    ) -> ToeplitzWhitening:
        """From d, o (< 0), root = √(d² - 4o²) (given so that callers avoid cancellation), M.

        Raises
        ------
        EstimationError
            If Σ is singular (r1 not a positive finite number).
        """
        r1 = 0.5 * (diagonal + root)
        if not (math.isfinite(r1) and r1 > 0.0):
            raise EstimationError(f"ml-eiv: the noise covariance is singular (d = {diagonal})")
        # s² = q = r2/r1 = 1 - root/r1. A diagonal Σ (o = 0: a search's trial whose poles
        # underflow) has q = 0, or a rounding below it: s is then the smallest positive q's
        # root, which every power of it takes to 0 as the limit does.
        share = root / r1
        log_q = math.log1p(-share) if share < 1.0 else _LOG_SMALLEST
        return cls(r1, off_diagonal / r1, 0.5 * log_q, size)

    @functools.cached_property
    def _powers(self) -> NDArray[np.float64]:
        """s^n - 1 for n = 1 .. M + 2, shape (M + 2,)."""
        return powers_minus_one(self.log_s, self.size + 2)

    @functools.cached_property
    def _minors(self) -> NDArray[np.float64]:
        """D̃_k = (1 - s^(2k+4)) / (1 - s²) for k = -1 .. M-1, shape (M + 1,)."""
        powers = self._powers[: self.size + 1]
        return powers * (powers + 2.0) / math.expm1(2.0 * self.log_s)

    @functools.cached_property
    def _inverse_norm(self) -> NDArray[np.float64]:
        """1 / √(r1 D̃_k D̃_(k-1)), k = 0 .. M-1, shape (M,)."""
        minors = self._minors
        return np.asarray(1.0 / np.sqrt(self.r1 * minors[1:] * minors[:-1]))

    def apply(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """L⁻¹ values, shape (M,) or (k, M) as ``values``."""
        recursion = lfilter([1.0], [1.0, self.ratio], self._minors[:-1] * values, axis=-1)
        return np.asarray(recursion * self._inverse_norm)

    def constant(self) -> NDArray[np.float64]:
        """L⁻¹1, shape (M,), in closed form (no filter).

        The recursion's (1 - s^(k+1)) (1 - s^(k+2)) / ((1 - s)(1 - s²)), normalised as
        :meth:`apply`.
        """
        powers = self._powers
        scale = math.expm1(self.log_s) * math.expm1(2.0 * self.log_s)
        recursion = powers[: self.size] * powers[1 : self.size + 1]
        return np.asarray(recursion * (self._inverse_norm / scale))
