"""The gas temperature from the diagnosed model against the first-order one (issue 16, baseline).

For records whose true gas temperature is known, the diagnosis (:func:`tcomp_core.diagnose.
diagnose`) is run and two reconstructions are compared with the truth: the first-order model's
and the final (extended) model's, each the inverse-variance fusion of the two sensors' gas
reconstructions, both parameter sets refitted on the whole record. The figure is the
diagnosis's own e_Tg (``ref_error_pct``): 100 rms(gas − ref)/std(ref) over the scored samples,
both low-passed at the comparison band edge (working rate), and the mean offset gas − ref in °C.

This is the offline smoother-free path (the chains inverted sample by sample) that the
diagnosis already computes; it measures what issue 16 asks the published output to gain. Records:
the effect simulator (:mod:`tcomp_core.simulate_effects`, every effect and none, multisine and
exhaust, K = 1 %) and the detailed simulator (``test/detailed_physics.py``, one record per
condition and gas signal, ``bench_diagnose``'s grid).

Run::

    cd /work/main && PYTHONPATH=. .venv/bin/python bench/bench_compensate.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from tcomp_core.diagnose import pipeline
from tcomp_core.diagnose.heldout import Evaluator
from tcomp_core.diagnose.ranking import MAX_EFFECTS
from tcomp_core.diagnose.result import ModelFit
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.io import Record
from tcomp_core.simulate_effects import simulate_effect

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_diagnose


def offset_c(evaluator: Evaluator, fit: ModelFit) -> float:
    """Mean of the fused gas less the reference over the scored samples, degrees C."""
    fused, reference, keep = pipeline.fused_against_reference(evaluator, fit)
    keep = keep & np.isfinite(fused)
    return float(np.mean(fused[keep] - reference[keep]))


def compare(record: Record) -> dict:
    """Verdict and e_Tg / offset of the first-order and the final model on one record."""
    started = time.perf_counter()
    evaluator, model, base, _ = pipeline._base_fit(record)
    steps, _, expected = pipeline._staircase(evaluator, model, base, EFFECT_NAMES, MAX_EFFECTS)
    first = evaluator.refit_whole(steps[0])
    final = evaluator.refit_whole(steps[-1])
    findings = [effect for effect in final.effects if effect not in expected]
    return {
        "verdict": findings[0] if findings else "none",
        "effects": final.effects,
        "first": pipeline._reference_errors(evaluator, first)["fused"],
        "final": pipeline._reference_errors(evaluator, final)["fused"],
        "first_offset": offset_c(evaluator, first),
        "final_offset": offset_c(evaluator, final),
        "seconds": time.perf_counter() - started,
    }


def effect_records(quick: bool):
    kinds = ("multisine",) if quick else ("multisine", "exhaust")
    for effect in (None, *EFFECT_NAMES):
        for kind in kinds:
            sim = simulate_effect(effect, kind, duration=10.0, noise_percent=1.0, seed=3)
            name = f"sim/{effect or 'none'}/{kind}"
            yield (
                effect or "none",
                name,
                Record(
                    time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=sim.gas, source=name, dt=sim.dt
                ),
            )


def detailed_records(quick: bool):
    physics = bench_diagnose.detailed_physics()
    size = "quick" if quick else "reduced"
    for condition, _, name, rig in bench_diagnose.detailed_records(size):
        rec = physics.simulate_rig(rig)
        yield (
            condition,
            f"detailed/{name}",
            Record(time=rec.time, tc1=rec.tc1, tc2=rec.tc2, ref=rec.gas, source=name, dt=rec.dt),
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="one signal, one record per row")
    args = parser.parse_args()
    print(
        f"{'record':<62}{'verdict':>13}{'e_Tg first %':>14}{'final %':>9}{'ratio':>7}"
        f"{'offset first':>14}{'final °C':>10}{'s':>6}"
    )
    rows = []
    for records in (effect_records(args.quick), detailed_records(args.quick)):
        for truth, name, record in records:
            row = {"truth": truth, "name": name, **compare(record)}
            rows.append(row)
            ratio = row["first"] / row["final"] if row["final"] > 0 else math.inf
            print(
                f"{name[:61]:<62}{row['verdict']:>13}{row['first']:>14.2f}{row['final']:>9.2f}"
                f"{ratio:>7.2f}{row['first_offset']:>14.3f}{row['final_offset']:>10.3f}"
                f"{row['seconds']:>6.1f}",
                flush=True,
            )
    changed = [row for row in rows if row["effects"]]
    ratios = [row["first"] / row["final"] for row in changed if row["final"] > 0]
    if ratios:
        worst = min(ratios)
        print(
            f"\nrecords where the final model has effects: {len(changed)} of {len(rows)}; e_Tg "
            f"first / final: median {statistics.median(ratios):.2f}x, worst {worst:.2f}x "
            f"({'worse' if worst < 1 else 'better'} than first order)"
        )


if __name__ == "__main__":
    main()
