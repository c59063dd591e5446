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

``--random N`` replaces the grid by N records drawn at random (seeded by ``--seed``), no
reference given to the diagnosis: effects cycle through none and the six, and each record
draws its gas signal (sinusoid included), sample interval (2, 1 or 0.5 ms), length (10 or
20 s), K (0.5, 1 or 2 %), τ1 in 10–40 ms, τ2/τ1 in 3–6 and the effect's strength
(:func:`random_params`). It shows how far the verdicts hold beyond the grid's defaults.

Run::

    .venv/bin/python bench/bench_diagnose.py            # full grid (several minutes)
    .venv/bin/python bench/bench_diagnose.py --quick    # a smaller grid
    .venv/bin/python bench/bench_diagnose.py --random 42 --seed 23
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
from tcomp_core.simulate_effects import (
    KELVIN,
    RADIATION_MEAN_C,
    simulate_effect,
)

TRUTHS = (None, *EFFECT_NAMES)
TAU_PAIRS = ((0.0238, 0.1168), (0.015, 0.06))


def record_of(effect, kind, noise, taus, seed) -> tuple[Record, object]:
    sim = simulate_effect(
        effect, kind, tau1=taus[0], tau2=taus[1], duration=10.0, noise_percent=noise, seed=seed
    )
    name = f"{effect or 'none'}/{kind}/K{noise}/tau{taus[0]}/s{seed}"
    record = Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=sim.gas, source=name, dt=sim.dt)
    return record, sim


def random_params(effect, rng, tau1, tau2) -> dict[str, float]:
    """Effect strengths drawn around the defaults of :func:`default_effect_params`."""

    def draw(low: float, high: float) -> float:
        return float(rng.uniform(low, high))

    if effect == "conduction":
        kappa1 = draw(0.03, 0.1)
        return {"kappa1": kappa1, "kappa2": kappa1 * draw(3.0, 6.0), "tau_p": draw(0.5, 2.5)}
    if effect == "radiation":
        r1 = draw(0.05, 0.15) / (4.0 * (RADIATION_MEAN_C + KELVIN) ** 3)
        return {"r1": r1, "r2": r1 * (tau2 / tau1) ** (1.0 / 3.0), "wall_c": draw(150, 450)}
    if effect == "velocity":
        return {"m": draw(0.5, 0.8), "depth": draw(0.25, 0.5), "period_s": draw(3.0, 10.0)}
    if effect == "delay":
        return {"delay_s": draw(0.005, 0.015)}
    if effect == "calibration":
        return {
            "gain": 1.0 + float(rng.choice([-1, 1])) * draw(0.02, 0.05),
            "offset_c": draw(-8, 8),
        }
    if effect == "noise_ratio":
        return {"sigma_ratio": draw(2.0, 4.0) if rng.random() < 0.5 else draw(0.25, 0.5)}
    return {}


def random_records(count: int, seed: int):
    """``count`` (record, simulation) pairs drawn as the module docstring says."""
    rng = np.random.default_rng(seed)
    for i in range(count):
        effect = TRUTHS[i % len(TRUTHS)]
        kind = str(rng.choice(["multisine", "ramp", "exhaust", "sinusoid"]))
        dt = float(rng.choice([0.002, 0.001, 0.0005]))
        duration = float(rng.choice([10.0, 20.0]))
        noise = float(rng.choice([0.5, 1.0, 2.0]))
        tau1 = float(rng.uniform(0.01, 0.04))
        tau2 = tau1 * float(rng.uniform(3.0, 6.0))
        params = random_params(effect, rng, tau1, tau2)
        sim = simulate_effect(
            effect,
            kind,
            tau1=tau1,
            tau2=tau2,
            dt=dt,
            duration=duration,
            noise_percent=noise,
            seed=int(rng.integers(1 << 30)),
            params=params,
        )
        name = f"{i}:{effect or 'none'}/{kind}/dt{dt * 1e3:g}ms/{duration:g}s/K{noise}"
        yield (
            Record(time=sim.time, tc1=sim.tc1, tc2=sim.tc2, ref=None, source=name, dt=sim.dt),
            sim,
        )


def grid_records(signals, noises, seeds):
    for effect, kind, noise, taus, seed in itertools.product(
        TRUTHS, signals, noises, TAU_PAIRS, seeds
    ):
        yield record_of(effect, kind, noise, taus, seed)


def run_records(records) -> list[dict]:
    rows = []
    for record, sim in records:
        effect = sim.effect
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
    parser.add_argument("--random", type=int, default=0, help="N random records, no reference")
    parser.add_argument("--seed", type=int, default=23, help="seed of --random")
    args = parser.parse_args()
    if args.random:
        rows = run_records(random_records(args.random, args.seed))
    elif args.quick:
        rows = run_records(grid_records(("multisine",), (1.0,), (1,)))
    else:
        rows = run_records(grid_records(("multisine", "ramp", "exhaust"), (1.0, 2.0), (1,)))
    print_confusion(rows)
    if not args.random:
        time_40k()


if __name__ == "__main__":
    main()
