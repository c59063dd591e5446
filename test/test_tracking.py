"""Tracking time constants that change with the flow velocity (β-GTLS with forgetting)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from tcomp_core.errors import DataError
from tcomp_core.estimators.scatter import beta_scatter
from tcomp_core.models import FirstOrderLag
from tcomp_core.simulate import add_noise, multisine
from tcomp_core.tracking import ForgettingEstimator, solve_scale, track_tau, varying_lag_response
from tcomp_core.window import SlidingBetaWindow

DT = 0.002
TAU1, TAU2 = 0.0238, 0.1168


@functools.lru_cache(maxsize=16)
def varying_record(shape="sine", duration=16.0, noise_percent=1.0, seed=0):
    """Multisine gas, τ_i(t) = τ_i0 · scale(t): a velocity change, the ratio constant.

    shape 'sine': scale = 1 + 0.3 sin(2π t / 8 s); 'step': 1 until half-way, then 1.3;
    'constant': 1.
    """
    time = np.arange(round(duration / DT)) * DT
    if shape == "sine":
        scale = 1.0 + 0.3 * np.sin(2.0 * np.pi * time / 8.0)
    elif shape == "step":
        scale = np.where(time < duration / 2, 1.0, 1.3)
    else:
        scale = np.ones_like(time)
    gas = multisine(time)
    clean1 = varying_lag_response(gas, TAU1 * scale, DT)
    clean2 = varying_lag_response(gas, TAU2 * scale, DT)
    tc1, tc2, _, _ = add_noise(clean1, clean2, noise_percent, rng=np.random.default_rng(seed))
    return tc1, tc2, scale


def rms_percent(track, scale, after_s):
    """rms relative error (%) of τ1 and τ2 against the truth at the track's times."""
    index = np.round(track.time / DT).astype(int) - 1
    keep = track.time > after_s
    errors = [
        track.tau1[keep] / (TAU1 * scale[index][keep]) - 1.0,
        track.tau2[keep] / (TAU2 * scale[index][keep]) - 1.0,
    ]
    return [100.0 * float(np.sqrt(np.mean(e**2))) for e in errors]


def test_varying_response_reduces_to_the_constant_lag():
    gas = multisine(np.arange(500) * DT)
    np.testing.assert_allclose(
        varying_lag_response(gas, np.full(gas.size, TAU1), DT),
        FirstOrderLag(tau=TAU1).respond(gas, DT),
        rtol=1e-12,
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_centred_track_follows_a_velocity_change(seed):
    tc1, tc2, scale = varying_record(seed=seed)
    track = track_tau(tc1, tc2, DT, memory_s=0.25, step_s=0.05)
    assert max(rms_percent(track, scale, after_s=0.5)) < 3.0
    assert track.ratio == pytest.approx(TAU1 / TAU2, rel=0.02)


@pytest.mark.parametrize("seed", [0, 1])
def test_causal_track_follows_a_velocity_change(seed):
    tc1, tc2, scale = varying_record(seed=seed)
    track = track_tau(tc1, tc2, DT, memory_s=0.1, step_s=0.05, centered=False)
    assert track.time[0] >= 0.1  # the first full memory
    assert max(rms_percent(track, scale, after_s=0.3)) < 5.0


def test_constant_ratio_lowers_the_variance():
    tc1, tc2, _ = varying_record("constant", duration=8.0, noise_percent=2.0)
    free = track_tau(tc1, tc2, DT, memory_s=0.1, step_s=0.05, constrain_ratio=False)
    tied = track_tau(tc1, tc2, DT, memory_s=0.1, step_s=0.05)
    assert np.std(tied.tau1) < 0.8 * np.std(free.tau1)
    assert np.isnan(free.ratio)


def test_constant_time_constants_give_a_flat_track():
    tc1, tc2, _ = varying_record("constant", duration=8.0)
    for centered in (True, False):
        track = track_tau(tc1, tc2, DT, memory_s=0.5, step_s=0.1, centered=centered)
        for values, truth in ((track.tau1, TAU1), (track.tau2, TAU2)):
            assert np.std(values) < 0.02 * truth
            assert np.mean(values) == pytest.approx(truth, rel=0.02)


def step_response_time(memory_s):
    """Seconds after the +30 % step until the causal τ2 track has risen half-way."""
    tc1, tc2, _ = varying_record("step", duration=8.0)
    track = track_tau(tc1, tc2, DT, memory_s=memory_s, step_s=0.01, centered=False)
    risen = (track.time > 4.0) & (track.tau2 > 1.15 * TAU2)
    return float(track.time[np.argmax(risen)] - 4.0), track


def test_shorter_memory_follows_a_step_faster_but_is_noisier():
    short_delay, short = step_response_time(0.1)
    long_delay, long = step_response_time(0.5)
    assert short_delay < 0.5 * long_delay
    assert short_delay == pytest.approx(0.1 * np.log(2), abs=0.06)  # exponential memory
    settled = lambda track: track.tau2[(track.time > 1.5) & (track.time < 4.0)]  # noqa: E731
    assert np.std(settled(short)) > 1.5 * np.std(settled(long))


def test_streaming_estimator_matches_the_offline_causal_track():
    tc1, tc2, _ = varying_record(duration=4.0)
    track = track_tau(
        tc1, tc2, DT, memory_s=0.2, step_s=0.1, phi=1.0, constrain_ratio=False, centered=False
    )
    tracker = ForgettingEstimator(DT, memory_s=0.2, constrain_ratio=False)
    done = 0
    for time, tau1, tau2 in zip(track.time, track.tau1, track.tau2, strict=True):
        stop = round(time / DT) + 1  # samples behind the track's row count
        for start in range(done, stop, 37):  # uneven batches
            tracker.extend(tc1[start : min(start + 37, stop)], tc2[start : min(start + 37, stop)])
        done = stop
        found = tracker.estimate()
        assert found.tau1 == pytest.approx(tau1, rel=1e-9)
        assert found.tau2 == pytest.approx(tau2, rel=1e-9)


def test_streaming_estimator_tracks_with_the_ratio_constrained():
    tc1, tc2, scale = varying_record(seed=3)
    tracker = ForgettingEstimator(DT, memory_s=0.1)
    errors = []
    for start in range(0, tc1.size, 250):
        tracker.extend(tc1[start : start + 250], tc2[start : start + 250])
        if start >= 500:
            found = tracker.estimate()
            truth = scale[start + 249]
            errors += [found.tau1 / (TAU1 * truth) - 1, found.tau2 / (TAU2 * truth) - 1]
            assert found.params["ratio"] == pytest.approx(found.tau1 / found.tau2)
            assert found.method == "beta-gtls-forgetting"
    assert 100 * np.sqrt(np.mean(np.square(errors))) < 5.0


def test_long_memory_agrees_with_the_batch_window():
    tc1, tc2, _ = varying_record("constant", duration=4.0)
    window = SlidingBetaWindow(tc1.size, DT)
    window.extend(tc1, tc2)
    tracker = ForgettingEstimator(DT, memory_s=1e9, constrain_ratio=False)
    tracker.extend(tc1, tc2)
    assert tracker.estimate().tau1 == pytest.approx(window.estimate().tau1, rel=1e-6)


def test_scale_solution_on_noise_free_rows():
    tc1, tc2, _ = varying_record("constant", duration=2.0, noise_percent=0.0)
    scatter = beta_scatter(tc1, tc2)
    assert solve_scale(scatter, DT, TAU1 / TAU2, 0.2) == pytest.approx(TAU2, rel=1e-6)


def test_invalid_arguments_are_refused():
    tc1, tc2, _ = varying_record("constant", duration=1.0)
    with pytest.raises(ValueError, match="memory_s"):
        track_tau(tc1, tc2, DT, memory_s=0.0, step_s=0.1)
    with pytest.raises(ValueError, match="memory_s"):
        ForgettingEstimator(DT, memory_s=-1.0)
    with pytest.raises(DataError):
        varying_lag_response(tc1, np.full(3, TAU1), DT)
