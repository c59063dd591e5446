"""The one CDR codec of ``sensor_msgs/msg/Temperature``: in bulk (numpy) and per message.

A serialized Temperature (XCDR1, little endian) is, in bytes from the start of the buffer::

    0   encapsulation header 00 01 00 00
    4   int32 header.stamp.sec
    8   uint32 header.stamp.nanosec
    12  uint32 length of header.frame_id, including its NUL
    16  frame_id bytes, NUL, zero padding to a multiple of 8 relative to byte 4
    V   float64 temperature        (V = 4 + 12 + length, rounded up to 8 past byte 4)
    V+8 float64 variance

All messages with one frame id length therefore share one layout, and a block of them held as
rows of a 2-D ``uint8`` array (one row per message, possibly a strided view into an MCAP chunk)
is decoded with a few column copies. Rows that do not fit the layout (another encapsulation,
big endian, a different frame id length, trailing bytes) go to the general deserializer of
``rosbags`` one by one. :func:`encode` builds the same rows for writing.

The node's 10 k messages/s data path uses the per-message pair :func:`decode_message` and
:class:`Encoder` (struct on the same offsets, no Python message object per sample), with the
same rosbags fallback. Every failure is a :class:`~tcomp_core.errors.DataError`.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError
from .record import NS_PER_S, TEMPERATURE_TYPE
from .rows import column

__all__ = [
    "CDR_LE_HEADER",
    "Encoder",
    "TemperatureBatch",
    "decode_message",
    "decode_payloads",
    "decode_rows",
    "encode",
    "encode_message",
    "payload_size",
    "values_offset",
]

#: Encapsulation header of little-endian plain CDR (XCDR1).
CDR_LE_HEADER = bytes((0, 1, 0, 0))
_NS_PER_S = NS_PER_S
_MAX_SEC = 2**31 - 1


def values_offset(frame_length: int) -> int:
    """Byte offset of ``temperature`` for a frame id of ``frame_length`` bytes (with NUL)."""
    end = 12 + frame_length  # relative to the payload start (after the encapsulation header)
    return 4 + end + (-end % 8)


def payload_size(frame_length: int) -> int:
    """Size in bytes of a serialized Temperature whose frame id takes ``frame_length`` bytes."""
    return values_offset(frame_length) + 16


@dataclass(frozen=True)
class TemperatureBatch:
    """Decoded Temperature messages, in the order given.

    Attributes
    ----------
    stamps_ns : ndarray of int64, shape (N,)
        ``header.stamp`` in nanoseconds.
    temperature : ndarray of float64, shape (N,)
        Degrees C.
    variance : ndarray of float64, shape (N,)
        Degrees C squared (0 = unknown).
    frame_id : str
        ``header.frame_id`` of the first message ('' when there is none).
    fallback : int
        How many messages the general deserializer decoded.
    """

    stamps_ns: NDArray[np.int64]
    temperature: NDArray[np.float64]
    variance: NDArray[np.float64]
    frame_id: str = ""
    fallback: int = 0

    def __len__(self) -> int:
        return int(self.stamps_ns.size)

    @staticmethod
    def concatenate(batches: Sequence[TemperatureBatch]) -> TemperatureBatch:
        """One batch holding ``batches`` in order (the first non-empty one's frame id)."""
        if not batches:
            return _EMPTY
        return TemperatureBatch(
            np.concatenate([b.stamps_ns for b in batches]),
            np.concatenate([b.temperature for b in batches]),
            np.concatenate([b.variance for b in batches]),
            next((b.frame_id for b in batches if len(b)), ""),
            sum(b.fallback for b in batches),
        )


_CDR_LE_HEADER_WORD = int.from_bytes(CDR_LE_HEADER, "little")
_EMPTY = TemperatureBatch(np.empty(0, np.int64), np.empty(0), np.empty(0))


@cache
def _typestore() -> Any:  # rosbags imported lazily
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _deserialize(data: bytes) -> tuple[int, float, float, str]:
    """One message through rosbags' general CDR deserializer: stamp, value, variance, frame."""
    try:
        message = _typestore().deserialize_cdr(bytes(data), TEMPERATURE_TYPE)
    except Exception as exc:  # rosbags raises several types for malformed bytes
        raise DataError(
            f"cannot deserialize a {len(data)}-byte {TEMPERATURE_TYPE} "
            f"({type(exc).__name__}: {exc})"
        ) from exc
    stamp = message.header.stamp
    return (
        int(stamp.sec) * _NS_PER_S + int(stamp.nanosec),
        float(message.temperature),
        float(message.variance),
        str(message.header.frame_id),
    )


def decode_rows(rows: NDArray[np.uint8]) -> TemperatureBatch:
    """Decode serialized Temperatures of one size, one per row.

    Parameters
    ----------
    rows : ndarray of uint8, shape (N, L)
        Row ``i`` holds the ``L`` bytes of message ``i``; any strides (a view into a larger
        buffer is fine).

    Returns
    -------
    TemperatureBatch
        In row order. Rows whose encapsulation or frame id length does not give exactly
        ``L`` bytes in the little-endian layout are decoded by rosbags (counted in
        ``fallback``).

    Raises
    ------
    DataError
        If a row that needs the general deserializer cannot be decoded by it either.
    """
    count, size = rows.shape
    if count == 0:
        return _EMPTY
    if size < 16:
        return _decode_slow([rows[i].tobytes() for i in range(count)])
    header_ok = column(rows, 0, "<u4") == _CDR_LE_HEADER_WORD
    lengths = column(rows, 12, "<u4")
    frame_length = int(lengths[0]) if header_ok[0] else int(np.median(lengths))
    good = header_ok & (lengths == frame_length)
    if frame_length == 0 or payload_size(frame_length) != size:
        good[:] = False
    if not good.any():
        return _decode_slow([rows[i].tobytes() for i in range(count)])
    offset = values_offset(frame_length)
    first = int(np.argmax(good))
    frame_id = rows[first, 16 : 16 + frame_length - 1].tobytes().decode(errors="replace")
    stamps = column(rows, 4, "<i4").astype(np.int64) * _NS_PER_S + column(rows, 8, "<u4")
    temperature = column(rows, offset, "<f8").astype(np.float64)
    variance = column(rows, offset + 8, "<f8").astype(np.float64)
    bad = np.flatnonzero(~good)
    for index in bad.tolist():
        stamps[index], temperature[index], variance[index], _ = _deserialize(rows[index].tobytes())
    if not good[0]:
        frame_id = _deserialize(rows[0].tobytes())[3]
    return TemperatureBatch(stamps, temperature, variance, frame_id, int(bad.size))


def _decode_slow(payloads: Sequence[bytes]) -> TemperatureBatch:
    decoded = [_deserialize(data) for data in payloads]
    stamps, values, variances, frames = zip(*decoded, strict=True)
    return TemperatureBatch(
        np.asarray(stamps, np.int64),
        np.asarray(values, np.float64),
        np.asarray(variances, np.float64),
        frames[0],
        len(decoded),
    )


def decode_payloads(payloads: Sequence[bytes]) -> TemperatureBatch:
    """Decode serialized Temperatures of any sizes (grouped by size, then :func:`decode_rows`).

    Parameters
    ----------
    payloads : sequence of bytes, length N
        One serialized message each.

    Returns
    -------
    TemperatureBatch
        In the order given.
    """
    if not payloads:
        return _EMPTY
    sizes = np.fromiter((len(p) for p in payloads), np.int64, len(payloads))
    stamps = np.empty(sizes.size, np.int64)
    values = np.empty(sizes.size)
    variances = np.empty(sizes.size)
    frame_id, fallback = "", 0
    for size in np.unique(sizes).tolist():
        where = np.flatnonzero(sizes == size)
        joined = b"".join(payloads[i] for i in where.tolist())
        batch = decode_rows(np.frombuffer(joined, np.uint8).reshape(where.size, size))
        stamps[where], values[where], variances[where] = (
            batch.stamps_ns,
            batch.temperature,
            batch.variance,
        )
        fallback += batch.fallback
        if where[0] == 0:
            frame_id = batch.frame_id
    return TemperatureBatch(stamps, values, variances, frame_id, fallback)


_ENCAPSULATION = int.from_bytes(CDR_LE_HEADER, "little")


@cache  # one per frame id length: building a structured dtype costs more than encoding 200 rows
def _message_dtype(frame_length: int) -> np.dtype:
    """One serialized Temperature whose frame id (with its NUL) has ``frame_length`` bytes."""
    offset = values_offset(frame_length)
    return np.dtype(
        {
            "names": [
                "encapsulation",
                "sec",
                "nanosec",
                "frame_length",
                "frame_id",
                "temperature",
                "variance",
            ],
            "formats": ["<u4", "<i4", "<u4", "<u4", f"S{frame_length}", "<f8", "<f8"],
            "offsets": [0, 4, 8, 12, 16, offset, offset + 8],
            "itemsize": offset + 16,
        }
    )


def encode(
    stamps_ns: ArrayLike,
    temperature: ArrayLike,
    variance: ArrayLike | float = 0.0,
    frame_id: str = "",
) -> NDArray[np.uint8]:
    """Serialize Temperatures with one frame id, one message per row.

    Parameters
    ----------
    stamps_ns : array_like of int, shape (N,)
        ``header.stamp``, nanoseconds, in [0, 2**31) s.
    temperature : array_like, shape (N,)
        Degrees C.
    variance : array_like, shape (N,), or float
        Degrees C squared.
    frame_id : str
        ``header.frame_id`` of every message.

    Returns
    -------
    ndarray of uint8, shape (N, L)
        Little-endian CDR, byte-identical to rosbags' ``serialize_cdr``.

    Raises
    ------
    DataError
        If a stamp lies outside the ``builtin_interfaces/msg/Time`` range.
    """
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    count = stamps.size
    sec, nanosec = np.divmod(stamps, _NS_PER_S)
    if count and (sec.min() < 0 or sec.max() > _MAX_SEC):
        index = int(np.argmin(sec) if sec.min() < 0 else np.argmax(sec))
        raise DataError(
            f"message {index} is stamped {int(stamps[index])} ns, outside the "
            "builtin_interfaces/msg/Time range [0, 2**31) s"
        )
    frame = frame_id.encode() + b"\x00"
    rows = np.zeros(count, _message_dtype(len(frame)))
    rows["encapsulation"] = _ENCAPSULATION
    rows["sec"] = sec
    rows["nanosec"] = nanosec
    rows["frame_length"] = len(frame)
    rows["frame_id"] = frame
    rows["temperature"] = temperature
    rows["variance"] = variance
    rows = rows.view(np.uint8).reshape(count, rows.dtype.itemsize)
    return rows


# --------------------------------------------------------------------------------------------
# One message at a time (the node)

_HEAD = struct.Struct("<iII")
_VALUES = struct.Struct("<dd")


def decode_message(data: bytes | memoryview) -> tuple[int, str, float, float]:
    """Decode one serialized Temperature.

    Parameters
    ----------
    data : bytes
        The serialized message (encapsulation header first).

    Returns
    -------
    stamp_ns : int
        ``header.stamp``, nanoseconds.
    frame_id : str
    temperature : float
        Degrees C.
    variance : float
        Degrees C squared.

    Raises
    ------
    DataError
        If neither the little-endian layout nor rosbags' general deserializer can decode it.
    """
    size = len(data)
    if size >= 16 and data[:4] == CDR_LE_HEADER:
        sec, nanosec, length = _HEAD.unpack_from(data, 4)
        offset = values_offset(length)
        if length and offset + 16 == size and data[15 + length] == 0:
            temperature, variance = _VALUES.unpack_from(data, offset)
            frame_id = bytes(data[16 : 15 + length]).decode(errors="replace")
            return sec * _NS_PER_S + nanosec, frame_id, temperature, variance
    stamp, temperature, variance, frame_id = _deserialize(bytes(data))
    return stamp, frame_id, temperature, variance


class Encoder:
    """Serializes Temperature messages with one frame id (the prefix is built once).

    Parameters
    ----------
    frame_id : str
        ``header.frame_id`` of every message.
    """

    def __init__(self, frame_id: str) -> None:
        encoded = frame_id.encode() + b"\x00"
        padding = values_offset(len(encoded)) - 4 - 12 - len(encoded)
        self.frame_id = frame_id
        self._frame = struct.pack("<I", len(encoded)) + encoded + b"\x00" * padding

    def encode(self, stamp_ns: int, temperature: float, variance: float = 0.0) -> bytes:
        """Serialized Temperature stamped ``stamp_ns`` (nanoseconds, in [0, 2**31) s).

        Raises
        ------
        DataError
            If the stamp lies outside the ``builtin_interfaces/msg/Time`` range.
        """
        sec, nanosec = divmod(stamp_ns, _NS_PER_S)
        if not 0 <= sec <= _MAX_SEC:
            raise DataError(
                f"stamp {stamp_ns} ns is outside the builtin_interfaces/msg/Time range "
                "[0, 2**31) s"
            )
        return (
            CDR_LE_HEADER
            + struct.pack("<iI", sec, nanosec)
            + self._frame
            + _VALUES.pack(temperature, variance)
        )


def encode_message(
    stamp_ns: int, frame_id: str, temperature: float, variance: float = 0.0
) -> bytes:
    """One serialized Temperature (:class:`Encoder` encodes many with one frame id faster)."""
    return Encoder(frame_id).encode(stamp_ns, temperature, variance)
