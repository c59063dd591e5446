"""The Kalman gas's std holds τ's own uncertainty (tcomp_core.fusion.tau_spread).

The smoother's and the causal filter's std are computed at the τ they are given; on a sinusoid
the noise leaves them small and an error of τ within its interval is most of the gas's error.
The records are lumped simulations with seeds the bench (``bench/bench_std_tau.py``, 900–905)
did not use.
"""

from dataclasses import replace

import numpy as np
import pytest

from tcomp_core.cli import main
from tcomp_core.estimators import estimate
from tcomp_core.fusion import fuse
from tcomp_core.fusion.tau_spread import STEP, tau_spread_std, with_tau_spread
from tcomp_core.io import read_record, write_csv
from tcomp_core.simulate import simulate_pair

#: Samples left out at each end (the smoother's start and end).
EDGE = 400


def _pair(kind: str, seed: int, duration: float = 16.0):
    return simulate_pair(kind, noise_percent=1.0, duration=duration, seed=seed)


def _coverage(kind: str, seed: int, causal: bool) -> tuple[float, float, float]:
    """Share of errors within 4 std without and with τ's spread, and the std's median ratio."""
    pair = _pair(kind, seed)
    found = estimate(pair.tc1, pair.tc2, pair.dt, phi=None)
    fused = fuse(pair.tc1, pair.tc2, pair.dt, found.tau1, found.tau2, causal=causal)
    spread = with_tau_spread(fused, pair.tc1, pair.tc2, found.tau_log_se())
    keep = slice(EDGE, -EDGE)
    error = np.abs(fused.gas - pair.gas)[keep]
    return (
        float(np.mean(error <= 4.0 * fused.std[keep])),
        float(np.mean(error <= 4.0 * spread.std[keep])),
        float(np.median(spread.std[keep] / fused.std[keep])),
    )


@pytest.mark.slow
@pytest.mark.parametrize("causal", [False, True])
def test_on_sinusoids_the_std_holds_the_error_once_taus_uncertainty_is_in(causal):
    rows = [_coverage("sinusoid", seed, causal) for seed in (906, 908, 909)]
    assert max(without for without, _, _ in rows) < 0.6, rows  # the noise's std alone fails
    assert min(within for _, within, _ in rows) >= 0.99, rows


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["multisine", "exhaust"])
def test_where_the_noise_dominates_the_std_is_left_as_it_was(kind):
    without, within, ratio = _coverage(kind, 906, False)
    assert without >= 0.99 and within >= 0.99
    assert ratio < 1.02


def test_the_slope_is_the_same_path_run_again_at_a_moved_tau():
    pair = _pair("sinusoid", 3, duration=4.0)
    fused = fuse(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2)
    moved = replace(fused.model, tau2=fused.model.tau2 * (1.0 + STEP))
    again = fuse(pair.tc1, pair.tc2, pair.dt, pair.tau1, pair.tau2, model=moved)
    spread = tau_spread_std(fused, pair.tc1, pair.tc2, (0.0, 0.02))
    np.testing.assert_allclose(spread, np.abs(again.gas - fused.gas) / STEP * 0.02, rtol=1e-12)
    assert not np.any(tau_spread_std(fused, pair.tc1, pair.tc2, (0.0, 0.0)))
    widened = with_tau_spread(fused, pair.tc1, pair.tc2, (0.01, 0.02))
    assert np.all(widened.std >= fused.std) and np.any(widened.std > fused.std)
    np.testing.assert_array_equal(widened.gas, fused.gas)  # the gas is left alone


def test_only_estimators_with_standard_errors_give_them():
    pair = _pair("multisine", 4, duration=4.0)
    found = estimate(pair.tc1, pair.tc2, pair.dt, phi=None)
    relative = found.tau_log_se()
    assert relative is not None
    assert relative[0] == pytest.approx(found.params["tau1_se"] / found.tau1)
    assert all(0.0 < value < 0.1 for value in relative)
    assert estimate(pair.tc1, pair.tc2, pair.dt, "beta-gtls").tau_log_se() is None


@pytest.mark.slow
def test_reconstruct_adds_the_spread_of_the_tau_it_estimated(tmp_path, capsys):
    pair = _pair("sinusoid", 906)
    data = write_csv(tmp_path / "sine.csv", pair.time, pair.tc1, pair.tc2, pair.gas)
    estimated, given = tmp_path / "estimated.csv", tmp_path / "given.csv"
    assert main(["reconstruct", str(data), "-o", str(estimated)]) == 0
    printed = capsys.readouterr().out
    assert "the std holds tau's uncertainty" in printed
    line = next(line for line in printed.splitlines() if line.startswith("ml-eiv:"))
    tau1, tau2 = (part.split()[0] for part in line.split("=")[1:])
    assert main(["reconstruct", str(data), "-o", str(given), "--tau1", tau1, "--tau2", tau2]) == 0
    assert "tau's uncertainty" not in capsys.readouterr().out  # τ given: no spread known
    columns = ("tc1", "tc2", "gas_variance")
    widened = read_record(estimated, columns=columns).ref
    alone = read_record(given, columns=columns).ref
    assert np.median(widened / alone) > 5.0  # on this sinusoid τ's share is most of it
