"""The shared-signal check pooled over the lowest bins (tcomp_core.validation).

A slow gas seen by a slow sensor spreads its coherence over the first bins of every resolution,
each short of the one-bin bound: such records were refused as "no shared signal" though the two
readings correlate at 0.8-0.98. The pooled test must find them, and independent noise, white or
drifting, must still be refused at the chance it is held to.
"""

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from tcomp_core import NoExcitationError
from tcomp_core.validation import (
    SHARED_POOLED_BINS,
    SHARED_SEGMENTS,
    _coherence,
    _pooled_log_chance,
    _shared_threshold,
    check_shared_signal,
)

DT = 2e-4  # 5 kHz


def slow_ramps_seen_by_a_slow_sensor(seed, noise=0.1, tau2=0.5):
    """6 s at 5 kHz: three ramps up and back, sensors of 40 ms and ``tau2``, noise share of std."""
    rng = np.random.default_rng(seed)
    t = np.arange(30000) * DT
    gas = np.full(t.size, 300.0)
    for start in np.sort(rng.uniform(0.0, 6.0, 3)):
        rise = rng.uniform(-150.0, 150.0)
        up = np.clip((t - start) / 0.5, 0.0, 1.0)
        down = np.clip((t - start - 1.0) / 0.8, 0.0, 1.0)
        gas += rise * (up - down)

    def sensor(tau):
        a = math.exp(-DT / tau)
        return lfilter([1 - a], [1, -a], gas, zi=[a * gas[0]])[0]

    tc1, tc2 = sensor(0.04), sensor(tau2)
    sigma = noise * np.std(tc1)
    return tc1 + sigma * rng.standard_normal(t.size), tc2 + sigma * rng.standard_normal(t.size)


@pytest.mark.parametrize("seed", [3, 4])
def test_a_slow_gas_short_of_every_one_bin_bound_is_a_shared_signal(seed):
    tc1, tc2 = slow_ramps_seen_by_a_slow_sensor(seed)
    assert np.corrcoef(tc1, tc2)[0, 1] > 0.75
    for segments in SHARED_SEGMENTS:  # what the check alone used to look at refuses them
        coherence, _ = _coherence(tc1, tc2, segments)
        assert coherence.max() < _shared_threshold(segments)
    check_shared_signal(tc1, tc2, DT)


def test_the_segments_cover_the_whole_record():
    # A record of 3 * 2**k + 1 samples: power-of-two segments used to leave a third out, and a
    # gas that moves only in that third was called noise. The segments are now of a length
    # whose transform is fast, at most a few percent short of an even split.
    rng = np.random.default_rng(8)
    n = 3 * 4096 + 1
    t = np.arange(n) * DT
    gas = np.where(t > 2 * 4096 * DT, 300.0 + 100.0 * np.sin(2 * np.pi * 40.0 * t), 300.0)
    tc1 = gas + rng.standard_normal(n)
    tc2 = gas + rng.standard_normal(n)
    for segments in SHARED_SEGMENTS:
        _, length = _coherence(tc1, tc2, segments)
        assert 0.95 * (n // segments) <= length <= n // segments
    check_shared_signal(tc1, tc2, DT)


def independent(kind, rng, n):
    first, second = rng.standard_normal((2, n))
    if kind == "drifting":  # random walks: the spurious correlation of independent trends
        return np.cumsum(first), np.cumsum(second)
    if kind == "resonant":  # two independent narrow-band noises at the same frequency
        return lfilter([1], [1, -1.9, 0.95], first), lfilter([1], [1, -1.9, 0.95], second)
    return first, second


@pytest.mark.parametrize("kind", ["white", "drifting", "resonant"])
def test_independent_noise_pools_its_coherence_as_its_null_says(kind):
    # Each band's chance under independence, Gamma(m, 1) of the pooled exponentials, is what
    # noise gives: the count of trials at or below 1 % sits within the binomial's spread.
    rng = np.random.default_rng(31)
    trials = 400
    below = 0
    for _ in range(trials):
        tc1, tc2 = independent(kind, rng, 2048)
        for segments in SHARED_SEGMENTS:
            coherence, _ = _coherence(tc1, tc2, segments)
            below += sum(
                _pooled_log_chance(coherence, segments, bins) <= math.log(0.01)
                for bins in SHARED_POOLED_BINS
            )
    tests = trials * len(SHARED_SEGMENTS) * len(SHARED_POOLED_BINS)
    expected = 0.01 * tests  # 32
    assert expected - 4 * math.sqrt(expected) < below < expected + 4 * math.sqrt(expected), below


@pytest.mark.parametrize("kind", ["white", "drifting", "resonant"])
@pytest.mark.parametrize("samples", [4000, 30000])
def test_independent_noise_of_any_colour_is_refused(kind, samples):
    rng = np.random.default_rng(32)
    for _ in range(60):
        tc1, tc2 = independent(kind, rng, samples)
        with pytest.raises(NoExcitationError, match=r"share no signal"):
            check_shared_signal(tc1, tc2, DT)
