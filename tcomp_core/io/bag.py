"""rosbag2 MCAP bags of ``sensor_msgs/msg/Temperature``: reading a record, writing series.

Bags are rosbag2 version 9 with MCAP storage. A sample's time is its ``header.stamp`` (not the
log time); the two thermocouples (and the reference) must carry identical stamps: this reader
pairs exactly, the ROS node approximately.

:func:`read_bag` reads through the same chunk-wise scanner as ``tcomp process``
(:class:`~tcomp_core.io.mcap_read.McapScan`, bulk decoding with the rosbags fallback), so every
verb accepts and refuses the same files with the same messages. A cut-off end is read up to
its last complete record, the samples after the last stamp every topic reached are dropped, and
a :class:`~tcomp_core.errors.TruncatedInputWarning` says where reading stopped.

:func:`write_bag` encodes arrays in bulk and :func:`write_bag_copy` copies the messages of a bag
unchanged (and adds a gas temperature topic), both through the writer of ``tcomp process``,
:class:`~tcomp_core.io.mcap_write.McapBagWriter`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError, TruncatedInputWarning
from ..validation import check_finite
from .mcap_read import McapScan, Truncation, payloads
from .mcap_write import McapBagWriter
from .outputs import atomic_output
from .paths import bag_files, bag_location
from .qos import offered_qos
from .record import (
    DEFAULT_TOPICS,
    GAS_TOPIC,
    MAX_STAMP_NS,
    TEMPERATURE_TYPE,
    BagOrigin,
    Record,
    check_names,
    format_stamp,
    seconds_to_ns,
    stamps_to_seconds,
    validated_record,
)
from .rows import column
from .temperature import TemperatureBatch, decode_rows, encode

__all__ = [
    "WRITE_BLOCK",
    "paired_record",
    "read_bag",
    "read_topics",
    "write_bag",
    "write_bag_copy",
]

#: Samples per topic encoded at a time by :func:`write_bag` (the topics alternate by block).
WRITE_BLOCK = 1024


def read_topics(
    path: Path, required: Sequence[str], optional: str | None = None
) -> tuple[dict[str, TemperatureBatch], str, tuple[Path, ...], Truncation | None]:
    """Read and decode every message of the wanted Temperature topics of a bag.

    Parameters
    ----------
    path : Path
        Bag directory, its ``.mcap`` file, or a bare ``.mcap`` file.
    required : sequence of str
        Topics that must exist.
    optional : str, optional
        A topic read when the bag has it.

    Returns
    -------
    batches : dict of str to TemperatureBatch
        Per topic read, in log order (``optional`` only when the bag has it).
    listed : str
        The bag's topics and types, for messages.
    files : tuple of Path
        The MCAP files read.
    truncation : Truncation or None
        Where a cut-off end stopped the reading (no warning is issued here).

    Raises
    ------
    DataError
        See :func:`read_bag`.
    """
    files = tuple(bag_files(path))
    wanted = list(dict.fromkeys([*required, *([optional] if optional else [])]))
    scan = McapScan(files, wanted, TEMPERATURE_TYPE, name=path)
    parts: dict[str, list[TemperatureBatch]] = {topic: [] for topic in wanted}
    for chunk in scan:
        for topic, blocks in chunk.topics.items():
            try:
                parts[topic].extend(decode_rows(payloads(block)) for block in blocks)
            except DataError as exc:
                raise DataError(
                    f"{chunk.file}: chunk at byte {chunk.offset}, topic {topic}: {exc}"
                ) from exc
    listed = scan.listed_topics()
    for topic in required:
        if topic not in scan.types:
            raise DataError(f"{path}: no topic {topic}; the bag has {listed or 'no topics'}")
    batches = {
        topic: TemperatureBatch.concatenate(parts[topic])
        for topic in wanted
        if topic in scan.types
    }
    return batches, listed, files, scan.truncation


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
        (N,) degrees C, ``frame_id`` of the first tc1 message, ``origin`` the bag.

    Raises
    ------
    DataError
        Missing path, not a bag, not MCAP, corrupt MCAP (CRC mismatch, a record length that
        disagrees, naming file, chunk and offset), missing topic (the bag's topics and types
        are listed), wrong message type, topic without messages, stamps of tc1 and tc2 (or
        ref) that do not pair one to one, stamps not strictly increasing or not uniform, or
        readings that :func:`~tcomp_core.io.screening.screen_samples` cannot leave out.

    Warns
    -----
    TruncatedInputWarning
        The bag ends early (still being written, or cut off): it is read up to its last
        complete record, and samples after the last stamp all topics reached are dropped.
    InvalidReadingsWarning
        Readings not finite or outside the physical range, or repeated stamps, left out
        (:mod:`tcomp_core.io.screening`).
    """
    path = Path(path)
    tc1_topic, tc2_topic, ref_topic = check_names(topics, DEFAULT_TOPICS, "topics")
    required = [tc1_topic, tc2_topic]
    optional = None
    if ref_topic is not None:
        if ref_topic == DEFAULT_TOPICS[2]:
            optional = ref_topic
        else:
            required.append(ref_topic)
    bag_location(path)
    found, listed, files, truncation = read_topics(path, required, optional)
    if truncation is not None:
        warnings.warn(str(truncation), TruncatedInputWarning, stacklevel=2)
    use_ref = ref_topic is not None and ref_topic in found
    order = [tc1_topic, tc2_topic, *([ref_topic] if use_ref and ref_topic else [])]
    for topic in dict.fromkeys(order):
        if not len(found[topic]):
            raise DataError(f"{path}: topic {topic} has no messages; the bag has {listed}")
    return paired_record(path, order, found, files, truncated=truncation is not None)


def paired_record(
    path: Path,
    order: Sequence[str],
    found: Mapping[str, TemperatureBatch],
    files: tuple[Path, ...],
    *,
    truncated: bool = False,
) -> Record:
    """The record of the samples decoded from a bag (all of it, or a stretch of it).

    Each topic's samples are sorted by stamp (log order need not be stamp order), the topics
    paired by identical stamps and the samples screened and checked uniform
    (:func:`~tcomp_core.io.record.validated_record`): what :func:`read_bag` does with the whole
    bag and the windows of ``tcomp diagnose --window-s`` with each stretch.

    Parameters
    ----------
    path : Path
        The bag, for messages.
    order : sequence of str
        The tc1 and tc2 topics and, when read, the reference's.
    found : mapping of topic to TemperatureBatch
        The decoded samples of each topic of ``order``, none empty.
    files : tuple of Path
        The bag's MCAP files (the record's origin).
    truncated : bool
        The bag ends early: samples after the last stamp every topic reached are dropped.

    Raises
    ------
    DataError
        As :func:`read_bag`: unpaired stamps, stamps not uniform, readings that cannot be
        left out.
    """
    stamps: dict[str, NDArray[np.int64]] = {}
    temperatures: dict[str, NDArray[np.float64]] = {}
    for topic in dict.fromkeys(order):
        batch = found[topic]
        sort = np.argsort(batch.stamps_ns, kind="stable")  # log order need not be stamp order
        stamps[topic], temperatures[topic] = (
            batch.stamps_ns[sort],
            batch.temperature[sort],
        )
    if truncated:  # a cut-off end: drop what not every topic reached
        last = min(int(topic_stamps[-1]) for topic_stamps in stamps.values())
        for topic, topic_stamps in stamps.items():
            keep = int(np.searchsorted(topic_stamps, last, side="right"))
            stamps[topic], temperatures[topic] = (
                topic_stamps[:keep],
                temperatures[topic][:keep],
            )
    tc1_topic, tc2_topic = order[0], order[1]
    for topic in order[1:]:
        _check_paired(path, tc1_topic, stamps[tc1_topic], topic, stamps[topic])
    stamps_ns = stamps[tc1_topic]
    return validated_record(
        f"{path} (topics {', '.join(order)})",
        stamps_to_seconds(stamps_ns),
        temperatures[tc1_topic],
        temperatures[tc2_topic],
        temperatures[order[2]] if len(order) > 2 else None,
        time_name=f"header.stamp of {tc1_topic}",
        names=(f"topic {tc1_topic}", f"topic {tc2_topic}"),
        where=lambda index: f"stamp {format_stamp(int(stamps_ns[index]))}",
        index_hint=f" (times counted from the first stamp, {format_stamp(int(stamps_ns[0]))})",
        frame_id=found[tc1_topic].frame_id,
        stamps_ns=stamps_ns,
        origin=BagOrigin(files, tuple(order)),
    )


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
            return format_stamp(int(stamps[index])) if index < stamps.size else "none"

        raise DataError(
            f"{path}: {first} has {first_stamps.size} messages but {second} has "
            f"{second_stamps.size}; the first unpaired sample is {index}: {first} stamped "
            f"{stamp_of(first_stamps)}, {second} {stamp_of(second_stamps)} "
            "(samples are paired by identical header.stamp)"
        )
    if differ.size:
        raise DataError(
            f"{path}: sample {index}: {first} is stamped {format_stamp(int(first_stamps[index]))}"
            f" but {second} {format_stamp(int(second_stamps[index]))} "
            "(samples are paired by identical header.stamp)"
        )


def write_bag(
    path: str | Path,
    time: ArrayLike,
    series: Mapping[str, ArrayLike],
    *,
    frame_id: str = "tc",
    variance: Mapping[str, ArrayLike] | None = None,
    overwrite: bool = False,
    compress: bool = False,
    start_ns: int = 0,
    inputs: Iterable[Path] = (),
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
        too: a gas marked not valid, or bad bags for tests; :func:`read_bag` leaves them out).
    frame_id : str
        ``header.frame_id`` of every message.
    variance : mapping of topic to float or array_like of shape (N,), optional
        ``variance`` field per topic (one value, or one per sample), (degrees C)**2; 0
        (unknown) by default.
    overwrite : bool
        Replace an existing bag (a directory holding ``metadata.yaml``, or a file).
    compress : bool
        Compress the MCAP chunks with zstd (storage-level compression, readable by
        ``ros2 bag``, rosbags and the mcap tools).
    start_ns : int
        Added to every stamp, nanoseconds: ``time`` can then be relative to an exact epoch.
    inputs : iterable of Path
        Files the data were read from: the bag may not overlap them. It is written under a
        temporary name and renamed when complete (:func:`~.outputs.atomic_output`).

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
    stamps = int(start_ns) + seconds_to_ns(times)
    if stamps.size and (stamps.min() < 0 or stamps.max() > MAX_STAMP_NS):
        index = int(np.argmin(stamps) if stamps.min() < 0 else np.argmax(stamps))
        raise DataError(
            f"{path}: sample {index} is stamped {int(stamps[index])} ns; stamps must lie in "
            f"[0, {MAX_STAMP_NS}] ns (builtin_interfaces/msg/Time)"
        )
    given = variance or {}
    try:
        variances = {
            topic: np.broadcast_to(np.asarray(given.get(topic, 0.0), np.float64), times.shape)
            for topic in arrays
        }
    except ValueError as exc:
        raise DataError(f"{path}: a variance does not match the {times.size} samples") from exc
    with atomic_output(path, overwrite, inputs, directory=True) as temporary:
        writer = McapBagWriter(temporary, compress=compress, name=path.name)
        try:
            channels = {
                topic: writer.add_channel(topic, TEMPERATURE_TYPE, offered_qos())
                for topic in arrays
            }
            for start in range(0, stamps.size, WRITE_BLOCK):
                part = slice(start, start + WRITE_BLOCK)
                for topic, channel in channels.items():
                    rows = encode(
                        stamps[part], arrays[topic][part], variances[topic][part], frame_id
                    )
                    writer.write_rows(channel, stamps[part], rows)
            writer.close()
        except BaseException:
            writer.abort()
            raise
    return path


def write_bag_copy(
    path: str | Path,
    origin: BagOrigin,
    gas_stamps_ns: ArrayLike,
    gas: ArrayLike,
    *,
    frame_id: str = "",
    overwrite: bool = False,
    compress: bool = True,
    gas_variance: ArrayLike | None = None,
) -> Path:
    """Copy a bag's Temperature topics unchanged and add a gas temperature topic.

    The input messages are copied record for record (payload, log and publish time, sequence,
    channel id and offered QoS as recorded) through the writer ``tcomp process`` uses; the gas
    samples go to :data:`GAS_TOPIC`, stamped and logged at their stamps.

    Parameters
    ----------
    path : str or Path
        Bag directory to create.
    origin : BagOrigin
        The bag and topics to copy (:attr:`Record.origin` of a record read by
        :func:`read_bag`).
    gas_stamps_ns : array_like of int, shape (M,)
        Stamps of the gas samples, nanoseconds.
    gas : array_like, shape (M,)
        Gas temperature, degrees C.
    frame_id : str
        ``header.frame_id`` of the gas messages.
    overwrite : bool
        Replace an existing bag.
    compress : bool
        zstd-compress the chunks.
    gas_variance : array_like, shape (M,), optional
        The gas messages' ``variance`` field, (degrees C)**2; 0 (unknown) without it.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    DataError
        The output exists and ``overwrite`` is False, it would replace the input, shapes
        differ, a stamp is out of range, or the input is unreadable (as :func:`read_bag`).
    """
    path = Path(path)
    stamps = np.asarray(gas_stamps_ns, dtype=np.int64)
    values = np.asarray(gas, dtype=np.float64)
    if stamps.shape != values.shape or stamps.ndim != 1:
        raise DataError(f"{path}: gas has shape {values.shape}, its stamps {stamps.shape}")
    variance = np.zeros_like(values) if gas_variance is None else np.asarray(gas_variance, float)
    if variance.shape != values.shape:
        raise DataError(f"{path}: gas variance has shape {variance.shape}, gas {values.shape}")
    rows = encode(stamps, values, variance, frame_id)
    inputs = [*origin.files, *(file.parent for file in origin.files)]
    with atomic_output(path, overwrite, inputs, directory=True) as temporary:
        _copy_with_gas(temporary, path.name, origin, stamps, rows, compress)
    return path


def _copy_with_gas(
    target: Path,
    name: str,
    origin: BagOrigin,
    stamps: NDArray[np.int64],
    rows: NDArray[np.uint8],
    compress: bool,
) -> None:
    """The body of :func:`write_bag_copy`, writing the bag directory ``target``."""
    writer = McapBagWriter(target, compress=compress, name=name)
    try:
        channels: dict[str, int] = {}
        scan = McapScan(origin.files, origin.topics, TEMPERATURE_TYPE, name=origin.files[0])
        for chunk in scan:
            for topic in origin.topics:  # channel order: the topics' order, as read
                for block in chunk.topics.get(topic, ()):
                    if topic not in channels:
                        qos = scan.metadata.get(topic, {}).get("offered_qos_profiles")
                        channels[topic] = writer.add_channel(
                            topic,
                            TEMPERATURE_TYPE,
                            offered_qos(),
                            channel_id=int(column(block, 9, "<u2")[0]),
                            qos_text=qos,
                        )
                    writer.write_records(channels[topic], block)
        if scan.truncation is not None:
            warnings.warn(str(scan.truncation), TruncatedInputWarning, stacklevel=2)
        gas_channel = writer.add_channel(GAS_TOPIC, TEMPERATURE_TYPE, offered_qos())
        writer.write_rows(gas_channel, stamps, rows)
        writer.close()
    except BaseException:
        writer.abort()
        raise
