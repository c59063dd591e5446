"""What ``tcomp diagnose`` and ``tcomp fit`` share: their output options, text and files."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .common import add_force_argument

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ..diagnose import Diagnosis
    from ..diagnose.result import Suspect
    from ..diagnose.windowed import WindowedDiagnosis

__all__ = [
    "add_outputs",
    "format_diagnosis",
    "format_windowed",
    "write_diagnosis",
    "write_windowed",
]


def add_outputs(parser: argparse.ArgumentParser) -> None:
    """Add ``--report DIR`` (HTML report), ``--json FILE`` and ``--force`` to a verb's parser."""
    parser.add_argument("--report", type=Path, metavar="DIR", help="write an HTML report here")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the results as JSON")
    add_force_argument(parser, "replace an existing --report or --json")


def write_diagnosis(diagnosis: Diagnosis, args: argparse.Namespace) -> int:
    """Print the diagnosis, write ``--json`` and ``--report`` if given; returns exit status 0."""
    from ..diagnose import diagnosis_to_dict

    print(format_diagnosis(diagnosis))
    if args.json:
        _write_json(diagnosis_to_dict(diagnosis), args)
    if args.report:
        from ..report import write_report  # matplotlib only when a report is asked for

        report = write_report(diagnosis, args.report, overwrite=args.force, inputs=[args.data])
        print(f"report: {report}")
    return 0


def format_diagnosis(diagnosis: Diagnosis) -> str:
    """The text ``tcomp diagnose`` prints.

    Parameters
    ----------
    diagnosis : Diagnosis
        The result of :func:`tcomp_core.diagnose.diagnose` or ``fit_effects``.

    Returns
    -------
    str
        Several lines: base model, where it fails, the suspects of each round, the error
        staircase, the verdict and the final model.
    """
    base, final = diagnosis.base, diagnosis.final
    lines = [
        f"{diagnosis.source}: {diagnosis.time.size} samples at {1 / diagnosis.dt:.6g} Hz; "
        f"tc{diagnosis.slow} (the slower) simulated from tc{3 - diagnosis.slow}",
        f"base model (first order): tau1 = {base.tau1:.5g} s, tau2 = {base.tau2:.5g} s, "
        f"held-out error {base.error_pct:.3g} %",
        "where it fails:",
        *(f"  - {finding}" for finding in diagnosis.failure.findings),
    ]
    for number, suspects in enumerate(diagnosis.rounds, start=1):
        lines.append(f"suspects, round {number} (best first):")
        lines.append(f"  {'effect':<12} {'held-out %':>10} {'evidence':>9} {'significant':>11}")
        for s in suspects:
            lines.append(
                f"  {s.effect:<12} {s.error_pct:>10.3g} {s.evidence:>+9.2f} "
                f"{'yes' if s.significant else 'no':>11}"
            )
        best = suspects[0] if suspects else None
        if best is not None:
            lines.append(f"  {best.effect}: {best.signature}")
        lines.extend(
            f"  {s.effect} not significant: {s.refusal}" for s in _refused_ahead(suspects)
        )
    lines.append("error staircase (held-out error):")
    for step in diagnosis.steps:
        label = "base" if not step.effects else "+ " + " + ".join(step.effects)
        lines.append(f"  {label:<40} {step.error_pct:8.3g} %")
    handled = (
        " (found by the default path, which accounts for it itself: see the notes)"
        if diagnosis.verdict in diagnosis.default_path_findings
        else ""
    )
    lines.append(f"verdict: {diagnosis.verdict}{handled}")
    lines.append(
        f"final: effects {', '.join(final.effects) or 'none'}; tau1 = {final.tau1:.5g} s, "
        f"tau2 = {final.tau2:.5g} s, held-out error {final.error_pct:.3g} %"
    )
    for name, (low, high) in final.intervals.items():
        flag = "  (at its physical bound)" if name in final.at_bound else ""
        lines.append(
            f"  {name} = {final.params[name]:.5g}, 95 % interval {low:.5g} .. {high:.5g}{flag}"
        )
    if diagnosis.unexplained:
        lines.append(f"unexplained: {diagnosis.unexplained}")
    lines.extend(f"identifiability: {text}" for text in diagnosis.identifiability)
    for name, value in diagnosis.ref_error_pct.items():
        lines.append(f"reference vs {name}: {value:.3g} % of its spread")
    lines.extend(f"note: {note}" for note in diagnosis.notes)
    return "\n".join(lines)


def _write_json(document: dict[str, Any], args: argparse.Namespace) -> None:
    """Write ``--json`` (atomically, never over the input) and say where."""
    from ..io import atomic_output

    with atomic_output(args.json, args.force, [args.data]) as temporary:
        temporary.write_text(json.dumps(document, indent=2) + "\n")
    print(f"json: {args.json}")


def write_windowed(result: WindowedDiagnosis, args: argparse.Namespace) -> int:
    """Print a diagnosis in windows, write ``--json`` and ``--report`` if given; returns 0."""
    from ..diagnose.windowed import windowed_to_dict

    print(format_windowed(result))
    if args.json:
        _write_json(windowed_to_dict(result), args)
    if args.report:
        from ..report import write_windowed_report  # matplotlib only when asked for

        report = write_windowed_report(
            result, args.report, overwrite=args.force, inputs=[args.data]
        )
        print(f"report: {report}")
    return 0


def format_windowed(result: WindowedDiagnosis) -> str:
    """The text ``tcomp diagnose`` prints for a record diagnosed in windows.

    One row per window (start, samples, τ1 and τ2 with their 95 % intervals, held-out error,
    verdict and the final model's effects, or why it was not diagnosed), then the whole
    record's verdict and τ, the windows that disagree and the windows' notes.
    """

    def tau(value: float, interval: tuple[float, float] | None) -> str:
        if interval is None:
            return f"{value:.4g}"
        return f"{value:.4g} [{interval[0]:.4g}, {interval[1]:.4g}]"

    rows = result.windows
    how = "chosen for a record this long" if result.automatic else "as asked"
    lines = [
        f"{result.source}: {len(rows)} windows of {result.window_s:g} s ({how}), each "
        "diagnosed on its own",
        f"  {'window':>6} {'start s':>8} {'samples':>8}  {'tau1 s [95 %]':<28} "
        f"{'tau2 s [95 %]':<28} {'error %':>8}  {'verdict':<12} effects",
    ]
    for row in rows:
        head = f"  {row.index + 1:>6} {row.start_s:>8.6g} {row.samples:>8}  "
        if row.verdict is None:
            lines.append(f"{head}not diagnosed: {row.problem}")
            continue
        mark = "" if row.votes else "  (short last window: no vote)"
        lines.append(
            f"{head}{tau(row.tau1, row.tau1_95):<28} {tau(row.tau2, row.tau2_95):<28} "
            f"{row.error_pct:>8.3g}  {row.verdict:<12} {', '.join(row.effects) or '-'}{mark}"
        )
    whole = result.whole
    lines.append(
        f"whole record: verdict {whole.verdict} (the verdict of {whole.agree} of "
        f"{whole.voting} windows); tau1 = {whole.tau1:.5g} s, tau2 = {whole.tau2:.5g} s "
        f"(medians over those windows; ranges {whole.tau1_range[0]:.4g} .. "
        f"{whole.tau1_range[1]:.4g} s and {whole.tau2_range[0]:.4g} .. "
        f"{whole.tau2_range[1]:.4g} s)"
    )
    if whole.disagreeing:
        others = {row.index: row for row in rows}
        listed = ", ".join(
            f"{index + 1} at {others[index].start_s:g} s: {others[index].verdict}"
            for index in whole.disagreeing
        )
        lines.append(f"windows disagree: {listed}")
    missing = [row for row in rows if row.verdict is None]
    if missing:
        lines.append(
            f"not diagnosed: {len(missing)} of {len(rows)} windows (their rows say why); the "
            "verdict rests on the others"
        )
    for row in rows:
        lines.extend(f"note: window {row.index + 1}: {note}" for note in row.notes)
    return "\n".join(lines)


def _refused_ahead(suspects: Sequence[Suspect]) -> list[Suspect]:
    """The suspects that lowered the error, ranked above any significant one and refused.

    What a user asks about: a better held-out error that was still not taken.
    """
    refused = []
    for suspect in suspects:
        if suspect.significant:
            break
        if suspect.evidence > 0.0 and suspect.refusal:
            refused.append(suspect)
    return refused
