"""ml-eiv's intervals where the noise, not the gas, makes most of JᵀJ (:mod:`.eiv_noise`).

A slow sine seen by sensors of 20 and 100 ms shows their lags only as a phase and a change of
amplitude of 1e-3; the noise in the readings' differences then adds most of the Gauss–Newton
information, and σ²(JᵀJ)⁻¹ put the intervals 2.5–10 times too narrow (47–95 % of them missed).
"""

import math
import warnings

import numpy as np
import pytest
from sim_records import make_pair

from tcomp_core import estimate
from tcomp_core.errors import NoExcitationError
from tcomp_core.estimators import mleiv
from tcomp_core.estimators.eiv_noise import NoiseMoments, noise_moments, sandwich_covariance

DT = 0.002
TAUS = (0.02, 0.1)


def _noise_jacobian(problem, x, step=1e-6):
    """∂w/∂x of the projected residual's data rows (the gain's prior row left out)."""
    columns = []
    for a in range(x.size):
        dx = np.zeros_like(x)
        dx[a] = step
        columns.append((problem.projected(x + dx) - problem.projected(x - dx))[:-1] / (2 * step))
    return np.stack(columns, axis=1)


@pytest.mark.parametrize(
    ("phi", "gain", "taus"), [(1.0, 0.0, TAUS), (0.3, 0.004, TAUS), (1.0, 0.0, (0.002, 0.1))]
)
def test_the_noise_terms_are_what_pure_noise_gives(phi, gain, taus):
    """On readings of noise alone w and J are their noise parts: their moments over many draws
    are the frequency-domain E[J_NᵀJ_N] and Var(J_Nᵀ w_N) (whose Isserlis cross term is 30 %
    of the gain's variance for the last pair)."""
    rng = np.random.default_rng(41)
    rows, draws, sigma = 2000, 1000, 0.7
    x = np.array([math.log(taus[0]), math.log(taus[1]), gain])
    products, scores = [], []
    for _ in range(draws):
        n1 = math.sqrt(phi) * sigma * rng.standard_normal(rows + 1)
        n2 = sigma * rng.standard_normal(rows + 1)
        problem = mleiv._CrossRelation.from_signals(n1, n2, DT, phi)
        jacobian = _noise_jacobian(problem, x)
        products.append(jacobian.T @ jacobian)
        scores.append(jacobian.T @ problem.projected(x)[:-1])
    moments = noise_moments(
        problem.noise_responses, x, sigma**2, problem.rows, float(max(problem.gains(x)))
    )
    noise_information, fourth = moments.information, moments.fourth
    scale = np.sqrt(np.outer(np.diag(noise_information), np.diag(noise_information)))
    np.testing.assert_array_less(
        np.abs(np.mean(products, axis=0) - noise_information) / scale, 0.05
    )
    observed = np.cov(np.array(scores).T)  # 1 000 draws: ~4.5 % on the diagonal
    scale = np.sqrt(np.outer(np.diag(fourth), np.diag(fourth)))
    np.testing.assert_array_less(np.abs(observed - fourth) / scale, 0.15)


def _estimates(kind, seeds, freq_hz=None, prefilter_hz=None):
    logs, errors, hits = [], [], []
    for seed in seeds:
        pair = make_pair(
            kind,
            tau1=TAUS[0],
            tau2=TAUS[1],
            duration=8.0,
            noise_percent=2.0,
            seed=seed,
            freq_hz=freq_hz,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found = estimate(pair.tc1, pair.tc2, pair.dt, prefilter_hz=prefilter_hz)
        logs.append((math.log(found.tau1), math.log(found.tau2)))
        errors.append((found.params["tau1_se"] / found.tau1, found.params["tau2_se"] / found.tau2))
        hits.append(
            [
                found.params[f"tau{i}_ci_low"] <= truth <= found.params[f"tau{i}_ci_high"]
                for i, truth in enumerate(TAUS, start=1)
            ]
        )
    return np.array(logs), np.array(errors), np.array(hits)


def test_intervals_on_a_slow_sine_hold_the_spread_of_the_estimates():
    """0.5 Hz for τ of 20 and 100 ms: the old intervals were 2.5 times too narrow (47 % missed)."""
    logs, errors, hits = _estimates("sinusoid", range(7000, 7040), freq_hz=0.5)
    # The standard error of log τ (se/τ, the delta method) against the spread of log τ over
    # 40 records (its own sampling spread: 11 %).
    np.testing.assert_allclose(np.median(errors, axis=0), logs.std(axis=0), rtol=0.3)
    assert hits.mean(axis=0).min() >= 0.85, hits.mean(axis=0)


@pytest.mark.parametrize("kind", ["multisine", "ramp"])
def test_intervals_after_a_pre_filter_hold_the_spread_of_the_estimates(kind):
    """A 20 Hz pre-filter at 500 Hz colours the noise the residual is weighted by: the plain
    σ²(JᵀJ)⁻¹ was a quarter of the spread (0.0011 against 0.0044 on the multisine)."""
    logs, errors, hits = _estimates(kind, range(7200, 7240), prefilter_hz=20.0)
    np.testing.assert_allclose(np.median(errors, axis=0), logs.std(axis=0), rtol=0.3)
    assert hits.mean(axis=0).min() >= 0.85, hits.mean(axis=0)


def test_broadband_intervals_are_unchanged_by_the_noise_terms():
    """A multisine excites the sensors across their band: the noise's share is negligible and
    the intervals are σ²(JᵀJ)⁻¹'s, as before."""
    pair = make_pair("multisine", tau1=TAUS[0], tau2=TAUS[1], duration=8.0, seed=3)
    found = estimate(pair.tc1, pair.tc2, pair.dt)
    problem = mleiv._CrossRelation.from_signals(
        pair.tc1, pair.tc2, DT, found.phi, mleiv._gain_weight(pair.tc2)
    )
    x = np.array([math.log(found.tau1), math.log(found.tau2), found.params["gain"] - 1.0])
    columns = []
    for a in range(x.size):
        dx = np.zeros_like(x)
        dx[a] = 1e-6
        columns.append((problem.projected(x + dx) - problem.projected(x - dx)) / 2e-6)
    jacobian = np.stack(columns, axis=1)
    plain = found.params["noise_sigma2"] ** 2 * np.linalg.inv(jacobian.T @ jacobian)
    for i, tau in enumerate((found.tau1, found.tau2)):
        reported = found.params[f"tau{i + 1}_se"] / tau
        assert reported == pytest.approx(math.sqrt(plain[i, i]), rel=0.01)


def test_a_direction_the_noise_explains_entirely_is_refused():
    noise = np.diag([4.0, 1.0, 1.0])
    moments = NoiseMoments(noise, np.zeros((3, 3)), 1.0)
    with pytest.raises(NoExcitationError, match="noise accounts for all the information"):
        sandwich_covariance(np.eye(3), moments)
