"""The causal filter's widening, one compiled loop, equals its formulation as array operations."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from scipy import signal

from tcomp_core.fusion import consistency
from tcomp_core.fusion.consistency import ConsistencyCheck


def _average(values, memory, carried):
    rate = 1.0 / memory
    return signal.lfilter([rate], [1.0, rate - 1.0], values, zi=[(1.0 - rate) * carried])[0]


def _hold(excess, carried, log_decay):
    """h_k = max(excess_k, h_(k-1) ρ) from h_(-1) = carried, as a cumulative maximum of logs."""
    steps = np.arange(excess.size)
    with np.errstate(divide="ignore"):
        logs = np.log(excess) - steps * log_decay
        start = math.log(carried) + log_decay if carried > 0.0 else -np.inf
    logs[0] = max(logs[0], start)
    return np.exp(np.maximum.accumulate(logs) + steps * log_decay)


class ArrayWidening:
    """ConsistencyCheck.widen as numpy calls on whole batches (the state carried as fields)."""

    def __init__(self, check):
        self.check, self.offset, self.seen = check, np.zeros(2), 0
        self.average, self.held, self.ratio, self.gas_held = 1.0, 1.0, 1.0, 0.0

    def widen(self, std, innovations, inverse, gas, inversion):
        count, memory = innovations.shape[1], consistency.OFFSET_MEMORY
        means = np.empty((2, count + 1))
        means[:, 0] = self.offset
        head = min(count, max(memory - self.seen, 0))
        if head:
            sums = self.offset[:, None] * self.seen + np.cumsum(innovations[:, :head], axis=1)
            means[:, 1 : head + 1] = sums / (self.seen + np.arange(1, head + 1))
        for row in (0, 1):
            if head < count:
                means[row, head + 1 :] = _average(
                    innovations[row, head:], memory, means[row, head]
                )
        self.offset, self.seen = means[:, -1].copy(), self.seen + count
        debiased = innovations - means[:, :-1]
        square = np.einsum("ik,kij,jk->k", debiased, inverse, debiased)
        average = _average(0.5 * square, consistency.CONSISTENCY_MEMORY, self.average)
        held = 1.0 + _hold(np.maximum(average - 1.0, 0.0), self.held - 1.0, self.check._log_decay)
        self.average, self.held = float(average[-1]), float(held[-1])
        widened = std * np.where(held > consistency.CONSISTENCY_THRESHOLD, np.sqrt(held), 1.0)
        variance, total = std**2, self.check.inversion_variance
        expected = np.maximum(total - variance, 1e-3 * total)
        ratio = _average((gas - inversion) ** 2 / expected, consistency.GAS_MEMORY, self.ratio)
        implied = ratio * expected - total + 2.0 * variance
        excess = np.where(
            ratio > consistency.GAS_THRESHOLD, np.maximum(implied - variance, 0.0), 0.0
        )
        held_excess = _hold(excess, self.gas_held, -1.0 / consistency.GAS_MEMORY)
        self.ratio, self.gas_held = float(ratio[-1]), float(held_excess[-1])
        published = np.maximum(widened, np.sqrt(variance + held_excess))
        return published, int(np.count_nonzero(published >= consistency.MATERIAL_WIDENING * std))


def test_the_compiled_widening_equals_the_array_formulation_batch_after_batch():
    rng = np.random.default_rng(41)
    model = SimpleNamespace(tau1=0.02, tau2=0.1, dt=2e-4, sigma1=0.3, sigma2=0.4)
    check = ConsistencyCheck(model, np.diag([0.995, 0.9]))
    reference = ArrayWidening(check)
    widened_batches = 0
    for _ in range(60):  # past OFFSET_MEMORY, where the plain mean turns exponential
        count = int(rng.integers(1, 600))
        std = np.abs(rng.normal(1.0, 0.2, count)) + 0.1
        surprise = 1.0 + 6.0 * (rng.random() < 0.3)  # a model the readings disagree with
        innovations = rng.normal(0.0, surprise, (2, count)) + rng.normal(0.0, 2.0, (2, 1))
        inverse = np.broadcast_to([[1.0, 0.1], [0.1, 0.8]], (count, 2, 2))
        gas = rng.normal(300.0, 2.0, count)
        inversion = gas + rng.normal(0.0, 5.0 * (1.0 + 20.0 * (rng.random() < 0.3)), count)
        found = check.widen(std, innovations, inverse, gas, inversion)
        expected, material = reference.widen(std, innovations, inverse, gas, inversion)
        np.testing.assert_allclose(found, expected, rtol=1e-12)
        assert check.last_widened == material
        widened_batches += material > 0
    assert widened_batches >= 10  # the comparison covers widenings, not only quiet batches
