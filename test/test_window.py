import math

import numpy as np
import pytest
from sim_records import make_pair

from tcomp_core import DataError, SlidingBetaWindow, estimate
from tcomp_core.estimators.scatter import beta_scatter
from tcomp_core.validation import MIN_SAMPLES
from tcomp_core.window import BETA_METHODS

CAPACITY = 700
RECORD_SECONDS = 8.0  # 4000 samples at dt = 0.002: the window slides over ~5.7 capacities


def record(kind="sinusoid", seed=11, noise_percent=2.0, phi=1.0):
    return make_pair(
        kind, duration=RECORD_SECONDS, noise_percent=noise_percent, seed=seed, phi=phi
    )


def assert_matches_batch(window, tc1, tc2, end, dt, phi=1.0):
    start = max(0, end - window.capacity)
    assert len(window) == end - start
    np.testing.assert_array_equal(window.samples[:, 0], tc1[start:end])
    np.testing.assert_array_equal(window.samples[:, 1], tc2[start:end])
    streamed = window.estimate()
    batch = estimate(tc1[start:end], tc2[start:end], dt, window.method, phi=phi)
    assert streamed.method == batch.method == window.method
    assert streamed.n_samples == batch.n_samples == end - start
    for key in ("tau1", "tau2", "a1", "a2"):
        assert getattr(streamed, key) == pytest.approx(getattr(batch, key), rel=1e-9), key
    for key in ("beta", "b1"):
        assert streamed.params[key] == pytest.approx(batch.params[key], rel=1e-9), key
    assert streamed.phi == batch.phi
    expected = beta_scatter(tc1[start:end].copy(), tc2[start:end].copy())
    scale = np.max(np.abs(expected))
    np.testing.assert_allclose(window.scatter, expected, rtol=0, atol=1e-10 * scale)
    return streamed


@pytest.mark.parametrize("method", BETA_METHODS)
@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
def test_push_one_at_a_time_matches_batch(method, kind):
    pair = record(kind)
    window = SlidingBetaWindow(CAPACITY, pair.dt, method)
    checkpoints = {350, 699, 700, 701, 1399, 1400, 1401, 2222, 3001, pair.tc1.size}
    taus = []
    for index in range(pair.tc1.size):
        window.push(pair.tc1[index], pair.tc2[index])
        if index + 1 in checkpoints:
            taus.append(assert_matches_batch(window, pair.tc1, pair.tc2, index + 1, pair.dt).tau1)
    assert len(window) == CAPACITY
    # different stretches of a noisy record give different estimates: the check is not vacuous
    assert len(set(taus)) == len(taus)


@pytest.mark.parametrize("method", BETA_METHODS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_extend_random_chunks_matches_batch(method, seed):
    pair = record("multisine", seed=seed)
    window = SlidingBetaWindow(CAPACITY, pair.dt, method)
    rng = np.random.default_rng(100 + seed)
    end = 0
    checked = 0
    while end < pair.tc1.size:
        size = int(rng.integers(1, int(1.5 * CAPACITY)))  # some chunks exceed the capacity
        stop = min(end + size, pair.tc1.size)
        window.extend(pair.tc1[end:stop], pair.tc2[end:stop])
        end = stop
        if end >= 200:
            assert_matches_batch(window, pair.tc1, pair.tc2, end, pair.dt)
            checked += 1
    assert checked >= 5


@pytest.mark.parametrize("seed", [3, 4])
def test_extend_small_chunks_many_slides(seed):
    """Many small chunks: the scatter is updated incrementally many times between refreshes."""
    pair = record("exhaust", seed=seed)
    window = SlidingBetaWindow(CAPACITY, pair.dt, "beta-gtls")
    rng = np.random.default_rng(seed)
    end = 0
    while end < pair.tc1.size:
        stop = min(end + int(rng.integers(1, 40)), pair.tc1.size)
        window.extend(pair.tc1[end:stop], pair.tc2[end:stop])
        end = stop
        if end > CAPACITY and rng.random() < 0.05:
            assert_matches_batch(window, pair.tc1, pair.tc2, end, pair.dt)
    assert_matches_batch(window, pair.tc1, pair.tc2, end, pair.dt)


@pytest.mark.parametrize("phi", [0.5, 2.5])
def test_gtls_window_uses_phi(phi):
    pair = record("ramp", seed=5, phi=phi, noise_percent=4.0)
    window = SlidingBetaWindow(CAPACITY, pair.dt, "beta-gtls", phi=phi)
    window.extend(pair.tc1[:2500], pair.tc2[:2500])
    streamed = assert_matches_batch(window, pair.tc1, pair.tc2, 2500, pair.dt, phi=phi)
    assert streamed.phi == phi
    default = estimate(pair.tc1[1800:2500], pair.tc2[1800:2500], pair.dt, "beta-gtls")
    assert abs(streamed.tau1 - default.tau1) > 1e-6 * default.tau1


def test_push_and_extend_agree():
    pair = record("sinusoid", seed=6)
    pushed = SlidingBetaWindow(CAPACITY, pair.dt)
    extended = SlidingBetaWindow(CAPACITY, pair.dt)
    for index in range(1500):
        pushed.push(pair.tc1[index], pair.tc2[index])
    extended.extend(pair.tc1[:1000], pair.tc2[:1000])
    extended.extend(pair.tc1[1000:1500], pair.tc2[1000:1500])
    np.testing.assert_array_equal(pushed.samples, extended.samples)
    np.testing.assert_allclose(pushed.scatter, extended.scatter, rtol=1e-10)
    assert pushed.estimate().tau2 == pytest.approx(extended.estimate().tau2, rel=1e-9)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("which", [0, 1])
def test_non_finite_push_leaves_window_unchanged(bad, which):
    pair = record("sinusoid", seed=7)
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    window.extend(pair.tc1[:1000], pair.tc2[:1000])
    samples, scatter, before = window.samples.copy(), window.scatter, window.estimate()
    values = [pair.tc1[1000], pair.tc2[1000]]
    values[which] = bad
    with pytest.raises(DataError, match="not finite"):
        window.push(*values)
    assert len(window) == CAPACITY
    np.testing.assert_array_equal(window.samples, samples)
    np.testing.assert_array_equal(window.scatter, scatter)
    assert window.estimate() == before
    # and it keeps working afterwards, as if the bad sample never came
    window.push(pair.tc1[1000], pair.tc2[1000])
    assert_matches_batch(window, pair.tc1, pair.tc2, 1001, pair.dt)


def test_non_finite_extend_leaves_window_unchanged():
    pair = record("sinusoid", seed=8)
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    window.extend(pair.tc1[:500], pair.tc2[:500])
    samples, scatter = window.samples.copy(), window.scatter
    chunk = pair.tc2[500:600].copy()
    chunk[42] = math.nan
    with pytest.raises(DataError, match="tc2: sample 42"):
        window.extend(pair.tc1[500:600], chunk)
    with pytest.raises(DataError, match="100 samples but tc2 has 99"):
        window.extend(pair.tc1[500:600], pair.tc2[500:599])
    np.testing.assert_array_equal(window.samples, samples)
    np.testing.assert_array_equal(window.scatter, scatter)
    window.extend(pair.tc1[500:600], pair.tc2[500:600])
    assert_matches_batch(window, pair.tc1, pair.tc2, 600, pair.dt)


def test_too_few_samples_to_estimate():
    pair = record("sinusoid")
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    with pytest.raises(DataError, match=r"holds 0 regression rows \(0 samples\)"):
        window.estimate()
    for index in range(MIN_SAMPLES - 1):
        window.push(pair.tc1[index], pair.tc2[index])
    few = MIN_SAMPLES - 1
    with pytest.raises(DataError, match=rf"\({few} samples\); at least {MIN_SAMPLES - 1}"):
        window.estimate()
    window.push(pair.tc1[MIN_SAMPLES], pair.tc2[MIN_SAMPLES])
    window.estimate()  # the minimum is enough (noise-free-ish sinusoid gives a physical answer)


def test_clear_forgets_everything():
    pair = record("ramp")
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    window.extend(pair.tc1[:900], pair.tc2[:900])
    window.clear()
    assert len(window) == 0
    np.testing.assert_array_equal(window.scatter, np.zeros((3, 3)))
    window.extend(pair.tc1[1000:1300], pair.tc2[1000:1300])
    expected = estimate(pair.tc1[1000:1300], pair.tc2[1000:1300], pair.dt, "beta-gtls")
    assert window.estimate().tau1 == pytest.approx(expected.tau1, rel=1e-9)


def test_samples_and_scatter_are_copies():
    pair = record("ramp")
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    window.extend(pair.tc1[:100], pair.tc2[:100])
    samples = window.samples
    samples[0, 0] = -1e9
    assert window.samples[0, 0] == pair.tc1[0]
    scatter = window.scatter
    scatter[:] = 0.0
    assert np.any(window.scatter != 0.0)
    window.push(1.0, 2.0)  # the buffer itself stays writable
    assert window.samples[-1].tolist() == [1.0, 2.0]


@pytest.mark.parametrize("capacity", [MIN_SAMPLES - 1, 2, 0, -5])
def test_capacity_below_minimum_refused(capacity):
    with pytest.raises(ValueError, match=f"at least {MIN_SAMPLES}"):
        SlidingBetaWindow(capacity, 0.002)


def test_minimum_capacity_accepted():
    window = SlidingBetaWindow(MIN_SAMPLES, 0.002)
    assert window.capacity == MIN_SAMPLES


def test_bad_method_and_dt_refused():
    with pytest.raises(ValueError, match="gamma-ls"):
        SlidingBetaWindow(100, 0.002, "gamma-ls")
    with pytest.raises(DataError, match="dt"):
        SlidingBetaWindow(100, 0.0)


def test_extend_with_nothing_changes_nothing():
    pair = record("ramp")
    window = SlidingBetaWindow(CAPACITY, pair.dt)
    window.extend([], [])
    assert len(window) == 0
    window.extend(pair.tc1[:300], pair.tc2[:300])
    scatter = window.scatter
    window.extend([], [])
    np.testing.assert_array_equal(window.scatter, scatter)
    assert len(window) == 300


def test_rounding_residue_of_a_huge_transient_is_flushed():
    """Rows of a huge transient added then subtracted leave rounding residue in the running
    scatter; the periodic recomputation must flush it once the transient has left."""
    pair = record("sinusoid", seed=13)
    tc1, tc2 = pair.tc1.copy(), pair.tc2.copy()
    tc1[300:500] *= 1e7
    tc2[300:500] *= -1e7
    window = SlidingBetaWindow(CAPACITY, pair.dt, "beta-gtls")
    window.extend(tc1[:600], tc2[:600])
    for index in range(600, 3000):
        window.push(tc1[index], tc2[index])
    assert_matches_batch(window, tc1, tc2, 3000, pair.dt)


def test_gap_leaves_out_the_straddling_row():
    """A sample marked non-contiguous contributes no row linking it to its predecessor."""
    pair = record("ramp", noise_percent=0.0)
    first, second = slice(0, 300), slice(400, 900)  # samples 300..399 lost
    window = SlidingBetaWindow(1000, pair.dt)
    window.extend(pair.tc1[first], pair.tc2[first])
    flags = np.ones(500, dtype=bool)
    flags[0] = False
    window.extend(pair.tc1[second], pair.tc2[second], contiguous=flags)
    expected = beta_scatter(pair.tc1[first], pair.tc2[first]) + beta_scatter(
        pair.tc1[second], pair.tc2[second]
    )
    np.testing.assert_allclose(window.scatter, expected, rtol=1e-12)
    assert window.rows == 299 + 499
    # Noise-free data: the regression over two segments still recovers τ exactly, whereas a
    # row straddling the gap would bias it.
    result = window.estimate()
    assert result.tau1 == pytest.approx(pair.tau1, rel=1e-9)
    ungapped = SlidingBetaWindow(1000, pair.dt)
    ungapped.extend(pair.tc1[first], pair.tc2[first])
    ungapped.extend(pair.tc1[second], pair.tc2[second])
    assert abs(ungapped.estimate().tau1 / pair.tau1 - 1.0) > 1e-6


def test_gap_rows_leave_the_window_correctly():
    pair = record("sinusoid")
    window = SlidingBetaWindow(200, pair.dt)
    for index in range(1000):
        window.push(pair.tc1[index], pair.tc2[index], contiguous=index % 97 != 0)
    block = np.arange(800, 1000)
    segments = np.split(block, np.flatnonzero(block % 97 == 0))
    expected = sum(
        beta_scatter(pair.tc1[part], pair.tc2[part]) for part in segments if part.size > 1
    )
    np.testing.assert_allclose(window.scatter, expected, rtol=1e-9, atol=1e-9)
