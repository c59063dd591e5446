"""CDR encoding of ``diagnostic_msgs/msg/DiagnosticArray`` for the bags ``tcomp process`` writes.

The τ history holds one status per second of stamp time with some fifty key-values; building
rosbags message objects and serializing them cost more than the rest of a status's work. This
encoder writes the same bytes (little-endian XCDR1, as rosbags and rmw write them: a 4-byte
encapsulation header, then each primitive aligned to its size counted from the end of that
header) straight from the strings.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from .temperature import CDR_LE_HEADER

__all__ = ["DiagnosticStatusFields", "encode_diagnostic_array"]

_UINT32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")
_NS_PER_S = 1_000_000_000
#: Zero bytes that align the next primitive, by their count.
_PADDING = tuple(bytes(n) for n in range(4))


@dataclass(frozen=True)
class DiagnosticStatusFields:
    """The fields of one ``diagnostic_msgs/msg/DiagnosticStatus``.

    Attributes
    ----------
    level : int
        0 OK, 1 WARN, 2 ERROR, 3 STALE (a byte).
    name, message, hardware_id : str
    values : mapping of str to str
        The key-values, in order.
    """

    level: int
    name: str
    message: str
    hardware_id: str
    values: Mapping[str, str]


def _strings(texts: Sequence[str], offset: int, parts: list[bytes]) -> int:
    """Append CDR strings (uint32 length with the NUL, UTF-8, NUL) from ``offset``; new offset."""
    for text in texts:
        data = text.encode("utf-8")
        pad = -offset % 4
        parts.append(_PADDING[pad] + _UINT32.pack(len(data) + 1) + data + b"\0")
        offset += pad + 5 + len(data)
    return offset


def _uint32(value: int, offset: int, parts: list[bytes]) -> int:
    pad = -offset % 4
    parts.append(_PADDING[pad] + _UINT32.pack(value))
    return offset + pad + 4


def encode_diagnostic_array(stamp_ns: int, statuses: Sequence[DiagnosticStatusFields]) -> bytes:
    """Serialize a ``DiagnosticArray`` (``header.frame_id`` empty) as rosbags would.

    Parameters
    ----------
    stamp_ns : int
        ``header.stamp``, nanoseconds since the epoch (>= 0).
    statuses : sequence of DiagnosticStatusFields

    Returns
    -------
    bytes
        The CDR message, encapsulation header included.

    Raises
    ------
    ValueError
        If the stamp is negative or beyond ``int32`` seconds, or a level is not a byte.
    """
    sec, nanosec = divmod(int(stamp_ns), _NS_PER_S)
    if not 0 <= sec < 2**31:
        raise ValueError(f"stamp_ns={stamp_ns!r} is outside builtin_interfaces/Time")
    parts = [_STAMP.pack(sec, nanosec)]
    offset = _strings(("",), _STAMP.size, parts)  # header.frame_id
    offset = _uint32(len(statuses), offset, parts)
    for status in statuses:
        if not 0 <= status.level <= 255:
            raise ValueError(f"level={status.level!r} must be a byte")
        parts.append(bytes((status.level,)))
        offset = _strings((status.name, status.message, status.hardware_id), offset + 1, parts)
        offset = _uint32(len(status.values), offset, parts)
        offset = _strings([text for item in status.values.items() for text in item], offset, parts)
    return CDR_LE_HEADER + b"".join(parts)
