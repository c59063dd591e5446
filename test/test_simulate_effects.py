"""Continuous-time records with hidden effects: against analytic responses and limiting cases."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.interpolate import CubicSpline

from tcomp_core import simulate as simulate_module
from tcomp_core.effects import EFFECT_NAMES as LIBRARY_EFFECT_NAMES
from tcomp_core.models import FirstOrderLag
from tcomp_core.simulate import gas_signal
from tcomp_core.simulate_effects import (
    EFFECT_NAMES,
    KELVIN,
    VELOCITY_PHASE,
    _fin_response,
    _lti_response,
    _velocity_factor,
    default_effect_params,
    effect_forms,
    simulate_effect,
)

HOT = {"mean": 700.0, "amplitude": 250.0}


def clean(effect, kind="sinusoid", **kwargs):
    return simulate_effect(effect, kind, noise_percent=0.0, **kwargs)


def test_effect_names_match_the_effect_library():
    assert EFFECT_NAMES == LIBRARY_EFFECT_NAMES


def test_plain_sensors_agree_with_the_first_order_lag_on_a_midpoint_hold():
    record = clean(None, duration=2.0)
    for tau, reading in ((record.tau1, record.clean1), (record.tau2, record.clean2)):
        # Holding the gas at mid-interval makes the difference equation second order in dt;
        # its remaining O(dt²/τ) timing error is 0.17 % of the std here. Holding it at the
        # interval start (half a sample late) would miss by 9 %.
        midpoint_gas = gas_signal("sinusoid", record.time + record.dt / 2)
        expected = FirstOrderLag(tau=tau).respond(midpoint_gas, record.dt, initial=record.gas[0])
        assert np.max(np.abs(reading - expected)) < 0.002 * np.std(reading)


def test_plain_sensors_reach_the_analytic_steady_state_sinusoid():
    record = clean(None, duration=2.0)
    omega = 2 * np.pi * 10.0
    after_transient = record.time > 1.5
    for tau, reading in ((record.tau1, record.clean1), (record.tau2, record.clean2)):
        phase = np.arctan(omega * tau)
        expected = 100.0 + 50.0 * np.cos(phase) * np.sin(omega * record.time - phase)
        error = np.abs(reading - expected)[after_transient]
        assert np.max(error) < 1e-5 * 50.0


def test_a_long_multisine_is_its_tone_sum_whatever_the_blocks():
    """Summed in blocks of samples (a long record's whole tone array is hundreds of MB): each
    sample the same to the bit as the tones summed at once, across the blocks' edges."""
    time = np.arange(2 * simulate_module._MULTISINE_BLOCK + 7) * 2e-4 + 0.1
    freqs = np.geomspace(1.0, 100.0, 40)
    k = np.arange(1, 41)
    angles = 2.0 * np.pi * freqs[:, None] * time[None, :] - (np.pi * k * (k - 1) / 40)[:, None]
    tones = np.sin(angles).sum(axis=0)
    expected = 100.0 + 50.0 * tones / np.max(np.abs(tones))
    assert np.array_equal(gas_signal("multisine", time), expected)


def test_linear_response_matches_lsim():
    step, gas = 1e-4, gas_signal("multisine", np.arange(5001) * 1e-4)
    time = np.arange(gas.size) * step
    # A lag with a slow mode: (1 + 1.25 s) / ((1 + s)(1 + 0.1168 s)).
    numerator, denominator = np.array([1.25, 1.0]), np.polymul([1.0, 1.0], [0.1168, 1.0])
    _, expected, _ = signal.lsim((numerator, denominator), gas - gas[0], time)
    response = _lti_response(numerator, denominator, gas, step)
    assert np.max(np.abs(response - gas[0] - expected)) < 1e-8 * np.ptp(gas)


@pytest.mark.slow
@pytest.mark.parametrize(("tau", "tau_leg"), [(0.0238, 0.1), (0.1168, 0.3)])
def test_fin_response_follows_the_fin_transfer_function(tau, tau_leg):
    # G(s) = (1 - S)/(1 + tau s) + S/(1 + tau_p s), S = sech(mL sqrt(1 + tau s)): the steady
    # sinusoid's amplitude and phase, and unity DC gain.
    step, tau_p = 1e-4, 1.0
    time = np.arange(120_001) * step
    for hz in (0.5, 5.0):
        gas = np.sin(2 * np.pi * hz * time)
        response = _fin_response(gas, tau, tau_leg, tau_p, step)
        s = 2j * np.pi * hz
        pull = 1 / np.cosh(np.sqrt(tau_leg / tau) * np.sqrt(1 + tau * s))
        gain = (1 - pull) / (1 + tau * s) + pull / (1 + tau_p * s)
        expected = np.imag(gain * np.exp(2j * np.pi * hz * time))
        settled = time > 8.0 * tau_p
        assert np.max(np.abs(response - expected)[settled]) < 2e-3 * abs(gain)
    assert _fin_response(np.full(1000, 3.0), tau, tau_leg, tau_p, step)[-1] == pytest.approx(3.0)


def test_conduction_record_lags_plain_sensors_and_reduces_to_them_without_conduction():
    plain = clean(None, "multisine", duration=4.0)
    conducting = clean("conduction", "multisine", duration=4.0)
    legs = {"tau_leg": 1e4, "tau_p": 1.0}  # legs ~300 mL long: the supports pull by ~e^-300
    same = clean("conduction", "multisine", duration=4.0, params=legs)
    np.testing.assert_allclose(same.clean1, plain.clean1, atol=1e-9)
    np.testing.assert_allclose(same.clean2, plain.clean2, atol=1e-9)
    # The slow mode holds back a visible part of the response: far above 1 % noise.
    assert np.std(conducting.clean2 - plain.clean2) > 0.1 * np.std(plain.clean2)
    assert conducting.params == {"tau_leg": 1.7**2 * conducting.tau2, "tau_p": 1.0}


def test_prong_conduction_follows_the_lumped_transfer_function_and_its_own_kappas():
    # G(s) = [1 + κ/(1 + τp s)]/(1 + κ + τ s): steady sinusoid amplitude and phase at 10 Hz.
    record = clean("conduction", duration=8.0, form="lumped prong")
    params = record.params
    assert set(params) == {"kappa1", "kappa2", "tau_p"}
    # κ ∝ τ^⅓: the thicker, slower wire couples relatively more to its prong.
    assert params["kappa2"] / params["kappa1"] == pytest.approx(
        (record.tau2 / record.tau1) ** (1 / 3)
    )
    omega = 2 * np.pi * 10.0
    settled = record.time > 8.0 - 1.0  # many τp after the start
    for tau, kappa, reading in (
        (record.tau1, params["kappa1"], record.clean1),
        (record.tau2, params["kappa2"], record.clean2),
    ):
        s = 1j * omega
        gain = (1 + kappa / (1 + params["tau_p"] * s)) / (1 + kappa + tau * s)
        expected = 100.0 + 50.0 * abs(gain) * np.sin(omega * record.time + np.angle(gain))
        assert np.max(np.abs(reading - expected)[settled]) < 2e-3 * 50.0
    without = clean(
        "conduction", duration=2.0, form="lumped prong", params={"kappa1": 0.0, "kappa2": 0.0}
    )
    plain = clean(None, duration=2.0)
    np.testing.assert_allclose(without.clean1, plain.clean1, atol=1e-9)
    np.testing.assert_allclose(without.clean2, plain.clean2, atol=1e-9)


def test_a_warming_wall_starts_at_its_temperature_and_lets_the_radiation_error_fall():
    steady = {"mean": 800.0, "amplitude": 0.0}
    fixed = clean("radiation", duration=6.0, signal_params=steady)
    warming = clean(
        "radiation",
        duration=6.0,
        signal_params=steady,
        form="lagging wall",
        params={"wall_lag_s": 3.0},
    )
    assert warming.form == "lagging wall" and fixed.form == "constant wall"
    # At the start both see the same wall; the warming one then approaches the gas, so the
    # junctions lose less: the radiation error falls towards zero as e^(-t/3 s).
    assert warming.clean1[0] == pytest.approx(fixed.clean1[0], abs=1e-6)
    error_start = 800.0 - warming.clean2[0]
    error_end = 800.0 - warming.clean2[-1]
    assert error_start > 10.0
    assert 0.0 < error_end < 0.3 * error_start
    # A wall that never warms is the constant wall.
    frozen = clean(
        "radiation",
        duration=1.0,
        signal_params=steady,
        form="lagging wall",
        params={"wall_lag_s": 1e9},
    )
    np.testing.assert_allclose(frozen.clean2, fixed.clean2[: frozen.clean2.size], atol=1e-6)


def test_speed_steps_hold_each_speed_for_half_a_period():
    time = np.linspace(0.0, 12.0, 120_001)
    factor = _velocity_factor(time, m=1.0, depth=0.4, period_s=6.0, form="steps")
    sine = np.sin(2 * np.pi * time / 6.0 + VELOCITY_PHASE)
    away = np.abs(sine) > 0.5  # beyond the edges (about 0.03 of a period each side)
    np.testing.assert_allclose(factor[away], 1.0 + 0.4 * np.sign(sine[away]), atol=1e-6)
    record = clean("velocity", "multisine", duration=6.0, form="steps")
    sine_record = clean("velocity", "multisine", duration=6.0)
    assert record.params == sine_record.params
    assert np.max(np.abs(record.clean2 - sine_record.clean2)) > 0.01 * np.std(record.clean2)


@pytest.mark.parametrize("effect", [None, *EFFECT_NAMES])
def test_each_effect_owns_its_forms_and_the_first_is_the_default(effect):
    forms = effect_forms(effect)
    assert len(forms) == len(set(forms)) >= 1
    for form in forms:
        record = simulate_effect(effect, "exhaust", duration=0.5, dt=0.001, form=form)
        assert record.form == form
        assert record.params == default_effect_params(effect, record.tau1, record.tau2, form)
    assert simulate_effect(effect, "exhaust", duration=0.5, dt=0.001).form == forms[0]
    with pytest.raises(ValueError, match="unknown form 'other'"):
        simulate_effect(effect, duration=0.5, form="other")


def test_radiation_steady_state_solves_the_balance_and_reads_low():
    gas_c = 800.0
    record = clean("radiation", duration=1.0, signal_params={"mean": gas_c, "amplitude": 0.0})
    wall_k = record.params["wall_c"] + KELVIN
    cube = 4.0 * (gas_c + KELVIN) ** 3  # rho_i = 4 r_i T̄³ at the gas mean
    for rho, reading in (
        (record.params["rho1"], record.clean1),
        (record.params["rho2"], record.clean2),
    ):
        r = rho / cube
        temp = reading + KELVIN
        balance = gas_c + KELVIN - temp - r * (temp**4 - wall_k**4)
        assert np.max(np.abs(balance)) < 1e-8
        assert np.ptp(reading) < 1e-8
        # Hotter than the wall, the junction loses heat by radiation: tens of kelvin here.
        assert np.all(gas_c - reading > 10.0)
    assert record.clean2[0] < record.clean1[0]  # rho2 > rho1: the thicker wire reads lower


def test_radiation_defaults_use_hot_gas_and_the_stated_conductance():
    params = default_effect_params("radiation", 0.0238, 0.1168)
    assert params["rho1"] == pytest.approx(0.08)
    assert params["rho2"] / params["rho1"] == pytest.approx((0.1168 / 0.0238) ** (1 / 3))
    record = clean("radiation", duration=2.0)
    assert np.mean(record.gas) == pytest.approx(700.0, abs=5.0)
    assert np.ptp(record.gas) == pytest.approx(500.0, rel=0.01)
    assert np.mean(record.gas - record.clean1) > 10.0


@pytest.mark.parametrize("kind", ["sinusoid", "multisine"])
def test_radiation_without_radiation_is_the_plain_sensor(kind):
    plain = clean(None, kind, duration=3.0, signal_params=HOT)
    cold = clean("radiation", kind, duration=3.0, params={"rho1": 0.0, "rho2": 0.0})
    for mine, theirs in ((cold.clean1, plain.clean1), (cold.clean2, plain.clean2)):
        assert np.max(np.abs(mine - theirs)) < 1e-4 * np.std(theirs)


def test_velocity_without_velocity_dependence_is_the_plain_sensor():
    plain = clean(None, "multisine", duration=3.0)
    constant = clean("velocity", "multisine", duration=3.0, params={"m": 0.0})
    for mine, theirs in ((constant.clean1, plain.clean1), (constant.clean2, plain.clean2)):
        assert np.max(np.abs(mine - theirs)) < 1e-4 * np.std(theirs)


def _phase_lag(reading, gas, time, centre, omega, half_width=0.3):
    """Phase of the gas relative to the reading at ``omega``, over a window of whole periods."""
    window = (time >= centre - half_width) & (time < centre + half_width - 1e-9)
    carrier = np.exp(-1j * omega * time[window])
    gas_phasor = np.sum((gas[window] - np.mean(gas[window])) * carrier)
    reading_phasor = np.sum((reading[window] - np.mean(reading[window])) * carrier)
    return float(np.angle(gas_phasor / reading_phasor))


def test_velocity_lag_is_larger_where_the_flow_is_slow():
    record = clean("velocity", duration=6.0)
    omega = 2 * np.pi * 10.0
    params = record.params
    # v/v0 = 1 + 0.4 sin(2π t/6 + 0.3) peaks at t = 1.21 s and dips at t = 4.21 s.
    fast_t, slow_t = [
        (angle - VELOCITY_PHASE) * params["period_s"] / (2 * np.pi)
        for angle in (np.pi / 2, 3 * np.pi / 2)
    ]
    for tau0, reading in ((record.tau1, record.clean1), (record.tau2, record.clean2)):
        lags = []
        for centre in (fast_t, slow_t):
            lag = _phase_lag(reading, record.gas, record.time, centre, omega)
            factor = _velocity_factor(np.array([centre]), **params, form="sine")[0]
            # Quasi-static: the lag of a first-order sensor with τ(t) = τ0 / factor.
            assert lag == pytest.approx(np.arctan(omega * tau0 / factor), abs=0.01)
            lags.append(lag)
        assert lags[1] > lags[0] + 0.05


@pytest.mark.parametrize(
    ("kind", "delay_s"), [("multisine", 0.008), ("sinusoid", 0.00523), ("exhaust", 0.006)]
)
def test_delayed_junction_reads_the_first_one_delay_later(kind, delay_s):
    record = clean("delay", kind, tau2=0.0238, duration=2.0, params={"delay_s": delay_s})
    settled = record.time > 1.0  # the different starts have decayed: e^(-1/τ) < 1e-18
    # tc1 at t - δ from a cubic spline; exact (spline nodes) when δ is whole samples.
    shifted = CubicSpline(record.time, record.clean1)(record.time - delay_s)
    error = np.abs(record.clean2 - shifted)[settled]
    tolerance = 1e-4 if kind == "sinusoid" else 1e-9
    assert np.max(error) < tolerance * np.std(record.clean1)


def test_delay_is_visible_in_the_default_record():
    plain = clean(None, "multisine", duration=3.0)
    delayed = clean("delay", "multisine", duration=3.0)
    # Sensor 2 sees the same gas: the plain sensor's response, delay_s later.
    lag = round(delayed.params["delay_s"] / delayed.dt)
    np.testing.assert_allclose(delayed.clean2, plain.clean2, atol=1e-9)
    np.testing.assert_allclose(delayed.clean1[1000:-lag], plain.clean1[1000 + lag :], atol=1e-9)


def test_calibration_scales_and_offsets_sensor_two_only():
    plain = simulate_effect(None, duration=3.0, seed=5)
    record = simulate_effect("calibration", duration=3.0, seed=5)
    np.testing.assert_array_equal(record.clean1, plain.clean1)
    np.testing.assert_allclose(record.clean2, 1.03 * plain.clean2 - 4.0, atol=1e-9)
    assert record.sigma1 == record.sigma2 == plain.sigma1
    np.testing.assert_allclose(record.tc2 - record.clean2, plain.tc2 - plain.clean2, atol=1e-9)


def test_noise_ratio_sets_unequal_noise():
    record = simulate_effect("noise_ratio", duration=10.0, noise_percent=2.0, seed=3)
    assert record.sigma1 == pytest.approx(0.02 * np.std(record.clean1))
    assert record.sigma2 == pytest.approx(2.5 * record.sigma1)
    measured = np.std(record.tc2 - record.clean2) / np.std(record.tc1 - record.clean1)
    assert measured == pytest.approx(2.5, rel=0.05)


def test_same_seed_same_record_other_seed_other_noise():
    first = simulate_effect("radiation", duration=1.0, seed=7)
    again = simulate_effect("radiation", duration=1.0, seed=7)
    other = simulate_effect("radiation", duration=1.0, seed=8)
    for name in ("time", "gas", "tc1", "tc2", "clean1", "clean2"):
        np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
    np.testing.assert_array_equal(first.clean1, other.clean1)
    assert not np.allclose(first.tc1, other.tc1)
    assert not np.allclose(first.tc2, other.tc2)


@pytest.mark.parametrize("effect", [None, *EFFECT_NAMES])
def test_every_effect_gives_a_well_formed_record(effect):
    record = simulate_effect(effect, "exhaust", duration=1.0, dt=0.001)
    assert record.time.shape == record.gas.shape == record.tc1.shape == (1000,)
    assert record.effect == effect and record.kind == "exhaust"
    assert record.params == default_effect_params(effect, record.tau1, record.tau2)
    for array in (record.gas, record.tc1, record.tc2, record.clean1, record.clean2):
        assert np.all(np.isfinite(array))
    # Equilibrium at t = 0: the plain sensors start at the gas temperature.
    if effect in (None, "conduction", "velocity", "noise_ratio"):
        assert record.clean1[0] == pytest.approx(record.gas[0])


@pytest.mark.parametrize(
    ("effect", "kwargs", "match"),
    [
        ("friction", {}, "conduction, radiation"),
        ("delay", {"params": {"lag_s": 0.1}}, "'lag_s'.*delay_s"),
        (None, {"params": {"gain": 1.0}}, "'gain'"),
        ("velocity", {"params": {"depth": 1.0}}, "depth"),
        ("conduction", {"params": {"tau_p": 0.0}}, "tau_p"),
        ("conduction", {"params": {"kappa1": 0.1}}, "'kappa1'.*tau_leg"),
        ("conduction", {"form": "lumped prong", "params": {"kappa2": -0.1}}, "kappa2"),
        ("radiation", {"form": "lagging wall", "params": {"wall_lag_s": 0.0}}, "wall_lag_s"),
        (None, {"dt": 0.0}, "dt"),
        (None, {"dt": -0.001}, "dt"),
        (None, {"duration": 0.0}, "duration"),
        (None, {"duration": -1.0}, "duration"),
        (None, {"noise_percent": -1.0}, "noise_percent"),
        (None, {"oversample": 0}, "oversample"),
        (None, {"tau1": 0.0}, "tau1"),
    ],
)
def test_bad_input_is_refused(effect, kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate_effect(effect, duration=kwargs.pop("duration", 1.0), **kwargs)
