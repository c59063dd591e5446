"""Data I/O: CSV files and rosbag2 MCAP bags of two (or three) thermocouple signals.

CSV: a header ``time,tc1,tc2`` (seconds, degrees C) and optionally ``ref``; further columns are
allowed and ignored on reading. Bags: rosbag2 version 9 with MCAP storage, holding
``sensor_msgs/msg/Temperature`` on ``/tc1/temperature``, ``/tc2/temperature`` and optionally
``/tref/temperature``. A sample's time is its ``header.stamp``; the two thermocouples must carry
the same stamps (this reader pairs exactly; the ROS node pairs approximately).

Every error is a :class:`~tcomp_core.errors.DataError` naming the file, the column or topic, the
sample and the value. Nothing is skipped: a record is read whole or refused.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DataError
from .validation import check_finite, sample_interval_from_time

__all__ = [
    "DEFAULT_COLUMNS",
    "DEFAULT_TOPICS",
    "GAS_TOPIC",
    "TEMPERATURE_TYPE",
    "Record",
    "read_bag",
    "read_csv",
    "read_record",
    "write_bag",
    "write_csv",
    "write_series",
]

DEFAULT_TOPICS: tuple[str, str, str | None] = (
    "/tc1/temperature",
    "/tc2/temperature",
    "/tref/temperature",
)
DEFAULT_COLUMNS: tuple[str, str, str | None] = ("tc1", "tc2", "ref")
GAS_TOPIC = "/gas_temperature"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"


@dataclass(frozen=True, kw_only=True)
class Record:
    """A uniformly sampled two-thermocouple record.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times, seconds (bag stamps are absolute).
    tc1, tc2 : ndarray, shape (N,)
        Thermocouple temperatures, degrees C.
    ref : ndarray, shape (N,) or None
        Reference (fast sensor or true gas temperature), degrees C.
    source : str
        Where the data came from, for messages.
    dt : float
        Sample interval, seconds.
    frame_id : str
        ``header.frame_id`` of the tc1 messages of a bag.
    stamps_ns : ndarray of int64, shape (N,) or None
        Exact ``header.stamp`` in nanoseconds (bags only); ``time`` is its float conversion.
    """

    time: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    ref: NDArray[np.float64] | None
    source: str
    dt: float
    frame_id: str = ""
    stamps_ns: NDArray[np.int64] | None = None


def _is_csv(path: Path) -> bool:
    return path.suffix.lower() == ".csv"


def read_record(
    path: str | Path,
    *,
    topics: Sequence[str | None] | None = None,
    columns: Sequence[str | None] | None = None,
) -> Record:
    """Read a CSV file or a rosbag2 MCAP bag, chosen by the path (``*.csv`` is CSV).

    Parameters
    ----------
    path : str or Path
        CSV file, bag directory, or the ``.mcap`` file of a bag.
    topics : (tc1, tc2, ref or None), optional
        Bag topics; :data:`DEFAULT_TOPICS` when omitted.
    columns : (tc1, tc2, ref or None), optional
        CSV columns; :data:`DEFAULT_COLUMNS` when omitted.
    """
    path = Path(path)
    if _is_csv(path):
        return read_csv(path, columns=tuple(columns) if columns else DEFAULT_COLUMNS)
    return read_bag(path, topics=tuple(topics) if topics else DEFAULT_TOPICS)


def _validated_record(
    source: str,
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    ref: NDArray[np.float64] | None,
    time_name: str,
    frame_id: str = "",
    stamps_ns: NDArray[np.int64] | None = None,
) -> Record:
    # Integer stamps are checked as exact offsets from the first: absolute epoch seconds in
    # float64 resolve only ~0.2 µs, too coarse for the spacing check at kHz rates.
    relative = time if stamps_ns is None else (stamps_ns - stamps_ns[0]) * 1e-9
    try:
        dt = sample_interval_from_time(relative, name=time_name)
    except DataError as exc:
        raise DataError(f"{source}: {exc}") from None
    return Record(
        time=time,
        tc1=tc1,
        tc2=tc2,
        ref=ref,
        source=source,
        dt=dt,
        frame_id=frame_id,
        stamps_ns=stamps_ns,
    )


def read_csv(path: str | Path, *, columns: Sequence[str | None] = DEFAULT_COLUMNS) -> Record:
    """Read a CSV record with a header ``time,tc1,tc2[,ref]``.

    Parameters
    ----------
    path : str or Path
    columns : (tc1, tc2, ref or None)
        Column names of the two thermocouples and the optional reference. A ``ref`` column that
        is absent is not an error unless it was named explicitly.

    Raises
    ------
    DataError
        Missing file, missing column, ragged row, non-numeric or non-finite cell, time not
        strictly increasing or not uniform: the message names the file, row (as numbered in the
        file, header = 1), column and text.
    """
    path = Path(path)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise DataError(f"{path}: cannot open CSV file: {exc.strerror}") from exc
    with handle:
        reader = csv.reader(handle)
        header = next(reader, None)
        if header is None or not any(cell.strip() for cell in header):
            raise DataError(f"{path}: empty file, expected a header time,tc1,tc2[,ref]")
        names = [cell.strip() for cell in header]
        tc1_name, tc2_name, ref_name = (*columns, None)[:3]
        wanted = ["time", tc1_name, tc2_name]
        for name in wanted:
            if name not in names:
                raise DataError(f"{path}: no column {name!r}; the header has {', '.join(names)}")
        use_ref = ref_name is not None and ref_name in names
        if ref_name is not None and not use_ref and ref_name != DEFAULT_COLUMNS[2]:
            raise DataError(f"{path}: no column {ref_name!r}; the header has {', '.join(names)}")
        if use_ref:
            wanted.append(ref_name)
        indices = [names.index(name) for name in wanted]
        values: list[list[float]] = [[] for _ in wanted]
        for row_number, row in enumerate(reader, start=2):
            if not row or not any(cell.strip() for cell in row):
                continue  # blank line (e.g. the trailing newline)
            if len(row) != len(names):
                raise DataError(
                    f"{path}: row {row_number} has {len(row)} fields, the header {len(names)}"
                )
            for column, index in enumerate(indices):
                text = row[index].strip()
                try:
                    number = float(text)
                except ValueError:
                    raise DataError(
                        f"{path}: row {row_number}, column {wanted[column]!r}: {text!r} is not "
                        "a number"
                    ) from None
                if not math.isfinite(number):
                    raise DataError(
                        f"{path}: row {row_number}, column {wanted[column]!r}: {text!r} is not "
                        "finite"
                    )
                values[column].append(number)
    if not values[0]:
        raise DataError(f"{path}: header only, no samples")
    arrays = [np.asarray(column, dtype=np.float64) for column in values]
    ref = arrays[3] if use_ref else None
    return _validated_record(
        str(path), arrays[0], arrays[1], arrays[2], ref, time_name="column 'time'"
    )


def _bag_directory(path: Path) -> Path:
    if path.is_file() and (path.parent / "metadata.yaml").is_file():
        return path.parent
    return path


def _read_bag_messages(
    path: Path, wanted: Sequence[str]
) -> tuple[dict[str, list[tuple[int, float, str]]], dict[str, str]]:
    """Stamps (ns), temperatures and frame ids per wanted topic; and every topic's type."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    found: dict[str, list[tuple[int, float, str]]] = {topic: [] for topic in wanted}
    directory = _bag_directory(path)
    try:
        with Reader(directory) as reader:
            types = {connection.topic: connection.msgtype for connection in reader.connections}
            connections = [c for c in reader.connections if c.topic in found]
            for topic in wanted:
                if topic not in types:
                    listed = ", ".join(f"{name} ({kind})" for name, kind in sorted(types.items()))
                    raise DataError(f"{path}: no topic {topic}; the bag has {listed or 'none'}")
                if types[topic] != TEMPERATURE_TYPE:
                    raise DataError(
                        f"{path}: topic {topic} carries {types[topic]}, not {TEMPERATURE_TYPE}"
                    )
            for connection, _, raw in reader.messages(connections=connections):
                message = typestore.deserialize_cdr(raw, connection.msgtype)
                stamp = message.header.stamp
                found[connection.topic].append(
                    (
                        int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec),
                        float(message.temperature),
                        message.header.frame_id,
                    )
                )
    except DataError:
        raise
    except Exception as exc:  # rosbags raises many types for truncated or corrupt files
        raise DataError(
            f"{path}: cannot read the bag ({type(exc).__name__}: {exc}); it may be truncated, "
            "corrupt or not a rosbag2 MCAP bag"
        ) from exc
    return found, types


def read_bag(path: str | Path, *, topics: Sequence[str | None] = DEFAULT_TOPICS) -> Record:
    """Read a rosbag2 MCAP bag of ``sensor_msgs/msg/Temperature`` messages.

    Parameters
    ----------
    path : str or Path
        Bag directory (with ``metadata.yaml``) or the ``.mcap`` file inside it.
    topics : (tc1, tc2, ref or None)
        Topics of the two thermocouples and the optional reference; the default reference topic
        is read when present and ignored when absent.

    Raises
    ------
    DataError
        Missing or unreadable bag, missing topic or wrong type, stamps of tc1 and tc2 that do
        not pair one to one, non-finite temperature, non-uniform sampling.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such bag")
    tc1_topic, tc2_topic, ref_topic = (*topics, None)[:3]
    wanted = [tc1_topic, tc2_topic]
    probe_ref = ref_topic is not None
    try:
        found, _ = _read_bag_messages(path, [*wanted, ref_topic] if probe_ref else wanted)
    except DataError as exc:
        # The default reference topic is optional: retry without it when it is the one missing.
        if probe_ref and ref_topic == DEFAULT_TOPICS[2] and f"no topic {ref_topic};" in str(exc):
            found, _ = _read_bag_messages(path, wanted)
            probe_ref = False
        else:
            raise
    series = {}
    for topic in [*wanted, ref_topic] if probe_ref else wanted:
        messages = sorted(found[topic], key=lambda item: item[0])
        stamps = np.array([item[0] for item in messages], dtype=np.int64)
        temperatures = np.array([item[1] for item in messages], dtype=np.float64)
        bad = ~np.isfinite(temperatures)
        if bad.any():
            index = int(np.flatnonzero(bad)[0])
            raise DataError(
                f"{path}: topic {topic}, message {index} (stamp {stamps[index] * 1e-9:.9f} s) "
                f"has temperature {float(temperatures[index])!r}"
            )
        if stamps.size == 0:
            raise DataError(f"{path}: topic {topic} has no messages")
        series[topic] = (stamps, temperatures, messages[0][2])
    stamps1 = series[tc1_topic][0]
    for topic in series:
        other = series[topic][0]
        if other.size != stamps1.size:
            raise DataError(
                f"{path}: {tc1_topic} has {stamps1.size} messages but {topic} has {other.size}; "
                "the readers pair samples by identical header.stamp"
            )
        mismatch = np.flatnonzero(other != stamps1)
        if mismatch.size:
            index = int(mismatch[0])
            raise DataError(
                f"{path}: sample {index}: {tc1_topic} is stamped {stamps1[index] * 1e-9:.9f} s "
                f"but {topic} {other[index] * 1e-9:.9f} s"
            )
    time = stamps1.astype(np.float64) * 1e-9
    return _validated_record(
        str(path),
        time,
        series[tc1_topic][1],
        series[tc2_topic][1],
        series[ref_topic][1] if probe_ref else None,
        time_name=f"header.stamp of {tc1_topic}",
        frame_id=series[tc1_topic][2],
        stamps_ns=stamps1,
    )


def write_csv(
    path: str | Path,
    time: ArrayLike,
    tc1: ArrayLike,
    tc2: ArrayLike,
    ref: ArrayLike | None = None,
    *,
    extra: Mapping[str, ArrayLike] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``time,tc1,tc2[,ref][,extra...]`` with full float64 precision (``repr``).

    Raises
    ------
    DataError
        If the path exists and ``overwrite`` is False, or the columns differ in length.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise DataError(f"{path} exists; pass overwrite (--force) to replace it")
    columns: dict[str, NDArray[np.float64]] = {
        "time": check_finite(time, "time"),
        "tc1": np.asarray(tc1, dtype=np.float64),
        "tc2": np.asarray(tc2, dtype=np.float64),
    }
    if ref is not None:
        columns["ref"] = np.asarray(ref, dtype=np.float64)
    for name, values in (extra or {}).items():
        columns[name] = np.asarray(values, dtype=np.float64)
    length = columns["time"].size
    for name, values in columns.items():
        if values.shape != (length,):
            raise DataError(f"{path}: column {name!r} has shape {values.shape}, time ({length},)")
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(zip(*(values.tolist() for values in columns.values()), strict=True))
    return path


def _offered_qos() -> list:
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    unset = QosTime(sec=0, nsec=0)
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=10,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.VOLATILE,
            deadline=unset,
            lifespan=unset,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=unset,
            avoid_ros_namespace_conventions=False,
        )
    ]


def write_bag(
    path: str | Path,
    time: ArrayLike,
    series: Mapping[str, ArrayLike],
    *,
    frame_id: str = "tc",
    variance: Mapping[str, float] | None = None,
    overwrite: bool = False,
    compress: bool = False,
    start_ns: int = 0,
) -> Path:
    """Write temperature series as a rosbag2 (version 9) MCAP bag.

    One ``sensor_msgs/msg/Temperature`` per sample and topic, ``header.stamp`` = the sample time
    rounded to the nanosecond, log time = stamp. Topics are offered with reliable, keep-last-10,
    volatile QoS so ``ros2 bag play`` republishes them as a sensor driver would.

    Parameters
    ----------
    path : str or Path
        Bag directory to create.
    time : array_like, shape (N,)
        Sample times, seconds, >= 0.
    series : mapping of topic to array_like, shape (N,)
        Temperatures per topic, degrees C.
    frame_id : str
        ``header.frame_id`` of every message.
    variance : mapping of topic to float, optional
        ``variance`` field per topic (0, i.e. unknown, by default).
    overwrite : bool
        Replace an existing bag.
    start_ns : int
        Added to every stamp, nanoseconds: ``time`` can then be relative to an exact epoch.
    compress : bool
        Compress the MCAP chunks with zstd (storage-level compression, readable by
        ``ros2 bag``, rosbags and the mcap tools).
    """
    import shutil

    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if path.exists():
        if not overwrite:
            raise DataError(f"{path} exists; pass overwrite (--force) to replace it")
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
    times = check_finite(time, "time")
    stamps = start_ns + np.rint(times * 1e9).astype(np.int64)
    if stamps.size and stamps[0] < 0:
        raise DataError(f"{path}: the first stamp is {int(stamps[0])} ns; stamps must be >= 0")
    typestore = get_typestore(Stores.ROS2_JAZZY)
    temperature_type = typestore.types[TEMPERATURE_TYPE]
    header_type = typestore.types["std_msgs/msg/Header"]
    time_type = typestore.types["builtin_interfaces/msg/Time"]
    arrays = {topic: np.asarray(values, dtype=np.float64) for topic, values in series.items()}
    for topic, values in arrays.items():
        if values.shape != times.shape:
            raise DataError(f"{path}: topic {topic} has {values.size} samples, time {times.size}")
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compress:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        connections = {
            topic: writer.add_connection(
                topic, TEMPERATURE_TYPE, typestore=typestore, offered_qos_profiles=_offered_qos()
            )
            for topic in arrays
        }
        for index, stamp in enumerate(stamps.tolist()):
            header = header_type(
                stamp=time_type(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000),
                frame_id=frame_id,
            )
            for topic, values in arrays.items():
                message = temperature_type(
                    header=header,
                    temperature=float(values[index]),
                    variance=float((variance or {}).get(topic, 0.0)),
                )
                writer.write(
                    connections[topic],
                    stamp,
                    typestore.serialize_cdr(message, TEMPERATURE_TYPE),
                )
    return path


def write_series(
    path: str | Path,
    time: ArrayLike,
    tc1: ArrayLike,
    tc2: ArrayLike,
    ref: ArrayLike | None = None,
    *,
    gas: ArrayLike | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a record as CSV (``*.csv``) or as an MCAP bag (any other path).

    CSV columns: ``time,tc1,tc2[,ref][,gas]``. Bag topics: :data:`DEFAULT_TOPICS` and
    :data:`GAS_TOPIC` for ``gas``.
    """
    path = Path(path)
    if _is_csv(path):
        extra = {} if gas is None else {"gas": gas}
        return write_csv(path, time, tc1, tc2, ref, extra=extra, overwrite=overwrite)
    series: dict[str, ArrayLike] = {DEFAULT_TOPICS[0]: tc1, DEFAULT_TOPICS[1]: tc2}
    if ref is not None:
        series[str(DEFAULT_TOPICS[2])] = ref
    if gas is not None:
        series[GAS_TOPIC] = gas
    return write_bag(path, time, series, overwrite=overwrite)
