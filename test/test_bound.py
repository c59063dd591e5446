"""The Cramér–Rao bound of (τ1, τ2) against a brute-force Fisher information (issue 14)."""

import numpy as np
import pytest

from tcomp_core.estimators import estimate
from tcomp_core.estimators.bound import cramer_rao_bound, crb_fisher_information
from tcomp_core.simulate import gas_signal, simulate_pair


def _periodic_response(gas, tau, dt):
    """The periodic steady state of the ZOH lag: y = ifft(G fft(u)), shape (N,)."""
    n = gas.size
    a = np.exp(-dt / tau)
    z = np.exp(-2j * np.pi * np.arange(n) / n)
    return np.real(np.fft.ifft((1 - a) * z / (1 - a * z) * np.fft.fft(gas)))


def _brute_force_information(gas, tau1, tau2, dt, sigma1, sigma2):
    """Schur complement of the full (2 + N)-parameter Fisher information, time domain."""
    n = gas.size
    eye = np.eye(n)
    blocks = []
    for index, (tau, sigma) in enumerate(((tau1, sigma1), (tau2, sigma2))):
        step = 1e-6 * tau
        d_tau = (
            _periodic_response(gas, tau + step, dt) - _periodic_response(gas, tau - step, dt)
        ) / (2 * step)
        jac = np.zeros((n, 2 + n))
        jac[:, index] = d_tau
        jac[:, 2:] = np.column_stack([_periodic_response(e, tau, dt) for e in eye])
        blocks.append(jac / sigma)
    jacobian = np.vstack(blocks)
    full = jacobian.T @ jacobian
    a, b, c = full[:2, :2], full[:2, 2:], full[2:, 2:]
    return a - b @ np.linalg.solve(c, b.T)


@pytest.mark.parametrize("kind", ["sinusoid", "ramp", "exhaust"])
@pytest.mark.parametrize(("sigma1", "sigma2"), [(0.5, 0.5), (0.2, 1.0)])
def test_bound_equals_brute_force_on_a_short_record(kind, sigma1, sigma2):
    dt, n = 0.002, 150
    gas = gas_signal(kind, np.arange(n) * dt)
    fast = crb_fisher_information(gas, 0.0238, 0.1168, dt, sigma1, sigma2)
    brute = _brute_force_information(gas, 0.0238, 0.1168, dt, sigma1, sigma2)
    assert np.allclose(fast, brute, rtol=1e-5)


def test_bound_scales_with_noise_and_length():
    t = np.arange(4000) * 0.002
    gas = gas_signal("ramp", t)
    base = cramer_rao_bound(gas, 0.0238, 0.1168, 0.002, 0.3, 0.3)
    assert np.allclose(cramer_rao_bound(gas, 0.0238, 0.1168, 0.002, 0.6, 0.6), 4 * base)
    longer = cramer_rao_bound(np.tile(gas, 2), 0.0238, 0.1168, 0.002, 0.3, 0.3)
    assert np.allclose(longer, base / 2, rtol=1e-3)


@pytest.mark.parametrize("kind", ["ramp", "sinusoid"])
def test_ml_eiv_scatter_is_near_the_bound(kind):
    # 30 seeded records, K = 2 %, the paper's conditions, sensors settled (one second of
    # warm-up: the bound is that of the running signal, without a start-up step response).
    found = []
    for seed in range(30):
        pair = simulate_pair(kind, noise_percent=2.0, seed=9_000 + seed, warmup=1.0)
        result = estimate(pair.tc1, pair.tc2, pair.dt, "ml-eiv")
        found.append((result.tau1, result.tau2))
    bound = np.sqrt(
        np.diag(
            cramer_rao_bound(pair.gas, pair.tau1, pair.tau2, pair.dt, pair.sigma1, pair.sigma2)
        )
    )
    ratio = np.std(found, axis=0, ddof=1) / bound
    assert np.all(ratio > 0.75) and np.all(ratio < 1.3), ratio
