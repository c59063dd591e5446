"""A generated test campaign: probes whose τ drift over simulated days, one with an effect.

Each probe is a directory of bags, one recording a day (``PROBE/dayNN``), stamped from
:data:`START_NS` plus the day: what ``tcomp campaign`` reads from a test cell. Recordings are
multisines at 500 Hz with K = 1 %:

* ``fouling``: τ1 and τ2 grow by ``growth`` (relative) from the first day to the last, as soot
  thickens the wires;
* ``steady``: constant τ, and from day ``days // 2`` on its junctions conduct heat to lagging
  supports (the effect simulator's ``conduction``, the bundled bag's settings): the diagnosis
  should name it there and not before.

Used by ``test/test_campaign.py`` and ``bench/bench_campaign.py``; the recordings are a pure
function of the arguments (seeded).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tcomp_core.io import write_bag
from tcomp_core.simulate import PAPER_TAU1, PAPER_TAU2
from tcomp_core.simulate_effects import simulate_effect

#: 2023-11-14 22:13:20 UTC, the first day's first stamp.
START_NS = 1_700_000_000 * 10**9
DAY_NS = 86_400 * 10**9
TOPICS = ("/tc1/temperature", "/tc2/temperature", "/tref/temperature")
#: The conduction of the bundled bag (``bags/make_bags.py``).
CONDUCTION = {"tau_leg": 1.7**2 * PAPER_TAU2, "tau_p": 1.0}


@dataclass(frozen=True)
class Truth:
    """What one recording was made with."""

    probe: str
    day: int
    tau1: float
    tau2: float
    effect: str


def write_campaign(
    out: Path,
    *,
    days: int = 4,
    duration_s: float = 10.0,
    dt: float = 0.002,
    growth: float = 0.4,
) -> list[Truth]:
    """Write the campaign's bags under ``out``; returns what each was made with."""
    truths = []
    for day in range(days):
        share = day / max(days - 1, 1)
        for probe, scale, effect in (
            ("fouling", 1.0 + growth * share, None),
            ("steady", 1.0, "conduction" if day >= days // 2 else None),
        ):
            tau1, tau2 = PAPER_TAU1 * scale, PAPER_TAU2 * scale
            record = simulate_effect(
                effect,
                "multisine",
                tau1=tau1,
                tau2=tau2,
                dt=dt,
                duration=duration_s,
                noise_percent=1.0,
                seed=100 * day + (1 if probe == "fouling" else 2),
                params=CONDUCTION if effect == "conduction" else None,
            )
            write_bag(
                out / probe / f"day{day:02d}",
                record.time,
                dict(zip(TOPICS, (record.tc1, record.tc2, record.gas), strict=True)),
                frame_id=probe,
                compress=True,
                start_ns=START_NS + day * DAY_NS,
            )
            truths.append(Truth(probe, day, tau1, tau2, effect or "none"))
    return truths
