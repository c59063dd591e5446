"""ml-eiv's projected residual in one compiled pass over the window.

Every evaluation of the ml-eiv criterion (:meth:`~.mleiv._CrossRelation.projected`) forms the
cross-relation residual e, whitens it and the constant by the tridiagonal Toeplitz covariance
(:class:`~.toeplitz.ToeplitzWhitening`) and projects the constant out. As numpy calls that is a
dozen passes over M samples and their temporaries (the powers s^n − 1, the minors, the
recursive filter, two dot products); a search takes a few dozen evaluations per window and
the node re-estimates every window. Here the same sums run as one loop compiled by
:func:`tcomp_core.compiled.compile_loops`, with the powers made as
:func:`~.toeplitz.powers_minus_one` makes them (``expm1`` while |n log s| is small, products of
two powers beyond). The results equal the numpy path's within rounding (the sums are taken in
another order).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..compiled import REWRITE_FLAGS, compile_loops
from .toeplitz import _POWER_BLOCK, ToeplitzWhitening, direct_powers

__all__ = ["projected_residual"]


def _projected(
    data: NDArray[np.float64],
    c1: float,
    c2: float,
    c3: float,
    r1: float,
    ratio: float,
    log_s: float,
    direct: int,
    block: int,
    out: NDArray[np.float64],
) -> float:
    # e_k = data[0, k] + c1 data[1, k] + c2 data[2, k] + c3 data[3, k]; with p_n = s^n − 1 and
    # D̃_j = p_(j+1) (p_(j+1) + 2) / (s² − 1): w_k = D̃_(k−1) e_k − ratio w_(k−1),
    # L⁻¹e = w_k / √(r1 D̃_k D̃_(k−1)), L⁻¹1 = p_(k+1) p_(k+2) / ((s − 1)(s² − 1)) / the same
    # norm. Writes L⁻¹e − b L⁻¹1 into out[:M] with b the least-squares offset; returns b.
    m = data.shape[1]
    square = math.expm1(2.0 * log_s)
    scale = math.expm1(log_s) * square
    root_r1 = 1.0 / math.sqrt(r1)  # out of the loop's square root
    inner = np.empty(block)
    for i in range(block):
        inner[i] = math.exp(i * log_s)
    constant = np.empty(m)
    outer = 0.0
    previous = 0.0  # p_(k+1)
    minor_previous = 0.0  # D̃_(k−1)
    w = 0.0
    cross = 0.0
    norm = 0.0
    for n in range(1, m + 2):  # p_n for n = 1 .. M + 1, one sample per step from n = 2
        if n <= direct:
            power = math.expm1(n * log_s)
        else:
            beyond = n - direct - 1
            if beyond % block == 0:
                outer = math.exp((direct + 1 + beyond) * log_s)
            power = outer * inner[beyond % block] - 1.0
        minor = power * (power + 2.0) / square
        if n >= 2:
            k = n - 2
            inverse = root_r1 / math.sqrt(minor * minor_previous)
            e = data[0, k] + c1 * data[1, k] + c2 * data[2, k] + c3 * data[3, k]
            w = minor_previous * e - ratio * w
            whitened = w * inverse
            one = previous * power * (inverse / scale)
            out[k] = whitened
            constant[k] = one
            cross += one * whitened
            norm += one * one
        previous = power
        minor_previous = minor
    offset = cross / norm
    for k in range(m):
        out[k] -= constant[k] * offset
    return offset


@functools.cache
def _kernel() -> Callable[..., Any]:
    """The loop, compiled where numba is installed (once per process, cached on disk)."""
    # With r1 out of the square root, rewrites of its divisions and products: a quarter off
    # each evaluation (82 to 62 µs on a 2 s window at 5 kHz), every sample within 6e-16 of
    # the strict loop's.
    return compile_loops(_projected, fastmath=REWRITE_FLAGS)[0]


def projected_residual(
    data: NDArray[np.float64],
    coefficients: tuple[float, float, float],
    whitening: ToeplitzWhitening,
    out: NDArray[np.float64],
) -> float:
    """L⁻¹(e − b) at the least-squares offset b, written into ``out[:M]``; returns b.

    Parameters
    ----------
    data : ndarray, shape (4, M)
        The residual's terms: e = data[0] + Σ_i coefficients[i] data[i + 1], degrees C.
    coefficients : (float, float, float)
        Their weights.
    whitening : ToeplitzWhitening
        L⁻¹ of the residual's covariance Σ = LLᵀ (size M).
    out : ndarray, shape (M,) or more
        Where the projected residual goes (its first M entries).

    Returns
    -------
    float
        b, degrees C (in the residual's units).
    """
    log_s = whitening.log_s
    direct = direct_powers(log_s, whitening.size + 2)
    c1, c2, c3 = coefficients
    return float(
        _kernel()(
            data,
            float(c1),
            float(c2),
            float(c3),
            whitening.r1,
            whitening.ratio,
            log_s,
            direct,
            _POWER_BLOCK,
            out,
        )
    )
