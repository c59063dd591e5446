"""Streaming sufficient statistics of the β regression over a sliding window.

Every β estimator is a function of the 3×3 scatter matrix ``S = Σ z_kᵀ z_k`` of the rows
``z_k = [x1, x2, y]`` of Eq. (14) (see :mod:`tcomp_core.estimators.scatter`). A sliding window
adds the row a new sample completes and subtracts the row the oldest sample leaves: O(1) work per
sample, and re-estimating costs a 3×3 generalized eigenproblem whatever the window length, where
the paper's route takes the SVD of an N×3 matrix.

Only the raw sample pairs of the window are kept (to know which row leaves); they sit in a
buffer twice the window long that is compacted once per window length, so appending is amortised
O(1). Adding and subtracting rows accumulates rounding error; the scatter is recomputed from the
buffer once per window length (amortised O(1)), which bounds the drift to a window's worth.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DataError
from .estimators.beta import beta_noise_covariance, estimate_beta_from_scatter
from .estimators.result import Estimate
from .estimators.scatter import beta_rows
from .validation import MIN_SAMPLES, check_finite, check_sample_interval

__all__ = ["BETA_METHODS", "SlidingBetaWindow"]

BETA_METHODS: tuple[str, ...] = ("beta-ls", "beta-tls", "beta-gtls")


class SlidingBetaWindow:
    """The last ``capacity`` sample pairs of two thermocouples, with their β scatter matrix.

    Parameters
    ----------
    capacity : int
        Window length in samples (rows of the regression: ``capacity - 1``).
    dt : float
        Sample interval, seconds.
    method : {'beta-ls', 'beta-tls', 'beta-gtls'}
        Estimator used by :meth:`estimate`.
    phi : float
        Noise variance ratio σ1²/σ2² for β-GTLS.

    Examples
    --------
    >>> window = SlidingBetaWindow(5000, dt=0.002)
    >>> window.extend(tc1, tc2)            # doctest: +SKIP
    >>> window.estimate().tau1             # doctest: +SKIP
    """

    def __init__(
        self, capacity: int, dt: float, method: str = "beta-gtls", phi: float = 1.0
    ) -> None:
        if capacity < MIN_SAMPLES:
            raise ValueError(f"{capacity=} must be at least {MIN_SAMPLES} samples")
        if method not in BETA_METHODS:
            raise ValueError(f"{method=} is not one of {', '.join(BETA_METHODS)}")
        self.capacity = int(capacity)
        self.dt = check_sample_interval(dt)
        self.method = method
        beta_noise_covariance(phi)  # validates φ now rather than at the first estimate
        self.phi = float(phi)
        # Columns: tc1, tc2, and 1.0 where the sample follows its predecessor without a gap.
        self._buffer = np.empty((2 * self.capacity, 3))
        self._start = 0
        self._end = 0
        self._scatter = np.zeros((3, 3))
        self._since_refresh = 0

    def __len__(self) -> int:
        """Number of sample pairs in the window."""
        return self._end - self._start

    @property
    def samples(self) -> NDArray[np.float64]:
        """The window's sample pairs, oldest first, shape (len, 2); a copy."""
        return self._buffer[self._start : self._end, :2].copy()

    @property
    def samples_view(self) -> NDArray[np.float64]:
        """:attr:`samples` without the copy: read-only, valid until the window next changes."""
        view = self._buffer[self._start : self._end, :2]
        view.flags.writeable = False
        return view

    @property
    def segment_starts(self) -> NDArray[np.intp]:
        """Indices (into :attr:`samples`) of the samples that follow a gap."""
        flags = self._buffer[self._start + 1 : self._end, 2]
        return np.flatnonzero(flags == 0.0) + 1

    @property
    def rows(self) -> int:
        """Number of regression rows in the window (sample pairs that follow their predecessor)."""
        if len(self) < 2:
            return 0
        return int(self._buffer[self._start + 1 : self._end, 2].sum())

    @property
    def scatter(self) -> NDArray[np.float64]:
        """Current 3×3 scatter matrix of the β rows in the window (a copy)."""
        return self._scatter.copy()

    def clear(self) -> None:
        """Forget every sample."""
        self._start = self._end = self._since_refresh = 0
        self._scatter[:] = 0.0

    def push(self, tc1: float, tc2: float, contiguous: bool = True) -> None:
        """Append one sample pair, dropping the oldest once the window is full.

        Parameters
        ----------
        tc1, tc2 : float
            Temperatures, degrees C.
        contiguous : bool
            False when samples were lost since the previous pair: no row links the two.

        Raises
        ------
        DataError
            If a value is not finite; the window is left unchanged.
        """
        first, second = float(tc1), float(tc2)
        if not (np.isfinite(first) and np.isfinite(second)):
            raise DataError(f"sample pair ({first!r}, {second!r}) is not finite")
        self._append(np.array([[first, second, float(contiguous)]]))

    def extend(self, tc1: ArrayLike, tc2: ArrayLike, contiguous: ArrayLike | bool = True) -> None:
        """Append many sample pairs at once (vectorised; same result as repeated :meth:`push`).

        Parameters
        ----------
        tc1, tc2 : array_like, shape (M,)
            Temperatures, degrees C.
        contiguous : bool or array_like of bool, shape (M,)
            Per sample (or for all): False where samples were lost before it.

        Raises
        ------
        DataError
            If a value is not finite or the lengths differ; the window is left unchanged.
        """
        first = check_finite(tc1, "tc1")
        second = check_finite(tc2, "tc2")
        if first.size != second.size:
            raise DataError(f"tc1 has {first.size} samples but tc2 has {second.size}")
        flags = np.broadcast_to(np.asarray(contiguous, dtype=np.float64), first.shape)
        self._append(np.column_stack((first, second, flags)))

    def estimate(self) -> Estimate:
        """Estimate τ1, τ2 from the window's scatter matrix.

        Raises
        ------
        DataError
            If the window holds fewer than the minimum number of samples.
        NoExcitationError, PhysicalRangeError
            As the batch estimator.
        """
        rows = self.rows
        if rows + 1 < MIN_SAMPLES:
            raise DataError(
                f"the window holds {rows} regression rows ({len(self)} samples); at least "
                f"{MIN_SAMPLES - 1} are needed"
            )
        return estimate_beta_from_scatter(self._scatter, self.dt, rows + 1, self.method, self.phi)

    @staticmethod
    def _rows_scatter(block: NDArray[np.float64]) -> NDArray[np.float64]:
        """Scatter of the rows linking consecutive samples of ``block`` (L, 3), gaps excluded."""
        rows = beta_rows(block[:, 0], block[:, 1])
        return (rows * block[1:, 2:3]).T @ rows

    def _append(self, pairs: NDArray[np.float64]) -> None:
        if pairs.shape[0] >= self.capacity:
            self._reset(pairs[-self.capacity :])
            return
        count = pairs.shape[0]
        # Rows completed by the new samples, starting from the current newest sample if any.
        linked = (
            np.vstack((self._buffer[self._end - 1 : self._end], pairs)) if len(self) else pairs
        )
        if linked.shape[0] > 1:
            self._scatter += self._rows_scatter(linked)
        overflow = len(self) + count - self.capacity
        if overflow > 0:
            leaving = self._buffer[self._start : self._start + overflow + 1]
            self._scatter -= self._rows_scatter(leaving)
            self._start += overflow
        if self._end + count > self._buffer.shape[0]:
            length = len(self)
            self._buffer[:length] = self._buffer[self._start : self._end]
            self._start, self._end = 0, length
        self._buffer[self._end : self._end + count] = pairs
        self._end += count
        self._since_refresh += count
        if self._since_refresh >= self.capacity:
            self._refresh()

    def _reset(self, pairs: NDArray[np.float64]) -> None:
        self._buffer[: pairs.shape[0]] = pairs
        self._start, self._end = 0, pairs.shape[0]
        self._refresh()

    def _refresh(self) -> None:
        window = self._buffer[self._start : self._end]
        self._scatter = self._rows_scatter(window) if len(window) > 1 else np.zeros((3, 3))
        self._since_refresh = 0
