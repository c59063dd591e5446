import math

import numpy as np
import pytest
from sim_records import make_pair

from tcomp_core import DataError, reconstruct
from tcomp_core.filters import lowpass_sos, postfilter, prefilter
from tcomp_core.metrics import (
    noise_level_percent,
    reconstruction_error_percent,
    tau_error_percent,
)
from tcomp_core.models import FirstOrderLag
from tcomp_core.reconstruct import combination_weight
from tcomp_core.simulate import SIGNALS, add_noise

# --------------------------------------------------------------------------------------------
# Reconstruction
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", SIGNALS)
@pytest.mark.parametrize(
    ("tau1", "tau2", "dt"),
    [(0.0238, 0.1168, 0.002), (0.1168, 0.0238, 0.002), (0.0238, 0.1168, 0.0002)],
)
@pytest.mark.parametrize("combine", ["inverse-variance", "mean", "tc1", "tc2"])
def test_noise_free_reconstruction_is_exact(kind, tau1, tau2, dt, combine):
    pair = make_pair(kind, tau1=tau1, tau2=tau2, dt=dt, duration=2.0)
    result = reconstruct(pair.tc1, pair.tc2, dt, tau1, tau2, combine=combine)
    expected = pair.gas[:-1]
    atol = 1e-10 * np.max(np.abs(expected))
    for name in ("gas1", "gas2", "gas"):
        reconstructed = getattr(result, name)
        assert reconstructed.shape == expected.shape, name
        np.testing.assert_allclose(reconstructed, expected, rtol=0, atol=atol, err_msg=name)
    np.testing.assert_allclose(result.time, pair.time[:-1], rtol=0, atol=1e-15)
    assert result.postfilter_hz is None
    # the sensor outputs themselves are far from the gas temperature: not vacuous
    assert np.max(np.abs(pair.tc2[:-1] - expected)) > 1.0


def test_reconstruction_with_wrong_tau_is_not_exact():
    pair = make_pair("ramp", duration=2.0)
    result = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1 * 1.01, pair.tau2)
    assert np.max(np.abs(result.gas1 - pair.gas[:-1])) > 0.1
    np.testing.assert_allclose(result.gas2, pair.gas[:-1], rtol=0, atol=1e-8)


def test_reconstruction_is_the_difference_equation():
    """Eq. (7) written out: T_g(k) = (T_m(k+1) - a T_m(k)) / (1 - a)."""
    rng = np.random.default_rng(17)
    tc1, tc2 = rng.normal(300, 20, 200), rng.normal(300, 20, 200)
    result = reconstruct(tc1, tc2, 0.01, 0.05, 0.2)
    for measured, tau, got in ((tc1, 0.05, result.gas1), (tc2, 0.2, result.gas2)):
        a = math.exp(-0.01 / tau)
        expected = [(measured[k + 1] - a * measured[k]) / (1 - a) for k in range(199)]
        np.testing.assert_allclose(got, expected, rtol=1e-13)


def test_time_vector_passed_through():
    pair = make_pair("sinusoid", duration=1.0)
    time = 1000.0 + pair.time
    result = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, time=time)
    np.testing.assert_array_equal(result.time, time[:-1])
    with pytest.raises(ValueError, match="time has shape"):
        reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, time=time[:-1])


def test_reconstruct_validates_input():
    pair = make_pair("sinusoid", duration=1.0)
    bad = pair.tc1.copy()
    bad[5] = math.nan
    with pytest.raises(DataError, match="tc1: sample 5"):
        reconstruct(bad, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    with pytest.raises(DataError, match="tc1 has 500 samples but tc2 has 400"):
        reconstruct(pair.tc1, pair.tc2[:400], pair.dt, pair.tau1, pair.tau2)
    with pytest.raises(ValueError, match="tau"):
        reconstruct(pair.tc1, pair.tc2, pair.dt, -0.1, pair.tau2)
    with pytest.raises(ValueError, match="unknown combination"):
        reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, combine="median")


def noise_variance_factor(tau, dt):
    a = math.exp(-dt / tau)
    return (1 + a * a) / (1 - a) ** 2


@pytest.mark.parametrize(
    ("tau1", "tau2", "phi"),
    [(0.0238, 0.1168, 1.0), (0.0238, 0.1168, 3.0), (0.05, 0.06, 1.0), (0.1168, 0.0238, 0.5)],
)
def test_inverse_variance_weight_formula(tau1, tau2, phi):
    dt = 0.002
    a1, a2 = math.exp(-dt / tau1), math.exp(-dt / tau2)
    v1 = phi * noise_variance_factor(tau1, dt)
    v2 = noise_variance_factor(tau2, dt)
    weight = combination_weight(a1, a2, phi)
    assert weight == pytest.approx(v2 / (v1 + v2), rel=1e-14)
    pair = make_pair("sinusoid", tau1=tau1, tau2=tau2, duration=1.0)
    result = reconstruct(pair.tc1, pair.tc2, dt, tau1, tau2, phi=phi)
    assert result.weight1 == pytest.approx(weight, rel=1e-14)
    np.testing.assert_allclose(
        result.gas, weight * result.gas1 + (1 - weight) * result.gas2, rtol=1e-14
    )


def test_equal_noise_favours_faster_sensor():
    dt = 0.002
    a1, a2 = math.exp(-dt / 0.0238), math.exp(-dt / 0.1168)
    weight = combination_weight(a1, a2)
    assert 0.5 < weight < 1.0
    assert combination_weight(a2, a1) == pytest.approx(1 - weight, rel=1e-14)
    assert combination_weight(a1, a1) == pytest.approx(0.5, rel=1e-15)
    # noisier sensor 1 (φ > 1) loses weight
    assert combination_weight(a1, a2, phi=10.0) < weight
    assert combination_weight(a1, a2, combine="mean") == 0.5
    assert combination_weight(a1, a2, combine="tc1") == 1.0
    assert combination_weight(a1, a2, combine="tc2") == 0.0


@pytest.mark.parametrize(("tau1", "tau2", "phi"), [(0.0238, 0.1168, 1.0), (0.06, 0.08, 2.0)])
def test_monte_carlo_combined_variance(tau1, tau2, phi):
    """Empirical reconstruction error variances against theory, over ~60 000 samples."""
    dt = 0.002
    pair = make_pair(
        "multisine", tau1=tau1, tau2=tau2, duration=120.0, noise_percent=2.0, phi=phi, seed=31
    )
    result = reconstruct(pair.tc1, pair.tc2, dt, tau1, tau2, phi=phi)
    mean_result = reconstruct(pair.tc1, pair.tc2, dt, tau1, tau2, combine="mean")
    truth = pair.gas[:-1]
    var1 = np.var(result.gas1 - truth)
    var2 = np.var(result.gas2 - truth)
    var3 = np.var(result.gas - truth)
    var_mean = np.var(mean_result.gas - truth)
    theory1 = pair.sigma1**2 * noise_variance_factor(tau1, dt)
    theory2 = pair.sigma2**2 * noise_variance_factor(tau2, dt)
    theory3 = theory1 * theory2 / (theory1 + theory2)
    assert pair.sigma1**2 / pair.sigma2**2 == pytest.approx(phi, rel=1e-12)
    assert var1 == pytest.approx(theory1, rel=0.04)
    assert var2 == pytest.approx(theory2, rel=0.04)
    assert var3 == pytest.approx(theory3, rel=0.04)
    assert var3 < min(var1, var2)
    assert var3 < var_mean
    assert var_mean == pytest.approx(0.25 * (theory1 + theory2), rel=0.04)
    # the errors are unbiased
    assert abs(np.mean(result.gas - truth)) < 5 * math.sqrt(2 * theory3 / truth.size)


def test_postfilter_applied_to_each_reconstruction():
    pair = make_pair("sinusoid", noise_percent=2.0, seed=3, duration=2.0)
    raw = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    filtered = reconstruct(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, postfilter_hz=20.0)
    assert filtered.postfilter_hz == 20.0
    np.testing.assert_allclose(filtered.gas1, postfilter(raw.gas1, pair.dt, 20.0), rtol=1e-13)
    np.testing.assert_allclose(filtered.gas2, postfilter(raw.gas2, pair.dt, 20.0), rtol=1e-13)
    np.testing.assert_allclose(
        filtered.gas,
        raw.weight1 * filtered.gas1 + (1 - raw.weight1) * filtered.gas2,
        rtol=1e-13,
    )
    truth = pair.gas[:-1]
    interior = slice(100, -100)
    raw_error = np.std((raw.gas - truth)[interior])
    filtered_error = np.std((filtered.gas - truth)[interior])
    assert filtered_error < 0.5 * raw_error


# --------------------------------------------------------------------------------------------
# Filters
# --------------------------------------------------------------------------------------------


def sine_fit(values, t, freq):
    """Amplitude and phase of the freq component by least squares (mean removed)."""
    design = np.column_stack(
        (np.sin(2 * np.pi * freq * t), np.cos(2 * np.pi * freq * t), np.ones_like(t))
    )
    (s, c, _), *_ = np.linalg.lstsq(design, values, rcond=None)
    return math.hypot(s, c), math.atan2(c, s)


DT = 0.002
TIME = np.arange(4000) * DT
INTERIOR = slice(500, -500)


def butterworth_filtfilt_gain(freq, cutoff, order=5):
    """|H|² of a digital (bilinear, prewarped) Butterworth low-pass: forward-backward gain."""
    ratio = math.tan(math.pi * freq * DT) / math.tan(math.pi * cutoff * DT)
    return 1.0 / (1.0 + ratio ** (2 * order))


@pytest.mark.parametrize("apply", [prefilter, postfilter])
@pytest.mark.parametrize(("freq", "cutoff"), [(5.0, 50.0), (3.0, 20.0), (10.0, 100.0)])
def test_in_band_sine_unchanged(apply, freq, cutoff):
    phase0 = 0.7
    sine = 100.0 + 40.0 * np.sin(2 * np.pi * freq * TIME + phase0)
    out = apply(sine, DT, cutoff)
    amplitude, phase = sine_fit(out[INTERIOR], TIME[INTERIOR], freq)
    assert amplitude / 40.0 == pytest.approx(1.0, abs=1e-3)
    assert abs(phase - phase0) < 1e-3
    np.testing.assert_allclose(out[INTERIOR], sine[INTERIOR], rtol=0, atol=40.0 * 1e-3)


@pytest.mark.parametrize("apply", [prefilter, postfilter])
def test_zero_phase_near_cutoff(apply):
    """At half the cut-off the amplitude drops by exactly |H|² yet the phase stays at zero."""
    freq, cutoff, phase0 = 10.0, 20.0, -1.1
    sine = 40.0 * np.sin(2 * np.pi * freq * TIME + phase0)
    amplitude, phase = sine_fit(apply(sine, DT, cutoff)[INTERIOR], TIME[INTERIOR], freq)
    gain = butterworth_filtfilt_gain(freq, cutoff)
    assert amplitude / 40.0 == pytest.approx(gain, rel=1e-6)
    assert abs(phase - phase0) < 1e-4
    # a causal single pass would lag visibly
    from scipy import signal as sps

    single = sps.sosfilt(lowpass_sos(cutoff, DT, 5), sine)
    _, lagged = sine_fit(single[INTERIOR], TIME[INTERIOR], freq)
    assert abs(lagged - phase0) > 0.5


@pytest.mark.parametrize("apply", [prefilter, postfilter])
@pytest.mark.parametrize(("freq", "cutoff"), [(100.0, 20.0), (200.0, 50.0)])
def test_strong_attenuation_above_cutoff(apply, freq, cutoff):
    tone = 40.0 * np.sin(2 * np.pi * freq * TIME)
    out = apply(tone + 100.0, DT, cutoff)
    amplitude, _ = sine_fit(out[INTERIOR], TIME[INTERIOR], freq)
    assert amplitude / 40.0 < 1e-5
    np.testing.assert_allclose(out[INTERIOR], 100.0, atol=1e-3)


def test_postfilter_default_order_is_five():
    freq, cutoff = 30.0, 20.0
    tone = np.sin(2 * np.pi * freq * TIME)
    amplitude, _ = sine_fit(postfilter(tone, DT, cutoff)[INTERIOR], TIME[INTERIOR], freq)
    assert amplitude == pytest.approx(butterworth_filtfilt_gain(freq, cutoff), rel=1e-3)
    amplitude, _ = sine_fit(postfilter(tone, DT, cutoff, order=2)[INTERIOR], TIME[INTERIOR], freq)
    assert amplitude == pytest.approx(butterworth_filtfilt_gain(freq, cutoff, 2), rel=1e-3)


@pytest.mark.parametrize("apply", [prefilter, postfilter])
@pytest.mark.parametrize("cutoff", [250.0, 251.0, 1e6, 0.0, -1.0, math.nan, math.inf])
def test_cutoff_outside_band_refused(apply, cutoff):
    with pytest.raises(ValueError, match="Nyquist frequency 250 Hz"):
        apply(np.sin(TIME), DT, cutoff)


@pytest.mark.parametrize("apply", [prefilter, postfilter])
def test_filter_input_checks(apply):
    with pytest.raises(ValueError, match="too few"):
        apply(np.sin(TIME[:20]), DT, 50.0)
    bad = np.sin(TIME)
    bad[7] = math.inf
    with pytest.raises(DataError, match="sample 7"):
        apply(bad, DT, 50.0)
    with pytest.raises(DataError, match="dt"):
        apply(np.sin(TIME), 0.0, 50.0)


def test_filter_just_below_nyquist_accepted():
    out = postfilter(np.sin(2 * np.pi * 5 * TIME), DT, 249.0)
    assert np.all(np.isfinite(out))


# --------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------


def test_noise_level_percent_definition():
    rng = np.random.default_rng(5)
    signal = 300.0 + 50.0 * np.sin(2 * np.pi * 3 * TIME)
    noise = 0.7 * rng.standard_normal(2500)  # may differ in length from the signal
    expected = 100.0 * math.sqrt(np.var(noise) / np.var(signal))
    assert noise_level_percent(signal, noise) == pytest.approx(expected, rel=1e-13)
    # K is independent of the signal's mean and scales with the noise
    assert noise_level_percent(signal - 300.0, 2 * noise) == pytest.approx(2 * expected)
    with pytest.raises(ValueError, match="constant"):
        noise_level_percent(np.full(10, 3.0), noise)


@pytest.mark.parametrize(("k", "phi"), [(1.0, 1.0), (2.0, 1.0), (4.0, 2.5)])
def test_noise_level_of_simulated_noise(k, phi):
    pair = make_pair("ramp", noise_percent=k, phi=phi, seed=12, duration=20.0)
    measured1 = noise_level_percent(pair.clean1, pair.tc1 - pair.clean1)
    measured2 = noise_level_percent(pair.clean1, pair.tc2 - pair.clean2)
    assert measured1 == pytest.approx(k, rel=0.03)
    assert measured2 == pytest.approx(k / math.sqrt(phi), rel=0.03)
    assert pair.sigma1 == pytest.approx(k / 100 * np.std(pair.clean1), rel=1e-12)


def test_add_noise_refuses_bad_arguments():
    clean = np.sin(TIME)
    with pytest.raises(ValueError, match="noise_percent"):
        add_noise(clean, clean, -1.0)
    with pytest.raises(ValueError, match="phi"):
        add_noise(clean, clean, 1.0, phi=0.0)


def test_tau_error_sign_convention():
    assert tau_error_percent(0.1, 0.09) == pytest.approx(10.0)  # underestimate: positive
    assert tau_error_percent(0.1, 0.11) == pytest.approx(-10.0)  # overestimate: negative
    assert tau_error_percent(0.0238, 0.0238) == 0.0
    assert tau_error_percent(2.0, 0.0) == pytest.approx(100.0)
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="true_tau"):
            tau_error_percent(bad, 0.1)


def test_reconstruction_error_centered_and_literal():
    rng = np.random.default_rng(8)
    reference = 300.0 + 10.0 * np.sin(2 * np.pi * 4 * TIME)
    error = 0.2 * rng.standard_normal(TIME.size)
    rms_error = math.sqrt(np.mean(error**2))
    centered = reconstruction_error_percent(reference, reference + error)
    literal = reconstruction_error_percent(reference, reference + error, centered=False)
    assert centered == pytest.approx(100 * rms_error / np.std(reference), rel=1e-12)
    assert literal == pytest.approx(100 * rms_error / math.sqrt(np.mean(reference**2)), rel=1e-12)
    assert literal < centered / 20  # the 300 °C offset shrinks the literal figure
    # centred figure ignores where the scale has its zero; the literal one does not
    shifted = reconstruction_error_percent(reference + 273.15, reference + error + 273.15)
    assert shifted == pytest.approx(centered, rel=1e-10)
    shifted_literal = reconstruction_error_percent(
        reference + 273.15, reference + error + 273.15, centered=False
    )
    assert shifted_literal < literal
    # a constant bias counts fully in the error
    assert reconstruction_error_percent(reference, reference + 1.0) == pytest.approx(
        100 / np.std(reference)
    )
    assert reconstruction_error_percent(reference, reference) == 0.0


def test_reconstruction_error_refusals():
    with pytest.raises(ValueError, match="reference has 10 samples but the reconstruction has 9"):
        reconstruction_error_percent(np.arange(10.0), np.arange(9.0))
    with pytest.raises(ValueError, match="zero rms"):
        reconstruction_error_percent(np.full(10, 5.0), np.arange(10.0))
    with pytest.raises(ValueError, match="zero rms"):
        reconstruction_error_percent(np.zeros(10), np.arange(10.0), centered=False)
    assert reconstruction_error_percent(np.full(10, 5.0), np.full(10, 4.0), centered=False) == (
        pytest.approx(20.0)
    )
    bad = np.arange(10.0)
    bad[3] = math.nan
    with pytest.raises(DataError, match="reconstruction: sample 3"):
        reconstruction_error_percent(np.arange(10.0), bad)


def test_first_order_lag_respond_invert_round_trip():
    rng = np.random.default_rng(1)
    gas = rng.normal(500, 50, 300)
    sensor = FirstOrderLag(tau=0.03)
    measured = sensor.respond(gas, 0.002)
    assert measured[0] == gas[0]
    np.testing.assert_allclose(sensor.invert(measured, 0.002), gas[:-1], rtol=1e-12)
    with pytest.raises(ValueError, match="tau"):
        FirstOrderLag(tau=0.0)
