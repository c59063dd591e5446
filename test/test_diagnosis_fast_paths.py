"""The diagnosis's faster paths give what the straightforward computations give, bit for bit.

Each fast path (cached filter designs and decays, a scalar steady state, the fit's chain memo,
the companion matrix of the fin filter's zeros) is compared with a plain reference written
here the way the code computed it before: equality, not closeness, because a fit's optimiser
turns the last bit of a residual into a different path.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from tcomp_core.effects import Model, make_context
from tcomp_core.effects.base import KELVIN
from tcomp_core.effects.chain import (
    CascadeFilter,
    SensorChain,
    _fin_filters,
    _quadratics,
    gas_from_reading,
)
from tcomp_core.effects.conduction import _roots, fin_filter, fin_sech
from tcomp_core.effects.interference import HARMONICS, interference_line
from tcomp_core.effects.model import _ChainMemo, _film_filter


def _fin_filter_reference(tau, fin_ml, tau_p, terms=6):
    """The fin filter's zeros and poles by ``np.convolve`` and ``np.roots``."""
    n = np.arange(1, terms + 1)
    a = 4.0 * fin_ml**2 / ((2 * n - 1) ** 2 * math.pi**2)
    tau_n = tau * a / (1.0 + a)
    tail = max(tau * 0.5 * fin_ml * math.tanh(fin_ml) - float(tau_n.sum()), 1e-12 * tau)
    lags = np.array([tau_p, *tau_n, tail])
    numerator = np.array([1.0])
    for lag in lags:
        numerator = np.convolve(numerator, [lag, 1.0])
    numerator[-2] -= (tau_p - tau) * fin_sech(fin_ml)
    zeros = np.roots(numerator).astype(np.complex128)
    zeros = np.where(zeros.real > 0.0, -zeros.conj(), zeros)
    return zeros, (-1.0 / lags).astype(np.complex128)


def _steady_state_reference(sos, value):
    b0, b1, b2, _, a1, a2 = sos.T
    zi = np.empty((sos.shape[0], 2))
    x = value
    for i in range(sos.shape[0]):
        y = x * (b0[i] + b1[i] + b2[i]) / (1.0 + a1[i] + a2[i])
        zi[i] = (y - b0[i] * x, b2[i] * x - a2[i] * y)
        x = y
    return zi


def _random_fins(count, seed):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        tau = float(10 ** rng.uniform(-4, 0))
        yield tau, float(rng.uniform(0.3, 9.0)), float(tau * 10 ** rng.uniform(-0.5, 2))


def test_fin_filter_equals_the_convolution_and_numpy_roots():
    for tau, fin_ml, tau_p in [*_random_fins(3000, 1), (0.01, 0.4, 0.02), (0.01, 800.0, 1.0)]:
        zeros, poles = fin_filter.__wrapped__(tau, fin_ml, tau_p)
        ref_zeros, ref_poles = _fin_filter_reference(tau, fin_ml, tau_p)
        assert np.array_equal(zeros, ref_zeros)
        assert np.array_equal(poles, ref_poles)


def test_roots_of_the_companion_matrix_are_numpys():
    rng = np.random.default_rng(3)
    for _ in range(200):
        coefficients = np.poly(-1.0 / rng.uniform(1e-3, 2.0, 8))
        coefficients[-2] -= rng.uniform(0.0, 1.0)
        assert np.array_equal(_roots(coefficients.tolist()), np.roots(coefficients))
    for coefficients in ([0.0, 1.0, 2.0], [1.0, 2.0, 0.0], [3.0]):
        assert np.array_equal(_roots(coefficients), np.roots(coefficients))


def _quadratics_reference(roots):
    """The sections' quadratics by numpy scalars and arrays."""
    tolerance = 1e-9 * max(1.0, float(np.max(np.abs(roots))))
    upper = roots[roots.imag > tolerance]
    real = np.sort(roots.real[np.abs(roots.imag) <= tolerance])[::-1]
    quads = [(abs(r), 1.0, -2.0 * r.real, abs(r) ** 2) for r in upper]
    quads += [
        (max(abs(p), abs(q)), 1.0, -(p + q), p * q)
        for p, q in zip(real[::2], real[1::2], strict=True)
    ]
    quads.sort(key=lambda quad: -quad[0])
    return np.array([quad[1:] for quad in quads])


def test_quadratics_equal_the_numpy_computation():
    rng = np.random.default_rng(4)
    for tau, fin_ml, tau_p in _random_fins(2000, 6):
        k = 2.0 / float(10 ** rng.uniform(-5, -2))
        for roots in fin_filter.__wrapped__(tau, fin_ml, tau_p):
            discrete = (k + roots) / (k - roots)
            assert np.array_equal(_quadratics(discrete), _quadratics_reference(discrete))


def test_cached_fin_filters_and_their_steady_start_are_the_designs_and_scipys_sosfilt():
    rng = np.random.default_rng(5)
    values = 400.0 + rng.standard_normal(3000).cumsum()
    dt = 2e-4
    for tau, fin_ml, tau_p in _random_fins(40, 2):
        zeros, poles = _fin_filter_reference(tau, fin_ml, tau_p)
        forward, inverse = _fin_filters(tau, fin_ml, tau_p, dt)
        for found, expected in (
            (forward, CascadeFilter.from_zeros_poles(zeros, poles, dt)),
            (inverse, CascadeFilter.from_zeros_poles(poles, zeros, dt)),
        ):
            assert np.array_equal(found.sos, expected.sos)
            zi = _steady_state_reference(expected.sos, values[0])
            assert np.array_equal(found.steady_state(values[0]), zi)
            assert np.array_equal(found(values), signal.sosfilt(expected.sos, values, zi=zi)[0])


def test_quadratics_pair_conjugates_and_sort_slow_first():
    roots = np.array([0.5 + 0.2j, 0.5 - 0.2j, 0.9, 0.1, -0.3, 0.7])
    quads = _quadratics(roots)
    assert quads.shape == (3, 3)
    # Largest root first: (0.9, 0.7), then the pair of modulus 0.539, then (0.1, -0.3).
    assert quads[0].tolist() == [1.0, -(0.9 + 0.7), 0.9 * 0.7]
    assert quads[2].tolist() == [1.0, -(0.1 + -0.3), 0.1 * -0.3]


def _record(n=2400, seed=11):
    rng = np.random.default_rng(seed)
    dt = 1e-3
    time = dt * np.arange(n)
    gas = 500.0 + 150.0 * np.sin(2 * np.pi * 1.3 * time) + 40.0 * np.sin(2 * np.pi * 7.0 * time)
    tc1 = gas + 0.2 * rng.standard_normal(n)
    tc2 = np.convolve(gas, np.full(20, 1 / 20), mode="same") + 0.2 * rng.standard_normal(n)
    return time, tc1, tc2, dt


PARAMS = {
    (): {},
    ("conduction",): {"tau_leg": 0.3, "tau_p": 0.9, "mode1": 0.4, "mode2": -0.2},
    ("delay",): {"delay_s": 1.7e-3},
    ("calibration",): {"gain": 1.01, "offset_c": 0.3},
    ("radiation",): {"rho1": 0.02, "rho2": 0.04, "wall_c": 30.0},
    ("property",): {"property_exponent": 0.4},
    ("interference",): {
        "interference_hz": 50.0,
        "interference_channel": 2.0,
        "interference_a1": 0.3,
        "interference_b1": -0.1,
        "interference_a3": 0.05,
        "interference_b3": 0.0,
        "interference_a5": 0.01,
        "interference_b5": 0.02,
    },
    ("delay", "conduction"): {
        "delay_s": -0.6e-3,
        "tau_leg": 0.4,
        "tau_p": 1.5,
        "mode1": 0.0,
        "mode2": 0.3,
    },
}


def _chains_reference(model, context, params):
    """The chains built by one ``dataclasses.replace`` per stage, as the model did."""
    chains = []
    for sensor in (1, 2):
        chain = SensorChain(tau=params[f"tau{sensor}"])
        if sensor == 2 and model.has_level and params.get("level_c", 0.0):
            chain = replace(chain, offset=params["level_c"])
        for effect in model.instances:
            additive = effect.additive(sensor, params, context)
            if additive is not None:
                chain = replace(chain, additive=additive)
            gain, offset = effect.calibration(sensor, params)
            if (gain, offset) != (1.0, 0.0):
                chain = replace(chain, gain=gain, offset=offset)
            conduction = effect.conduction(sensor, params)
            if conduction is not None:
                fin_ml, tau_p, mode0 = conduction
                chain = replace(chain, fin_ml=fin_ml, tau_p=tau_p, mode0=mode0)
            exponent = effect.level_exponent(params)
            if exponent is not None:
                chain = replace(
                    chain,
                    level_exponent=exponent,
                    level_ref_k=context.level_mean_c + KELVIN,
                    level_weight=effect.level_weights(params)[0],
                    film_weight=effect.level_weights(params)[1],
                    film_sos=_film_filter(context.dt, context.film_cutoff_hz),
                )
            radiation = effect.radiation(sensor, params, context)
            if radiation is not None:
                chain = replace(chain, r=radiation[0], wall_k=radiation[1])
            if sensor == 2 and effect.delay_s(params):
                chain = replace(chain, delay_s=effect.delay_s(params))
        chains.append(chain)
    return tuple(chains)


@pytest.mark.parametrize("effects", list(PARAMS))
def test_chains_and_memoised_residuals_equal_fresh_ones(effects):
    time, tc1, tc2, dt = _record()
    context = make_context(time, tc1, tc2, dt, film_cutoff_hz=30.0, base_taus_s=(0.002, 0.01))
    params = {"tau1": 0.002, "tau2": 0.01, "level_c": 0.2, **PARAMS[effects]}
    model = Model(effects, params)
    assert model.chains(context) == _chains_reference(model, context, params)
    # Residuals through one memo, the parameters moved one at a time and back, as a Jacobian
    # moves them, equal residuals computed afresh.
    memo = _ChainMemo()
    for name in [None, *params, None]:
        moved = dict(params)
        if name is not None:
            moved[name] = params[name] * (1.0 + 1e-7) + 1e-9
        found = model.cross_residual(tc1, tc2, context, moved, memo)
        fresh = model.cross_residual(tc1, tc2, context, moved, _ChainMemo())
        first, second = _chains_reference(model, context, moved)
        gas1, gain1 = gas_from_reading(first, tc1, dt)
        gas2, gain2 = gas_from_reading(second, tc2, dt)
        expected = (gas1 - gas2) / (context.sigma2 * np.sqrt(model.phi * gain1 + gain2))
        assert np.array_equal(found, fresh, equal_nan=True)
        assert np.array_equal(found, expected, equal_nan=True)


def test_interference_line_equals_the_sum_of_its_harmonics():
    rng = np.random.default_rng(8)
    time = 1e-3 * np.arange(5000)
    for _ in range(20):
        params = {"interference_hz": float(rng.uniform(1.0, 400.0))}
        params.update(
            {f"interference_{p}{h}": float(rng.normal()) for h in HARMONICS for p in "ab"}
        )
        phase = 2.0 * np.pi * params["interference_hz"] * time
        expected = np.zeros(time.size)
        for h in HARMONICS:
            expected += params[f"interference_a{h}"] * np.cos(h * phase)
            expected += params[f"interference_b{h}"] * np.sin(h * phase)
        assert np.array_equal(interference_line(params, time), expected)


def test_the_memo_keys_arrays_by_identity_and_everything_else_by_value():
    from dataclasses import fields

    from tcomp_core.effects.model import _ARRAY_FIELDS

    names = [f.name for f in fields(SensorChain)]
    arrays = {name for name in names if "NDArray" in str(SensorChain.__annotations__[name])}
    assert {names[i] for i in _ARRAY_FIELDS} == arrays
    factor = np.ones(10)
    chain = SensorChain(tau=0.1, factor=factor)
    same = SensorChain(tau=0.1, factor=factor)
    copied = SensorChain(tau=0.1, factor=factor.copy())
    assert _ChainMemo._key(chain) == _ChainMemo._key(same)
    assert _ChainMemo._key(chain) != _ChainMemo._key(copied)
    assert _ChainMemo._key(chain) != _ChainMemo._key(replace(chain, tau=0.1 + 1e-15))


def _lag_loop_reference(drive, a, start, r, wall4, level=None):
    out = [start]
    y = start
    films = (drive if level is None else level[2]).tolist()
    for u, pole, film_u in zip(drive.tolist(), a.tolist(), films, strict=True):
        kelvin = y + KELVIN
        if level is not None:  # T̄ + c (T − T̄) + w (Tg − T), Tg = film_u + K
            film = (
                level[1] + level[4] * (kelvin - level[1]) + level[3] * (film_u + KELVIN - kelvin)
            )
            ratio = min(max(film / level[1], 0.5), 2.0)
            pole = pole ** (1.0 / ratio ** level[0])
        loss = r * (kelvin**4 - wall4) if r else 0.0
        y = pole * y + (1.0 - pole) * (u - loss)
        out.append(y)
    return np.asarray(out)


@pytest.mark.parametrize("r", [0.0, 3e-13])
@pytest.mark.parametrize("weights", [None, (0.5, 1.0), (0.0, 1.0), (0.5, 0.0)])
def test_lag_loop_equals_the_one_loop_for_every_case(r, weights):
    from tcomp_core.effects.chain import _lag_loop

    rng = np.random.default_rng(9)
    drive = 600.0 + 300.0 * rng.standard_normal(3000).cumsum() / 50.0
    drive[::97] = -400.0  # films below half the reference: the clip at 0.5
    drive[::89] = 4000.0  # and above twice: the clip at 2
    film = drive + rng.standard_normal(drive.size)
    level = None if weights is None else (0.4, 873.0, film, *weights)
    varying = np.exp(-1e-3 / rng.uniform(0.01, 0.05, drive.size))
    constant = np.exp(-1e-3 / (0.03 * np.ones(drive.size)))  # as SensorChain.poles gives it
    for a in (varying, constant):
        found = _lag_loop(drive, a, 612.5, r, 300.0**4, level)
        expected = _lag_loop_reference(drive, a, 612.5, r, 300.0**4, level)
        if level is None:
            assert np.array_equal(found, expected)
        else:  # the film temperature's sum may round differently
            np.testing.assert_allclose(found, expected, rtol=1e-12, atol=1e-9)


def test_velocity_penalty_is_the_second_difference_of_numpy():
    from tcomp_core.effects.velocity import Velocity

    rng = np.random.default_rng(13)
    params = {f"velocity_{j}": float(rng.normal()) for j in range(1, 12)}
    params["velocity_smoothness"] = 0.05
    coefficients = np.array([0.0, *(params[f"velocity_{j}"] for j in range(1, 12))])
    expected = 0.05 * np.sqrt(1500) * np.diff(coefficients, 2)
    assert np.array_equal(Velocity().penalty(params, 1500), expected)


def test_sections_from_quadratics_equal_the_array_expressions():
    rng = np.random.default_rng(21)
    for _ in range(5000):
        count = int(rng.integers(1, 6))
        numerators = np.column_stack((np.ones(count), rng.normal(size=(count, 2))))
        denominators = np.column_stack((np.ones(count), rng.normal(size=(count, 2))))
        numerators[:, 1:] *= 10 ** rng.uniform(-3, 2, (count, 2))
        expected = np.hstack((numerators, denominators))
        expected[0, :3] /= np.prod(expected[:, :3].sum(axis=1) / expected[:, 3:].sum(axis=1))
        found = CascadeFilter.from_quadratics(numerators, denominators).sos
        assert np.array_equal(found, expected)
