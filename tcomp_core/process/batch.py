"""Many records at once: ``--jobs N`` worker processes, and the summary table.

A directory that is not itself a bag holds the inputs: its bag directories (with
``metadata.yaml``), bare ``.mcap`` files and ``.csv`` files, each processed into the output
directory under its own name (``NAME`` for a bag, ``NAME.csv`` for CSV output with
``suffix='.csv'``). A failing input does not stop the others; its row says why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from ..errors import DataError, TcompError
from ..io import is_data_file
from .pipeline import ProcessConfig, ProcessResult, process
from .progress import progress_bar

__all__ = ["Outcome", "find_inputs", "format_summary", "process_many", "process_one"]


@dataclass(frozen=True)
class Outcome:
    """One input's result, or the error that stopped it."""

    source: Path
    output: Path
    result: ProcessResult | None = None
    error: str = ""


def find_inputs(directory: Path) -> list[Path]:
    """The bags, ``.mcap`` and ``.csv`` files directly inside ``directory``, sorted by name."""
    if not directory.is_dir():
        raise DataError(f"{directory}: not a directory")
    found = [item for item in sorted(directory.iterdir()) if is_data_file(item)]
    if not found:
        raise DataError(f"{directory}: holds no bag directory, .mcap or .csv file")
    return found


def _output_name(source: Path, out_dir: Path, suffix: str) -> Path:
    return out_dir / f"{source.stem if source.is_file() else source.name}{suffix}"


def process_one(source: Path, output: Path, config: ProcessConfig, show_progress: bool) -> Outcome:
    """Process one input; an error becomes the outcome's ``error`` instead of raising."""
    try:
        bar = progress_bar(source.name) if show_progress else None
        return Outcome(source, output, process(source, output, config, progress=bar))
    except (TcompError, ValueError, OSError) as exc:
        return Outcome(source, output, error=str(exc))


def process_many(
    sources: Sequence[Path],
    out_dir: Path,
    config: ProcessConfig,
    *,
    jobs: int = 1,
    suffix: str = "",
) -> list[Outcome]:
    """Process ``sources`` into ``out_dir``, ``jobs`` at a time in worker processes.

    Parameters
    ----------
    sources : sequence of Path
        Bags or CSV files.
    out_dir : Path
        Directory of the outputs (created).
    config : ProcessConfig
    jobs : int
        Worker processes (1: in this process, with a progress bar on a terminal).
    suffix : str
        '' for bag outputs, '.csv' for CSV outputs.

    Returns
    -------
    list of Outcome
        In the order of ``sources``.
    """
    if jobs < 1:
        raise ValueError(f"{jobs=} must be >= 1")
    out_dir.mkdir(parents=True, exist_ok=True)
    outputs = [_output_name(source, out_dir, suffix) for source in sources]
    if len(set(outputs)) != len(outputs):
        raise DataError(f"{out_dir}: two inputs would write the same output name")
    if jobs == 1 or len(sources) == 1:
        return [process_one(s, o, config, True) for s, o in zip(sources, outputs, strict=True)]
    with ProcessPoolExecutor(max_workers=min(jobs, len(sources))) as pool:
        futures = [
            pool.submit(process_one, s, o, config, False)
            for s, o in zip(sources, outputs, strict=True)
        ]
        return [future.result() for future in futures]


def format_summary(outcomes: Sequence[Outcome]) -> str:
    """The summary table: bag, pairs, τ1, τ2, verdict, seconds, pairs/s (and errors).

    ``seconds`` is the whole run; ``diagnosis`` the part of it the closing diagnosis took, and
    ``pairs/s`` the rate of the rest (reading, estimation, reconstruction, writing).
    """
    name_width = max([len("input"), *(len(o.source.name) for o in outcomes)])
    lines = [
        f"{'input':<{name_width}} {'pairs':>10} {'tau1 (s)':>10} {'tau2 (s)':>10} "
        f"{'verdict':<12} {'seconds':>8} {'diagnosis':>10} {'pairs/s':>10}"
    ]
    for outcome in outcomes:
        name = f"{outcome.source.name:<{name_width}}"
        result = outcome.result
        if result is None:
            lines.append(f"{name} failed: {outcome.error}")
            continue
        tau1, tau2 = result.tau if result.tau else (math.nan, math.nan)
        share = f"{result.diagnosis_seconds:.2f} s" if result.verdict != "skipped" else "skipped"
        verdict = _verdict_cell(result.verdict)
        lines.append(
            f"{name} {result.pairs:>10} {tau1:>10.5g} {tau2:>10.5g} {verdict:<12} "
            f"{result.seconds:>8.2f} {share:>10} {result.pairs_per_s:>10.4g}"
        )
    for outcome in outcomes:
        output = outcome.result.output_model if outcome.result is not None else {}
        if output:
            pieces = "; ".join(
                f"{p['effect']}: {p['handling']}"
                + (f" ({p['reason']})" if p["handling"] == "first order" else "")
                for p in output["pieces"]
            )
            lines.append(
                f"{outcome.source.name}: gas published with {output['name']} "
                f"(fitted in {outcome.result.output_model_seconds:.1f} s"  # type: ignore[union-attr]
                f"{'; ' + pieces if pieces else ''})"
            )
    return "\n".join(lines)


def _verdict_cell(verdict: str) -> str:
    """The verdict in the table's 12 characters; why a diagnosis failed is in the warnings."""
    return "failed" if verdict.startswith("failed") else verdict[:12]
