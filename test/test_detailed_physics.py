"""Tests of the independent detailed-physics simulator (test/detailed_physics.py).

Each test checks the simulator against physics written out here independently: the analytic
balance, the analytic fin, an adaptive ODE solver on the same node equations, the advection
integral done by quadrature.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from detailed_physics import (
    KELVIN,
    STEFAN_BOLTZMANN,
    Rig,
    Wire,
    heat_transfer_coefficient,
    junction_time_constant,
    make_gas,
    simulate_rig,
    speed_at,
)
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq, fsolve
from scipy.signal import periodogram

ONE_MINUS_E = 1.0 - math.exp(-1.0)


def _rise_time(time, values, low, high, t_step):
    """Time after ``t_step`` at which a rising response crosses 63.2 % of low -> high."""
    level = low + ONE_MINUS_E * (high - low)
    i = int(np.argmax(values >= level))
    assert i > 0 and values[i - 1] < level
    frac = (level - values[i - 1]) / (values[i] - values[i - 1])
    return time[i - 1] + frac * (time[i] - time[i - 1]) - t_step


def _step_tau(wire, low, high, speed=4.0, **kwargs):
    rig = Rig(
        signal="step",
        gas_low_c=low,
        gas_high_c=high,
        duration_s=0.4,
        rate_hz=20000.0,
        warmup_s=0.02,
        speed_m_s=speed,
        wires=(wire, wire),
        **kwargs,
    )
    rec = simulate_rig(rig)
    return _rise_time(rec.time, rec.junction1, low, high, rec.truth["step_time_s"]), rec


@pytest.mark.parametrize(
    "wire",
    [Wire(25e-6), Wire(50e-6), Wire(75e-6, bead_factor=2.0, junction_shape="sphere")],
    ids=["25um", "50um", "75um-sphere"],
)
def test_step_response_63_percent_time_is_truth_tau(wire):
    measured, rec = _step_tau(wire, 20.0, 80.0, frozen_gas_properties=True)
    assert measured == pytest.approx(rec.truth["tau1"], rel=0.01)
    assert rec.truth["tau1_eff"] == pytest.approx(rec.truth["tau1"], rel=1e-9)  # no rad., cond.


def test_time_constant_follows_speed_as_the_correlation_says():
    wire = Wire(50e-6)
    slow, _ = _step_tau(wire, 20.0, 21.0, speed=2.0)
    fast, _ = _step_tau(wire, 20.0, 21.0, speed=8.0)
    predicted = junction_time_constant(wire, 20.5, 8.0) / junction_time_constant(wire, 20.5, 2.0)
    assert predicted < 0.6
    assert fast / slow == pytest.approx(predicted, rel=0.003)


def test_film_temperature_dependence_of_tau():
    wire = Wire(50e-6)
    tau20, _ = _step_tau(wire, 19.5, 20.5)
    tau80, _ = _step_tau(wire, 79.5, 80.5)
    predicted = junction_time_constant(wire, 80.0, 4.0) / junction_time_constant(wire, 20.0, 4.0)
    assert abs(predicted - 1.0) > 0.02  # the correlation implies a visible change
    assert (tau80 / tau20 - 1.0) * (predicted - 1.0) > 0.0
    assert tau80 / tau20 == pytest.approx(predicted, rel=0.003)
    # Frozen gas properties (and a constant heat capacity): τ no longer depends on the level.
    flat = Wire(50e-6, cp_slope_j_kg_k2=0.0)
    frozen = {"frozen_gas_properties": True, "property_reference_c": 50.0}
    tau20f, _ = _step_tau(flat, 19.5, 20.5, **frozen)
    tau80f, _ = _step_tau(flat, 79.5, 80.5, **frozen)
    assert tau80f / tau20f == pytest.approx(1.0, abs=1e-3)


def test_steady_radiation_error_matches_the_analytic_balance():
    wires = (Wire(50e-6, emissivity=0.8), Wire(125e-6, emissivity=0.3))
    gas_c, wall_c, speed = 700.0, 20.0, 5.0
    rig = Rig(
        signal="step",
        gas_low_c=gas_c,
        gas_high_c=gas_c,
        wires=wires,
        wall_c=wall_c,
        speed_m_s=speed,
        duration_s=0.05,
        warmup_s=0.2,
    )
    rec = simulate_rig(rig)
    tg, tw = gas_c + KELVIN, wall_c + KELVIN
    for wire, junction in zip(wires, (rec.junction1, rec.junction2), strict=True):

        def balance(tj, wire=wire):
            h = heat_transfer_coefficient(
                wire.bead_diameter_m, speed, tg, tj, rig.pressure_pa, wire.junction_shape
            )
            return h * (tg - tj) - wire.emissivity * STEFAN_BOLTZMANN * (tj**4 - tw**4)

        expected = tg - brentq(balance, tw, tg)
        simulated = gas_c - junction
        assert expected > 2.0
        assert np.ptp(simulated) < 1e-6  # settled
        assert simulated[-1] == pytest.approx(expected, rel=0.005)


def _fin_junction_error(wire, gas_k, support_k, junction_k, speed, pressure):
    """Analytic steady junction error of a lumped junction on two fin legs to fixed supports."""
    h_j = heat_transfer_coefficient(
        wire.bead_diameter_m, speed, gas_k, junction_k, pressure, wire.junction_shape
    )
    h_w = heat_transfer_coefficient(wire.diameter_m, speed, gas_k, junction_k, pressure)
    k, d = wire.conductivity_w_m_k, wire.diameter_m
    m = math.sqrt(4.0 * h_w / (k * d))
    ml = m * wire.length_m
    kam = k * math.pi * d * d / 4.0 * m
    if wire.junction_shape == "sphere":
        area = math.pi * wire.bead_diameter_m**2
    else:
        area = math.pi * wire.bead_diameter_m * wire.bead_diameter_m
    theta_s = support_k - gas_k
    return 2.0 * kam / math.sinh(ml) * theta_s / (h_j * area + 2.0 * kam / math.tanh(ml))


@pytest.mark.parametrize(
    "wires",
    [
        (Wire(50e-6), Wire(100e-6, bead_factor=2.0, junction_shape="sphere", length_m=2e-3)),
        (Wire(125e-6, length_m=0.5e-3), Wire(25e-6, length_m=2e-3)),  # mL 0.4 and 6
    ],
    ids=["50um-100um_sphere", "125um_short-25um_long"],
)
def test_steady_conduction_error_matches_the_analytic_fin(wires):
    gas_c, support_c, speed = 80.0, 20.0, 3.0
    rig = Rig(
        signal="step",
        gas_low_c=gas_c,
        gas_high_c=gas_c,
        wires=wires,
        conduction=True,
        support_c=support_c,
        speed_m_s=speed,
        duration_s=0.05,
        warmup_s=0.2,
    )
    rec = simulate_rig(rig)
    for i, (wire, junction) in enumerate(zip(wires, (rec.junction1, rec.junction2), strict=True)):
        simulated = junction[-1] - gas_c
        expected = _fin_junction_error(
            wire, gas_c + KELVIN, support_c + KELVIN, junction[-1] + KELVIN, speed, rig.pressure_pa
        )
        assert expected < -0.1  # a real conduction error
        assert np.ptp(junction) < 1e-6
        assert simulated == pytest.approx(expected, rel=0.02)
        # The truth's band gain is the same fin solution (properties at the gas temperature).
        assert simulated == pytest.approx(
            -(1.0 - rec.truth[f"gain{i + 1}"]) * (gas_c - support_c), rel=0.02
        )


def _reference_rhs(rig, wire, gas_fn, c_ref):
    """Right-hand side of the documented node equations, for an adaptive ODE solver."""
    rho, eps_sigma = wire.density_kg_m3, wire.emissivity * STEFAN_BOLTZMANN
    vol_j, area_j = wire.junction_geometry()
    tw = rig.wall_c + KELVIN
    d, n = wire.diameter_m, wire.fin_nodes
    area_w, dx = math.pi * d * d / 4.0, wire.length_m / n
    g = wire.conductivity_w_m_k * area_w / dx
    cap_leg = rho * c_ref * area_w * dx

    def rhs(t, x):
        tg = float(gas_fn(np.array([t]))[0]) + KELVIN
        u = float(speed_at(rig, t))
        tj = x[0]
        c_j = float(wire.specific_heat(tj))
        h_j = float(
            heat_transfer_coefficient(
                wire.bead_diameter_m, u, tg, tj, rig.pressure_pa, wire.junction_shape
            )
        )
        rad = eps_sigma * (tj**4 - tw**4)
        dx_dt = np.empty_like(x)
        dx_dt[0] = area_j * (h_j * (tg - tj) - rad) / (rho * c_j * vol_j)
        if x.size == 1:
            return dx_dt
        h_w = float(heat_transfer_coefficient(d, u, tg, tj, rig.pressure_pa))
        dx_dt[0] += 2.0 * (2.0 * g) * (x[1] - tj) / (rho * c_j * vol_j)
        legs = x[1:]
        left = np.concatenate(([tj], legs[:-1]))
        right = np.concatenate((legs[1:], [rig.support_c + KELVIN]))
        g_left = np.full(n, g)
        g_left[0] = 2.0 * g
        g_right = np.full(n, g)
        g_right[-1] = 2.0 * g
        flux = g_left * (left - legs) + g_right * (right - legs)
        surface = math.pi * d * dx
        rad_leg = eps_sigma * (tj**4 + 4.0 * tj**3 * (legs - tj) - tw**4)
        flux += surface * (h_w * (tg - legs) - rad_leg)
        dx_dt[1:] = flux / cap_leg
        return dx_dt

    return rhs


@pytest.mark.slow
@pytest.mark.parametrize("conduction", [False, True], ids=["junction", "fin"])
def test_integrator_matches_an_adaptive_ode_solver(conduction):
    wires = (Wire(25e-6, emissivity=0.6, fin_nodes=12), Wire(50e-6, emissivity=0.6, fin_nodes=6))
    rig = Rig(
        signal="rotating_disk",
        duration_s=0.15,
        rate_hz=4000.0,
        warmup_s=0.15,
        wires=wires,
        speed_m_s=3.0,
        speed_fluctuation=0.3,
        speed_period_s=0.07,
        wall_c=20.0,
        conduction=conduction,
        support_c=35.0,
        seed=3,
    )
    rec = simulate_rig(rig)
    gas_fn = make_gas(rig)
    pairs = zip(wires, (rec.junction1, rec.junction2), (rec.gas, rec.gas2), strict=True)
    for wire, junction, gas in pairs:
        c_ref = float(wire.specific_heat(np.mean(gas) + KELVIN))
        rhs = _reference_rhs(rig, wire, gas_fn, c_ref)
        # The simulator starts the warm-up at rest: the steady state of the node equations.
        start = -math.ceil(rig.warmup_s * rig.rate_hz) / rig.rate_hz
        guess = np.full(1 + (wire.fin_nodes if conduction else 0), gas_fn(np.array([start]))[0])
        x0 = fsolve(lambda x, rhs=rhs, start=start: rhs(start, x), guess + KELVIN, xtol=1e-13)
        assert np.max(np.abs(rhs(start, x0))) < 1e-6
        sol = solve_ivp(
            rhs,
            (start, rec.time[-1]),
            x0,
            method="Radau" if conduction else "DOP853",
            t_eval=rec.time,
            rtol=1e-9,
            atol=1e-7,
            max_step=2e-4,
        )
        assert sol.success
        reference = sol.y[0] - KELVIN
        assert np.ptp(reference) > 20.0
        assert np.max(np.abs(junction - reference)) < 1e-4  # second order: 1e-5 K here


def test_transport_delay_is_spacing_over_speed():
    rig = Rig(duration_s=2.0, rate_hz=10000.0, spacing_m=4e-3, speed_m_s=4.0, warmup_s=0.05)
    rec = simulate_rig(rig)
    assert rec.truth["delay_s"] == pytest.approx(1e-3)
    a = rec.gas - rec.gas.mean()
    b = rec.gas2 - rec.gas2.mean()
    lags = np.arange(-30, 31)
    corr = [np.dot(a[30 : a.size - 30], b[30 + lag : b.size - 30 + lag]) for lag in lags]
    assert abs(lags[int(np.argmax(corr))] - 10) <= 1


def test_advection_with_varying_speed_uses_the_travel_integral():
    rig = Rig(
        duration_s=0.3,
        rate_hz=2000.0,
        spacing_m=0.02,
        speed_m_s=2.0,
        speed_fluctuation=0.4,
        speed_period_s=0.05,
        warmup_s=0.05,
    )
    rec = simulate_rig(rig)
    gas_fn = make_gas(rig)
    naive_gap = 0.0
    for k in range(50, rec.time.size, 23):
        t = rec.time[k]

        def travelled(tp, t=t):
            return quad(lambda x: float(speed_at(rig, x)), tp, t, epsabs=1e-13)[0] - 0.02

        t_up = brentq(travelled, t - 0.05, t, xtol=1e-13)
        assert rec.gas2[k] == pytest.approx(float(gas_fn(np.array([t_up]))[0]), abs=1e-6)
        naive = float(gas_fn(np.array([t - 0.02 / rig.speed_m_s]))[0])
        naive_gap = max(naive_gap, abs(naive - rec.gas2[k]))
    assert naive_gap > 1.0  # a constant delay would not do


def test_adc_output_lies_on_the_step_grid():
    rig = Rig(
        duration_s=1.0,
        adc_bits=16,
        noise_c=(0.05, 0.02),
        warmup_s=0.05,
    )
    rec = simulate_rig(rig)
    lo, hi = rig.adc_range_c
    step = (hi - lo) / 2**16
    assert rec.truth["adc_step_c"] == pytest.approx(step)
    for tc, junction in ((rec.tc1, rec.junction1), (rec.tc2, rec.junction2)):
        codes = (tc - lo) / step
        assert np.max(np.abs(codes - np.round(codes))) < 1e-6
        assert np.unique(tc).size > 20
        assert np.max(np.abs(tc - junction)) < 0.5


def test_mains_line_on_the_chosen_channel_only():
    rig = Rig(
        signal="step",
        gas_low_c=50.0,
        gas_high_c=50.0,
        duration_s=2.0,
        rate_hz=2000.0,
        noise_c=(0.02, 0.02),
        mains_hz=50.0,
        mains_amplitude_c=0.2,
        mains_channel=2,
        warmup_s=0.05,
    )
    rec = simulate_rig(rig)
    freq, p1 = periodogram(rec.tc1, fs=rig.rate_hz)
    _, p2 = periodogram(rec.tc2, fs=rig.rate_hz)
    line = int(np.argmin(np.abs(freq - 50.0)))
    third = int(np.argmin(np.abs(freq - 150.0)))
    floor1, floor2 = np.median(p1[1:]), np.median(p2[1:])
    assert p2[line] > 1e3 * floor2
    assert p2[third] > 1e2 * floor2
    assert p1[line] < 30.0 * floor1
    assert np.std(rec.tc2 - rec.junction2) == pytest.approx(
        math.sqrt(0.2**2 / 2 * (1 + 0.3**2 + 0.1**2) + 0.02**2), rel=0.05
    )


def test_calibration_and_noise_on_the_chosen_channels():
    rig = Rig(
        duration_s=1.0,
        calibration=(1, 1.02, -0.5),
        noise_c=(0.0, 0.1),
        warmup_s=0.05,
    )
    rec = simulate_rig(rig)
    np.testing.assert_allclose(rec.tc1, 1.02 * rec.junction1 - 0.5, atol=1e-12)
    assert np.std(rec.tc2 - rec.junction2) == pytest.approx(0.1, rel=0.05)
    assert rec.truth["gain"] == pytest.approx(1 / 1.02)
    assert rec.truth["offset_c"] == pytest.approx(0.5 / 1.02)


def _spectrum_peak(values, rate, fmin):
    freq, power = periodogram(values - values.mean(), fs=rate)
    keep = freq > fmin
    return freq[keep][int(np.argmax(power[keep]))]


def test_rotating_disk_signal():
    rig = Rig(signal="rotating_disk", duration_s=4.0, seed=5)
    t = np.arange(0.0, 4.0, 1.0 / 2000.0)
    gas = make_gas(rig)(t)
    assert _spectrum_peak(gas, 2000.0, 1.0) == pytest.approx(10.0, abs=0.5)
    assert np.percentile(gas, 1) == pytest.approx(20.0, abs=2.0)
    assert np.percentile(gas, 99) == pytest.approx(80.0, abs=2.0)
    # Finite-width transitions: 60 °C in about 5 ms at the steepest.
    assert 5e3 < np.max(np.abs(np.diff(gas))) * 2000.0 < 2e4
    assert not np.array_equal(gas, make_gas(Rig(signal="rotating_disk", seed=6))(t))


def test_engine_pulses_signal():
    rig = Rig(signal="engine_pulses", duration_s=4.0, seed=2)
    t = np.arange(0.0, 4.0, 1.0 / 2000.0)
    gas = make_gas(rig)(t)
    assert _spectrum_peak(gas, 2000.0, 5.0) == pytest.approx(40.0, abs=1.0)
    assert 380.0 < np.percentile(gas, 1) < 500.0
    assert 540.0 < np.percentile(gas, 99) < 720.0


def test_step_ramp_signal():
    rig = Rig(signal="step_ramp", duration_s=20.0, seed=1)
    t = np.arange(0.0, 20.0, 1.0 / 500.0)
    gas = make_gas(rig)(t)
    assert gas.min() > 15.0
    assert gas.max() < 305.0
    assert np.std(gas) > 30.0


@pytest.mark.parametrize("support_lag", [30.0, 0.3])
def test_support_lag_gives_a_band_gain_and_unit_dc_gain(support_lag):
    rig = Rig(
        signal="step",
        duration_s=4.0,
        rate_hz=1000.0,
        conduction=True,
        support_lag_s=support_lag,
        wires=(Wire(50e-6), Wire(125e-6)),
        warmup_s=0.05,
    )
    rec = simulate_rig(rig)
    assert rec.truth["tau_p"] == support_lag
    t_step = rec.truth["step_time_s"]
    # The support starts at the record's mean gas temperature and lags the gas.
    mean_gas = rec.truth["mean_gas_c"]
    before = 20.0 + (mean_gas - 20.0) * math.exp(-(t_step + 0.05) / support_lag)
    for i, junction in ((1, rec.junction1), (2, rec.junction2)):
        gain = rec.truth[f"gain{i}"]
        assert gain < 0.9
        if support_lag > 10.0:  # quasi-static band response: a fraction 1 - g of gas - support
            k = int(np.searchsorted(rec.time, t_step + 0.4))
            support = 80.0 - (80.0 - before) * math.exp(-0.4 / support_lag)
            expected = -(1.0 - gain) * (80.0 - support)
            assert junction[k] - 80.0 == pytest.approx(expected, rel=0.02)
        else:  # DC gain 1: the support catches up, the error shrinks with its lag
            support_error = 60.0 * math.exp(-(rec.time[-1] - t_step) / support_lag)
            assert -support_error < junction[-1] - 80.0 < -0.1 * support_error


def test_wall_lag_follows_the_mean_gas():
    rig = Rig(duration_s=2.0, wall_c=None, wires=(Wire(50e-6, emissivity=0.5), Wire(100e-6)))
    rec = simulate_rig(rig)
    assert rec.truth["wall_c"] == pytest.approx(rec.truth["mean_gas_c"], abs=0.3)
    assert rec.truth["rho1"] > 0.0
    assert rec.truth["rho2"] == 0.0
