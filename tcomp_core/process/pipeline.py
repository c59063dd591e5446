"""``tcomp process``: one recorded bag or CSV file in, compensated outputs out, streamed.

Reading goes chunk by chunk (:mod:`tcomp_core.io.stream`, bulk decoding in :mod:`tcomp_core.io`);
the samples drive the node's engine (:class:`~tcomp_core.online.Engine`: the same pair
matcher, compensator and health rules) on a schedule set by the stamps alone
(:mod:`tcomp_core.online.schedule`: batches of ``batch_s``, re-estimation every
``update_period_s`` and a ``/diagnostics`` status every second of stamp time, each read at its
stamp); the results go to a bag or CSV file as they come (:mod:`.output`). Memory holds a
chunk, the compensator's window, the pairs of the current batch and the tail kept for the
diagnosis, whatever the length of the record.

The diagnosis (:func:`tcomp_core.diagnose.diagnose`, tens of seconds on 40 k samples) runs at
the end on the longest gap-free stretch of the last ``diagnose_samples`` pairs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from .. import parameters
from ..diagnose.saved import saved_diagnosis_effects
from ..errors import DataError, TcompError
from ..io import (
    DEFAULT_COLUMNS,
    DEFAULT_TOPICS,
    BagStream,
    CsvStream,
    Record,
    atomic_output,
    check_output,
    format_stamp,
    is_csv,
    open_stream,
)
from ..online import Engine, EngineStep, OnlineConfig, PairCounters, ScheduledEngine
from ..online.diagnosis import diagnosis_values
from ..online.extended import RecentPairs
from ..online.health import Level, format_value, sensor_disagreement
from ..online.schedule import REF
from ..workers import InlineRunner
from .output import BagOutput, CsvOutput
from .output_model import FittedOutput, fit_stream_output_model

__all__ = ["ProcessConfig", "ProcessResult", "process"]

#: Shortest gap-free stretch the diagnosis is run on, samples.
MIN_DIAGNOSIS_SAMPLES = 1000
#: Share of the pairs left without a gas above which the run says so and why (the last pair,
#: held for the next one, and the start before a first estimate lands are ordinary).
MISSING_GAS_WARNING = 0.01


@dataclass(frozen=True, kw_only=True)
class ProcessConfig:
    """Settings of :func:`process`.

    Attributes
    ----------
    online : OnlineConfig
        The compensator's settings, the node's parameters (window, method, reconstruction,
        ``update_period_s`` in stamp time, ``sync_slop_s``, ``queue_size``,
        ``silence_timeout_s`` in stamp time, ...).
    batch_s : float
        Pairs are handed to the compensator in batches of this much stamp time, seconds.
    topics : (tc1, tc2, ref or None)
        Bag topics; the reference is optional (copied and put in the CSV when present).
    columns : (tc1, tc2, ref or None)
        CSV input columns besides ``time``.
    diagnose : bool
        Run the diagnosis at the end.
    diagnose_samples : int
        The diagnosis sees at most the last this many pairs.
    compress : bool
        zstd-compress the output bag's chunks (default: the output is about a third of the
        size and writes faster).
    overwrite : bool
        Replace an existing output.
    frame_id : str
        ``header.frame_id`` of ``gas_temperature``; '' = that of tc1.
    hardware_id : str
        ``hardware_id`` of the diagnostic statuses.
    effects : str
        The model the published gas uses: ``"none"`` (first order), ``"auto"`` (the
        diagnosis's final model), comma-separated effects, or a diagnosis saved by ``tcomp
        diagnose --json`` (``*.json``: its final model's effects, read when the config is
        made), fitted on the first ``diagnose_samples`` pairs (:mod:`.output_model`) and taken
        by the node's rules (:func:`tcomp_core.online.diagnosis.judge_output`).
    """

    online: OnlineConfig = field(default_factory=OnlineConfig)
    batch_s: float = 0.1
    topics: tuple[str, str, str | None] = DEFAULT_TOPICS
    columns: tuple[str, str, str | None] = DEFAULT_COLUMNS
    diagnose: bool = True
    diagnose_samples: int = 20_000
    compress: bool = True
    overwrite: bool = False
    frame_id: str = ""
    hardware_id: str = str(parameters.default("hardware_id"))
    effects: str = "none"

    def __post_init__(self) -> None:
        object.__setattr__(self, "effects", saved_diagnosis_effects(self.effects))
        if not (math.isfinite(self.batch_s) and self.batch_s > 0.0):
            raise ValueError(f"batch_s={self.batch_s!r} must be > 0 s")
        if self.diagnose_samples < MIN_DIAGNOSIS_SAMPLES:
            raise ValueError(
                f"diagnose_samples={self.diagnose_samples!r} must be >= {MIN_DIAGNOSIS_SAMPLES}"
            )


@dataclass(frozen=True, kw_only=True)
class ProcessResult:
    """What :func:`process` did.

    Attributes
    ----------
    source, output : Path
    pairs : int
        Matched sample pairs.
    gas : int
        Reconstructed gas samples written.
    estimates : int
        Re-estimations.
    reports : int
        ``/diagnostics`` statuses written (one per second of stamp time: the τ history).
    tau : (float, float) or None
        The last τ1, τ2 in use, seconds.
    verdict : str
        The diagnosis verdict (an effect or 'none'), 'skipped' or 'failed: ...'.
    seconds : float
        Wall time, the closing diagnosis included.
    diagnosis_seconds : float
        Wall time of the closing diagnosis (0 when skipped). It sees at most
        ``diagnose_samples`` pairs, so its cost does not grow with the record.
    warnings : list of str
        Truncated input, dropped samples.
    counters : dict of str to int
        Pairing and compensator counters.
    diagnosis : dict
        Key values of the diagnosis (empty when skipped).
    output_model : dict
        The model the published gas used (:meth:`~tcomp_core.compensation.OutputModel.summary`
        as a causal stream applies it; empty for first order).
    output_model_seconds : float
        Wall time of its fit (0 for first order).
    """

    source: Path
    output: Path
    pairs: int
    gas: int
    estimates: int
    tau: tuple[float, float] | None
    verdict: str
    seconds: float
    reports: int = 0
    diagnosis_seconds: float = 0.0
    warnings: list[str] = field(default_factory=list)
    counters: dict[str, int] = field(default_factory=dict)
    diagnosis: dict[str, str] = field(default_factory=dict)
    output_model: dict[str, Any] = field(default_factory=dict)
    output_model_seconds: float = 0.0

    @property
    def pairs_per_s(self) -> float:
        """Pairs processed per wall-clock second, the closing diagnosis left out."""
        streaming = self.seconds - self.diagnosis_seconds
        return self.pairs / streaming if streaming > 0 else math.nan


class Progress(Protocol):
    """What :func:`process` reports progress to (see :mod:`.progress`)."""

    def update(self, fraction: float, pairs: int) -> None:
        """The input read so far (0..1) and the pairs matched."""

    def close(self) -> None:
        """The run is over."""


# --------------------------------------------------------------------------------------------
# The diagnosis


def _diagnose(
    tail: RecentPairs, source: Path, gap_factor: float
) -> tuple[str, dict[str, str], Level]:
    """Run the diagnosis on the tail: verdict, key values, level."""
    from ..diagnose import diagnose

    if tail.size == 0:
        return "failed: no pairs", {}, Level.ERROR
    stamps, tc1, tc2, ref = tail.longest(gap_factor)
    if stamps.size < MIN_DIAGNOSIS_SAMPLES:
        return f"failed: longest gap-free stretch has only {stamps.size} pairs", {}, Level.WARN
    dt = float(np.median(np.diff(stamps))) * 1e-9
    record = Record(
        time=np.arange(stamps.size, dtype=np.float64) * dt,
        tc1=tc1,
        tc2=tc2,
        ref=ref if np.isfinite(ref).all() else None,
        source=f"{source} (pairs stamped {format_stamp(int(stamps[0]))} to "
        f"{format_stamp(int(stamps[-1]))})",
        dt=dt,
    )
    started = time.perf_counter()
    try:
        result = diagnose(record)
    except (TcompError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return f"failed: {exc}", {"samples": str(stamps.size)}, Level.ERROR
    top = next((suspect for suspect in result.suspects if suspect.significant), None)
    effects = tuple(result.final.effects)
    found = {  # as the node's background diagnosis reports a job (one vocabulary)
        "base_error_pct": result.base.error_pct,
        "error_pct": result.final.error_pct,
        "tau1": result.final.tau1,
        "tau2": result.final.tau2,
        "top_suspect": top.effect if top else "none",
        "top_suspect_error_pct": top.error_pct if top else math.nan,
        "seconds": time.perf_counter() - started,
        "requested": effects,
    }
    values = {
        "verdict": result.verdict,
        "samples": str(stamps.size),
        "first_stamp_s": f"{int(stamps[0]) * 1e-9:.9f}",
        "last_stamp_s": f"{int(stamps[-1]) * 1e-9:.9f}",
        "base_tau1_s": format_value(result.base.tau1),
        "base_tau2_s": format_value(result.base.tau2),
        **diagnosis_values(found, effects),
    }
    del values["diagnosis_age_s"]  # it is the last pairs' diagnosis, at the end of the record
    return result.verdict, values, Level.OK if result.verdict == "none" else Level.WARN


# --------------------------------------------------------------------------------------------
# The run


def _dropped_warnings(source: Path, counters: PairCounters) -> list[str]:
    what = {
        "unmatched_tc1": "tc1 samples without a tc2 sample to pair with",
        "unmatched_tc2": "tc2 samples without a tc1 sample to pair with",
        "out_of_order": "samples stamped at or before a pair already processed",
        "duplicates": "samples repeating a stamp",
        "invalid_tc1": "tc1 temperatures not finite or outside the physical range",
        "invalid_tc2": "tc2 temperatures not finite or outside the physical range",
    }
    values = counters.as_dict()
    warnings = [
        f"{source}: dropped {values[name]} {text} (the first stamped {format_stamp(stamp)})"
        for name, text in what.items()
        if (stamp := counters.first_dropped.get(name)) is not None
    ]
    if counters.discontinuities:
        warnings.append(
            f"{source}: the stamps jumped back {counters.discontinuities} time(s); the window "
            f"restarted there (the last at {format_stamp(counters.last_discontinuity_ns)})"
        )
    return warnings


def _stream_warnings(source: Path, pairs: int, engine: Engine) -> list[str]:
    """What a user must know about the published gas: pairs without one, rate changes, misfit."""
    compensator = engine.compensator
    warnings = []
    if compensator.rate_changes:
        warnings.append(
            f"{source}: the sample rate changed {compensator.rate_changes} time(s); the window, "
            "tau and the reconstruction restarted at each (see the /diagnostics statuses)"
        )
    missing = pairs - engine.published
    if missing > MISSING_GAS_WARNING * pairs:
        status = compensator.last_status
        if compensator.published_tau is None:
            why = "no estimate of tau1, tau2 was accepted"
            if status is not None and status.reason:
                why += f" (the last: {status.reason})"
        else:
            why = "gaps in the stamps, screened readings, or before an estimate was accepted"
        warnings.append(f"{source}: no gas for {missing} of {pairs} pairs: {why}")
    if compensator.misfit_warning:  # as the last filter fitted on the stream saw it
        warnings.append(f"{source}: {compensator.misfit_warning}")
    disagreement = sensor_disagreement(compensator.last_status)
    if disagreement:
        remedy = (
            "the gas is published compensated with the output model of --effects"
            if compensator.output is not None
            else "the closing diagnosis tells which (unless --no-diagnose) and --effects auto "
            "compensates it"
        )
        warnings.append(
            f"{source}: in the last window's estimate {disagreement}: a physical effect the "
            "first-order model lacks (conduction to the supports, radiation) or a "
            f"miscalibration: {remedy}"
        )
    return warnings


class _RefJoin:
    """Attach the reference sample of each pair's stamp (NaN where there is none).

    The reference samples of the current batch and the one before are searched, so a reference
    stamped like its pair but delivered one batch later than the pair is still found only when
    it is in one of those two batches.
    """

    def __init__(self) -> None:
        self._stamps = np.empty(0, np.int64)
        self._values = np.empty(0)

    def __call__(self, step: EngineStep) -> NDArray[np.float64]:
        new_stamps, new_values = step.ref
        stamps = np.concatenate((self._stamps, new_stamps))
        values = np.concatenate((self._values, new_values))
        order = np.argsort(stamps, kind="stable")
        stamps, values = stamps[order], values[order]
        self._stamps, self._values = new_stamps, new_values
        wanted = step.pairs.stamps_ns
        ref = np.full(wanted.size, np.nan)
        if stamps.size and wanted.size:
            at = np.clip(np.searchsorted(stamps, wanted), 0, stamps.size - 1)
            hit = stamps[at] == wanted
            ref[hit] = values[at[hit]]
        return ref


def process(
    source: str | Path,
    output: str | Path,
    config: ProcessConfig | None = None,
    *,
    progress: Progress | None = None,
) -> ProcessResult:
    """Process one record into a bag (any path but ``*.csv``) or a CSV file.

    Parameters
    ----------
    source : str or Path
        rosbag2 MCAP bag (directory or ``.mcap`` file) or CSV file.
    output : str or Path
        Bag directory to create, or a ``*.csv`` file.
    config : ProcessConfig, optional
    progress : Progress, optional
        Told the fraction of the input read and the pairs matched after every chunk.

    Returns
    -------
    ProcessResult

    Raises
    ------
    DataError
        Unreadable input (missing, not a bag or CSV, wrong message type, a topic missing, no
        pairs), an output that exists without ``overwrite``, the output equal to the input.
        A bag cut off or still being written is not an error: it is processed up to its last
        complete message and ``warnings`` says where it stopped.
    """
    started = time.perf_counter()
    config = config or ProcessConfig()
    source, output = Path(source), Path(output)
    bag = not is_csv(output)
    check_output(output, config.overwrite, [source], directory=bag)  # before reading anything
    reader = open_stream(source, topics=config.topics, columns=config.columns)
    try:
        with atomic_output(output, config.overwrite, [source], directory=bag) as temporary:
            sink: BagOutput | CsvOutput
            if bag:
                sink = BagOutput(
                    temporary,
                    reader.topics,
                    compress=config.compress,
                    hardware_id=config.hardware_id,
                    with_diagnosis=config.diagnose,
                    name=output.name,
                )
            else:
                sink = CsvOutput(temporary, with_ref="ref" in reader.topics)
            try:
                result = _run(source, output, config, reader, sink, progress, started)
            except BaseException:
                sink.abort()
                raise
    finally:
        if progress is not None:
            progress.close()
    return result


def _run(
    source: Path,
    output: Path,
    config: ProcessConfig,
    reader: BagStream | CsvStream,
    sink: BagOutput | CsvOutput,
    progress: Progress | None,
    started: float,
) -> ProcessResult:
    # Every job inline: a fit lands at the stamp where it is asked for, on every run.
    engine = Engine(
        replace(config.online, effects=config.effects),
        runner=InlineRunner(),
        diagnosis_runner=InlineRunner(),
    )
    schedule = ScheduledEngine(
        engine, update_period_s=config.online.update_period_s, batch_s=config.batch_s
    )
    fitted = _output_model(source, config)
    if fitted is not None:
        engine.diagnosis.adopt(
            engine.compensator,
            fitted.model,
            fitted.origin_ns,
            fitted.record,
            fitted.origin_ns * 1e-9,
            fitted.note(config.effects),
            fitted.seconds,
        )
    tail = RecentPairs(config.diagnose_samples)
    join_ref = _RefJoin()
    frame_id = config.frame_id
    last_good: dict[str, tuple[int, int]] = {}  # role -> (messages read, newest stamp)
    indices = {"tc1": 0, "tc2": 1, "ref": REF}

    def consume(steps: list[EngineStep]) -> None:
        compensator = engine.compensator
        if isinstance(sink, CsvOutput) and compensator.period_s:
            period = compensator.period_s
            rows = round((config.online.window_s + 2 * config.batch_s) / period)
            sink.keep_rows = min(rows, 2 * config.online.max_window_samples) + 256
        for step in steps:
            pairs = step.pairs
            ref = join_ref(step)
            sink.pairs(pairs.stamps_ns, pairs.tc1, pairs.tc2, ref)
            tail.add(pairs.stamps_ns, pairs.tc1, pairs.tc2, ref)
            gas = step.gas
            sink.gas(gas.stamps_ns, gas.gas, gas.variance, step.tau, frame_id, step.last_stamp_ns)
            if step.health is not None:
                health = step.health
                sink.report(step.last_stamp_ns, int(health.level), health.message, health.values)

    for block in reader:
        samples = {}
        for role, batch in block.series.items():
            samples[indices[role]] = (batch.stamps_ns, batch.temperature)
            sink.inputs(role, batch, block.records.get(role), reader.qos_text(role))
            if len(batch):
                count, newest = last_good.get(role, (0, np.iinfo(np.int64).min))
                last_good[role] = (count + len(batch), max(newest, int(batch.stamps_ns.max())))
                if role == "tc1" and not frame_id:
                    frame_id = batch.frame_id
        consume(schedule.feed(samples))
        if progress is not None:
            progress.update(block.fraction, engine.counters.matched)
    reader.check_topics()
    consume(schedule.finish())
    engine.matcher.discard_pending()
    pairs = engine.counters.matched
    warnings = _dropped_warnings(source, engine.counters)
    if pairs == 0:
        why = "; ".join(warning.removeprefix(f"{source}: ") for warning in warnings)
        raise DataError(
            f"{source}: no tc1/tc2 pair to process"
            + (f": {why}" if why else " (no samples with identical stamps)")
        )
    truncation = reader.truncation
    if truncation is not None:
        where = "; ".join(
            f"{reader.topics[role]}: {count} messages, the last good stamped {format_stamp(stamp)}"
            for role, (count, stamp) in last_good.items()
        )
        warnings[:0] = [str(truncation), f"{source}: processed up to there ({where})"]
    verdict: str = "skipped"
    diagnosis: dict[str, str] = {}
    diagnosis_started = time.perf_counter()
    if config.diagnose:
        verdict, diagnosis, level = _diagnose(tail, source, config.online.gap_factor)
        last_stamp = max(stamp for _, stamp in last_good.values())
        sink.diagnosis(last_stamp, level, f"diagnosis verdict: {verdict}", diagnosis)
        if verdict.startswith("failed: "):
            warnings.append(f"{source}: the diagnosis {verdict}")
    warnings += _stream_warnings(source, pairs, engine)
    diagnosis_seconds = time.perf_counter() - diagnosis_started if config.diagnose else 0.0
    sink.close()
    counters: dict[str, Any] = {**engine.counters.as_dict(), **engine.compensator.counters}
    return ProcessResult(
        source=source,
        output=output,
        pairs=pairs,
        gas=engine.published,
        estimates=schedule.estimates,
        reports=schedule.reports,
        tau=engine.compensator.published_tau,
        verdict=verdict,
        seconds=time.perf_counter() - started,
        diagnosis_seconds=diagnosis_seconds,
        warnings=warnings,
        counters=counters,
        diagnosis=diagnosis,
        output_model={}
        if engine.compensator.output is None
        else engine.compensator.output.model.summary(causal_stream=True),
        output_model_seconds=0.0 if fitted is None else fitted.seconds,
    )


def _output_model(source: Path, config: ProcessConfig) -> FittedOutput | None:
    """The output model ``config.effects`` asks for, fitted on the first pairs (or None)."""
    from ..compensation import parse_compensate_effects

    effects = parse_compensate_effects(config.effects)
    if effects == ():
        return None
    return fit_stream_output_model(
        source,
        effects,
        topics=config.topics,
        columns=config.columns,
        samples=config.diagnose_samples,
        slop_ns=config.online.slop_ns,
        queue_size=config.online.queue_size,
        valid_range=config.online.valid_range,
        gap_factor=config.online.gap_factor,
    )
