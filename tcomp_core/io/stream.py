"""Chunk-by-chunk input of ``tcomp process``: decoded samples per role, and the raw records.

:func:`open_stream` opens a bag (:class:`BagStream`, one :class:`Block` per MCAP chunk, read by
:class:`~tcomp_core.io.mcap_read.McapScan` and decoded in bulk) or a CSV file
(:class:`CsvStream`, read whole, handed over :data:`CSV_BLOCK` rows at a time). Roles are
``'tc1'``, ``'tc2'`` and ``'ref'``.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from .csvfile import read_csv
from .mcap_read import McapScan, Truncation, payloads
from .paths import bag_files, is_csv
from .record import (
    DEFAULT_COLUMNS,
    DEFAULT_TOPICS,
    TEMPERATURE_TYPE,
    check_names,
    seconds_to_ns,
)
from .temperature import TemperatureBatch, decode_rows

__all__ = ["CSV_BLOCK", "ROLES", "BagStream", "Block", "CsvStream", "open_stream"]

#: The roles of the input series.
ROLES = ("tc1", "tc2", "ref")
#: Rows of CSV input handed over at a time.
CSV_BLOCK = 100_000


@dataclass
class Block:
    """Decoded samples per role and, from a bag, the raw records to copy.

    Attributes
    ----------
    series : dict of str to TemperatureBatch
        Per role, in log order.
    records : dict of str to list of ndarray of uint8, shape (n, R)
        Per role, the whole MCAP message records the samples were decoded from (bags only).
    fraction : float
        The share of the input read so far, 0..1.
    """

    series: dict[str, TemperatureBatch]
    records: dict[str, list[NDArray[np.uint8]]]
    fraction: float


class BagStream:
    """The Temperature topics of a bag, one :class:`Block` per MCAP chunk.

    Parameters
    ----------
    path : Path
        Bag directory, its ``.mcap`` file or a bare ``.mcap`` file.
    topics : mapping of role to topic

    Raises
    ------
    DataError
        On opening: see :func:`~tcomp_core.io.paths.bag_files`; while iterating: see
        :class:`~tcomp_core.io.mcap_read.McapScan`, and an undecodable message (file, chunk,
        topic).
    """

    def __init__(self, path: Path, topics: Mapping[str, str]) -> None:
        self.path = path
        self.topics = dict(topics)
        self.scan = McapScan(bag_files(path), list(topics.values()), TEMPERATURE_TYPE, name=path)

    def __iter__(self) -> Iterator[Block]:
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
                        f"{chunk.file}: chunk at byte {chunk.offset}, topic {topic}: {exc}"
                    ) from exc
                records[role] = blocks
            total = max(self.scan.bytes_total, 1)
            yield Block(series, records, min(self.scan.bytes_read / total, 1.0))

    @property
    def truncation(self) -> Truncation | None:
        """Where a cut-off end stopped the reading (None: read to the end)."""
        return self.scan.truncation

    def qos_text(self, role: str) -> str | None:
        """The input channel's ``offered_qos_profiles``, as recorded (None if it has none)."""
        return self.scan.metadata.get(self.topics[role], {}).get("offered_qos_profiles")

    def check_topics(self) -> None:
        """Refuse a bag without the tc1 or tc2 topic (call after iterating).

        Raises
        ------
        DataError
            Naming the bag, the topic and the topics the bag has.
        """
        listed = self.scan.listed_topics()
        for role in ("tc1", "tc2"):
            if self.topics[role] not in self.scan.types:
                raise DataError(
                    f"{self.path}: no topic {self.topics[role]}; the bag has "
                    f"{listed or 'no topics'}"
                )


class CsvStream:
    """A CSV record, :data:`CSV_BLOCK` rows per :class:`Block`, stamped at its times.

    Parameters
    ----------
    path : Path
    columns : (tc1, tc2, ref or None)

    Raises
    ------
    DataError
        See :func:`~tcomp_core.io.read_csv`; negative times (while iterating).
    """

    def __init__(self, path: Path, columns: tuple[str, str, str | None]) -> None:
        self.path = path
        # Unscreened: the pair matcher drops and counts invalid readings, as from a bag; and
        # like a bag's stamps, the times may change rate (the engine notices and restarts).
        self.record = read_csv(path, columns=columns, screen=False, uniform=False)
        self.topics = {
            role: topic
            for role, topic in zip(ROLES, DEFAULT_TOPICS, strict=True)
            if topic is not None and (role != "ref" or self.record.ref is not None)
        }

    def __iter__(self) -> Iterator[Block]:
        record = self.record
        stamps = seconds_to_ns(record.time)
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
            yield Block(series, {}, min((start + CSV_BLOCK) / stamps.size, 1.0))

    @property
    def truncation(self) -> Truncation | None:
        """A CSV file is read whole or refused."""
        return None

    def qos_text(self, role: str) -> str | None:
        """A CSV file has no QoS: the default is offered."""
        return None

    def check_topics(self) -> None:
        """CSV columns were checked on reading."""


def open_stream(
    source: Path,
    *,
    topics: Sequence[str | None] = DEFAULT_TOPICS,
    columns: Sequence[str | None] = DEFAULT_COLUMNS,
) -> BagStream | CsvStream:
    """Open a bag or CSV input for chunk-by-chunk reading, chosen by the path.

    Parameters
    ----------
    source : Path
        Bag (directory or ``.mcap`` file) or ``*.csv`` file.
    topics : (tc1, tc2[, ref or None])
        Bag topics; the reference is read when given and present.
    columns : (tc1, tc2[, ref or None])
        CSV columns besides ``time``.

    Returns
    -------
    BagStream or CsvStream
    """
    if is_csv(source):
        return CsvStream(source, check_names(columns, DEFAULT_COLUMNS, "columns"))
    tc1, tc2, ref = check_names(topics, DEFAULT_TOPICS, "topics")
    return BagStream(source, {"tc1": tc1, "tc2": tc2, **({"ref": ref} if ref else {})})
