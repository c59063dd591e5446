"""``tcomp diagnose`` on data with hidden effects: confusion matrix, τ accuracy, error fall, time.

Every record is simulated by :func:`tcomp_core.simulate_effects.simulate_effect`, a finely
sampled continuous-time simulation of the effect, independent of the difference equations the
fit uses. The grid crosses each effect (and none) with gas signals, noise levels K, time
constant pairs and seeds. Per record the diagnosis gives a verdict; the table counts verdicts
against the truth (rows: true effect, columns: verdict), then prints per true effect

* accuracy: verdict == truth;
* fall: median of base held-out error / final held-out error (the issue asks >= 2);
* tau: share of records whose final τ1 and τ2 are both within 5 % of the truth.

Time: ``diagnose`` on one 40 000-sample record (80 s at 500 Hz, multisine with conduction),
beside the baseline measured in the same run: the paper's base model alone on the same record
(β-GTLS on the estimation blocks plus its held-out score), so the ratio says what the effect
search costs on top of the paper's method.

Run::

    .venv/bin/python bench/bench_diagnose.py            # full grid (several minutes)
    .venv/bin/python bench/bench_diagnose.py --quick    # a smaller grid
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from tcomp_core.diagnose import diagnose, pipeline
from tcomp_core.diagnose.prepare import prepare
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.io import Record
from tcomp_core.simulate_effects import simulate_effect

TRUTHS = (None, *EFFECT_NAMES)
TAU_PAIRS = ((0.0238, 0.1168), (0.015, 0.06))


def record_of(effect, kind, noise, taus, seed) -> tuple[Record, object]:
    sim = simulate_effect(
        effect, kind, tau1=taus[0], tau2=taus[1], duration=10.0, noise_percent=noise, seed=seed
    )
    name = f"{effect or 'none'}/{kind}/K{noise}/tau{taus[0]}/s{seed}"
    record = Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=sim.gas, source=name, dt=sim.dt)
    return record, sim


def run_grid(signals, noises, seeds) -> list[dict]:
    rows = []
    for effect, kind, noise, taus, seed in itertools.product(
        TRUTHS, signals, noises, TAU_PAIRS, seeds
    ):
        record, sim = record_of(effect, kind, noise, taus, seed)
        started = time.perf_counter()
        found = diagnose(record, max_effects=1)
        rows.append(
            {
                "truth": effect or "none",
                "verdict": found.verdict,
                "fall": found.base.error_pct / found.final.error_pct,
                "tau_ok": abs(found.final.tau1 / sim.tau1 - 1) <= 0.05
                and abs(found.final.tau2 / sim.tau2 - 1) <= 0.05,
                "seconds": time.perf_counter() - started,
                "name": record.source,
            }
        )
        print(
            f"{record.source:<40} verdict {found.verdict:<12} base {found.base.error_pct:6.2f} "
            f"final {found.final.error_pct:6.2f} tau1 {found.final.tau1:.4f} "
            f"tau2 {found.final.tau2:.4f}",
            flush=True,
        )
    return rows


def print_confusion(rows: list[dict]) -> None:
    labels = ["none", *EFFECT_NAMES]
    counts = np.zeros((len(labels), len(labels)), dtype=int)
    for row in rows:
        counts[labels.index(row["truth"]), labels.index(row["verdict"])] += 1
    width = max(len(label) for label in labels) + 1
    print("\nconfusion matrix (rows: true effect, columns: verdict)")
    print(" " * width + "".join(f"{label[:11]:>12}" for label in labels))
    for i, label in enumerate(labels):
        print(f"{label:<{width}}" + "".join(f"{n:>12d}" for n in counts[i]))
    print(f"\n{'truth':<{width}} {'accuracy':>9} {'median fall':>12} {'tau within 5 %':>15}")
    for label in labels:
        mine = [row for row in rows if row["truth"] == label]
        if not mine:
            continue
        accuracy = np.mean([row["verdict"] == label for row in mine])
        fall = np.median([row["fall"] for row in mine])
        tau_ok = np.mean([row["tau_ok"] for row in mine])
        print(f"{label:<{width}} {100 * accuracy:>8.0f}% {fall:>12.2f} {100 * tau_ok:>14.0f}%")
    total = np.mean([row["verdict"] == row["truth"] for row in rows])
    print(f"overall accuracy {100 * total:.1f} % over {len(rows)} records")


def time_40k() -> None:
    sim = simulate_effect("conduction", "multisine", duration=80.0, noise_percent=1.0, seed=5)
    record = Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=None, source="40k", dt=sim.dt)
    started = time.perf_counter()
    data = prepare(record)
    taus = pipeline._initial_taus(data)
    evaluator = pipeline._evaluator(data, taus)
    pipeline._fit_base(evaluator, taus)
    base_s = time.perf_counter() - started
    started = time.perf_counter()
    found = diagnose(record)
    full_s = time.perf_counter() - started
    print(
        f"\ntime on {sim.time.size} samples ({sim.time.size * sim.dt:.0f} s at "
        f"{1 / sim.dt:.0f} Hz, conduction):"
    )
    print(f"  base model (beta-GTLS + held-out score): {base_s:8.3f} s")
    print(
        f"  diagnose (all effects, staircase):       {full_s:8.3f} s "
        f"({full_s / base_s:.0f}x the base model); verdict {found.verdict}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="one signal, one noise, one seed")
    args = parser.parse_args()
    if args.quick:
        rows = run_grid(("multisine",), (1.0,), (1,))
    else:
        rows = run_grid(("multisine", "ramp", "exhaust"), (1.0, 2.0), (1,))
    print_confusion(rows)
    time_40k()


if __name__ == "__main__":
    main()
