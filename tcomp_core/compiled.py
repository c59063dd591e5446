"""Python loops compiled by numba where it is installed, run as Python where it is not.

Recurrences that step one sample at a time (a nonlinear sensor's lag, a Kalman filter's modes)
and small matrix iterations are slow as Python and awkward as numpy calls. The functions handed
to :func:`compile_loops` are written as plain Python over numpy arrays; numba compiles them
(:func:`numba.njit`, cached on disk beside their module, or in numba's user cache where that is
read-only; in memory when neither is writable) on their first call. Without numba the same
functions run as Python, with the same results.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["compile_loops"]


def compile_loops(*functions: Callable[..., Any]) -> tuple[Callable[..., Any], ...]:
    """The ``functions`` compiled by numba (nopython, no GIL held), or themselves without it."""
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a dependency; Python is the fallback
        return functions
    try:
        compile_: Any = numba.njit(cache=True, nogil=True)
        return tuple(compile_(function) for function in functions)
    except RuntimeError:  # no writable cache directory (a read-only install, no home)
        compile_ = numba.njit(nogil=True)
        return tuple(compile_(function) for function in functions)
