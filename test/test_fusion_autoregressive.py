"""The autoregressive signal model of the Kalman reconstruction (issue 14)."""

import numpy as np
import pytest

from tcomp_core.fusion import FusionModel, fuse
from tcomp_core.fusion.fitting import AUTO_MODELS
from tcomp_core.metrics import reconstruction_error_percent
from tcomp_core.simulate import simulate_pair


def _model(ar, q=0.5):
    return FusionModel(
        kind="autoregressive",
        dt=0.002,
        tau1=0.0238,
        tau2=0.1168,
        sigma1=0.1,
        sigma2=0.1,
        q=q,
        ar=ar,
    )


def test_transition_is_the_integrated_autoregression():
    ar = (0.5, -0.2, 0.1)
    transition, covariance, output, _ = _model(ar).discrete_signal()
    rng = np.random.default_rng(1)
    state = rng.standard_normal(4)  # [g_k, d_k, d_(k-1), d_(k-2)]
    change = ar[0] * state[1] + ar[1] * state[2] + ar[2] * state[3]
    expected = np.array([state[0] + change, change, state[1], state[2]])
    assert np.allclose(transition @ state, expected)
    # the innovation enters the gas and its change alike, variance q
    assert np.allclose(covariance, 0.5 * np.outer([1, 1, 0, 0], [1, 1, 0, 0]))
    assert output @ state == state[0]
    assert _model(ar).n_hyperparameters == 4


@pytest.mark.parametrize("ar", [(), (1.2,), (0.5, 0.6)])
def test_non_stationary_coefficients_refused(ar):
    with pytest.raises(ValueError, match="stationary"):
        _model(ar)


def _errors(kind, noise_percent, seed):
    pair = simulate_pair(kind, noise_percent=noise_percent, seed=seed)
    truth = pair.gas[:-1]
    out = {}
    for model in ("autoregressive", "band-limited"):
        fused = fuse(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, model=model)
        out[model] = reconstruction_error_percent(truth, fused.gas[: truth.size])
        assert fused.model.kind == model
    return out


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_autoregressive_beats_band_limited_on_exhaust_pulses(seed):
    errors = _errors("exhaust", 4.0, seed)
    assert errors["autoregressive"] < 0.9 * errors["band-limited"], errors


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["multisine", "exhaust"])
def test_auto_picks_the_autoregressive_model_for_broadband_gas_and_causal_filter_runs(kind):
    assert "autoregressive" in AUTO_MODELS
    pair = simulate_pair(kind, noise_percent=2.0, seed=3, duration=4.0)
    smoothed = fuse(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    assert smoothed.model.kind == "autoregressive"
    causal = fuse(
        pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, model=smoothed.model, causal=True
    )
    truth = pair.gas[:-1]
    smooth_error = reconstruction_error_percent(truth, smoothed.gas[: truth.size])
    causal_error = reconstruction_error_percent(truth, causal.gas[: truth.size])
    assert smooth_error <= causal_error < 3.0 * smooth_error
    assert np.all(np.isfinite(causal.std))


@pytest.mark.slow
def test_autoregression_stays_off_the_unit_circle():
    # Seed 3 once gave a Yule–Walker root at 1 - 4e-13 from a spectrum with an empty stop
    # band, and the smoother overflowed to nan.
    pair = simulate_pair("multisine", noise_percent=1.0, seed=3)
    fused = fuse(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, model="autoregressive")
    roots = np.roots(np.concatenate(([1.0], -np.asarray(fused.model.ar))))
    assert np.max(np.abs(roots)) <= 1.0 - 1e-4
    assert np.all(np.isfinite(fused.gas)) and np.all(np.isfinite(fused.std))
    truth = pair.gas[:-1]
    assert reconstruction_error_percent(truth, fused.gas[: truth.size]) < 5.0
