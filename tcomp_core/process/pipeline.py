"""``tcomp process``: one recorded bag or CSV file in, compensated outputs out, streamed.

Reading goes chunk by chunk (:mod:`.mcap_read`, bulk decoding by :mod:`.temperature_codec`);
samples are paired by identical stamps (:mod:`.pairing`); the pairs drive the node's engine,
:class:`~tcomp_core.online.OnlineCompensator`, on a schedule set by the stamps alone
(:mod:`.schedule`: batches of ``batch_s``, re-estimation every ``update_period_s`` of stamp
time); the results go to a bag or CSV file as they come (:mod:`.output`). Memory holds a
chunk, the compensator's window, the pairs of the current batch and the tail kept for the
diagnosis, whatever the length of the record.

The diagnosis (:func:`tcomp_core.diagnose.diagnose`, tens of seconds on 40 k samples) runs at
the end on the longest gap-free stretch of the last ``diagnose_samples`` pairs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, TcompError
from ..io import (
    DEFAULT_COLUMNS,
    DEFAULT_TOPICS,
    TEMPERATURE_TYPE,
    Record,
    _bag_location,
    _clear_for_writing,
    _format_stamp,
    _is_csv,
    _names,
    _seconds_to_ns,
    read_csv,
)
from ..online import EstimateStatus, OnlineConfig
from ..status_values import engine_values, format_value
from .mcap_read import McapScan, payloads
from .output import BagOutput, CsvOutput
from .pairing import Pairs, StampPairer
from .schedule import ScheduledEngine
from .temperature_codec import TemperatureBatch, decode_rows

__all__ = ["ProcessConfig", "ProcessResult", "process"]

_ROLES = ("tc1", "tc2", "ref")
#: Rows of CSV input handed over at a time.
CSV_BLOCK = 100_000
#: Shortest gap-free stretch the diagnosis is run on, samples.
MIN_DIAGNOSIS_SAMPLES = 1000
_OK, _WARN, _ERROR = 0, 1, 2


@dataclass(frozen=True, kw_only=True)
class ProcessConfig:
    """Settings of :func:`process`.

    Attributes
    ----------
    online : OnlineConfig
        The compensator's settings (window, method, φ, filters, reconstruction, ...).
    update_period_s : float
        Re-estimation period in stamp time, seconds (the node's ``update_period_s``).
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
    """

    online: OnlineConfig = field(default_factory=OnlineConfig)
    update_period_s: float = 0.5
    batch_s: float = 0.1
    topics: tuple[str, str, str | None] = DEFAULT_TOPICS
    columns: tuple[str, str, str | None] = DEFAULT_COLUMNS
    diagnose: bool = True
    diagnose_samples: int = 20_000
    compress: bool = True
    overwrite: bool = False
    frame_id: str = ""
    hardware_id: str = "thermocouple-pair"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.update_period_s) and self.update_period_s > 0.0):
            raise ValueError(f"update_period_s={self.update_period_s!r} must be > 0 s")
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
        Re-estimations (entries of the τ history).
    tau : (float, float) or None
        The last τ1, τ2 in use, seconds.
    verdict : str
        The diagnosis verdict (an effect or 'none'), 'skipped' or 'failed: ...'.
    seconds : float
        Wall time.
    warnings : list of str
        Truncated input, dropped samples.
    counters : dict of str to int
        Pairing and compensator counters.
    diagnosis : dict
        Key values of the diagnosis (empty when skipped).
    """

    source: Path
    output: Path
    pairs: int
    gas: int
    estimates: int
    tau: tuple[float, float] | None
    verdict: str
    seconds: float
    warnings: list[str] = field(default_factory=list)
    counters: dict[str, int] = field(default_factory=dict)
    diagnosis: dict[str, str] = field(default_factory=dict)

    @property
    def pairs_per_s(self) -> float:
        """Pairs processed per wall-clock second."""
        return self.pairs / self.seconds if self.seconds > 0 else math.nan


class Progress(Protocol):
    """What :func:`process` reports progress to (see :mod:`.progress`)."""

    def update(self, fraction: float, pairs: int) -> None:
        """The input read so far (0..1) and the pairs matched."""

    def close(self) -> None:
        """The run is over."""


# --------------------------------------------------------------------------------------------
# Inputs


@dataclass
class _Block:
    """Decoded samples per role and, from a bag, the raw records to copy."""

    series: dict[str, TemperatureBatch]
    records: dict[str, list[NDArray[np.uint8]]]
    fraction: float


def _bag_files(path: Path) -> list[Path]:
    """The MCAP files of a bag directory (from ``metadata.yaml``) or a bare MCAP file."""
    location = _bag_location(path)
    if location.is_file():
        return [location]
    from ruamel.yaml import YAML

    try:
        info = YAML(typ="safe").load((location / "metadata.yaml").read_text("utf8"))
        names = info["rosbag2_bagfile_information"]["relative_file_paths"]
    except Exception as exc:  # ruamel raises many types; a bad metadata.yaml is a data error
        raise DataError(f"{location}/metadata.yaml: cannot read the file list: {exc}") from exc
    files = [location / name for name in names]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise DataError(f"{location}: metadata.yaml lists missing files: {', '.join(missing)}")
    return files


class _BagInput:
    def __init__(self, path: Path, topics: Mapping[str, str]) -> None:
        self.path = path
        self.topics = dict(topics)
        self.scan = McapScan(_bag_files(path), list(topics.values()), TEMPERATURE_TYPE)

    def __iter__(self) -> Iterator[_Block]:
        roles = {topic: role for role, topic in self.topics.items()}
        for chunk in self.scan:
            series, records = {}, {}
            for topic, blocks in chunk.topics.items():
                role = roles[topic]
                try:
                    series[role] = TemperatureBatch.concatenate(
                        [decode_rows(payloads(block)) for block in blocks]
                    )
                except DataError as exc:
                    raise DataError(
                        f"{chunk.file}: topic {topic}, chunk at byte {chunk.offset}: {exc}"
                    ) from exc
                records[role] = blocks
            total = max(self.scan.bytes_total, 1)
            yield _Block(series, records, min(self.scan.bytes_read / total, 1.0))

    def qos_text(self, role: str) -> str | None:
        """The input channel's ``offered_qos_profiles``, as recorded (None if it has none)."""
        return self.scan.metadata.get(self.topics[role], {}).get("offered_qos_profiles")

    def check_topics(self) -> None:
        listed = ", ".join(
            f"{topic} ({', '.join(sorted(kinds))})"
            for topic, kinds in sorted(self.scan.types.items())
        )
        for role in ("tc1", "tc2"):
            if self.topics[role] not in self.scan.types:
                raise DataError(
                    f"{self.path}: no topic {self.topics[role]}; the bag has "
                    f"{listed or 'no topics'}"
                )


class _CsvInput:
    def __init__(self, path: Path, columns: tuple[str, str, str | None]) -> None:
        self.path = path
        self.record = read_csv(path, columns=columns)
        self.topics = {
            role: topic
            for role, topic in zip(_ROLES, DEFAULT_TOPICS, strict=True)
            if topic is not None and (role != "ref" or self.record.ref is not None)
        }

    def __iter__(self) -> Iterator[_Block]:
        record = self.record
        stamps = _seconds_to_ns(record.time)
        if stamps.size and stamps.min() < 0:
            raise DataError(f"{self.path}: column 'time' has negative times; stamps must be >= 0")
        columns = {"tc1": record.tc1, "tc2": record.tc2, "ref": record.ref}
        for start in range(0, stamps.size, CSV_BLOCK):
            part = slice(start, start + CSV_BLOCK)
            series = {
                role: TemperatureBatch(stamps[part], values[part], np.zeros(stamps[part].size))
                for role, values in columns.items()
                if values is not None
            }
            yield _Block(series, {}, min((start + CSV_BLOCK) / stamps.size, 1.0))

    def qos_text(self, role: str) -> str | None:
        """A CSV file has no QoS: the default is offered."""
        return None

    def check_topics(self) -> None:
        """CSV columns were checked on reading."""


# --------------------------------------------------------------------------------------------
# The diagnosis


class _Tail:
    """The newest ``capacity`` pairs (stamps, tc1, tc2, ref), for the diagnosis."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.parts: list[tuple[NDArray, ...]] = []
        self.size = 0

    def add(self, pairs: Pairs) -> None:
        if not len(pairs):
            return
        self.parts.append((pairs.stamps_ns, pairs.tc1, pairs.tc2, pairs.ref))
        self.size += len(pairs)
        while self.size - self.parts[0][0].size >= self.capacity:
            self.size -= self.parts.pop(0)[0].size

    def stretch(self, gap_factor: float) -> tuple[NDArray, ...]:
        """The longest gap-free stretch of the tail: stamps, tc1, tc2, ref."""
        columns = [np.concatenate(c)[-self.capacity :] for c in zip(*self.parts, strict=True)]
        steps = np.diff(columns[0])
        if steps.size == 0:
            return tuple(columns)
        breaks = np.flatnonzero(steps > gap_factor * np.median(steps)) + 1
        edges = np.concatenate(([0], breaks, [columns[0].size]))
        longest = int(np.argmax(np.diff(edges)))
        part = slice(int(edges[longest]), int(edges[longest + 1]))
        return tuple(c[part] for c in columns)


def _diagnose(tail: _Tail, source: Path, gap_factor: float) -> tuple[str, dict[str, str], int]:
    """Run the diagnosis on the tail: verdict, key values, level."""
    from ..diagnose import diagnose

    if tail.size == 0:
        return "failed: no pairs", {}, _ERROR
    stamps, tc1, tc2, ref = tail.stretch(gap_factor)
    if stamps.size < MIN_DIAGNOSIS_SAMPLES:
        return f"failed: longest gap-free stretch has only {stamps.size} pairs", {}, _WARN
    dt = float(np.median(np.diff(stamps))) * 1e-9
    record = Record(
        time=np.arange(stamps.size) * dt,
        tc1=tc1,
        tc2=tc2,
        ref=ref if np.isfinite(ref).all() else None,
        source=f"{source} (pairs stamped {_format_stamp(int(stamps[0]))} to "
        f"{_format_stamp(int(stamps[-1]))})",
        dt=dt,
    )
    started = time.perf_counter()
    try:
        result = diagnose(record)
    except (TcompError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return f"failed: {exc}", {"samples": str(stamps.size)}, _ERROR
    top = result.suspects[0] if result.suspects else None
    values = {
        "verdict": result.verdict,
        "samples": str(stamps.size),
        "first_stamp_s": f"{int(stamps[0]) * 1e-9:.9f}",
        "last_stamp_s": f"{int(stamps[-1]) * 1e-9:.9f}",
        "base_tau1_s": format_value(result.base.tau1),
        "base_tau2_s": format_value(result.base.tau2),
        "base_error_pct": format_value(result.base.error_pct),
        "effects": ",".join(result.final.effects) or "none",
        "final_tau1_s": format_value(result.final.tau1),
        "final_tau2_s": format_value(result.final.tau2),
        "final_error_pct": format_value(result.final.error_pct),
        "top_suspect": top.effect if top else "none",
        "top_suspect_error_pct": format_value(top.error_pct if top else math.nan),
        "diagnosis_duration_s": format_value(time.perf_counter() - started),
    }
    return result.verdict, values, _OK if result.verdict == "none" else _WARN


# --------------------------------------------------------------------------------------------
# The run


def _history_values(
    engine: ScheduledEngine, status: EstimateStatus, counters: Mapping[str, int], published: int
) -> dict[str, str]:
    """Key values of one τ history entry (the node's names, where they apply offline)."""
    return {
        **engine_values(engine.compensator, status),
        "matched": str(counters["matched"]),
        "unmatched": str(counters["unmatched_tc1"] + counters["unmatched_tc2"]),
        "out_of_order": str(counters["out_of_order"]),
        "duplicates": str(counters["duplicates"]),
        "invalid_tc1": str(counters["invalid_tc1"]),
        "invalid_tc2": str(counters["invalid_tc2"]),
        "published": str(published),
    }


def _status_level(status: EstimateStatus) -> tuple[int, str]:
    if not status.accepted:
        return _WARN, f"estimate not accepted: {status.reason}"
    if status.poor_fit:
        return _WARN, f"poor fit: model error {status.model_error_pct:.3g} %"
    return _OK, "ok"


def _open_input(source: Path, config: ProcessConfig) -> _BagInput | _CsvInput:
    if _is_csv(source):
        return _CsvInput(source, _names(config.columns, DEFAULT_COLUMNS, "columns"))
    tc1, tc2, ref = _names(config.topics, DEFAULT_TOPICS, "topics")
    topics = {"tc1": tc1, "tc2": tc2, **({"ref": ref} if ref else {})}
    return _BagInput(source, topics)


def _dropped_warnings(source: Path, pairer: StampPairer) -> list[str]:
    what = {
        "unmatched_tc1": "tc1 samples without a tc2 sample of the same stamp",
        "unmatched_tc2": "tc2 samples without a tc1 sample of the same stamp",
        "out_of_order": "samples stamped at or before a pair already processed",
        "duplicates": "samples repeating a stamp",
        "invalid_tc1": "non-finite tc1 temperatures",
        "invalid_tc2": "non-finite tc2 temperatures",
    }
    return [
        f"{source}: dropped {pairer.counters[name]} {text} (the first stamped "
        f"{_format_stamp(stamp)})"
        for name, text in what.items()
        if (stamp := pairer.first_dropped.get(name)) is not None
    ]


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
    if output.resolve() == source.resolve():
        raise DataError(f"{output}: the output would replace the input")
    reader = _open_input(source, config)
    _clear_for_writing(output, config.overwrite, bag=not _is_csv(output))
    output.parent.mkdir(parents=True, exist_ok=True)
    sink: BagOutput | CsvOutput
    if _is_csv(output):
        sink = CsvOutput(output, with_ref="ref" in reader.topics)
    else:
        sink = BagOutput(
            output,
            reader.topics,
            compress=config.compress,
            hardware_id=config.hardware_id,
            with_diagnosis=config.diagnose,
        )
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
    reader: _BagInput | _CsvInput,
    sink: BagOutput | CsvOutput,
    progress: Progress | None,
    started: float,
) -> ProcessResult:
    engine = ScheduledEngine(config.online, config.update_period_s, config.batch_s)
    pairer = StampPairer()
    tail = _Tail(config.diagnose_samples)
    frame_id = config.frame_id
    last_good: dict[str, tuple[int, int]] = {}  # role -> (messages read, newest stamp)
    published = 0

    def consume(pairs: Pairs, finish: bool = False) -> None:
        nonlocal published
        sink.pairs(pairs.stamps_ns, pairs.tc1, pairs.tc2, pairs.ref)
        tail.add(pairs)
        steps = engine.feed(pairs.stamps_ns, pairs.tc1, pairs.tc2)
        if finish:
            steps += engine.finish()
        if isinstance(sink, CsvOutput) and engine.compensator.period_s:
            period = engine.compensator.period_s
            sink.keep_rows = round((config.online.window_s + 2 * config.batch_s) / period) + 256
        for step in steps:
            sink.gas(
                step.stamps_ns, step.gas, step.variance, step.tau, frame_id, step.last_stamp_ns
            )
            published += int(step.stamps_ns.size)
            if step.status is not None:
                level, message = _status_level(step.status)
                stamp = step.status.stamp_ns or step.last_stamp_ns
                values = _history_values(engine, step.status, pairer.counters, published)
                sink.estimate(stamp, level, message, values)

    for block in reader:
        for role, batch in block.series.items():
            pairer.add(role, batch.stamps_ns, batch.temperature)
            sink.inputs(role, batch, block.records.get(role), reader.qos_text(role))
            if len(batch):
                count, newest = last_good.get(role, (0, np.iinfo(np.int64).min))
                last_good[role] = (count + len(batch), max(newest, int(batch.stamps_ns.max())))
                if role == "tc1" and not frame_id:
                    frame_id = batch.frame_id
        consume(pairer.pop())
        if progress is not None:
            progress.update(block.fraction, pairer.counters["matched"])
    reader.check_topics()
    consume(pairer.pop(final=True), finish=True)
    pairs = pairer.counters["matched"]
    if pairs == 0:
        raise DataError(f"{source}: no tc1/tc2 samples with identical stamps: nothing to process")
    warnings = _dropped_warnings(source, pairer)
    truncation = getattr(getattr(reader, "scan", None), "truncation", None)
    if truncation is not None:
        where = "; ".join(
            f"{reader.topics[role]}: {count} messages, the last good stamped "
            f"{_format_stamp(stamp)}"
            for role, (count, stamp) in last_good.items()
        )
        warnings.insert(0, f"input truncated: {truncation}; processed up to there ({where})")
    verdict, diagnosis = "skipped", {}
    if config.diagnose:
        verdict, diagnosis, level = _diagnose(tail, source, config.online.gap_factor)
        last_stamp = max(stamp for _, stamp in last_good.values())
        sink.diagnosis(last_stamp, level, f"diagnosis verdict: {verdict}", diagnosis)
    sink.close()
    counters: dict[str, Any] = {**pairer.counters, **engine.compensator.counters}
    return ProcessResult(
        source=source,
        output=output,
        pairs=pairs,
        gas=published,
        estimates=engine.estimates,
        tau=engine.compensator.tau,
        verdict=verdict,
        seconds=time.perf_counter() - started,
        warnings=warnings,
        counters=counters,
        diagnosis=diagnosis,
    )
