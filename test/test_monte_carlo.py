"""Reduced Monte Carlo of Sec. IV A: bias and spread of e_τ (Eq. 23) against noise level K.

30 seeded runs per case, 10 s at dt = 0.002 s with the paper's τ1 = 0.0238 s, τ2 = 0.1168 s and
equal noise on both sensors. Reference figures at 100 runs: sinusoid K=2: γ-LS +9.81±0.59,
γ-TLS -0.13±0.66, β-LS +9.76±0.59, β-GTLS -0.13±0.66; ramp K=2: β-LS +7.53±0.80,
β-GTLS +0.01±0.85, γ-TLS +0.01±1.03 (e_τ1, percent).
"""

import functools

import numpy as np
import pytest

from tcomp_core import estimate
from tcomp_core.estimators import DIFFERENCE_EQUATION_METHODS
from tcomp_core.metrics import tau_error_percent
from tcomp_core.simulate import PAPER_DT, PAPER_DURATION, PAPER_TAU1, PAPER_TAU2, simulate_pair

pytestmark = pytest.mark.slow

RUNS = 30
SIGNAL_SEEDS = {"sinusoid": 100_000, "ramp": 200_000}


@functools.cache
def errors(kind, noise_percent):
    """{method: array (RUNS, 2) of (e_τ1, e_τ2) in percent}."""
    table = {method: np.empty((RUNS, 2)) for method in DIFFERENCE_EQUATION_METHODS}
    for run in range(RUNS):
        pair = simulate_pair(
            kind, noise_percent=noise_percent, seed=SIGNAL_SEEDS[kind] + 1000 * noise_percent + run
        )
        for method in DIFFERENCE_EQUATION_METHODS:
            result = estimate(pair.tc1, pair.tc2, pair.dt, method)
            table[method][run] = (
                tau_error_percent(pair.tau1, result.tau1),
                tau_error_percent(pair.tau2, result.tau2),
            )
    return table


def test_simulation_uses_paper_conditions():
    pair = simulate_pair("sinusoid", noise_percent=2, seed=1)
    assert (pair.tau1, pair.tau2, pair.dt) == (PAPER_TAU1, PAPER_TAU2, PAPER_DT)
    assert pair.tc1.size == round(PAPER_DURATION / PAPER_DT) == 5000
    assert pair.sigma1 == pair.sigma2  # equal noise, φ = 1


def test_runs_are_independent():
    table = errors("sinusoid", 2)
    assert np.unique(table["beta-gtls"][:, 0]).size == RUNS


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
@pytest.mark.parametrize("noise_percent", [1, 2])
@pytest.mark.parametrize("method", ["beta-gtls", "gamma-tls"])
def test_consistent_estimators_unbiased(kind, noise_percent, method):
    table = errors(kind, noise_percent)[method]
    mean = table.mean(axis=0)
    assert abs(mean[0]) < 0.5, mean
    assert abs(mean[1]) < 0.5, mean
    # and the spread is what noise at this level gives: not zero, not wild
    std = table.std(axis=0, ddof=1)
    assert np.all(std > 0.05 * noise_percent)
    assert np.all(std < 0.6 * noise_percent)


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
@pytest.mark.parametrize("noise_percent", [1, 2, 4])
def test_gtls_and_gamma_tls_agree_run_by_run(kind, noise_percent):
    """β-GTLS and γ-TLS are equivalent (Sec. IV A): per run, not only on average."""
    table = errors(kind, noise_percent)
    difference = np.abs(table["beta-gtls"] - table["gamma-tls"]).mean(axis=0)
    spread = table["beta-gtls"].std(axis=0, ddof=1)
    assert np.all(difference < 0.1 * spread), (difference, spread)


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
def test_least_squares_biased_and_equal(kind):
    table = errors(kind, 2)
    gamma_ls = table["gamma-ls"].mean(axis=0)
    beta_ls = table["beta-ls"].mean(axis=0)
    # LS underestimates τ (positive e_τ) at K = 2 ...
    assert gamma_ls[0] > 3.0
    assert beta_ls[0] > 3.0
    assert gamma_ls[1] > 1.5
    assert beta_ls[1] > 1.5
    # ... and γ-LS and β-LS give equal biases (Sec. IV A)
    assert abs(gamma_ls[0] - beta_ls[0]) < 0.1 * beta_ls[0]
    assert abs(gamma_ls[1] - beta_ls[1]) < 0.1 * beta_ls[1]
    # the bias is many standard errors: it is real
    standard_error = table["beta-ls"].std(axis=0, ddof=1) / np.sqrt(RUNS)
    assert np.all(beta_ls > 10 * standard_error)


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
def test_lsq_bias_grows_with_noise(kind):
    biases = [errors(kind, k)["beta-ls"].mean(axis=0)[0] for k in (1, 2, 4)]
    assert 0 < biases[0] < biases[1] < biases[2]
    # roughly quadratic in K: doubling the noise multiplies the bias by about 4
    assert 2.5 < biases[1] / biases[0] < 5.0
    assert 2.5 < biases[2] / biases[1] < 5.0


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
def test_beta_tls_less_biased_only_for_fast_sensor(kind):
    """β-TLS: still biased, less so than LS for τ1, about as much as LS for τ2."""
    table = errors(kind, 2)
    tls = table["beta-tls"].mean(axis=0)
    ls = table["beta-ls"].mean(axis=0)
    assert 3.0 < tls[0] < 0.75 * ls[0]
    assert tls[1] > 1.5
    assert abs(tls[1] - ls[1]) < 0.2 * ls[1]


@pytest.mark.parametrize("kind", ["sinusoid", "ramp"])
def test_total_least_squares_spreads_more_at_high_noise(kind):
    table = errors(kind, 4)

    def std1(method):
        return table[method][:, 0].std(ddof=1)

    assert std1("beta-gtls") > std1("beta-ls")
    assert std1("gamma-tls") > std1("gamma-ls")
