"""The one record type, the default names, and exact stamp arithmetic.

A :class:`Record` is a uniformly sampled two-thermocouple record as every verb sees it, read
from CSV or a bag. Stamps are integer nanoseconds (``builtin_interfaces/msg/Time`` as
``sec * 1e9 + nanosec``); the helpers here convert them to seconds and back exactly and format
them for messages.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..choices import DEFAULT_COLUMNS, DEFAULT_TOPICS
from ..errors import DataError
from ..validation import UNIFORM_TOLERANCE, sample_interval_from_time

__all__ = [
    "DEFAULT_COLUMNS",
    "DEFAULT_TOPICS",
    "GAS_TOPIC",
    "MAX_STAMP_NS",
    "NS_PER_S",
    "TEMPERATURE_TYPE",
    "BagOrigin",
    "Record",
    "check_names",
    "format_stamp",
    "seconds_to_ns",
    "stamps_to_seconds",
    "validated_record",
]

#: Topic of a reconstructed gas temperature.
GAS_TOPIC = "/gas_temperature"
#: The only message type read and written.
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
#: Nanoseconds per second.
NS_PER_S = 1_000_000_000
#: Largest stamp ``builtin_interfaces/msg/Time`` holds (``sec`` is an int32), nanoseconds.
MAX_STAMP_NS = (2**31 - 1) * NS_PER_S + NS_PER_S - 1


@dataclass(frozen=True)
class BagOrigin:
    """Where a record read from a bag came from, so that its messages can be copied.

    Attributes
    ----------
    files : tuple of Path
        The MCAP files of the bag, in order.
    topics : tuple of str
        The topics read (tc1, tc2 and the reference when one was read).
    """

    files: tuple[Path, ...]
    topics: tuple[str, ...]


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
    origin : BagOrigin or None
        The bag read (bags only): writers copy its messages unchanged from there.
    left_out : ndarray of bool, shape (N,), or None
        Samples whose readings were invalid and are bridged by straight lines
        (:mod:`tcomp_core.io.screening`): no gas is written there. None when there are none.

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
    origin: BagOrigin | None = None
    left_out: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        arrays: dict[str, NDArray[np.generic]] = {
            "time": self.time,
            "tc1": self.tc1,
            "tc2": self.tc2,
        }
        if self.left_out is not None:
            arrays["left_out"] = self.left_out
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


def check_names(
    given: Sequence[str | None] | None,
    default: tuple[str, str, str | None],
    what: str,
) -> tuple[str, str, str | None]:
    """Normalise ``(tc1, tc2[, ref])`` topic or column names.

    Parameters
    ----------
    given : sequence of 2 or 3 str (the third may be None), or None
        The names; None means ``default``; a missing third entry means no reference.
    default : (str, str, str or None)
    what : str
        'topics' or 'columns', for messages.

    Returns
    -------
    (str, str, str or None)

    Raises
    ------
    DataError
        Wrong count, or a name that is empty or not a string.
    """
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


def format_stamp(stamp_ns: int) -> str:
    """A stamp in seconds with all nine decimals, exact for any int64 nanoseconds."""
    sign = "-" if stamp_ns < 0 else ""
    seconds, nanoseconds = divmod(abs(int(stamp_ns)), NS_PER_S)
    return f"{sign}{seconds}.{nanoseconds:09d} s"


def stamps_to_seconds(stamps_ns: NDArray[np.int64]) -> NDArray[np.float64]:
    """Stamps (ns), shape (N,), as seconds ``sec + nanosec / 1e9``, shape (N,)."""
    seconds, nanoseconds = np.divmod(stamps_ns, NS_PER_S)
    return seconds.astype(np.float64) + nanoseconds / NS_PER_S


def seconds_to_ns(seconds: NDArray[np.float64]) -> NDArray[np.int64]:
    """Round times (s), shape (N,), to integer nanoseconds exactly (ties to even).

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
        nanoseconds[index] = round(Fraction(float(fraction[index])) * NS_PER_S)
    return whole.astype(np.int64) * NS_PER_S + nanoseconds


def validated_record(
    source: str,
    time: NDArray[np.float64],
    tc1: NDArray[np.float64],
    tc2: NDArray[np.float64],
    ref: NDArray[np.float64] | None,
    *,
    time_name: str,
    names: tuple[str, str] = ("tc1", "tc2"),
    where: Callable[[int], str] = lambda index: f"sample {index}",
    index_hint: str = "",
    frame_id: str = "",
    stamps_ns: NDArray[np.int64] | None = None,
    origin: BagOrigin | None = None,
    screen: bool = True,
    uniform: bool = True,
) -> Record:
    """Screen the samples, check the time vector (strictly increasing, uniform), build the record.

    ``uniform=False`` only asks for increasing times (a stream whose rate may change, read
    by ``tcomp process``): ``dt`` is then the mean step.

    Repeated samples and invalid readings are left out, counted and named by
    :func:`~tcomp_core.io.screening.screen_samples` (``names`` are the readings' columns or
    topics, ``where`` names sample k of the file), the one boundary of every reader.

    Raises
    ------
    DataError
        Naming ``source``, ``time_name`` and the sample (``index_hint`` says how samples
        map to the file); or as :func:`~tcomp_core.io.screening.screen_samples`.
    """
    from .screening import screen_samples

    left_out = None
    if screen:
        readings = list(zip(names, (tc1, tc2), strict=True))
        screened = screen_samples(
            source, time if stamps_ns is None else stamps_ns, readings, where
        )
        keep, tc1, tc2, left_out = screened.keep, screened.tc1, screened.tc2, screened.left_out
        time = time[keep]
        ref = None if ref is None else ref[keep]
        stamps_ns = None if stamps_ns is None else stamps_ns[keep]
    # Integer stamps are checked as exact offsets from the first: absolute epoch seconds in
    # float64 resolve only ~0.2 µs, too coarse for the spacing check at kHz rates.
    relative = time if stamps_ns is None else (stamps_ns - stamps_ns[0]) / NS_PER_S
    try:
        dt = sample_interval_from_time(
            relative, name=time_name, tolerance=UNIFORM_TOLERANCE if uniform else math.inf
        )
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
        origin=origin,
        left_out=left_out,
    )
