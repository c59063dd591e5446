"""Second-order sections applied as scipy applies them, without its per-call overhead.

A diagnosis filters short records (a few thousand samples) tens of thousands of times:
scipy's ``sosfilt`` spends three times as long checking and reshaping its arguments as
filtering 3 000 samples, and ``sosfiltfilt`` designs its initial state (``sosfilt_zi``, a
linear solve per section) on every call. The functions here run scipy's own filter kernel on
the same arrays, in the same order, so their results are bit for bit those of
:func:`scipy.signal.sosfilt` and :func:`scipy.signal.sosfiltfilt` (odd padding of
``3 (2 S + 1)`` samples, less the sections' trailing zeros, as scipy pads by default);
``test/test_sections.py`` checks that. Where scipy's kernel cannot be imported (it is
private), the public functions are called instead.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy import signal

__all__ = ["sosfilt_from", "zero_phase"]


def _public_kernel(
    sos: NDArray[np.float64], x: NDArray[np.float64], zi: NDArray[np.float64]
) -> None:
    """The public ``sosfilt`` in the calling convention of scipy's kernel (x, zi in place)."""
    for row in range(x.shape[0]):
        x[row], zi[row] = signal.sosfilt(sos, x[row], zi=zi[row])


def _find_kernel() -> Callable[[NDArray[np.float64], NDArray[np.float64], NDArray], None]:
    """The compiled kernel ``_sosfilt(sos, x, zi)`` of scipy (x, zi in place), or a stand-in."""
    try:
        from scipy.signal._sosfilt import _sosfilt
    except ImportError:  # pragma: no cover - depends on scipy's private layout
        return _public_kernel
    return _sosfilt  # type: ignore[no-any-return]


_KERNEL = _find_kernel()


def sosfilt_from(
    sos: NDArray[np.float64], values: NDArray[np.float64], zi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``scipy.signal.sosfilt(sos, values, zi=zi)[0]`` for one float64 series.

    Parameters
    ----------
    sos : ndarray, shape (S, 6)
        Second-order sections, float64 (``sos[:, 3]`` all 1, not checked).
    values : ndarray, shape (N,)
        The series.
    zi : ndarray, shape (S, 2)
        The sections' initial state (not modified).

    Returns
    -------
    ndarray, shape (N,)
        The filtered series (a new array).
    """
    out = np.array(values, dtype=np.float64, order="C", ndmin=2)
    state = np.array(zi, dtype=np.float64, order="C", ndmin=3)
    # The kernel's typed memoryviews want C order and a writeable buffer, even for sos.
    if not (sos.dtype == np.float64 and sos.flags.c_contiguous and sos.flags.writeable):
        sos = np.array(sos, dtype=np.float64, order="C")
    _KERNEL(sos, out, state)
    return out[0]


class ZeroPhase:
    """``scipy.signal.sosfiltfilt(sos, x)`` with the sections' initial state computed once.

    Parameters
    ----------
    sos : ndarray, shape (S, 6)
        Second-order sections.
    """

    def __init__(self, sos: NDArray[np.float64]) -> None:
        self.sos = np.require(sos, np.float64, ("C", "W"))
        sections = self.sos.shape[0]
        taps = 2 * sections + 1
        taps -= min(int((self.sos[:, 2] == 0).sum()), int((self.sos[:, 5] == 0).sum()))
        self.edge = 3 * taps
        self.zi = signal.sosfilt_zi(self.sos)

    def __call__(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """The zero-phase filtered series, shape (N,), as ``sosfiltfilt`` gives it.

        Raises
        ------
        ValueError
            If the series is not longer than the padding, as scipy raises it.
        """
        x = np.asarray(values)
        edge = self.edge
        if x.ndim != 1 or x.shape[0] <= edge:
            return signal.sosfiltfilt(self.sos, values)  # scipy's checks and messages
        extended = np.concatenate(
            (2 * x[0:1] - x[edge:0:-1], x, 2 * x[-1:] - x[-2 : -(edge + 2) : -1])
        )
        forward = sosfilt_from(self.sos, extended, self.zi * extended[0:1])
        backward = sosfilt_from(self.sos, forward[::-1], self.zi * forward[-1:])
        return backward[::-1][edge:-edge]


@functools.lru_cache(maxsize=64)
def _zero_phase(key: bytes, shape: tuple[int, ...]) -> ZeroPhase:
    return ZeroPhase(np.frombuffer(key, dtype=np.float64).reshape(shape).copy())


def zero_phase(sos: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.signal.sosfiltfilt(sos, values)`` for one series, the filter's state cached.

    Parameters
    ----------
    sos : ndarray, shape (S, 6)
        Second-order sections (looked up by value).
    values : ndarray, shape (N,)

    Returns
    -------
    ndarray, shape (N,)
    """
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    return _zero_phase(sos.tobytes(), sos.shape)(values)
