"""The one boundary every record passes: invalid readings and repeated samples, left out.

A reading is valid when it is finite and inside the physical range of a thermocouple,
:data:`VALID_RANGE_C` (below absolute zero nothing is a temperature; above 2 000 °C no base-metal
or noble thermocouple of a test cell survives). The node and ``tcomp process`` drop an invalid
sample in the pair matcher (:mod:`tcomp_core.online.pairing`, which takes the same range from
here and restarts after a gap; ``process`` reads CSV files unscreened for it). The verbs that
read a whole record (``estimate``, ``reconstruct``, ``diagnose``, ``fit``, ``track``) get it
from :func:`screen_samples`, called by both readers, so one file gets one verdict:

* a sample whose time repeats the previous one is left out (the later of the two);
* invalid readings at either end of the record are left out (the record starts and ends at the
  first and last sample where both sensors read a valid value);
* a run of at most :data:`MAX_BRIDGE_SAMPLES` samples inside the record, where either sensor reads
  an invalid value, is bridged (each invalid reading by a straight line between its sensor's
  valid neighbours) so the record stays uniform; the samples are marked
  (:attr:`Screened.left_out`) and no gas is written there;
* a longer run, or more than :data:`MAX_BRIDGED_FRACTION` of the record bridged (and more than
  one run's worth), is refused with
  its place: the record is broken there, and estimating across it would invent data
  (``tcomp process`` restarts at such a gap).

Every leaving-out is counted and named in one :class:`~tcomp_core.errors.InvalidReadingsWarning`
per kind: the file, the column or topic, the row or stamp and the value of the first.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, InvalidReadingsWarning

__all__ = [
    "MAX_BRIDGED_FRACTION",
    "MAX_BRIDGE_SAMPLES",
    "VALID_RANGE_C",
    "Screened",
    "invalid_readings",
    "screen_gas",
    "screen_samples",
]

#: The physical range of a reading, degrees C (both ends allowed): absolute zero to 2 000 °C,
#: above type K's and type N's range (types B, R and S reach 1 700-1 800 °C).
VALID_RANGE_C = (-273.15, 2000.0)
#: Longest run of invalid samples bridged inside a record: a few glitches of an acquisition
#: (a spike, a dropped conversion), short beside any τ a test cell measures at its rate.
MAX_BRIDGE_SAMPLES = 8
#: Largest fraction of a record that may be bridged.
MAX_BRIDGED_FRACTION = 0.01


@dataclass(frozen=True)
class Screened:
    """A record's samples after screening.

    Attributes
    ----------
    keep : ndarray of int, shape (M,)
        Indices of the samples read that the record keeps.
    tc1, tc2 : ndarray, shape (M,)
        The readings kept, bridged runs filled by straight lines, degrees C.
    left_out : ndarray of bool, shape (M,), or None
        Samples whose readings were bridged (None when none was).
    """

    keep: NDArray[np.intp]
    tc1: NDArray[np.float64]
    tc2: NDArray[np.float64]
    left_out: NDArray[np.bool_] | None


def invalid_readings(
    values: NDArray[np.float64], valid_range: tuple[float, float] = VALID_RANGE_C
) -> NDArray[np.bool_]:
    """Whether each reading is not finite or outside ``valid_range``, shape as ``values``."""
    low, high = valid_range
    with np.errstate(invalid="ignore"):
        return ~((values >= low) & (values <= high))


def screen_samples(
    source: str,
    time: NDArray[np.float64] | NDArray[np.int64],
    readings: Sequence[tuple[str, NDArray[np.float64]]],
    where: Callable[[int], str],
) -> Screened:
    """Leave out repeated samples and invalid readings of a record as the module says.

    Parameters
    ----------
    source : str
        The file and the columns or topics, for messages.
    time : ndarray, shape (N,)
        Sample times (seconds, or stamps), checked for repeats only.
    readings : sequence of (str, ndarray of shape (N,))
        The two thermocouples' names (column or topic) and readings, tc1 first, degrees C.
    where : callable
        Names sample k of the file for messages (``"row 7"``, ``"stamp 12.000000500"``).

    Returns
    -------
    Screened

    Warns
    -----
    InvalidReadingsWarning
        Once per kind of sample left out, with the count and the first.

    Raises
    ------
    DataError
        When no sample has two valid readings, or a run inside the record is too long (or too
        much of it is invalid) to bridge.
    """
    (name1, tc1), (name2, tc2) = readings
    count = time.size
    keep = np.ones(count, dtype=bool)
    repeated = np.flatnonzero(time[1:] == time[:-1]) + 1
    if repeated.size:
        keep[repeated] = False
        warnings.warn(
            f"{source}: left out {repeated.size} sample(s) whose time repeats the one before "
            f"(the first at {where(int(repeated[0]))})",
            InvalidReadingsWarning,
            stacklevel=3,
        )
    invalid = []
    for name, values in readings:
        bad = invalid_readings(values) & keep
        invalid.append(bad)
        if bad.any():
            index = int(np.flatnonzero(bad)[0])
            warnings.warn(
                f"{source}: left out {int(bad.sum())} {name} reading(s) not finite or outside "
                f"{VALID_RANGE_C[0]:g}..{VALID_RANGE_C[1]:g} °C (the first at {where(index)}: "
                f"{float(values[index])!r})",
                InvalidReadingsWarning,
                stacklevel=3,
            )
    indices = np.flatnonzero(keep)
    bad = (invalid[0] | invalid[1])[indices]
    good = np.flatnonzero(~bad)
    if not good.size:
        raise DataError(
            f"{source}: no sample has valid readings of both {name1} and {name2} (finite, "
            f"{VALID_RANGE_C[0]:g}..{VALID_RANGE_C[1]:g} °C)"
        )
    indices, bad = indices[good[0] : good[-1] + 1], bad[good[0] : good[-1] + 1]
    kept = [tc1[indices], tc2[indices]]
    if not bad.any():
        return Screened(indices, kept[0], kept[1], None)
    _check_bridgeable(source, bad, indices, where)
    positions = np.arange(indices.size)
    for values, invalid_here in zip(kept, invalid, strict=True):
        own = invalid_here[indices]  # a valid reading beside the other's glitch stays
        values[own] = np.interp(positions[own], positions[~own], values[~own])
    return Screened(indices, kept[0], kept[1], bad)


def _check_bridgeable(
    source: str, bad: NDArray[np.bool_], indices: NDArray[np.intp], where: Callable[[int], str]
) -> None:
    """Refuse a run longer than :data:`MAX_BRIDGE_SAMPLES` or too many bridged samples."""
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(ends - starts))
    length = int(ends[longest] - starts[longest])
    if length > MAX_BRIDGE_SAMPLES:
        raise DataError(
            f"{source}: {length} samples in a row without valid readings of both sensors, from "
            f"{where(int(indices[starts[longest]]))} to {where(int(indices[ends[longest] - 1]))}: "
            f"the record is broken there (at most {MAX_BRIDGE_SAMPLES} are bridged); split it "
            "at the gap, or run tcomp process, which restarts after a gap"
        )
    if bad.sum() > max(MAX_BRIDGED_FRACTION * bad.size, MAX_BRIDGE_SAMPLES):
        raise DataError(
            f"{source}: {int(bad.sum())} of {bad.size} samples lack a valid reading of one "
            f"sensor, more than {100 * MAX_BRIDGED_FRACTION:g} % that are bridged; the sensor "
            "or its acquisition is failing"
        )


def screen_gas(
    source: str,
    gas: NDArray[np.float64],
    left_out: NDArray[np.bool_] | None,
) -> NDArray[np.float64]:
    """The gas to write: NaN (no value) where it cannot be a gas temperature.

    Element k of a reconstruction rests on the readings k and k + 1, so it is left out where
    either was bridged (``left_out``, shape (N,) for N >= ``gas.size``); a value outside
    :data:`VALID_RANGE_C` or not finite is left out as well. Each kind is counted in an
    :class:`~tcomp_core.errors.InvalidReadingsWarning` naming the first sample.

    Parameters
    ----------
    source : str
        The record, for messages.
    gas : ndarray, shape (M,)
        Reconstructed gas temperature, degrees C.
    left_out : ndarray of bool, shape (N,), or None
        The record's bridged samples.

    Returns
    -------
    ndarray, shape (M,)
        A copy of ``gas`` with NaN where it is left out.
    """
    screened = np.array(gas, dtype=np.float64)
    count = screened.size
    if left_out is not None:
        bridged = left_out[:count].copy()
        bridged[: min(count, left_out.size - 1)] |= left_out[1 : count + 1]
        if bridged.any():
            screened[bridged] = np.nan
            warnings.warn(
                f"{source}: no gas written at {int(bridged.sum())} sample(s) that rest on "
                f"bridged readings (the first is sample {int(np.flatnonzero(bridged)[0])})",
                InvalidReadingsWarning,
                stacklevel=2,
            )
    absurd = invalid_readings(screened) & ~np.isnan(screened)
    if absurd.any():
        first = int(np.flatnonzero(absurd)[0])
        warnings.warn(
            f"{source}: no gas written at {int(absurd.sum())} sample(s) where the "
            f"reconstruction lies outside {VALID_RANGE_C[0]:g}..{VALID_RANGE_C[1]:g} °C (the "
            f"first is sample {first}: {float(screened[first]):.6g} °C); a reconstruction that "
            "far off amplifies noise or rests on a wrong model",
            InvalidReadingsWarning,
            stacklevel=2,
        )
        screened[absurd] = np.nan
    return screened
