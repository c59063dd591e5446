"""Seeded random draws of two-thermocouple records for the compensation campaign (issue 24).

Each draw is one record of the detailed simulator (``test/detailed_physics.py``, physics that
shares no code with :mod:`tcomp_core`) with randomly chosen conditions:

* **effects**: none (20 %), one (50 %) or two (30 %) of :data:`CAMPAIGN_EFFECTS`, each in one
  of its forms (:data:`FORMS`): conduction to supports at a constant or a lagging temperature,
  radiation to a constant or a lagging wall, velocity as a sine or a drift of the flow speed;
* **signal**: a hot/cold mixing rig (periodic), exhaust pulses, or steps and ramps (drifts);
  radiation and property draws use hot gas;
* **rate** 0.5–20 kHz, **noise** K = 0.5–4 % of the reading's standard deviation (equal on both
  channels unless ``noise_ratio`` is drawn), a delay of 1–5 samples when ``delay`` is drawn;
* **sensors** as users own them: on every draw a gain and an offset between the two sensors
  within IEC 60584 class 2 (±0.75 %, ±2.5 °C); a ``calibration`` draw goes beyond it;
* **wires**: diameters of 25–75 µm and 1.8–3 times that, flow speed 2–10 m/s.

The draw is a pure function of its index (a seed sequence of :data:`CAMPAIGN_SEED` and the
index), so a campaign's draws are the same on every machine and a fast subset in the test suite
is a prefix of the benchmark's.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Root of every draw's seed sequence.
CAMPAIGN_SEED = 24_2026
#: Effects a draw can hold (quantisation is a property of the ADC, not a missing physics).
CAMPAIGN_EFFECTS = (
    "conduction",
    "radiation",
    "velocity",
    "delay",
    "calibration",
    "interference",
    "noise_ratio",
    "property",
)
#: The forms each effect is drawn in: the project's fitted form and a second one.
FORMS = {
    "conduction": ("constant supports", "lagging supports"),
    "radiation": ("constant wall", "lagging wall"),
    "velocity": ("sine", "drift"),
}
#: Effects that need a hot gas to show.
HOT = ("radiation", "property")
#: Shares of draws with 0, 1 and 2 effects.
EFFECT_COUNTS = ((0, 0.2), (1, 0.5), (2, 0.3))
RATES_HZ = (500.0, 1000.0, 2000.0, 5000.0, 10000.0, 20000.0)
#: IEC 60584 class 2 between the two sensors: relative gain and offset, degrees C.
CLASS2_GAIN, CLASS2_OFFSET_C = 0.0075, 2.5


def detailed_physics():
    """The module ``test/detailed_physics.py`` (the repository's ``test/`` put on the path)."""
    folder = str(Path(__file__).resolve().parents[1] / "test")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    import detailed_physics as module

    return module


@dataclass(frozen=True)
class Draw:
    """One drawn record: its conditions and the simulator's record.

    Attributes
    ----------
    index : int
    effects : tuple of str
        The effects put in, sorted (empty for a clean draw).
    forms : dict of str to str
        The form of each effect that has two.
    label : str
        A short description (signal, rate, K, effects and their sizes).
    rig : Any
        The simulator's ``Rig``.
    noise_percent : float
        K, % of the std of the noise-free reading 1.
    sigma_ratio : float
        sigma2 / sigma1.
    """

    index: int
    effects: tuple[str, ...]
    forms: dict[str, str]
    label: str
    rig: Any
    noise_percent: float
    sigma_ratio: float
    details: dict[str, float] = field(default_factory=dict)


def _pick_effects(rng: np.random.Generator) -> tuple[str, ...]:
    counts, weights = zip(*EFFECT_COUNTS, strict=True)
    count = int(rng.choice(counts, p=weights))
    return tuple(sorted(rng.choice(CAMPAIGN_EFFECTS, size=count, replace=False).tolist()))


def draw(index: int) -> Draw:
    """The draw ``index`` of the campaign (deterministic).

    Parameters
    ----------
    index : int
        Non-negative draw number.
    """
    physics = detailed_physics()
    rng = np.random.default_rng([CAMPAIGN_SEED, index])
    effects = _pick_effects(rng)
    hot = any(effect in HOT for effect in effects)
    signal = str(rng.choice(("rotating_disk", "engine_pulses", "step_ramp")))
    rate = float(rng.choice(RATES_HZ))
    noise = float(rng.uniform(0.5, 4.0))
    d1 = float(rng.uniform(25e-6, 75e-6))
    d2 = d1 * float(rng.uniform(1.8, 3.0))
    speed = float(rng.uniform(2.0, 10.0))
    seed = int(rng.integers(1 << 30))
    emissivity = float(rng.uniform(0.6, 0.9)) if "radiation" in effects else 0.0
    wires = (physics.Wire(d1, emissivity=emissivity), physics.Wire(d2, emissivity=emissivity))
    options: dict[str, Any] = {}
    forms: dict[str, str] = {}
    details: dict[str, float] = {}
    for effect in effects:
        if effect in FORMS:
            forms[effect] = str(rng.choice(FORMS[effect]))
    if hot:
        signal = str(rng.choice(("engine_pulses", "step_ramp")))
        low = float(rng.uniform(100.0, 400.0))
        options["gas_low_c"] = low
        options["gas_high_c"] = low + float(rng.uniform(300.0, 600.0))
    if "radiation" in effects:
        if forms["radiation"] == "constant wall":
            options["wall_c"] = float(rng.uniform(100.0, 400.0))
        else:
            options["wall_c"] = None
            options["wall_lag_s"] = float(rng.uniform(3.0, 30.0))
    if "conduction" in effects:
        options["conduction"] = True
        # Legs of 0.5-1.5 mm: the supports pull the junction by a few to tens of %.
        length = float(rng.uniform(0.5e-3, 1.5e-3))
        wires = tuple(
            physics.Wire(w.diameter_m, length_m=length, emissivity=w.emissivity) for w in wires
        )
        if forms["conduction"] == "constant supports":
            options["support_c"] = float(rng.uniform(20.0, 60.0))
        else:
            options["support_c"] = None
            options["support_lag_s"] = float(rng.uniform(1.0, 4.0))
        details["leg_mm"] = length * 1e3
    if "velocity" in effects:
        if forms["velocity"] == "sine":
            options["speed_fluctuation"] = float(rng.uniform(0.2, 0.45))
            options["speed_period_s"] = float(rng.uniform(1.0, 4.0))
        else:
            options["speed_drift"] = float(rng.choice((-1.0, 1.0)) * rng.uniform(0.5, 0.9))
    if "delay" in effects:
        samples = float(rng.uniform(1.0, 5.0))
        options["spacing_m"] = samples / rate * speed
        details["delay_samples"] = samples
    if "interference" in effects:
        options["mains_hz"] = float(rng.choice((50.0, 60.0)))
        options["mains_channel"] = int(rng.choice((1, 2)))
        details["mains_share"] = float(rng.uniform(0.02, 0.1))
    channel = int(rng.choice((1, 2)))
    if "calibration" in effects:
        gain = 1.0 + float(rng.choice((-1.0, 1.0)) * rng.uniform(0.02, 0.05))
        offset = float(rng.choice((-1.0, 1.0)) * rng.uniform(4.0, 10.0))
    else:
        gain = 1.0 + float(rng.uniform(-CLASS2_GAIN, CLASS2_GAIN))
        offset = float(rng.uniform(-CLASS2_OFFSET_C, CLASS2_OFFSET_C))
    options["calibration"] = (channel, gain, offset)
    sigma_ratio = 1.0
    if "noise_ratio" in effects:
        sigma_ratio = float(rng.uniform(2.0, 3.5)) ** float(rng.choice((-1.0, 1.0)))
    duration = 6.0 if signal == "step_ramp" else 4.0
    rig = physics.Rig(
        signal=signal,
        duration_s=duration,
        rate_hz=rate,
        seed=seed,
        wires=wires,
        speed_m_s=speed,
        **options,
    )
    parts = [f"{signal}", f"{rate / 1e3:g}kHz", f"K{noise:.1f}"]
    parts += [f"{e}({forms[e]})" if e in forms else e for e in effects] or ["clean"]
    parts.append(f"cal{channel}:{(gain - 1) * 100:+.2f}%/{offset:+.1f}C")
    return Draw(
        index=index,
        effects=effects,
        forms=forms,
        label=" ".join(parts),
        rig=rig,
        noise_percent=noise,
        sigma_ratio=sigma_ratio,
        details=details,
    )


def simulate(item: Draw):
    """The draw's record: ``(Record, truth dict)``, noise and interference added (seeded)."""
    from tcomp_core.io import Record

    physics = detailed_physics()
    rig = item.rig
    if "interference" in item.effects:
        # The mains amplitude is a share of the signal's swing: simulate once clean to size it.
        probe = physics.simulate_rig(_replace(rig, mains_hz=None))
        amplitude = item.details["mains_share"] * float(np.std(probe.gas))
        rig = _replace(rig, mains_amplitude_c=amplitude)
    record = physics.simulate_rig(rig)
    rng = np.random.default_rng([CAMPAIGN_SEED, item.index, 1])
    sigma1 = item.noise_percent / 100.0 * float(np.std(record.tc1))
    sigma2 = sigma1 * item.sigma_ratio
    tc1 = record.tc1 + sigma1 * rng.standard_normal(record.tc1.size)
    tc2 = record.tc2 + sigma2 * rng.standard_normal(record.tc2.size)
    truth = dict(record.truth)
    truth["noise1_c"], truth["noise2_c"] = sigma1, sigma2
    name = f"draw{item.index:03d} {item.label}"
    return (
        Record(time=record.time, tc1=tc1, tc2=tc2, ref=record.gas, source=name, dt=record.dt),
        truth,
    )


def _replace(rig, **changes):
    from dataclasses import replace

    return replace(rig, **changes)


def tau_errors_pct(truth: dict[str, float], tau1: float, tau2: float) -> tuple[float, float]:
    """Relative errors of τ1, τ2 against the simulator's (effective) time constants, %."""
    return (
        100.0 * (tau1 / truth["tau1"] - 1.0) if math.isfinite(tau1) else math.nan,
        100.0 * (tau2 / truth["tau2"] - 1.0) if math.isfinite(tau2) else math.nan,
    )


#: Compensation is materially worse than first order beyond both of these (issue 24).
WORSE_RATIO, WORSE_POINTS = 1.1, 0.1


def materially_worse(first_pct: float, final_pct: float) -> bool:
    """Whether a compensated gas error is materially worse than the first-order one (both %)."""
    if not math.isfinite(final_pct):
        return math.isfinite(first_pct)
    return final_pct > WORSE_RATIO * first_pct and final_pct - first_pct > WORSE_POINTS
