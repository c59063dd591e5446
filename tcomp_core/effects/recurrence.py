"""The first-order lag's forward recurrence where it is not a fixed linear filter.

A radiating sensor (a loss ∝ T⁴ taken at the state) and a sensor whose τ follows its film
temperature are nonlinear recurrences, and one whose τ follows the flow is linear with a pole
per sample: neither is an ``lfilter``. Every free-run simulation of such a sensor in a fit runs
one sample at a time, so the loops are compiled by numba on their first use
(:func:`tcomp_core.compiled.compile_loops`); without numba the same functions run as Python.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..compiled import compile_loops
from .base import KELVIN

__all__ = ["lag_steps", "level_lag_steps"]


def _lag_steps(
    drive: NDArray[np.float64],
    a: NDArray[np.float64],
    start: float,
    r: float,
    wall4: float,
    out: NDArray[np.float64],
) -> None:
    # y[k+1] = a_k y[k] + (1 - a_k)(u[k] - r ((y[k] + K)^4 - T_w^4)), y[0] = start.
    y = start
    out[0] = y
    for k in range(drive.size):
        pole = a[k]
        loss = 0.0
        if r != 0.0:
            kelvin = y + KELVIN
            square = kelvin * kelvin
            loss = r * (square * square - wall4)
        y = pole * y + (1.0 - pole) * (drive[k] - loss)
        out[k + 1] = y


def _level_lag_steps(
    drive: NDArray[np.float64],
    a: NDArray[np.float64],
    start: float,
    r: float,
    wall4: float,
    exponent: float,
    reference: float,
    film_drive: NDArray[np.float64],
    weight: float,
    own: float,
    out: NDArray[np.float64],
) -> None:
    # As _lag_steps with the pole of step k raised to 1/(T/T_ref)^exponent at the film
    # temperature T = T_ref + own (y[k] + K - T_ref) + weight (film_drive[k] - y[k]).
    anchor = (1.0 - own) * reference
    y = start
    out[0] = y
    for k in range(drive.size):
        kelvin = y + KELVIN
        # own = 1 (the film) written apart so that it rounds as the state itself does
        film = (kelvin if own == 1.0 else own * kelvin + anchor) + weight * (film_drive[k] - y)
        # min(max(film / reference, 0.5), 2.0), as in SensorChain.poles (NaN kept)
        ratio = film / reference
        if ratio < 0.5:
            ratio = 0.5
        if ratio > 2.0:
            ratio = 2.0
        pole = a[k] ** (1.0 / ratio**exponent)
        loss = 0.0
        if r != 0.0:
            square = kelvin * kelvin
            loss = r * (square * square - wall4)
        y = pole * y + (1.0 - pole) * (drive[k] - loss)
        out[k + 1] = y


@functools.cache
def _kernels() -> tuple[Callable[..., Any], ...]:
    """The two loops, compiled where numba is installed (once per process, cached on disk)."""
    return compile_loops(_lag_steps, _level_lag_steps)


def _floats(values: NDArray[Any]) -> NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)


def lag_steps(
    drive: NDArray[np.float64], a: NDArray[np.float64], start: float, r: float, wall4: float
) -> NDArray[np.float64]:
    """y[k+1] = a_k y[k] + (1 − a_k)(u[k] − r ((y[k] + K)⁴ − T_w⁴)), y[0] = ``start``.

    Parameters
    ----------
    drive : ndarray, shape (N - 1,)
        u, degrees C.
    a : ndarray, shape (N - 1,)
        The pole of each step.
    start : float
        y[0], degrees C.
    r : float
        Radiation coefficient, 1/K³ (0: none).
    wall4 : float
        T_w⁴ of the wall, K⁴.

    Returns
    -------
    ndarray, shape (N,)
        y, degrees C.
    """
    drive = _floats(drive)
    out = np.empty(drive.size + 1)
    _kernels()[0](drive, _floats(a), float(start), float(r), float(wall4), out)
    return out


def level_lag_steps(
    drive: NDArray[np.float64],
    a: NDArray[np.float64],
    start: float,
    r: float,
    wall4: float,
    level: tuple[float, float, NDArray[np.float64], float, float],
) -> NDArray[np.float64]:
    """:func:`lag_steps` with τ at the film temperature.

    ``level = (exponent, T_ref, film_drive, w, c)``: the pole of step k is
    a_k^(1/(T/T_ref)^exponent) at the film temperature T = T_ref + c (y[k] + K − T_ref) +
    w (film_drive[k] − y[k]) (K; film_drive shape (N - 1,), degrees C), ``a`` holding the
    poles without that factor.
    """
    exponent, reference, film_drive, weight, own = level
    drive = _floats(drive)
    out = np.empty(drive.size + 1)
    _kernels()[1](
        drive,
        _floats(a),
        float(start),
        float(r),
        float(wall4),
        float(exponent),
        float(reference),
        _floats(film_drive),
        float(weight),
        float(own),
        out,
    )
    return out
