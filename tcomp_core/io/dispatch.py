"""Read or write a record as CSV or as a bag, chosen by the path (:mod:`.paths` decides)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError
from .bag import read_bag, write_bag, write_bag_copy
from .csvfile import read_csv, write_csv
from .paths import check_readable_format, is_csv
from .record import DEFAULT_COLUMNS, DEFAULT_TOPICS, GAS_TOPIC, Record, check_names

__all__ = ["read_record", "write_series"]


def read_record(
    path: str | Path,
    *,
    topics: Sequence[str | None] | None = None,
    columns: Sequence[str | None] | None = None,
) -> Record:
    """Read a CSV file or a rosbag2 MCAP bag, chosen by the path.

    A ``*.csv`` path is read by :func:`~tcomp_core.io.read_csv`; a directory, a ``*.mcap``
    file, a file that starts with the MCAP magic bytes or a path that does not exist by
    :func:`~tcomp_core.io.read_bag`.

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
    if is_csv(path):
        return read_csv(path, columns=check_names(columns, DEFAULT_COLUMNS, "columns"))
    check_readable_format(path)
    return read_bag(path, topics=check_names(topics, DEFAULT_TOPICS, "topics"))


def write_series(
    path: str | Path,
    time: ArrayLike,
    tc1: ArrayLike,
    tc2: ArrayLike,
    ref: ArrayLike | None = None,
    *,
    gas: ArrayLike | None = None,
    gas_variance: ArrayLike | None = None,
    overwrite: bool = False,
    inputs: Record | None = None,
) -> Path:
    """Write a record as CSV (``*.csv``) or as an MCAP bag with zstd chunks (any other path).

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
    gas_variance : array_like, shape (N,), optional
        Its variance, (degrees C)**2: CSV column ``gas_variance``, the gas messages'
        ``variance`` field in a bag (0, "unknown", without it).
    overwrite : bool
        Replace an existing output.
    inputs : Record, optional
        The record ``time`` and the series come from. When it was read from a bag and a bag
        is written, the bag's messages are copied unchanged (every message, its frame id,
        QoS and log time) instead of encoding ``tc1``/``tc2``/``ref``, and ``gas`` is
        stamped with the input stamps of ``time`` and the input's frame id.

    Returns
    -------
    Path
        ``path``. CSV columns: ``time,tc1,tc2[,ref][,gas[,gas_variance]]``. Bag topics:
        :data:`DEFAULT_TOPICS` (ref only if given) and :data:`GAS_TOPIC` for ``gas``.

    Raises
    ------
    DataError
        As :func:`write_csv`, :func:`write_bag` and :func:`write_bag_copy`; a time of
        ``time`` that is not a sample time of ``inputs``.
    """
    path = Path(path)
    if gas is None and gas_variance is not None:
        raise DataError(f"{path}: a gas variance without a gas")
    if is_csv(path):
        extra = {} if gas is None else {"gas": gas}
        if gas_variance is not None:
            extra["gas_variance"] = gas_variance
        return write_csv(path, time, tc1, tc2, ref, extra=extra, overwrite=overwrite)
    if inputs is not None and inputs.origin is not None and inputs.stamps_ns is not None:
        gas_stamps, values = np.empty(0, np.int64), np.empty(0)
        if gas is not None:
            gas_stamps = _input_stamps(path, np.asarray(time, dtype=np.float64), inputs)
            values = np.asarray(gas, dtype=np.float64)
        return write_bag_copy(
            path,
            inputs.origin,
            gas_stamps,
            values,
            frame_id=inputs.frame_id,
            overwrite=overwrite,
            gas_variance=gas_variance,
        )
    series: dict[str, ArrayLike] = {DEFAULT_TOPICS[0]: tc1, DEFAULT_TOPICS[1]: tc2}
    if ref is not None and DEFAULT_TOPICS[2] is not None:
        series[DEFAULT_TOPICS[2]] = ref
    variance: dict[str, ArrayLike] = {}
    if gas is not None:
        series[GAS_TOPIC] = gas
        if gas_variance is not None:
            variance[GAS_TOPIC] = gas_variance
    return write_bag(path, time, series, variance=variance, overwrite=overwrite, compress=True)


def _input_stamps(path: Path, times: NDArray[np.float64], inputs: Record) -> NDArray[np.int64]:
    """The exact input stamps (ns) of sample times (s) taken from ``inputs``.

    Raises
    ------
    DataError
        If a time is not one of the record's sample times.
    """
    stamps = inputs.stamps_ns
    if stamps is None or inputs.time.size == 0:
        raise DataError(f"{path}: {inputs.source} has no stamps to copy")
    where = np.clip(np.searchsorted(inputs.time, times), 0, inputs.time.size - 1)
    off = np.flatnonzero(inputs.time[where] != times)
    if off.size:
        index = int(off[0])
        raise DataError(
            f"{path}: time[{index}] = {float(times[index])!r} s is not a sample time of "
            f"{inputs.source}"
        )
    return stamps[where]
