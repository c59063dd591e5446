"""How long the diagnosis takes, against a baseline commit measured in the same run.

The diagnosis as ``tcomp reconstruct --effects auto`` runs it
(:func:`tcomp_core.compensation.fit_output_model`: the default first-order estimate, the
diagnosis, the output model) on campaign draws (``bench/campaign_draws.py``, simulated once
by this checkout and handed to both codes as the same arrays) and on bags (read by each code's
own reader). Each record is diagnosed in a child process of its own by the baseline's code
(``git archive`` of ``--baseline`` unpacked in a temporary directory and put first on the
child's ``PYTHONPATH``) and by this checkout's, alternating which goes first from one repeat
to the next, so that both see the same load on a busy machine.

It prints, per record, the median wall and CPU seconds of each code, their ratios (baseline /
current: above 1 the current code is faster) and whether the two found the same: the verdict,
the final effects and the output model's name (its applied pieces) equal; whether the current
code's τ1, τ2 (the base model's and the final model's) lie in the baseline fits' own 95 %
intervals; and the largest relative difference of any number in the diagnosis's JSON
(``tcomp diagnose --json``) and the output model's summary. ``identical`` means every number
and every string of both documents is the same.

Usage::

    PYTHONPATH=. .venv/bin/python bench/bench_diagnose_speed.py \\
        --draws 2003,2010 --bags bags/conduction_500hz --repeats 1

``--baseline`` defaults to the commit where this branch left ``main``, so that the baseline
is the code the branch changed, however ``main`` has moved since.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

REPOSITORY = Path(__file__).resolve().parents[1]


def child(source: str, out: str) -> None:
    """Diagnose one record as ``fit_output_model`` does; write timings and results to ``out``.

    Runs with whichever ``tcomp_core`` is first on ``PYTHONPATH``, so it uses only what the
    baseline has too. A refusal is a result: a diagnosis that raises is recorded as its
    message (verdict ``error``), an output model refused (no gas compensated) as
    ``refused`` with its message.
    """
    import numpy as np

    from tcomp_core.compensation import (
        default_estimate,
        default_first_order_failure,
        output_model_from_diagnosis,
    )
    from tcomp_core.diagnose import diagnose
    from tcomp_core.diagnose.result import diagnosis_to_dict
    from tcomp_core.errors import TcompError
    from tcomp_core.io import Record, read_record

    if source.endswith(".npz"):
        arrays = np.load(source)
        record = Record(
            time=arrays["time"],
            tc1=arrays["tc1"],
            tc2=arrays["tc2"],
            ref=arrays.get("ref"),
            source=Path(source).stem,
            dt=float(arrays["dt"]),
        )
    else:
        record = read_record(source)
    wall, cpu = time.perf_counter(), time.process_time()
    plain = default_estimate(record)
    taus = None if plain is None else (float(plain.tau1), float(plain.tau2))
    lines = () if plain is None else plain.lines
    found: dict[str, Any]
    try:
        diagnosis = diagnose(record, published_taus=taus, published_lines=lines)
    except TcompError as exc:
        found = {"verdict": "error", "error": str(exc), "final": {"effects": []}}
        summary, name = {}, "error"
    else:
        found = diagnosis_to_dict(diagnosis)
        try:
            output = output_model_from_diagnosis(
                diagnosis,
                origin_s=float(record.time[0]),
                first_order_taus=taus,
                first_order_lines=lines,
                first_order_failure=default_first_order_failure(record, plain),
            )
        except TcompError as exc:
            summary, name = {"refused": str(exc)}, "refused"
        else:
            summary, name = output.summary(), output.name()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    document = {
        "seconds": wall,
        "cpu_seconds": cpu,
        "samples": int(record.tc1.size),
        "diagnosis": found,
        "output": summary,
        "output_name": name,
    }
    Path(out).write_text(json.dumps(document, default=float))


def merge_base() -> str:
    """The commit where this checkout's branch left ``main`` (main itself on main)."""
    found = subprocess.run(
        ["git", "-C", str(REPOSITORY), "merge-base", "HEAD", "main"],
        capture_output=True,
        text=True,
        check=True,
    )
    return found.stdout.strip()


def unpack_baseline(reference: str, into: Path) -> Path:
    """``git archive`` of ``reference`` unpacked in ``into``; its root."""
    archive = into / "baseline.tar"
    with archive.open("wb") as handle:
        subprocess.run(
            ["git", "-C", str(REPOSITORY), "archive", reference], stdout=handle, check=True
        )
    root = into / "baseline"
    with tarfile.open(archive) as tar:
        tar.extractall(root, filter="data")
    return root


def child_environment(root: Path) -> dict[str, str]:
    """This process's environment with ``root``'s code first on ``PYTHONPATH``, one BLAS thread."""
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(
        [str(root), *filter(None, [environment.get("PYTHONPATH")])]
    )
    environment.setdefault("OMP_NUM_THREADS", "1")
    return environment


def run_child(root: Path, source: str, scratch: Path) -> dict[str, Any]:
    """One diagnosis in a child process with ``root``'s code first on the path."""
    out = scratch / "result.json"
    command = [sys.executable, str(Path(__file__).resolve()), "--child", source, str(out)]
    subprocess.run(command, env=child_environment(root), check=True, cwd=REPOSITORY)
    return json.loads(out.read_text())


def differences(left: Any, right: Any, path: str = "") -> tuple[float, list[str]]:
    """Largest relative difference of the numbers in two JSON documents, and unequal leaves.

    Numbers compare by |a − b| / max(|a|, |b|) (NaN equals NaN); anything else must be equal.
    """
    if isinstance(left, dict) and isinstance(right, dict):
        if left.keys() != right.keys():
            return math.inf, [f"{path}: keys {sorted(left.keys() ^ right.keys())}"]
        largest, unequal = 0.0, []
        for key in left:
            found, where = differences(left[key], right[key], f"{path}.{key}")
            largest, unequal = max(largest, found), unequal + where
        return largest, unequal
    if isinstance(left, list) and isinstance(right, list):
        if len(left) != len(right):
            return math.inf, [f"{path}: lengths {len(left)} and {len(right)}"]
        largest, unequal = 0.0, []
        for index, (a, b) in enumerate(zip(left, right, strict=True)):
            found, where = differences(a, b, f"{path}[{index}]")
            largest, unequal = max(largest, found), unequal + where
        return largest, unequal
    numbers = (int, float)
    if isinstance(left, numbers) and isinstance(right, numbers) and not isinstance(left, bool):
        a, b = float(left), float(right)
        if a == b or (math.isnan(a) and math.isnan(b)):
            return 0.0, []
        scale = max(abs(a), abs(b))
        relative = abs(a - b) / scale if math.isfinite(scale) else math.inf
        return relative, [f"{path}: {a!r} / {b!r}"]
    return (0.0, []) if left == right else (math.inf, [f"{path}: {left!r} / {right!r}"])


def taus_inside(old: dict[str, Any], new: dict[str, Any]) -> bool:
    """Whether the new diagnosis's τ1, τ2 (base model and final) lie in the old's 95 % intervals.

    A τ without an interval (the fit's covariance singular) counts as inside only when equal.
    """
    if "error" in old or "error" in new:
        return old.get("error") == new.get("error")
    for step in ("base", "final"):
        for name in ("tau1", "tau2"):
            value = new[step][name]
            low, high = old[step].get("intervals_95", {}).get(name, (None, None))
            if low is None or high is None:
                if value != old[step][name]:
                    return False
            elif not low <= value <= high:
                return False
    return True


def draw_indices(text: str) -> list[int]:
    """Draws from ``"2003,2010"`` or ranges ``"5000-5019"``."""
    indices: list[int] = []
    for part in filter(None, text.split(",")):
        first, _, last = part.partition("-")
        indices += range(int(first), int(last or first) + 1)
    return indices


def records(draws: list[int], bags: list[str], scratch: Path) -> list[tuple[str, str]]:
    """(label, source) of every record: draws saved as ``.npz``, bags as their paths."""
    found = []
    if draws:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import campaign_draws
        import numpy as np

        for index in draws:
            record, _ = campaign_draws.simulate(campaign_draws.draw(index))
            path = scratch / f"draw{index}.npz"
            arrays = {"time": record.time, "tc1": record.tc1, "tc2": record.tc2}
            if record.ref is not None:
                arrays["ref"] = record.ref
            np.savez(path, dt=record.dt, **arrays)
            found.append((f"draw {index}", str(path)))
    found += [(bag, str((REPOSITORY / bag).resolve())) for bag in bags]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--baseline",
        help="git commit or branch to compare with (default: where this branch left main)",
    )
    parser.add_argument(
        "--draws",
        default="2003,2010,2020,2030,2040",
        help="campaign draws (2003,2010 or 5000-5019)",
    )
    parser.add_argument(
        "--bags", default="bags/conduction_500hz,bags/radiation_500hz", help="bag paths"
    )
    parser.add_argument("--repeats", type=int, default=1, help="runs of each code per record")
    parser.add_argument("--json", type=Path, help="write every run and comparison here")
    parser.add_argument("--child", nargs=2, metavar=("SOURCE", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    baseline = args.baseline or merge_base()
    draws = draw_indices(args.draws)
    bags = [text for text in args.bags.split(",") if text]
    with tempfile.TemporaryDirectory() as directory:
        scratch = Path(directory)
        codes = {"baseline": unpack_baseline(baseline, scratch), "current": REPOSITORY}
        rows, everything = [], []
        header = (
            f"{'record':<24} {'samples':>7} {'base s':>8} {'now s':>8} {'wall x':>7} "
            f"{'base cpu':>8} {'now cpu':>8} {'cpu x':>6}  same verdict/effects/output, "
            "tau in the baseline's 95 % intervals, largest relative difference"
        )
        print(f"baseline {baseline}; current {REPOSITORY}")
        print(header)
        for label, source in records(draws, bags, scratch):
            runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "current": []}
            for repeat in range(args.repeats):
                order = ["baseline", "current"] if repeat % 2 == 0 else ["current", "baseline"]
                for name in order:
                    runs[name].append(run_child(codes[name], source, scratch))
            old, new = runs["baseline"][0], runs["current"][0]
            largest, unequal = differences(
                {"d": old["diagnosis"], "o": old["output"]},
                {"d": new["diagnosis"], "o": new["output"]},
            )
            same = (
                old["diagnosis"]["verdict"] == new["diagnosis"]["verdict"]
                and old["diagnosis"]["final"]["effects"] == new["diagnosis"]["final"]["effects"]
                and old["output_name"] == new["output_name"]
            )
            times = {
                name: (
                    statistics.median(run["seconds"] for run in done),
                    statistics.median(run["cpu_seconds"] for run in done),
                )
                for name, done in runs.items()
            }
            (base_wall, base_cpu), (now_wall, now_cpu) = times["baseline"], times["current"]
            verdicts = f"{old['diagnosis']['verdict']}/{new['diagnosis']['verdict']}"
            outputs = f"{old['output_name']}/{new['output_name']}"
            inside = taus_inside(old["diagnosis"], new["diagnosis"])
            print(
                f"{label:<24} {new['samples']:>7} {base_wall:>8.2f} {now_wall:>8.2f} "
                f"{base_wall / now_wall:>6.2f}x {base_cpu:>8.2f} {now_cpu:>8.2f} "
                f"{base_cpu / now_cpu:>5.2f}x  {'yes' if same else 'NO'} ({verdicts}, "
                f"{outputs}), tau {'inside' if inside else 'OUTSIDE'}, "
                + ("identical" if not unequal else f"{largest:.2g} in {len(unequal)} values"),
                flush=True,
            )
            for line in unequal[:5]:
                print(f"    {line}")
            rows.append((base_wall, now_wall, base_cpu, now_cpu))
            everything.append(
                {
                    "record": label,
                    "runs": runs,
                    "same": same,
                    "taus_inside": inside,
                    "largest": largest,
                    "unequal": unequal,
                }
            )
        if rows:
            totals = [sum(column) for column in zip(*rows, strict=True)]
            print(
                f"{'total':<24} {'':>7} {totals[0]:>8.2f} {totals[1]:>8.2f} "
                f"{totals[0] / totals[1]:>6.2f}x {totals[2]:>8.2f} {totals[3]:>8.2f} "
                f"{totals[2] / totals[3]:>5.2f}x"
            )
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        print(f"children's CPU: {usage.ru_utime + usage.ru_stime:.1f} s")
        if args.json:
            args.json.write_text(json.dumps(everything, default=float, indent=1))


if __name__ == "__main__":
    main()
