"""CSV records: a header ``time,tc1,tc2[,ref]`` (seconds, degrees C), one sample per row.

Further columns are allowed and ignored on reading. Values are written as their shortest
round-tripping ``repr``, so a write and a read give back the same float64 bits. Every error is a
:class:`~tcomp_core.errors.DataError` naming the file, the row as numbered in the file, the
column and the text.
"""

from __future__ import annotations

import contextlib
import csv
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError
from ..validation import check_finite
from .outputs import atomic_output
from .paths import check_regular_file
from .record import DEFAULT_COLUMNS, Record, check_names, validated_record

__all__ = ["CSV_CHUNK_ROWS", "CsvChunks", "read_csv", "write_csv"]


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Rows of a CSV file parsed at a time by :class:`CsvChunks`.
CSV_CHUNK_ROWS = 100_000


def read_csv(
    path: str | Path,
    *,
    columns: Sequence[str | None] = DEFAULT_COLUMNS,
    screen: bool = True,
    uniform: bool = True,
) -> Record:
    """Read a CSV record with a header ``time,tc1,tc2[,ref]``.

    Parameters
    ----------
    path : str or Path
        The CSV file (UTF-8, an optional byte-order mark is accepted).
    columns : (tc1, tc2[, ref or None])
        Column names of the two thermocouples and the optional reference; the time column is
        always ``time`` (seconds). The default reference column ``ref`` is read when present
        and ignored when absent; any other reference column named must exist.
    screen : bool
        Leave out invalid readings and repeated rows (:mod:`tcomp_core.io.screening`); False
        keeps them for the pair matcher of ``tcomp process``, which drops them itself.
    uniform : bool
        Require a uniform time step; False only asks for increasing times (``tcomp process``
        follows a change of rate as it does in a bag).

    Returns
    -------
    Record
        ``time`` (N,) seconds as written, ``tc1``/``tc2``/``ref`` (N,) degrees C.

    Raises
    ------
    DataError
        Missing or unreadable file, no header, missing or duplicated column, empty file or
        header only, ragged row, blank line inside the data, non-numeric cell, non-finite
        time, time not strictly increasing or not uniform, or readings that
        :func:`~tcomp_core.io.screening.screen_samples` cannot
        leave out. The message names the file, the row as
        numbered in the file (header = row 1), the column and the text.

    Warns
    -----
    InvalidReadingsWarning
        Readings not finite or outside the physical range, or repeated times, left out
        (:mod:`tcomp_core.io.screening`).
    """
    chunks = CsvChunks(path, columns=columns)
    parts = [arrays for _, arrays in chunks]
    whole = [np.concatenate([part[k] for part in parts]) for k in range(len(chunks.wanted))]
    return chunks.record(0, whole, screen=screen, uniform=uniform)


class CsvChunks:
    """A CSV record's columns parsed :data:`CSV_CHUNK_ROWS` rows at a time, in bounded memory.

    Creating it opens the file and checks the header; iterating parses the rows (each
    checked as :func:`read_csv` says) and yields ``(first, arrays)``: the index of the chunk's
    first sample (sample k is on row k + 2 of the file) and ``time``, tc1, tc2 (and the
    reference when read) as float64 arrays of shape (n,). :meth:`record` builds the
    :class:`Record` of consecutive rows as :func:`read_csv` builds the whole file's.

    Parameters
    ----------
    path : str or Path
    columns : (tc1, tc2[, ref or None])
        As :func:`read_csv`.
    rows : int
        Rows per chunk.

    Attributes
    ----------
    wanted : list of str
        The columns read: ``time``, tc1, tc2 and the reference when read.
    source : str
        The file and the columns, for messages.
    bytes_total, bytes_read : int
        The file's size and how far the parsing has read it.

    Raises
    ------
    DataError
        As :func:`read_csv` (the header's errors on creation, the rows' while iterating).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        columns: Sequence[str | None] = DEFAULT_COLUMNS,
        rows: int = CSV_CHUNK_ROWS,
    ) -> None:
        self.path = Path(path)
        self.rows = rows
        self.names = check_names(columns, DEFAULT_COLUMNS, "columns")
        with self._reading() as (_, reader):
            self.header, self.wanted = self._header(reader)
        self.indices = [self.header.index(name) for name in self.wanted]
        self.source = f"{self.path} (columns {', '.join(self.wanted)})"
        self.bytes_total = self.path.stat().st_size
        self.bytes_read = 0

    @contextlib.contextmanager
    def _reading(self) -> Iterator[tuple[Any, Any]]:
        """The open file and its ``csv.reader``; decoding and CSV errors as DataError."""
        try:
            if self.path.exists():  # a FIFO or device would block or never end
                check_regular_file(self.path)
            handle = self.path.open(newline="", encoding="utf-8-sig")
        except OSError as exc:
            raise DataError(f"{self.path}: cannot open CSV file: {exc.strerror}") from exc
        try:
            with handle:
                yield handle, csv.reader(handle)
        except UnicodeDecodeError as exc:
            raise DataError(
                f"{self.path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})"
            ) from exc
        except csv.Error as exc:
            raise DataError(f"{self.path}: malformed CSV: {exc}") from exc

    def _header(self, reader: Any) -> tuple[list[str], list[str]]:
        """The header's names and the columns to read, checked."""
        path = self.path
        tc1_name, tc2_name, ref_name = self.names
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
        # The default reference column is optional; any other one named must exist.
        if ref_name is not None and (ref_name in names or ref_name != DEFAULT_COLUMNS[2]):
            wanted.append(ref_name)
        for name in dict.fromkeys(wanted):
            count = names.count(name)
            if count == 0:
                raise DataError(
                    f"{path}: no column {name!r}; the header has columns "
                    f"{', '.join(map(repr, names))}"
                )
            if count > 1:
                raise DataError(f"{path}: column {name!r} appears {count} times in the header")
        return names, wanted

    def __iter__(self) -> Iterator[tuple[int, list[NDArray[np.float64]]]]:
        with self._reading() as (handle, reader):
            next(reader, None)  # the header, checked on creation
            yield from self._chunks(handle, reader)

    def _chunks(self, handle: Any, reader: Any) -> Iterator[tuple[int, list[NDArray[np.float64]]]]:
        path, wanted, indices = self.path, self.wanted, self.indices
        values: list[list[float]] = [[] for _ in wanted]
        first = 0
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
            if len(row) != len(self.header):
                raise DataError(
                    f"{path}: row {row_number} has {len(row)} fields, the header "
                    f"{len(self.header)}"
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
                if column == 0 and not math.isfinite(number):
                    raise DataError(
                        f"{path}: row {row_number}, column 'time': {text!r} is not finite"
                    )
                values[column].append(number)
            if len(values[0]) == self.rows:
                self.bytes_read = handle.buffer.tell()
                yield first, [np.asarray(column, dtype=np.float64) for column in values]
                first += len(values[0])
                values = [[] for _ in wanted]
        if not first and not values[0]:
            raise DataError(f"{path}: header only, no samples")
        self.bytes_read = self.bytes_total
        if values[0]:
            yield first, [np.asarray(column, dtype=np.float64) for column in values]

    def record(
        self,
        first: int,
        arrays: Sequence[NDArray[np.float64]],
        *,
        screen: bool = True,
        uniform: bool = True,
    ) -> Record:
        """The record of consecutive rows from sample ``first`` on, as :func:`read_csv` reads.

        ``arrays`` are ``time``, tc1, tc2 (and the reference) of those rows; the messages
        number the rows as in the file.
        """
        tc1_name, tc2_name = self.wanted[1], self.wanted[2]
        return validated_record(
            self.source,
            arrays[0],
            arrays[1],
            arrays[2],
            arrays[3] if len(self.wanted) == 4 else None,
            time_name="column 'time'",
            names=(f"column {tc1_name!r}", f"column {tc2_name!r}"),
            where=lambda index: f"row {first + index + 2}",
            index_hint=(
                " (sample k is on row k + 2 of the file)"
                if first == 0
                else f" (sample k is on row k + {first + 2} of the file)"
            ),
            screen=screen,
            uniform=uniform,
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
    inputs: Iterable[Path] = (),
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
    inputs : iterable of Path
        Files the data were read from: the output may not overlap them
        (:func:`~tcomp_core.io.outputs.atomic_output`, which writes the file).

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
    with (
        atomic_output(path, overwrite, inputs) as temporary,
        temporary.open("w", newline="", encoding="utf-8") as handle,
    ):
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        # tolist() gives Python floats, which csv writes as repr(): shortest exact round trip.
        writer.writerows(zip(*(values.tolist() for values in columns.values()), strict=True))
    return path
