"""The ``tcomp diagnose`` and ``tcomp fit`` commands: model against measurement, effects."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .diagnose import Diagnosis, diagnose, diagnosis_to_dict, fit_effects
from .effects import EFFECT_NAMES

__all__ = ["add_diagnose_commands", "format_diagnosis"]


def _effect_list(text: str) -> list[str]:
    names = [name.strip() for name in text.split(",") if name.strip()]
    for name in names:
        if name not in EFFECT_NAMES:
            raise argparse.ArgumentTypeError(
                f"unknown effect {name!r}; choose from {', '.join(EFFECT_NAMES)}"
            )
    return names


def add_diagnose_commands(verbs: Any, add_data_arguments: Any) -> None:
    """Register ``diagnose`` and ``fit`` on the sub-parsers of ``tcomp``."""
    dia = verbs.add_parser(
        "diagnose",
        help="compare the model with the data, find where it fails and the missing effect",
        description="Fit the first-order model (beta-GTLS), score its free-run simulation of "
        "the slow sensor on held-out blocks, analyse where it fails, rank the effects "
        f"({', '.join(EFFECT_NAMES)}) by held-out error after refitting, and add the best "
        "while the error falls significantly.",
    )
    add_data_arguments(dia)
    dia.add_argument(
        "--candidates",
        type=_effect_list,
        default=list(EFFECT_NAMES),
        help="comma-separated effects to consider (default all)",
    )
    dia.add_argument("--max-effects", type=int, default=3, help="most effects to add (default 3)")
    _add_outputs(dia)
    dia.set_defaults(handler=_cmd_diagnose)

    fit = verbs.add_parser(
        "fit",
        help="fit the model with a chosen set of effects",
        description="Fit the first-order model plus the effects given, in that order, and "
        "score every step on held-out blocks like diagnose does.",
    )
    add_data_arguments(fit)
    fit.add_argument(
        "--effects",
        type=_effect_list,
        required=True,
        help=f"comma-separated effects to add, from {', '.join(EFFECT_NAMES)}",
    )
    _add_outputs(fit)
    fit.set_defaults(handler=_cmd_fit)


def _add_outputs(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--report", type=Path, metavar="DIR", help="write an HTML report here")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the results as JSON")


def _finish(diagnosis: Diagnosis, args: argparse.Namespace) -> int:
    print(format_diagnosis(diagnosis))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(diagnosis_to_dict(diagnosis), indent=2) + "\n")
        print(f"json: {args.json}")
    if args.report:
        from .report import write_report  # matplotlib only when a report is asked for

        print(f"report: {write_report(diagnosis, args.report)}")
    return 0


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from .cli import read_data

    if args.max_effects < 0:
        raise ValueError(f"--max-effects {args.max_effects} must be >= 0")
    record = read_data(args)
    return _finish(
        diagnose(record, candidates=args.candidates, max_effects=args.max_effects), args
    )


def _cmd_fit(args: argparse.Namespace) -> int:
    from .cli import read_data

    return _finish(fit_effects(read_data(args), args.effects), args)


def format_diagnosis(diagnosis: Diagnosis) -> str:
    """The text ``tcomp diagnose`` prints."""
    base, final = diagnosis.base, diagnosis.final
    lines = [
        f"{diagnosis.source}: {diagnosis.time.size} samples at {1 / diagnosis.dt:.6g} Hz; "
        f"tc{diagnosis.slow} (the slower) simulated from tc{3 - diagnosis.slow}",
        f"base model (beta-GTLS, phi = 1): tau1 = {base.tau1:.5g} s, tau2 = {base.tau2:.5g} s, "
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
    lines.append("error staircase (held-out error):")
    for step in diagnosis.steps:
        label = "base" if not step.effects else "+ " + " + ".join(step.effects)
        lines.append(f"  {label:<40} {step.error_pct:8.3g} %")
    lines.append(f"verdict: {diagnosis.verdict}")
    lines.append(
        f"final: effects {', '.join(final.effects) or 'none'}; tau1 = {final.tau1:.5g} s, "
        f"tau2 = {final.tau2:.5g} s, held-out error {final.error_pct:.3g} %"
    )
    for name, value in diagnosis.ref_error_pct.items():
        lines.append(f"reference vs {name}: {value:.3g} % of its spread")
    lines.extend(f"note: {note}" for note in diagnosis.notes)
    return "\n".join(lines)
