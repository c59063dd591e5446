"""Equivalent first-order readings of a stream, causally, chunk by chunk.

The streaming form of :func:`~.offline.equivalent_readings` for the compensator node and
``tcomp process``: each sensor's chain (as a causal stream applies it,
:meth:`~.plan.OutputModel.applied`) is undone sample by sample with its state carried across
chunks (the fin filter's sections, the radiation term's lag); a delay of tc2 reads tc2's
readings ``delay + SHIFT_HALF_TAPS`` samples ahead, so the equivalent pairs come out that many
samples late (:attr:`EquivalentStream.latency`), each with its own stamp.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from ..effects import Model
from ..effects.base import KELVIN
from ..effects.chain import SHIFT_HALF_TAPS, SensorChain, shift_weights
from ..effects.interference import interference_line
from .plan import OutputModel

__all__ = ["EquivalentStream"]


class _ChainState:
    """One sensor's chain after the delay, undone with its state carried between chunks."""

    def __init__(self, chain: SensorChain, dt: float) -> None:
        self.chain = chain
        self.sections = chain.support_filters(dt)
        self.pole = math.exp(-dt / chain.tau)
        self.zi: NDArray[np.float64] | None = None
        self.excess: float | None = None  # radiation: equivalent reading less the lagged one

    def __call__(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        chain = self.chain
        lagged = (values - chain.offset) / chain.gain
        if self.sections is not None:
            sos_filter = self.sections[1]
            if self.zi is None:
                self.zi = sos_filter.steady_state(float(lagged[0]))
            lagged, self.zi = signal.sosfilt(sos_filter.sos, lagged, zi=self.zi)
        if not chain.r:
            return lagged
        # e[k+1] = a e[k] + (1 - a) r (T[k]^4 - T_w^4): the radiation loss re-lagged by the
        # first-order lag, from its value at rest (as first_order_reading starts).
        kelvin = lagged + KELVIN
        loss = chain.r * (kelvin * kelvin * kelvin * kelvin - chain.wall_k**4)
        if self.excess is None:
            self.excess = float(loss[0])
        a = self.pole
        following = signal.lfilter([1.0 - a], [1.0, -a], loss, zi=[a * self.excess])[0]
        excess = np.concatenate(([self.excess], following[:-1]))
        self.excess = float(following[-1])
        return lagged + excess


class EquivalentStream:
    """Readings in, equivalent first-order readings out, causally.

    Parameters
    ----------
    model : OutputModel
        The model; the effects a causal stream cannot apply stay first order
        (:meth:`OutputModel.stream_pieces`), the supports' initial excess is left out (a stream
        has no start at rest).
    dt : float
        Sample interval, s.
    origin_ns : int
        Stamp of the fitted record's sample 0, ns (an interference line's phase counts from it).

    Attributes
    ----------
    latency : int
        Samples an equivalent pair comes out after its own (a delay's look-ahead; else 0).
    """

    def __init__(self, model: OutputModel, dt: float, origin_ns: int) -> None:
        self.model = model
        self.dt = dt
        self.origin_ns = int(origin_ns)
        applied = model.applied(causal_stream=True)
        # The line is subtracted here at each sample's own time, not through the chain.
        chained = tuple(name for name in applied if name != "interference")
        span = np.array([0.0, dt]) + model.origin_s
        chains = Model(chained, model.params).chains(model.context_for(span, dt))
        self._states_chains = tuple(replace(c, mode0=0.0) for c in chains)
        self._line_channel = (
            int(model.params.get("interference_channel", 2)) if "interference" in applied else 0
        )
        shift = chains[1].delay_s / dt
        whole = math.floor(shift)
        self._weights = shift_weights(shift - whole) if chains[1].delay_s else None
        self._first_offset = whole - SHIFT_HALF_TAPS + 1
        self.latency = max(0, whole + SHIFT_HALF_TAPS) if self._weights is not None else 0
        self.reset()

    def reset(self) -> None:
        """Start over (after a gap): the samples not yet emitted are dropped."""
        self._states = tuple(_ChainState(chain, self.dt) for chain in self._states_chains)
        self._stamps = np.empty(0, np.int64)
        self._tc1 = np.empty(0)
        self._tc2 = np.empty(0)  # from index self._tc2_start of the run
        self._tc2_start = 0
        self._tc2_first = math.nan
        self._received = 0
        self._emitted = 0

    @property
    def pending(self) -> int:
        """Samples taken but not emitted yet."""
        return self._received - self._emitted

    def push(
        self, stamps_ns: NDArray[np.int64], tc1: NDArray[np.float64], tc2: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """Take contiguous samples; return the equivalent pairs now complete.

        Parameters
        ----------
        stamps_ns : ndarray of int, shape (M,)
        tc1, tc2 : ndarray, shape (M,)
            Readings, degrees C, following the previous call's without a gap.

        Returns
        -------
        stamps_ns, tc1, tc2 : ndarray, shape (R,) each
            The pairs of the oldest R samples not emitted before, degrees C.
        """
        stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
        readings = [np.asarray(tc1, dtype=np.float64), np.asarray(tc2, dtype=np.float64)]
        if self._line_channel and stamps_ns.size:
            time = ((stamps_ns - self.origin_ns) * 1e-9).astype(np.float64)
            line = interference_line(self.model.params, time)
            readings[self._line_channel - 1] = np.subtract(readings[self._line_channel - 1], line)
        if self._received == 0 and stamps_ns.size:
            self._tc2_first = float(readings[1][0])
        self._stamps = np.concatenate((self._stamps, stamps_ns))
        self._tc1 = np.concatenate((self._tc1, readings[0]))
        self._tc2 = np.concatenate((self._tc2, readings[1]))
        self._received += stamps_ns.size
        count = max(0, self._received - self.latency - self._emitted)
        if count == 0:
            return np.empty(0, np.int64), np.empty(0), np.empty(0)
        first = self._tc1[:count]
        second = self._shifted_tc2(count)
        stamps = self._stamps[:count]
        self._stamps, self._tc1 = self._stamps[count:], self._tc1[count:]
        self._emitted += count
        self._trim_tc2()
        return stamps, self._states[0](first), self._states[1](second)

    def _shifted_tc2(self, count: int) -> NDArray[np.float64]:
        """tc2 read at k + delay/dt for the next ``count`` samples to emit."""
        if self._weights is None:
            start = self._emitted - self._tc2_start
            return self._tc2[start : start + count]
        taps = self._weights.size
        lo = self._emitted + self._first_offset  # first index the first stencil reads
        hi = lo + count + taps - 1  # one past the last index the last stencil reads
        index = np.arange(lo, hi)
        # Before the run's first sample the stencil reads that sample (nothing earlier exists).
        values = np.where(
            index < 0,
            self._tc2_first,
            self._tc2[np.clip(index - self._tc2_start, 0, self._tc2.size - 1)],
        )
        return np.correlate(values, self._weights, mode="valid")

    def _trim_tc2(self) -> None:
        """Keep tc2 from the first index a future stencil reads."""
        offset = self._first_offset if self._weights is not None else 0
        keep_from = max(self._tc2_start, self._emitted + offset)
        self._tc2 = self._tc2[keep_from - self._tc2_start :]
        self._tc2_start = keep_from
