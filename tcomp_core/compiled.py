"""Python loops compiled by numba where it is installed, run as Python where it is not.

Recurrences that step one sample at a time (a nonlinear sensor's lag, a Kalman filter's modes)
and small matrix iterations are slow as Python and awkward as numpy calls. The functions handed
to :func:`compile_loops` are written as plain Python over numpy arrays; numba compiles them
(:func:`numba.njit`, cached on disk beside their module, or in numba's user cache where that is
read-only; in memory when neither is writable) on their first call. Without numba the same
functions run as Python, with the same results.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

__all__ = ["REWRITE_FLAGS", "compile_loops", "warm_compiler"]

#: Fast-math flags that only rewrite arithmetic, each step within an ulp or so: a division by a
#: loop-invariant becomes a multiplication by its reciprocal (``arcp``), a product and a sum
#: one fused multiply-add (``contract``). Not the flags that assume no NaN or infinity (a loop
#: fed one must still return it) nor those that reorder sums.
REWRITE_FLAGS = frozenset({"arcp", "contract"})


def compile_loops(
    *functions: Callable[..., Any], fastmath: frozenset[str] = frozenset()
) -> tuple[Callable[..., Any], ...]:
    """The ``functions`` compiled by numba (nopython, no GIL held), or themselves without it.

    ``fastmath``: LLVM's fast-math flags to allow (:data:`REWRITE_FLAGS`, say); none by default.
    """
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a dependency; Python is the fallback
        return functions
    options: dict[str, Any] = {"nogil": True, "fastmath": set(fastmath)}
    try:
        compile_: Any = numba.njit(cache=True, **options)
        return tuple(compile_(function) for function in functions)
    except RuntimeError:  # no writable cache directory (a read-only install, no home)
        compile_ = numba.njit(**options)
        return tuple(compile_(function) for function in functions)


def _increment(value: float) -> float:
    return value + 1.0


def warm_compiler() -> None:
    """Import numba and build its typing and target contexts, by compiling a trivial function.

    A process that compiles (or loads from the disk cache) its first loop spends about 0.35 s
    of CPU on this first. The fork server does it once before it forks workers
    (:mod:`tcomp_core.worker_preload`), so each worker loads its loops at once. Without numba,
    or where the trivial compile fails, nothing is done: the warm-up is only a saving and the
    fork server must start all the same (a loop that cannot compile then fails where it runs,
    with its own error).
    """
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a dependency
        return
    with contextlib.suppress(Exception):  # a broken numba or LLVM install
        numba.njit(_increment)(0.0)  # not cached: the contexts are wanted, not the code
