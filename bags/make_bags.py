"""Regenerate the sample bags in this folder, deterministically (seeded).

    python bags/make_bags.py [--out bags]

===================  ==============================================================================
rig_sine_5khz        10 Hz sinusoid at 5 kHz, like the paper's test rig; first-order sensors
ramp_500hz           the paper's periodic ramp (Fig. 3b) at 500 Hz; first-order sensors
conduction_500hz     multisine at 500 Hz through junctions between fin legs whose supports lag the
                     gas, an effect the first-order model lacks:
                     G(s) = (1 − S)/(1 + τ s) + S/(1 + τp s), S = sech(mL √(1 + τ s))
radiation_500hz      multisine around 700 °C at 500 Hz through wires radiating to a 300 °C wall:
                     τ dT/dt = u − T − r (T⁴ − T_w⁴), an effect the first-order model lacks
===================  ==============================================================================

Every bag holds /tc1/temperature, /tc2/temperature and the true gas temperature on
/tref/temperature. The first two bags use the zero-order-hold simulation of tcomp_core; the
conduction and radiation bags are simulated independently of the estimators' difference
equation and of the effect library's filters, by
:func:`tcomp_core.simulate_effects.simulate_effect` (the fin's transfer function as a cascade of
200 lags, the radiating wire by Runge-Kutta, integrated on a grid 20 times finer than the
samples with the gas temperature evaluated on that grid, then decimated).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tcomp_core.io import write_bag
from tcomp_core.simulate import PAPER_TAU2, simulate_pair
from tcomp_core.simulate_effects import simulate_effect

TOPICS = ("/tc1/temperature", "/tc2/temperature", "/tref/temperature")
#: Bag stamps start here (ns): an arbitrary but fixed wall-clock-like epoch.
START_NS = 1_700_000_000 * 1_000_000_000
#: Conduction: the legs' diffusion time L²/α (mL2 = 1.7 on the thicker wire, 3.8 on the thinner)
#: and the supports' lag, s.
CONDUCTION = {"tau_leg": 1.7**2 * PAPER_TAU2, "tau_p": 1.0}


def rig_sine(out: Path) -> Path:
    """10 Hz sinusoid at 5 kHz, K = 1 %, 3 s."""
    data = simulate_pair("sinusoid", dt=0.0002, duration=3.0, noise_percent=1.0, seed=11)
    return _write(out / "rig_sine_5khz", data.time, data.tc1, data.tc2, data.gas)


def ramp(out: Path) -> Path:
    """The paper's periodic ramp at 500 Hz, K = 2 %, 10 s."""
    data = simulate_pair("ramp", dt=0.002, duration=10.0, noise_percent=2.0, seed=12)
    return _write(out / "ramp_500hz", data.time, data.tc1, data.tc2, data.gas)


def conduction(out: Path) -> Path:
    """Multisine at 500 Hz through junctions conducting to lagging supports, K = 1 %, 20 s."""
    record = simulate_effect(
        "conduction",
        "multisine",
        dt=0.002,
        duration=20.0,
        noise_percent=1.0,
        seed=13,
        params=CONDUCTION,
    )
    return _write(out / "conduction_500hz", record.time, record.tc1, record.tc2, record.gas)


def radiation(out: Path) -> Path:
    """Multisine around 700 °C at 500 Hz through radiating wires, K = 1 %, 10 s."""
    record = simulate_effect(
        "radiation", "multisine", dt=0.002, duration=10.0, noise_percent=1.0, seed=14
    )
    return _write(out / "radiation_500hz", record.time, record.tc1, record.tc2, record.gas)


def _write(path: Path, time, tc1, tc2, gas) -> Path:
    series = dict(zip(TOPICS, (tc1, tc2, gas), strict=True))
    write_bag(
        path, time, series, frame_id="probe", overwrite=True, compress=True, start_ns=START_NS
    )
    size = sum(item.stat().st_size for item in path.iterdir())
    print(f"wrote {path}: {time.size} samples, {size / 1e6:.2f} MB")
    return path


def main() -> None:
    """Write the bags (all, or those named)."""
    makers = {
        "rig_sine_5khz": rig_sine,
        "ramp_500hz": ramp,
        "conduction_500hz": conduction,
        "radiation_500hz": radiation,
    }
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    parser.add_argument("bags", nargs="*", help=f"some of {', '.join(makers)} (default: all)")
    args = parser.parse_args()
    unknown = sorted(set(args.bags) - set(makers))
    if unknown:
        parser.error(f"unknown bag(s): {', '.join(unknown)}")
    for name in args.bags or makers:
        makers[name](args.out)


if __name__ == "__main__":
    main()
