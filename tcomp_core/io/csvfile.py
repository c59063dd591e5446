"""CSV records: a header ``time,tc1,tc2[,ref]`` (seconds, degrees C), one sample per row.

Further columns are allowed and ignored on reading. Values are written as their shortest
round-tripping ``repr``, so a write and a read give back the same float64 bits. Every error is a
:class:`~tcomp_core.errors.DataError` naming the file, the row as numbered in the file, the
column and the text.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError
from ..validation import check_finite
from .outputs import atomic_output
from .paths import check_regular_file
from .record import DEFAULT_COLUMNS, Record, check_names, validated_record

__all__ = ["read_csv", "write_csv"]


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


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
    path = Path(path)
    tc1_name, tc2_name, ref_name = check_names(columns, DEFAULT_COLUMNS, "columns")
    try:
        if path.exists():  # a FIFO or device would block or never end
            check_regular_file(path)
        handle = path.open(newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise DataError(f"{path}: cannot open CSV file: {exc.strerror}") from exc
    try:
        with handle:
            return _parse_csv(
                path, csv.reader(handle), tc1_name, tc2_name, ref_name, screen, uniform
            )
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
    screen: bool,
    uniform: bool,
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
            if column == 0 and not math.isfinite(number):
                raise DataError(f"{path}: row {row_number}, column 'time': {text!r} is not finite")
            values[column].append(number)
    if not values[0]:
        raise DataError(f"{path}: header only, no samples")
    arrays = [np.asarray(column, dtype=np.float64) for column in values]
    source = f"{path} (columns {', '.join(wanted)})"
    return validated_record(
        source,
        arrays[0],
        arrays[1],
        arrays[2],
        arrays[3] if use_ref else None,
        time_name="column 'time'",
        names=(f"column {tc1_name!r}", f"column {tc2_name!r}"),
        where=lambda index: f"row {index + 2}",
        index_hint=" (sample k is on row k + 2 of the file)",
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
