"""Regenerate the sample bags in this folder, deterministically (seeded).

    python bags/make_bags.py [--out bags]

===================  ==============================================================================
rig_sine_5khz        10 Hz sinusoid at 5 kHz, like the paper's test rig; first-order sensors
ramp_500hz           the paper's periodic ramp (Fig. 3b) at 500 Hz; first-order sensors
conduction_500hz     multisine at 500 Hz through sensors with conduction to the supports, an effect
                     the first-order model lacks: G(s) = [1 + κ/(1 + τp s)] / (1 + κ + τ s)
===================  ==============================================================================

Every bag holds /tc1/temperature, /tc2/temperature and the true gas temperature on
/tref/temperature. The first two bags use the zero-order-hold simulation of tcomp_core; the
conduction bag is simulated independently of the estimators' difference equation: the continuous
transfer functions are integrated (scipy.signal.lsim) on a grid 20 times finer than the samples,
with the gas temperature evaluated on that grid, and then decimated.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy import signal

from tcomp_core.io import write_bag
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2, add_noise, gas_signal, simulate_pair

TOPICS = ("/tc1/temperature", "/tc2/temperature", "/tref/temperature")
#: Bag stamps start here (ns): an arbitrary but fixed wall-clock-like epoch.
START_NS = 1_700_000_000 * 1_000_000_000
#: Conduction to the supports per sensor. The thicker wire loses relatively more heat to its
#: supports (larger κ); with equal κ the effect would cancel between the two sensors and only
#: scale both τ by 1/(1 + κ), invisible in their relation.
CONDUCTION = ({"kappa": 0.05, "tau_p": 1.0}, {"kappa": 0.25, "tau_p": 1.0})
OVERSAMPLE = 20


def conduction_response(
    t: np.ndarray, gas: np.ndarray, tau: float, kappa: float, tau_p: float
) -> np.ndarray:
    """Continuous response of a sensor with conduction to its supports, from rest.

    ``lsim`` interpolates the input linearly between grid points; the caller passes the
    deviation from the initial gas temperature so that starting at rest means equilibrium.
    """
    # G(s) = (1 + κ + τp s) / ((1 + τp s)(1 + κ + τ s)): unity DC gain, slow mode τp.
    numerator = [tau_p, 1.0 + kappa]
    denominator = np.polymul([tau_p, 1.0], [tau, 1.0 + kappa])
    _, response, _ = signal.lsim((numerator, denominator), gas, t)
    return response


def rig_sine(out: Path) -> Path:
    """10 Hz sinusoid at 5 kHz, K = 1 %, 3 s."""
    data = simulate_pair("sinusoid", dt=0.0002, duration=3.0, noise_percent=1.0, seed=11)
    return _write(out / "rig_sine_5khz", data.time, data.tc1, data.tc2, data.gas)


def ramp(out: Path) -> Path:
    """The paper's periodic ramp at 500 Hz, K = 2 %, 10 s."""
    data = simulate_pair("ramp", dt=0.002, duration=10.0, noise_percent=2.0, seed=12)
    return _write(out / "ramp_500hz", data.time, data.tc1, data.tc2, data.gas)


def conduction(out: Path) -> Path:
    """Multisine at 500 Hz through sensors with conduction to the supports, K = 1 %, 20 s."""
    dt, duration = 0.002, 20.0
    fine_t = np.arange(round(duration / dt) * OVERSAMPLE) * (dt / OVERSAMPLE)
    gas_fine = gas_signal("multisine", fine_t)
    start = gas_fine[0]
    clean = [
        start + conduction_response(fine_t, gas_fine - start, tau, **effect)
        for tau, effect in zip((PAPER_TAU1, PAPER_TAU2), CONDUCTION, strict=True)
    ]
    sample = slice(None, None, OVERSAMPLE)
    rng = np.random.default_rng(13)
    tc1, tc2, _, _ = add_noise(clean[0][sample], clean[1][sample], 1.0, rng=rng)
    return _write(out / "conduction_500hz", fine_t[sample], tc1, tc2, gas_fine[sample])


def _write(path: Path, time, tc1, tc2, gas) -> Path:
    series = dict(zip(TOPICS, (tc1, tc2, gas), strict=True))
    write_bag(
        path, time, series, frame_id="probe", overwrite=True, compress=True, start_ns=START_NS
    )
    size = sum(item.stat().st_size for item in path.iterdir())
    print(f"wrote {path}: {time.size} samples, {size / 1e6:.2f} MB")
    return path


def main() -> None:
    """Write the three bags."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    args = parser.parse_args()
    for make in (rig_sine, ramp, conduction):
        make(args.out)


if __name__ == "__main__":
    main()
