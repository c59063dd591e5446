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

``--detailed`` runs records of ``test/detailed_physics.py`` instead, an independent physically
detailed simulator (film-temperature gas properties, Collis & Williams convection, fin
conduction, radiation, transport along the flow, a measurement chain with calibration, mains
and ADC). Rows are true conditions made with its ``Rig`` options (:data:`DETAILED_ROWS`):
clean physics (``none``), radiation, conduction, velocity, delay, calibration, interference,
quantisation (12-bit ADC, expected ``none``) and property (a wide temperature span); each record
draws its sample rate (2 or 5 kHz), noise (0.05-0.2 °C per channel, equal on both) and the
effect's strength from a seeded generator. It prints the confusion matrix, then per row
accuracy, the false-alarm rate of the clean rows, median base and final error, the share with
both τ within 5 % of the truth, the coverage of the 95 % intervals (each fitted parameter with a
truth counterpart: τ1, τ2, gain, offset_c, wall_c, delay_s) and seconds per 40 000 samples. A
diagnose that raises counts as verdict ``error``. The default run ends with a reduced detailed
grid (two records per row); ``--detailed --quick`` runs one record per row.

Run::

    .venv/bin/python bench/bench_diagnose.py            # full grid (several minutes)
    .venv/bin/python bench/bench_diagnose.py --quick    # a smaller grid
    .venv/bin/python bench/bench_diagnose.py --random 42 --seed 23
    .venv/bin/python bench/bench_diagnose.py --detailed           # detailed grid (~5 min)
    .venv/bin/python bench/bench_diagnose.py --detailed --quick   # one record per row
"""

from __future__ import annotations

import argparse
import itertools
import math
import statistics
import sys
import time
from pathlib import Path

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


def random_params(effect, rng, tau1, tau2) -> dict[str, float]:
    """Effect strengths drawn around the defaults of :func:`default_effect_params`."""

    def draw(low: float, high: float) -> float:
        return float(rng.uniform(low, high))

    if effect == "conduction":  # mL of the slower wire's legs 1.3-2.3 (kappa2 0.2-0.9)
        return {"tau_leg": max(tau1, tau2) * draw(1.3, 2.3) ** 2, "tau_p": draw(0.5, 2.5)}
    if effect == "radiation":
        rho1 = draw(0.05, 0.15)
        return {
            "rho1": rho1,
            "rho2": rho1 * (tau2 / tau1) ** (1.0 / 3.0),
            "wall_c": draw(150, 450),
        }
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


def verdict_columns(verdicts) -> list[str]:
    """``none`` and every effect, then any other verdict seen (``unexplained``, ``error``)."""
    known = ["none", *EFFECT_NAMES]
    return known + sorted(set(verdicts) - set(known))


def print_confusion(rows: list[dict]) -> None:
    labels = ["none", *EFFECT_NAMES]
    columns = verdict_columns(row["verdict"] for row in rows)  # "unexplained" and the like too
    counts = np.zeros((len(labels), len(columns)), dtype=int)
    for row in rows:
        counts[labels.index(row["truth"]), columns.index(row["verdict"])] += 1
    width = max(len(label) for label in labels) + 1
    print("\nconfusion matrix (rows: true effect, columns: verdict)")
    print(" " * width + "".join(f"{label[:11]:>12}" for label in columns))
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


# --------------------------------------------------------------------------------------------
# Records of the independent detailed simulator (test/detailed_physics.py)
# --------------------------------------------------------------------------------------------

#: Seeds every detailed record (its rate, noise, strength and the simulator's own seed).
DETAILED_SEED = 2024
#: True conditions of the detailed grid and the verdict each should get.
DETAILED_ROWS: tuple[tuple[str, str], ...] = (
    ("none", "none"),
    ("radiation", "radiation"),
    ("conduction", "conduction"),
    ("velocity", "velocity"),
    ("delay", "delay"),
    ("calibration", "calibration"),
    ("interference", "interference"),
    ("quantisation", "none"),
    ("property", "property"),
)
#: Rows whose records carry no effect: every verdict but "none" is a false alarm.
CLEAN_ROWS = ("none", "quantisation")
#: Records per row of each size of the detailed grid.
DETAILED_SIZES = {"quick": 1, "reduced": 2, "full": 6}
#: Fitted parameter -> key of the simulator's truth, for the 95 % interval coverage.
COVERED = {
    "tau1": "tau1",
    "tau2": "tau2",
    "gain": "gain",
    "offset_c": "offset_c",
    "wall_c": "wall_c",
    "delay_s": "delay_s",
}
DETAILED_RATES_HZ = (2000.0, 5000.0)
DETAILED_NOISES_C = (0.05, 0.1, 0.2)
SAMPLES_40K = 40_000


def detailed_physics():
    """The module ``test/detailed_physics.py`` (the repository's ``test/`` put on the path)."""
    folder = str(Path(__file__).resolve().parents[1] / "test")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    import detailed_physics as module  # only the detailed grid needs it

    return module


def detailed_rig(physics, condition: str, row: int, index: int):
    """Record ``index`` of the row ``condition``: its name and ``Rig``, drawn from a seed."""
    rng = np.random.default_rng([DETAILED_SEED, row, index])
    seed = int(rng.integers(1 << 30))
    rate = DETAILED_RATES_HZ[(row + index) % 2]
    noise = DETAILED_NOISES_C[(row + index) % 3]
    signal = ("rotating_disk", "engine_pulses")[index % 2]
    options: dict = {}
    label = ""
    if condition == "radiation":
        signal = "engine_pulses"
        wall = float(rng.uniform(250.0, 350.0))
        options = {
            "wires": (
                physics.Wire(50e-6, emissivity=0.8),
                physics.Wire(125e-6, emissivity=0.8),
            ),
            "wall_c": wall,
        }
        label = f"/wall{wall:.0f}C"
    elif condition == "conduction":
        options = {"conduction": True}
    elif condition == "velocity":
        amplitude = float(rng.uniform(0.3, 0.5))
        period = float(rng.uniform(3.0, 6.0))
        options = {"speed_fluctuation": amplitude, "speed_period_s": period}
        label = f"/a{amplitude:.2f}/P{period:.1f}s"
    elif condition == "delay":
        delay = float(rng.uniform(0.003, 0.010))
        options = {"spacing_m": delay * physics.Rig.speed_m_s}
        label = f"/{delay * 1e3:.1f}ms"
    elif condition == "calibration":
        options = {"calibration": (2, 1.03, -2.0)}
    elif condition == "interference":
        amplitude = float(rng.uniform(0.3, 1.0))
        options = {"mains_hz": 50.0, "mains_amplitude_c": amplitude, "mains_channel": 2}
        label = f"/{amplitude:.2f}C"
    elif condition == "quantisation":
        noise = DETAILED_NOISES_C[0]  # little noise, so the 0.4 °C steps dominate it
        options = {"adc_bits": 12}
    elif condition == "property":
        # Levels from 100 to 900 °C (pulses: 100 °C baseline, 700 °C peaks, up to ~900 °C with
        # the cycle-to-cycle spread and the drift). Note the detailed physics changes τ by
        # under 7 % over 20-900 °C at a fixed speed (junction_time_constant).
        signal = ("step_ramp", "engine_pulses")[index % 2]
        high = 900.0 if signal == "step_ramp" else 700.0
        options = {"gas_low_c": 100.0, "gas_high_c": high}
    rig = physics.Rig(
        **{
            "signal": signal,
            "duration_s": 10.0,
            "rate_hz": rate,
            "seed": seed,
            "noise_c": (noise, noise),
            "adc_bits": 16,
            **options,
        }
    )
    name = f"{condition}/{signal}/{rate / 1e3:g}kHz/n{noise:g}{label}/s{seed}"
    return name, rig


def detailed_records(size: str):
    """(condition, expected verdict, name, Rig) of every record of the detailed grid."""
    physics = detailed_physics()
    for row, (condition, expected) in enumerate(DETAILED_ROWS):
        for index in range(DETAILED_SIZES[size]):
            name, rig = detailed_rig(physics, condition, row, index)
            yield condition, expected, name, rig


def interval_checks(final, truth: dict[str, float]) -> list[tuple[str, bool]]:
    """(parameter, truth inside its 95 % interval) for each fitted parameter with a truth."""
    radiating = truth.get("rho1", 0.0) > 0.0 or truth.get("rho2", 0.0) > 0.0
    checks = []
    for name, key in COVERED.items():
        if name not in final.intervals or not math.isfinite(truth.get(key, math.nan)):
            continue
        if name == "wall_c" and not radiating:  # no radiation: the wall has no truth
            continue
        low, high = final.intervals[name]
        checks.append((name, bool(low <= truth[key] <= high)))  # NaN bounds: not covered
    return checks


def run_detailed(records) -> list[dict]:
    physics = detailed_physics()
    rows = []
    for condition, expected, name, rig in records:
        row = {
            "truth": condition,
            "expected": expected,
            "verdict": "error",
            "base": math.nan,
            "final": math.nan,
            "tau_ok": False,
            "checks": [],
            "per_40k": math.nan,
            "name": name,
        }
        rows.append(row)
        try:
            rec = physics.simulate_rig(rig)
            record = Record(
                time=rec.time, tc1=rec.tc1, tc2=rec.tc2, ref=rec.gas, source=name, dt=rec.dt
            )
            started = time.perf_counter()
            found = diagnose(record)
            seconds = time.perf_counter() - started
        except Exception as exc:  # a failure is a result of the benchmark, not its end
            print(f"{name:<58} verdict error: {type(exc).__name__}: {exc}", flush=True)
            continue
        truth = rec.truth
        final = found.final
        row.update(
            verdict=found.verdict,
            base=found.base.error_pct,
            final=final.error_pct,
            tau_ok=abs(final.tau1 / truth["tau1"] - 1) <= 0.05
            and abs(final.tau2 / truth["tau2"] - 1) <= 0.05,
            checks=interval_checks(final, truth),
            per_40k=seconds * SAMPLES_40K / rec.time.size,
        )
        covered = sum(ok for _, ok in row["checks"])
        print(
            f"{name:<58} verdict {found.verdict:<12} base {found.base.error_pct:6.2f} "
            f"final {final.error_pct:6.2f} tau1 {final.tau1:.4f}/{truth['tau1']:.4f} "
            f"tau2 {final.tau2:.4f}/{truth['tau2']:.4f} "
            f"in CI {covered}/{len(row['checks'])} {seconds:5.1f} s",
            flush=True,
        )
    return rows


def _median(values) -> float:
    values = [value for value in values if math.isfinite(value)]
    return statistics.median(values) if values else math.nan


def _share(hits: int, total: int) -> str:
    return f"{100 * hits / total:.0f}% ({hits}/{total})" if total else "-"


def print_detailed(rows: list[dict]) -> None:
    conditions = [c for c, _ in DETAILED_ROWS if any(row["truth"] == c for row in rows)]
    seen = {row["verdict"] for row in rows}
    columns = [v for v in verdict_columns(seen) if v in seen]
    width = max(len(label) for label in conditions) + 1
    cell = max(12, *(len(label) + 1 for label in columns))
    print("\ndetailed simulator: confusion matrix (rows: true condition, columns: verdict)")
    print(" " * width + "".join(f"{label:>{cell}}" for label in columns))
    for condition in conditions:
        mine = [row["verdict"] for row in rows if row["truth"] == condition]
        print(f"{condition:<{width}}" + "".join(f"{mine.count(v):>{cell}d}" for v in columns))

    print(
        f"\n{'truth':<{width}} {'n':>3} {'expected':>12} {'accuracy':>9} {'false alarm':>12} "
        f"{'base err %':>11} {'final err %':>12} {'tau within 5 %':>15} {'95 % CI covers':>15} "
        f"{'s/40k':>7}"
    )
    for condition in conditions:
        mine = [row for row in rows if row["truth"] == condition]
        expected = mine[0]["expected"]
        accuracy = np.mean([row["verdict"] == expected for row in mine])
        alarm = "-"
        if condition in CLEAN_ROWS:
            alarm = f"{100 * np.mean([row['verdict'] != 'none' for row in mine]):.0f}%"
        checks = [ok for row in mine for _, ok in row["checks"]]
        print(
            f"{condition:<{width}} {len(mine):>3} {expected:>12} {100 * accuracy:>8.0f}% "
            f"{alarm:>12} {_median(row['base'] for row in mine):>11.2f} "
            f"{_median(row['final'] for row in mine):>12.2f} "
            f"{100 * np.mean([row['tau_ok'] for row in mine]):>14.0f}% "
            f"{_share(sum(checks), len(checks)):>15} "
            f"{_median(row['per_40k'] for row in mine):>7.2f}"
        )

    total = np.mean([row["verdict"] == row["expected"] for row in rows])
    clean = [row for row in rows if row["truth"] in CLEAN_ROWS]
    alarms = sum(row["verdict"] != "none" for row in clean)
    checks = [check for row in rows for check in row["checks"]]
    errors = sum(row["verdict"] == "error" for row in rows)
    per_40k = [row["per_40k"] for row in rows if math.isfinite(row["per_40k"])]
    print(f"overall accuracy {100 * total:.1f} % over {len(rows)} records ({errors} errors)")
    print(f"false alarms on the clean rows: {_share(alarms, len(clean))}")
    print(f"95 % intervals covering the truth: {_share(sum(ok for _, ok in checks), len(checks))}")
    by_param = []
    for name in COVERED:
        mine = [ok for n, ok in checks if n == name]
        if mine:
            by_param.append(f"{name} {_share(sum(mine), len(mine))}")
    if by_param:
        print("  by parameter: " + ", ".join(by_param))
    if per_40k:
        print(
            f"time per 40 000 samples (diagnose, scaled from each record's length): median "
            f"{statistics.median(per_40k):.2f} s, max {max(per_40k):.2f} s"
        )


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
    parser.add_argument(
        "--detailed",
        action="store_true",
        help="records of the detailed simulator test/detailed_physics.py (with --quick: one "
        "per row)",
    )
    args = parser.parse_args()
    if args.detailed:
        print_detailed(run_detailed(detailed_records("quick" if args.quick else "full")))
        return
    if args.random:
        rows = run_records(random_records(args.random, args.seed))
    elif args.quick:
        rows = run_records(grid_records(("multisine",), (1.0,), (1,)))
    else:
        rows = run_records(grid_records(("multisine", "ramp", "exhaust"), (1.0, 2.0), (1,)))
    print_confusion(rows)
    if not args.random and not args.quick:
        print_detailed(run_detailed(detailed_records("reduced")))
    if not args.random:
        time_40k()


if __name__ == "__main__":
    main()
