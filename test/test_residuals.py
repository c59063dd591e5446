"""Residual statistics of the diagnosis against known cases (all seeded)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

from tcomp_core.diagnose.residuals import (
    analyse_failure,
    autocorrelation,
    band_errors,
    candidate_correlations,
    cross_correlation,
    level_errors,
    windowed_error,
    windowed_tau,
)
from tcomp_core.errors import DataError
from tcomp_core.fit import simulate_tc2_from_tc1
from tcomp_core.simulate import simulate_pair

DT = 0.002


def ar1(rng, phi, n, burn=200):
    return signal.lfilter([1.0], [1.0, -phi], rng.standard_normal(n + burn))[burn:]


def test_acf_matches_a_direct_sum_and_white_noise_stays_within_the_bound(rng):
    e = rng.standard_normal(4000)
    acf = autocorrelation(e, DT, max_lag_s=0.2)
    centred = e - e.mean()
    direct = [np.sum(centred[k:] * centred[: e.size - k]) / np.sum(centred**2) for k in (0, 1, 7)]
    np.testing.assert_allclose(acf.values[[0, 1, 7]], direct, atol=1e-12)
    np.testing.assert_allclose(acf.lags_s[:3], [0.0, DT, 2 * DT])
    assert acf.values.size == 101
    assert acf.bound == pytest.approx(1.96 / np.sqrt(4000), rel=1e-3)
    assert acf.fraction_outside < 0.12
    assert acf.p_value > 0.01


def test_ljung_box_rejects_an_ar1_residual(rng):
    acf = autocorrelation(ar1(rng, 0.5, 2000), DT)
    assert acf.p_value < 1e-6
    assert acf.values[1] == pytest.approx(0.5, abs=0.06)
    assert acf.fraction_outside > 0.0
    assert acf.values.size == 201  # 0.4 s of lags would be 200 at 2 ms; 0.5 s caps at 200


def test_bartlett_bound_keeps_the_false_alarm_rate_for_independent_ar1_series():
    rng = np.random.default_rng(1)
    corrected = naive = 0
    trials, n = 600, 200
    for _ in range(trials):
        result = cross_correlation(ar1(rng, 0.9, n), ar1(rng, 0.9, n), DT, max_lag_s=5 * DT)
        r0 = result.values[result.values.size // 2]
        corrected += abs(r0) > result.bound
        naive += abs(r0) > 1.96 / np.sqrt(n)
    # About 3-5 % over seeds: the truncated sum errs slightly on the safe side.
    assert 0.015 < corrected / trials < 0.08
    assert naive / trials > 0.4


@pytest.mark.parametrize("shift", [7, -4])
def test_cross_correlation_finds_the_lag_of_a_shifted_copy(rng, shift):
    u = ar1(rng, 0.8, 3000)
    e = np.roll(u, shift) + 0.5 * rng.standard_normal(u.size)  # e(t) = u(t - shift)
    result = cross_correlation(e, u, DT)
    assert result.peak_lag_s == pytest.approx(shift * DT)
    assert result.peak > 0.8
    assert result.significant


def test_cross_correlation_of_independent_series_is_not_significant(rng):
    result = cross_correlation(ar1(rng, 0.9, 3000), ar1(rng, 0.9, 3000), DT)
    assert not result.significant
    assert result.bound > 2.5 * 1.96 / np.sqrt(3000)  # Bartlett widens the bound


def test_candidate_correlations_rank_the_signal_in_the_residual_first(rng):
    n = 3000
    level, trend = ar1(rng, 0.95, n), np.arange(n, dtype=float)
    residual = 0.3 * level + rng.standard_normal(n)
    found = candidate_correlations(
        residual, {"trend": trend, "level": level, "noise": ar1(rng, 0.0, n)}
    )
    assert found[0].name == "level"
    assert found[0].z > 5.0
    assert all(abs(c.z) < 3.0 for c in found[1:])
    assert found[0].correlation == pytest.approx(np.corrcoef(residual, level)[0, 1])


def test_windowed_error_finds_the_bad_window_and_skips_masked_ones():
    time = np.arange(5000) * DT
    measured = np.sin(2 * np.pi * time)
    predicted = measured.copy()
    predicted[2000:3000] += 0.1  # window 3 of 5
    mask = np.ones(time.size, dtype=bool)
    mask[4000:] = False
    result = windowed_error(measured, predicted, time, 2.0, mask)
    np.testing.assert_allclose(result.centres_s, [0.999, 2.999, 4.999, 6.999, 8.999])
    expected = 100 * 0.1 / np.std(measured[mask])
    np.testing.assert_allclose(result.error_pct[:4], [0.0, 0.0, expected, 0.0], atol=1e-9)
    assert np.isnan(result.error_pct[4])


def test_windowed_tau_recovers_the_simulated_time_constants():
    pair = simulate_pair("multisine", tau1=0.03, tau2=0.12, dt=DT, duration=8.0)
    result = windowed_tau(pair.tc1, pair.tc2, DT, 2.0)
    assert result.tau1.size == 4
    np.testing.assert_allclose(result.tau1, 0.03, rtol=0.02)
    np.testing.assert_allclose(result.tau2, 0.12, rtol=0.02)
    np.testing.assert_allclose(result.ratio, 4.0, rtol=0.03)
    assert result.tau1_spread_pct < 2.0
    assert not result.vary_together


def test_windowed_tau_sees_both_time_constants_scale_together():
    scales = [0.6, 0.8, 1.0, 1.25, 1.5, 0.7]
    pieces = [
        simulate_pair("multisine", tau1=0.03 * s, tau2=0.12 * s, dt=DT, duration=2.0, seed=k)
        for k, s in enumerate(scales)
    ]
    tc1 = np.concatenate([p.tc1 for p in pieces])
    tc2 = np.concatenate([p.tc2 for p in pieces])
    result = windowed_tau(tc1, tc2, DT, 2.0)
    np.testing.assert_allclose(result.tau1, 0.03 * np.array(scales), rtol=0.05)
    assert result.log_correlation > 0.95
    assert result.ratio_spread_pct < 3.0
    assert result.tau1_spread_pct > 20.0
    assert result.vary_together


def test_band_errors_put_a_3_hz_tone_in_its_band(rng):
    time = np.arange(20000) * DT
    measured = np.cumsum(rng.standard_normal(time.size)) * 0.05
    predicted = measured - 0.2 * np.sin(2 * np.pi * 3.0 * time)
    result = band_errors(measured, predicted, DT)
    low, high = result.peak_band_hz
    assert low <= 3.0 < high
    # Hann leakage sends a sixth of the tone's power to the 2.8 Hz bin, below the band's edge.
    assert result.residual_share[result.peak_band] > 0.8
    assert result.residual_share[result.peak_band - 1 : result.peak_band + 1].sum() > 0.97
    assert result.residual_share.sum() == pytest.approx(1.0)
    assert result.edges_hz[-1] == pytest.approx(250.0)
    assert np.all(np.diff(result.edges_hz) > 0)
    assert 6 <= result.edges_hz.size - 1 <= 8
    assert np.nanmin(result.coherence) >= 0.0


def test_band_errors_with_given_edges():
    time = np.arange(4000) * DT
    measured = np.sin(2 * np.pi * 1.0 * time) + np.sin(2 * np.pi * 20.0 * time)
    predicted = measured - 0.1 * np.sin(2 * np.pi * 20.0 * time)
    result = band_errors(measured, predicted, DT, edges_hz=[0.5, 5.0, 50.0])
    assert result.peak_band == 1
    assert result.residual_to_signal[1] == pytest.approx(0.01, rel=0.05)
    with pytest.raises(ValueError, match="increasing"):
        band_errors(measured, predicted, DT, edges_hz=[5.0, 1.0])


def test_level_errors_find_a_slope_and_nothing_in_white_noise(rng):
    n = 4000
    level = 500 + 100 * np.sin(2 * np.pi * np.arange(n) / 1000)
    noise = 0.5 * rng.standard_normal(n)
    sloped = level_errors(0.1 * level + noise, level)
    assert sloped.slope == pytest.approx(0.1, abs=0.003)
    assert sloped.slope_t > 50
    assert abs(sloped.curvature_t) < 3.5
    assert sloped.offset == pytest.approx(50.0, abs=0.1)
    assert sloped.centres.size == 10
    np.testing.assert_allclose(sloped.mean, 0.1 * sloped.centres, atol=0.1)
    flat = level_errors(noise, level)
    assert abs(flat.slope_t) < 3.5 and abs(flat.offset_t) < 3.5


def test_level_errors_are_honest_about_an_autocorrelated_residual(rng):
    n = 4000
    level = 500 + 100 * np.sin(2 * np.pi * np.arange(n) / 1000)
    result = level_errors(ar1(rng, 0.95, n), level)
    assert result.n_eff < n / 10
    white = level_errors(rng.standard_normal(n), level)
    assert white.n_eff > 0.8 * n


def test_level_t_statistics_account_for_autocorrelation():
    rng = np.random.default_rng(11)
    n, trials = 1000, 150
    level = 500 + 100 * np.sin(2 * np.pi * np.arange(n) / 300)
    honest = naive = 0
    for _ in range(trials):
        result = level_errors(ar1(rng, 0.9, n), level)
        honest += abs(result.slope_t) > 1.96
        naive += abs(result.slope_t) * np.sqrt(n / result.n_eff) > 1.96
    assert honest / trials < 0.16
    assert naive / trials > 0.4


def failing_model_record():
    """tc2 simulated from tc1 with a wrong tau2: a residual with structure."""
    pair = simulate_pair("multisine", tau1=0.03, tau2=0.12, dt=DT, duration=8.0, noise_percent=1)
    predicted = simulate_tc2_from_tc1(pair.tc1, pair.tc2[0], np.exp(-DT / 0.03), np.exp(-DT / 0.1))
    sos = signal.butter(4, 20.0, output="sos", fs=1 / DT)
    mask = np.zeros(pair.time.size, dtype=bool)
    for start in range(500, pair.time.size, 1000):
        mask[start : start + 500] = True
    return pair, predicted, sos, mask


def test_analyse_failure_reports_a_wrong_time_constant():
    pair, predicted, sos, mask = failing_model_record()
    result = analyse_failure(
        pair.time,
        pair.tc1,
        pair.tc2,
        signal.sosfiltfilt(sos, predicted),
        signal.sosfiltfilt(sos, pair.tc2),
        pair.tc2 - predicted,
        dt=DT,
        slow=2,
        mask=mask,
    )
    assert result.findings[0].startswith("residual not white")
    assert any("input rate" in finding for finding in result.findings)
    assert result.ccf_input.significant
    assert {c.name for c in result.candidates} == {
        "level",
        "level^4",
        "rate",
        "slow_rate",
        "trend",
        "drift",
    }
    text = json.dumps(result.summary(), allow_nan=False)
    assert "findings" in text


def test_analyse_failure_survives_a_perfect_model_and_checks_its_inputs():
    pair, _, _, mask = failing_model_record()
    zero = np.zeros_like(pair.tc2)
    result = analyse_failure(
        pair.time, pair.tc1, pair.tc2, pair.tc2, pair.tc2, zero, dt=DT, slow=2, mask=mask
    )
    assert result.findings[0].startswith("residual consistent with white noise")
    json.dumps(result.summary(), allow_nan=False)
    with pytest.raises(DataError, match="lengths differ"):
        analyse_failure(
            pair.time, pair.tc1, pair.tc2, pair.tc2, pair.tc2, zero[:-1], dt=DT, slow=2, mask=mask
        )
    with pytest.raises(ValueError, match="slow"):
        analyse_failure(
            pair.time, pair.tc1, pair.tc2, pair.tc2, pair.tc2, zero, dt=DT, slow=3, mask=mask
        )
