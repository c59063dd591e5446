"""Data I/O: CSV files and rosbag2 MCAP bags of two (or three) thermocouple signals.

CSV: a header ``time,tc1,tc2`` (seconds, degrees C) and optionally ``ref`` (a fast reference
sensor or the true gas temperature); further columns are allowed and ignored on reading. Bags:
rosbag2 version 9 with MCAP storage, holding ``sensor_msgs/msg/Temperature`` on
``/tc1/temperature``, ``/tc2/temperature`` and optionally ``/tref/temperature``. A sample's time
is its ``header.stamp`` (not the log time); the two thermocouples must carry identical stamps
(this reader pairs exactly; the ROS node pairs approximately).

Every error is a :class:`~tcomp_core.errors.DataError` naming the file, the column or topic, the
sample and the value; errors of the third-party readers are wrapped with ``from``. Nothing is
skipped: a record is read whole or refused.
"""

from __future__ import annotations

import csv
import math
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DataError
from .validation import check_finite, sample_interval_from_time

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

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

#: Topics of tc1, tc2 and the optional reference in a bag.
DEFAULT_TOPICS: tuple[str, str, str | None] = (
    "/tc1/temperature",
    "/tc2/temperature",
    "/tref/temperature",
)
#: Columns of tc1, tc2 and the optional reference in a CSV file (besides ``time``).
DEFAULT_COLUMNS: tuple[str, str, str | None] = ("tc1", "tc2", "ref")
#: Topic of a reconstructed gas temperature written by :func:`write_series`.
GAS_TOPIC = "/gas_temperature"
#: The only message type read and written.
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"

_NS_PER_S = 1_000_000_000
#: ``builtin_interfaces/msg/Time.sec`` is an int32.
_MAX_STAMP_NS = (2**31 - 1) * _NS_PER_S + _NS_PER_S - 1
_MCAP_MAGIC = b"\x89MCAP"


@dataclass(frozen=True, kw_only=True)
class Record:
    """A uniformly sampled two-thermocouple record.

    Attributes
    ----------
    time : ndarray of float64, shape (N,)
        Sample times, seconds, as read (bag stamps are absolute).
    tc1, tc2 : ndarray of float64, shape (N,)
        Thermocouple temperatures, degrees C.
    ref : ndarray of float64, shape (N,), or None
        Reference (fast sensor or true gas temperature), degrees C.
    source : str
        The file and the columns or topics read, for messages.
    dt : float
        Sample interval, seconds (checked uniform and > 0).
    frame_id : str
        ``header.frame_id`` of the first tc1 message of a bag; ``""`` for CSV.
    stamps_ns : ndarray of int64, shape (N,), or None
        Exact ``header.stamp`` in nanoseconds (bags only); ``time`` is its conversion
        ``sec + nanosec / 1e9``.

    Raises
    ------
    DataError
        If the arrays are not 1-D of one length or ``dt`` is not a finite interval > 0.
    """

    time: NDArray[np.float64]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    ref: NDArray[np.float64] | None
    source: str
    dt: float
    frame_id: str = ""
    stamps_ns: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        arrays = {"time": self.time, "tc1": self.tc1, "tc2": self.tc2}
        if self.ref is not None:
            arrays["ref"] = self.ref
        if self.stamps_ns is not None:
            arrays["stamps_ns"] = self.stamps_ns
        shape = np.shape(self.time)
        for name, values in arrays.items():
            if np.ndim(values) != 1 or np.shape(values) != shape:
                raise DataError(
                    f"{self.source}: {name} has shape {np.shape(values)}, time {shape}; "
                    "all series must be 1-D and of one length"
                )
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise DataError(f"{self.source}: dt={self.dt!r} must be a finite interval > 0 s")


# --------------------------------------------------------------------------------------------
# Dispatch


def _is_csv(path: Path) -> bool:
    return path.suffix.lower() == ".csv"


def _names(
    given: Sequence[str | None] | None,
    default: tuple[str, str, str | None],
    what: str,
) -> tuple[str, str, str | None]:
    """Normalise ``(tc1, tc2[, ref])`` names; a missing third entry means no reference."""
    if given is None:
        return default
    names = tuple(given)
    if len(names) not in (2, 3):
        raise DataError(f"{what} takes 2 or 3 names (tc1, tc2, ref or None), got {names!r}")
    first, second, *rest = names
    if not isinstance(first, str) or not first or not isinstance(second, str) or not second:
        raise DataError(f"{what}: the tc1 and tc2 names must be non-empty strings, got {names!r}")
    third = rest[0] if rest else None
    if third is not None and (not isinstance(third, str) or not third):
        raise DataError(f"{what}: the ref name must be a non-empty string or None, got {third!r}")
    return first, second, third


def read_record(
    path: str | Path,
    *,
    topics: Sequence[str | None] | None = None,
    columns: Sequence[str | None] | None = None,
) -> Record:
    """Read a CSV file or a rosbag2 MCAP bag, chosen by the path.

    A ``*.csv`` path is read by :func:`read_csv`; a directory, a ``*.mcap`` file, a file that
    starts with the MCAP magic bytes or a path that does not exist by :func:`read_bag`.

    Parameters
    ----------
    path : str or Path
        CSV file, bag directory, or an ``.mcap`` file (inside a bag directory or bare).
    topics : (tc1, tc2[, ref or None]), optional
        Bag topics; :data:`DEFAULT_TOPICS` when omitted.
    columns : (tc1, tc2[, ref or None]), optional
        CSV columns besides ``time``; :data:`DEFAULT_COLUMNS` when omitted.

    Returns
    -------
    Record

    Raises
    ------
    DataError
        See :func:`read_csv` and :func:`read_bag`; also for an existing file whose format
        cannot be told from its name or first bytes.
    """
    path = Path(path)
    if _is_csv(path):
        return read_csv(path, columns=_names(columns, DEFAULT_COLUMNS, "columns"))
    if path.is_file() and path.suffix.lower() != ".mcap":
        try:
            with path.open("rb") as handle:
                magic = handle.read(len(_MCAP_MAGIC))
        except OSError as exc:
            raise DataError(f"{path}: cannot open: {exc.strerror}") from exc
        if magic != _MCAP_MAGIC:
            raise DataError(
                f"{path}: cannot tell the format: expected a .csv file, a rosbag2 bag directory "
                "or an .mcap file"
            )
    return read_bag(path, topics=_names(topics, DEFAULT_TOPICS, "topics"))


def _validated_record(
    source: str,
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    ref: NDArray[np.float64] | None,
    *,
    time_name: str,
    index_hint: str = "",
    frame_id: str = "",
    stamps_ns: NDArray[np.int64] | None = None,
) -> Record:
    """Check the time vector (strictly increasing, uniform) and build the record."""
    # Integer stamps are checked as exact offsets from the first: absolute epoch seconds in
    # float64 resolve only ~0.2 µs, too coarse for the spacing check at kHz rates.
    relative = time if stamps_ns is None else (stamps_ns - stamps_ns[0]) / _NS_PER_S
    try:
        dt = sample_interval_from_time(relative, name=time_name)
    except DataError as exc:
        raise DataError(f"{source}: {exc}{index_hint}") from None
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


# --------------------------------------------------------------------------------------------
# CSV


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_csv(path: str | Path, *, columns: Sequence[str | None] = DEFAULT_COLUMNS) -> Record:
    """Read a CSV record with a header ``time,tc1,tc2[,ref]``.

    Parameters
    ----------
    path : str or Path
        The CSV file (UTF-8, an optional byte-order mark is accepted).
    columns : (tc1, tc2[, ref or None])
        Column names of the two thermocouples and the optional reference; the time column is
        always ``time`` (seconds). The default reference column ``ref`` is read when present
        and ignored when absent; any other reference column named must exist.

    Returns
    -------
    Record
        ``time`` (N,) seconds as written, ``tc1``/``tc2``/``ref`` (N,) degrees C.

    Raises
    ------
    DataError
        Missing or unreadable file, no header, missing or duplicated column, empty file or
        header only, ragged row, blank line inside the data, non-numeric or non-finite cell,
        time not strictly increasing or not uniform. The message names the file, the row as
        numbered in the file (header = row 1), the column and the text.
    """
    path = Path(path)
    tc1_name, tc2_name, ref_name = _names(columns, DEFAULT_COLUMNS, "columns")
    try:
        handle = path.open(newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise DataError(f"{path}: cannot open CSV file: {exc.strerror}") from exc
    try:
        with handle:
            return _parse_csv(path, csv.reader(handle), tc1_name, tc2_name, ref_name)
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})"
        ) from exc
    except csv.Error as exc:
        raise DataError(f"{path}: malformed CSV: {exc}") from exc


def _parse_csv(
    path: Path,
    reader: Any,  # the iterator csv.reader returns (its class is not public)
    tc1_name: str,
    tc2_name: str,
    ref_name: str | None,
) -> Record:
    header = next(reader, None)
    if header is None or not any(cell.strip() for cell in header):
        raise DataError(f"{path}: empty file, expected a header time,tc1,tc2[,ref]")
    names = [cell.strip() for cell in header]
    if all(_looks_numeric(name) for name in names):
        raise DataError(
            f"{path}: no header: row 1 holds numbers ({','.join(names)}); expected a header "
            "time,tc1,tc2[,ref]"
        )
    wanted = ["time", tc1_name, tc2_name]
    # The default reference column is optional; any other one named must exist (checked below).
    if ref_name is not None and (ref_name in names or ref_name != DEFAULT_COLUMNS[2]):
        wanted.append(ref_name)
    use_ref = len(wanted) == 4
    for name in dict.fromkeys(wanted):
        count = names.count(name)
        if count == 0:
            raise DataError(
                f"{path}: no column {name!r}; the header has columns {', '.join(map(repr, names))}"
            )
        if count > 1:
            raise DataError(f"{path}: column {name!r} appears {count} times in the header")
    indices = [names.index(name) for name in wanted]
    values: list[list[float]] = [[] for _ in wanted]
    blank_row = 0
    for row in reader:
        row_number = reader.line_num
        if not any(cell.strip() for cell in row):
            blank_row = blank_row or row_number
            continue
        if blank_row:
            raise DataError(
                f"{path}: row {blank_row} is blank but data follow on row {row_number}; "
                "remove the blank line (rows are never skipped)"
            )
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
                    f"{path}: row {row_number}, column {wanted[column]!r}: {text!r} is not finite"
                )
            values[column].append(number)
    if not values[0]:
        raise DataError(f"{path}: header only, no samples")
    arrays = [np.asarray(column, dtype=np.float64) for column in values]
    source = f"{path} (columns {', '.join(wanted)})"
    return _validated_record(
        source,
        arrays[0],
        arrays[1],
        arrays[2],
        arrays[3] if use_ref else None,
        time_name="column 'time'",
        index_hint=" (sample k is on row k + 2 of the file)",
    )


# --------------------------------------------------------------------------------------------
# Bags


def _format_stamp(stamp_ns: int) -> str:
    """A stamp in seconds with all nine decimals, exact for any int64 nanoseconds."""
    sign = "-" if stamp_ns < 0 else ""
    seconds, nanoseconds = divmod(abs(int(stamp_ns)), _NS_PER_S)
    return f"{sign}{seconds}.{nanoseconds:09d} s"


def _bag_location(path: Path) -> Path:
    """The path to hand to the rosbags reader: a bag directory or a bare ``.mcap`` file."""
    if not path.exists():
        raise DataError(f"{path}: no such bag (neither a bag directory nor an .mcap file)")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            mcaps = sorted(item.name for item in path.glob("*.mcap"))
            hint = f"; to read a bare MCAP file, pass it: {', '.join(mcaps)}" if mcaps else ""
            raise DataError(f"{path}: not a rosbag2 bag: the directory has no metadata.yaml{hint}")
        return path
    if path.suffix.lower() == ".mcap" and (path.parent / "metadata.yaml").is_file():
        return path.parent  # the .mcap file of a bag: read the bag (all its files)
    return path


@dataclass
class _Series:
    """Messages of one topic as read: stamps (ns), temperatures (deg C), first frame id."""

    stamps: list[int]
    temperatures: list[float]
    frame_id: str = ""


def _read_bag_messages(
    path: Path, required: Sequence[str], optional: str | None
) -> tuple[dict[str, _Series], str]:
    """Read the Temperature messages of the wanted topics, checking topics and types.

    Returns the series per topic read (``optional`` only when the bag has it) and the bag's
    topic list (for messages).
    """
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    location = _bag_location(path)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    try:
        with Reader(location) as reader:
            types: dict[str, set[str]] = {}
            for connection in reader.connections:
                types.setdefault(connection.topic, set()).add(connection.msgtype)
            listed = ", ".join(
                f"{topic} ({', '.join(sorted(kinds))})" for topic, kinds in sorted(types.items())
            )
            wanted = list(dict.fromkeys(required))
            if optional is not None and optional in types and optional not in wanted:
                wanted.append(optional)
            for topic in wanted:
                if topic not in types:
                    raise DataError(
                        f"{path}: no topic {topic}; the bag has {listed or 'no topics'}"
                    )
                if types[topic] != {TEMPERATURE_TYPE}:
                    raise DataError(
                        f"{path}: topic {topic} carries {', '.join(sorted(types[topic]))}, "
                        f"not {TEMPERATURE_TYPE}"
                    )
            found = {topic: _Series([], []) for topic in wanted}
            connections = [c for c in reader.connections if c.topic in found]
            for connection, _, raw in reader.messages(connections=connections):
                message = typestore.deserialize_cdr(raw, connection.msgtype)
                series = found[connection.topic]
                if not series.stamps:
                    series.frame_id = str(message.header.frame_id)
                stamp = message.header.stamp
                series.stamps.append(int(stamp.sec) * _NS_PER_S + int(stamp.nanosec))
                series.temperatures.append(float(message.temperature))
    except DataError:
        raise
    except Exception as exc:  # rosbags and its decoders raise many types for corrupt input
        raise DataError(
            f"{path}: cannot read the bag ({type(exc).__name__}: {exc}); it may be truncated, "
            "corrupt or not a rosbag2 MCAP bag"
        ) from exc
    return found, listed


def _check_paired(
    path: Path,
    first: str,
    first_stamps: NDArray[np.int64],
    second: str,
    second_stamps: NDArray[np.int64],
) -> None:
    """Refuse two topics whose stamps are not identical sample by sample."""
    common = min(first_stamps.size, second_stamps.size)
    differ = np.flatnonzero(first_stamps[:common] != second_stamps[:common])
    index = int(differ[0]) if differ.size else common
    if first_stamps.size != second_stamps.size:

        def stamp_of(stamps: NDArray[np.int64]) -> str:
            return _format_stamp(int(stamps[index])) if index < stamps.size else "none"

        raise DataError(
            f"{path}: {first} has {first_stamps.size} messages but {second} has "
            f"{second_stamps.size}; the first unpaired sample is {index}: {first} stamped "
            f"{stamp_of(first_stamps)}, {second} {stamp_of(second_stamps)} "
            "(samples are paired by identical header.stamp)"
        )
    if differ.size:
        raise DataError(
            f"{path}: sample {index}: {first} is stamped {_format_stamp(int(first_stamps[index]))}"
            f" but {second} {_format_stamp(int(second_stamps[index]))} "
            "(samples are paired by identical header.stamp)"
        )


def read_bag(path: str | Path, *, topics: Sequence[str | None] = DEFAULT_TOPICS) -> Record:
    """Read a rosbag2 MCAP bag of ``sensor_msgs/msg/Temperature`` messages.

    Parameters
    ----------
    path : str or Path
        Bag directory (with ``metadata.yaml``), the ``.mcap`` file inside one (the whole bag is
        read), or a bare ``.mcap`` file without metadata.
    topics : (tc1, tc2[, ref or None])
        Topics of the two thermocouples and the optional reference. The default reference
        topic is read when present and ignored when absent; any other reference topic named
        must exist.

    Returns
    -------
    Record
        One sample per message, sorted by ``header.stamp``: ``time`` (N,) seconds
        (``sec + nanosec / 1e9``, absolute), ``stamps_ns`` (N,) the exact stamps, temperatures
        (N,) degrees C, ``frame_id`` of the first tc1 message.

    Raises
    ------
    DataError
        Missing path, not a bag, truncated or corrupt MCAP (the reader's exception is the
        ``__cause__``), missing topic (the bag's topics and types are listed), wrong message
        type, topic without messages, stamps of tc1 and tc2 (or ref) that do not pair one to
        one, non-finite temperature, stamps not strictly increasing or not uniform.
    """
    path = Path(path)
    tc1_topic, tc2_topic, ref_topic = _names(topics, DEFAULT_TOPICS, "topics")
    required = [tc1_topic, tc2_topic]
    optional = None
    if ref_topic is not None:
        if ref_topic == DEFAULT_TOPICS[2]:
            optional = ref_topic
        else:
            required.append(ref_topic)
    found, listed = _read_bag_messages(path, required, optional)
    use_ref = ref_topic is not None and ref_topic in found
    order = [tc1_topic, tc2_topic, *([ref_topic] if use_ref and ref_topic else [])]
    stamps: dict[str, NDArray[np.int64]] = {}
    temperatures: dict[str, NDArray[np.float64]] = {}
    for topic in dict.fromkeys(order):
        series = found[topic]
        if not series.stamps:
            raise DataError(f"{path}: topic {topic} has no messages; the bag has {listed}")
        topic_stamps = np.asarray(series.stamps, dtype=np.int64)
        sort = np.argsort(topic_stamps, kind="stable")  # log-time order need not be stamp order
        topic_stamps = topic_stamps[sort]
        values = np.asarray(series.temperatures, dtype=np.float64)[sort]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            index = int(bad[0])
            raise DataError(
                f"{path}: topic {topic}, message {index} (stamp "
                f"{_format_stamp(int(topic_stamps[index]))}) has temperature "
                f"{float(values[index])!r}; {bad.size} of {values.size} messages are not finite"
            )
        stamps[topic], temperatures[topic] = topic_stamps, values
    for topic in order[1:]:
        _check_paired(path, tc1_topic, stamps[tc1_topic], topic, stamps[topic])
    stamps_ns = stamps[tc1_topic]
    seconds, nanoseconds = np.divmod(stamps_ns, _NS_PER_S)
    time = seconds.astype(np.float64) + nanoseconds / _NS_PER_S
    return _validated_record(
        f"{path} (topics {', '.join(order)})",
        time,
        temperatures[tc1_topic],
        temperatures[tc2_topic],
        temperatures[order[2]] if use_ref else None,
        time_name=f"header.stamp of {tc1_topic}",
        index_hint=f" (times counted from the first stamp, {_format_stamp(int(stamps_ns[0]))})",
        frame_id=found[tc1_topic].frame_id,
        stamps_ns=stamps_ns,
    )


# --------------------------------------------------------------------------------------------
# Writing


def _clear_for_writing(path: Path, overwrite: bool, *, bag: bool) -> None:
    """Refuse an existing output unless ``overwrite``; then remove it (files and bags only)."""
    if not (path.exists() or path.is_symlink()):
        return
    if not overwrite:
        raise DataError(f"{path} exists; pass overwrite (--force) to replace it")
    if path.is_dir() and not path.is_symlink():
        is_bag = (path / "metadata.yaml").is_file()
        if not bag or not (is_bag or not any(path.iterdir())):
            raise DataError(
                f"{path} is a directory that is not a rosbag2 bag; refusing to replace it"
            )
        shutil.rmtree(path)
    else:
        path.unlink()


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
    """Write ``time,tc1,tc2[,ref][,extra...]`` with full float64 precision.

    Every value is written as its shortest round-tripping ``repr``, so :func:`read_csv` gives
    back the same float64 bits.

    Parameters
    ----------
    path : str or Path
        CSV file to create; parent directories are created.
    time : array_like, shape (N,)
        Sample times, seconds (must be finite).
    tc1, tc2 : array_like, shape (N,)
        Temperatures, degrees C.
    ref : array_like, shape (N,), optional
        Reference temperature, degrees C (column ``ref``).
    extra : mapping of str to array_like, shape (N,), optional
        Further columns appended in order (for example ``gas``).
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    DataError
        If the path exists and ``overwrite`` is False, a column name repeats or is empty, a
        column has another length than ``time``, or ``time`` is not finite.
    """
    path = Path(path)
    columns: dict[str, NDArray[np.float64]] = {
        "time": check_finite(time, f"{path}: column 'time'"),
        "tc1": np.asarray(tc1, dtype=np.float64),
        "tc2": np.asarray(tc2, dtype=np.float64),
    }
    if ref is not None:
        columns["ref"] = np.asarray(ref, dtype=np.float64)
    for name, values in (extra or {}).items():
        if not name or name in columns:
            raise DataError(f"{path}: extra column name {name!r} is empty or already used")
        columns[name] = np.asarray(values, dtype=np.float64)
    length = columns["time"].size
    for name, values in columns.items():
        if values.shape != (length,):
            raise DataError(f"{path}: column {name!r} has shape {values.shape}, time ({length},)")
    _clear_for_writing(path, overwrite, bag=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        # tolist() gives Python floats, which csv writes as repr(): shortest exact round trip.
        writer.writerows(zip(*(values.tolist() for values in columns.values()), strict=True))
    return path


def _seconds_to_ns(seconds: NDArray[np.float64]) -> NDArray[np.int64]:
    """Round times to integer nanoseconds exactly (the float's exact value, ties to even).

    ``np.rint(t * 1e9)`` rounds twice (the product, then to an integer) and misplaces values
    near a half nanosecond, and loses up to ~100 ns for epoch times. Here the whole seconds are
    split off exactly; the fraction's product is rounded once by float arithmetic and only the
    samples within an ulp of a half nanosecond are redone with exact rationals.
    """
    whole = np.floor(seconds)
    fraction = seconds - whole  # exact: both lie on the float grid of ``seconds``
    scaled = fraction * 1e9  # in [0, 1e9], error <= half an ulp (< 6e-8)
    nearest = np.rint(scaled)
    doubtful = np.flatnonzero(np.abs(np.abs(scaled - nearest) - 0.5) <= np.spacing(scaled))
    nanoseconds = nearest.astype(np.int64)
    for index in doubtful.tolist():
        nanoseconds[index] = round(Fraction(float(fraction[index])) * _NS_PER_S)
    return whole.astype(np.int64) * _NS_PER_S + nanoseconds


def _offered_qos() -> list[Qos]:
    """Reliable, keep-last-10, volatile: what ``ros2 bag play`` should offer subscribers."""
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

    One ``sensor_msgs/msg/Temperature`` per sample and topic; ``header.stamp`` is
    ``start_ns`` plus the sample time rounded exactly to the nanosecond, and the log time is
    the same stamp. Topics are offered with reliable, keep-last-10, volatile QoS so
    ``ros2 bag play`` republishes them as a sensor driver would.

    Parameters
    ----------
    path : str or Path
        Bag directory to create.
    time : array_like, shape (N,)
        Sample times, seconds (finite; stamps must come out in [0, 2**31) s).
    series : mapping of topic to array_like, shape (N,)
        Temperatures per topic, degrees C. Values are written as given (non-finite values
        too, so that bad bags can be made for tests; :func:`read_bag` refuses them).
    frame_id : str
        ``header.frame_id`` of every message.
    variance : mapping of topic to float, optional
        ``variance`` field per topic, (degrees C)**2; 0 (unknown) by default.
    overwrite : bool
        Replace an existing bag (a directory holding ``metadata.yaml``, or a file).
    compress : bool
        Compress the MCAP chunks with zstd (storage-level compression, readable by
        ``ros2 bag``, rosbags and the mcap tools).
    start_ns : int
        Added to every stamp, nanoseconds: ``time`` can then be relative to an exact epoch.

    Returns
    -------
    Path
        ``path``, the bag directory.

    Raises
    ------
    DataError
        If the path exists and ``overwrite`` is False, ``series`` is empty, a series has
        another length than ``time``, ``variance`` names a topic not written, or a stamp falls
        outside the ``builtin_interfaces/msg/Time`` range.
    """
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    times = check_finite(time, f"{path}: time")
    if not series:
        raise DataError(f"{path}: no series to write")
    arrays = {topic: np.asarray(values, dtype=np.float64) for topic, values in series.items()}
    for topic, values in arrays.items():
        if values.shape != times.shape:
            raise DataError(f"{path}: topic {topic} has shape {values.shape}, time {times.shape}")
    unknown = sorted(set(variance or {}) - set(arrays))
    if unknown:
        raise DataError(f"{path}: variance given for topics not written: {', '.join(unknown)}")
    if times.size and np.max(np.abs(times)) >= 2.0**33:
        raise DataError(f"{path}: time {float(np.max(np.abs(times)))!r} s is out of range")
    stamps = int(start_ns) + _seconds_to_ns(times)
    if stamps.size and (stamps.min() < 0 or stamps.max() > _MAX_STAMP_NS):
        index = int(np.argmin(stamps) if stamps.min() < 0 else np.argmax(stamps))
        raise DataError(
            f"{path}: sample {index} is stamped {int(stamps[index])} ns; stamps must lie in "
            f"[0, {_MAX_STAMP_NS}] ns (builtin_interfaces/msg/Time)"
        )
    _clear_for_writing(path, overwrite, bag=True)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    temperature_type = typestore.types[TEMPERATURE_TYPE]
    header_type = typestore.types["std_msgs/msg/Header"]
    time_type = typestore.types["builtin_interfaces/msg/Time"]
    variances = {topic: float((variance or {}).get(topic, 0.0)) for topic in arrays}
    columns = {topic: values.tolist() for topic, values in arrays.items()}
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
            sec, nanosec = divmod(stamp, _NS_PER_S)
            header = header_type(stamp=time_type(sec=sec, nanosec=nanosec), frame_id=frame_id)
            for topic, connection in connections.items():
                message = temperature_type(
                    header=header, temperature=columns[topic][index], variance=variances[topic]
                )
                writer.write(connection, stamp, typestore.serialize_cdr(message, TEMPERATURE_TYPE))
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

    Parameters
    ----------
    path : str or Path
        ``*.csv`` file, or bag directory to create.
    time : array_like, shape (N,)
        Sample times, seconds.
    tc1, tc2 : array_like, shape (N,)
        Thermocouple temperatures, degrees C.
    ref : array_like, shape (N,), optional
        Reference temperature, degrees C.
    gas : array_like, shape (N,), optional
        Reconstructed gas temperature, degrees C.
    overwrite : bool
        Replace an existing output.

    Returns
    -------
    Path
        ``path``. CSV columns: ``time,tc1,tc2[,ref][,gas]``. Bag topics:
        :data:`DEFAULT_TOPICS` (ref only if given) and :data:`GAS_TOPIC` for ``gas``.

    Raises
    ------
    DataError
        As :func:`write_csv` and :func:`write_bag`.
    """
    path = Path(path)
    if _is_csv(path):
        extra = {} if gas is None else {"gas": gas}
        return write_csv(path, time, tc1, tc2, ref, extra=extra, overwrite=overwrite)
    series: dict[str, ArrayLike] = {DEFAULT_TOPICS[0]: tc1, DEFAULT_TOPICS[1]: tc2}
    if ref is not None and DEFAULT_TOPICS[2] is not None:
        series[DEFAULT_TOPICS[2]] = ref
    if gas is not None:
        series[GAS_TOPIC] = gas
    return write_bag(path, time, series, overwrite=overwrite)
