"""Fast CDR codec for ``sensor_msgs/msg/Temperature``, for the 10 k messages/s data path.

Building a Python message object per sample costs more than everything else the compensator does
per sample, so its subscriptions take the serialized bytes (``raw=True``) and its publisher sends
bytes. The layout (XCDR1, little endian, after the 4-byte encapsulation header) is fixed but for
the frame id (the layout and its offsets are
:mod:`tcomp_core.process.temperature_codec`'s, whose bulk codec serves ``tcomp process``):

    int32 sec | uint32 nanosec | uint32 len | frame_id bytes incl. NUL | pad to 8 |
    float64 temperature | float64 variance

:func:`decode` refuses anything else (big-endian or other encapsulations) with ``ValueError`` so
the caller can fall back to rclpy's general deserializer.
"""

from __future__ import annotations

import struct

from tcomp_core.process.temperature_codec import CDR_LE_HEADER, values_offset

__all__ = ["Encoder", "decode", "encode"]

_HEAD = struct.Struct("<iII")
_VALUES = struct.Struct("<dd")


def decode(data: bytes) -> tuple[int, str, float, float]:
    """Decode a serialized Temperature.

    Returns
    -------
    stamp_ns : int
    frame_id : str
    temperature : float
        Degrees C.
    variance : float

    Raises
    ------
    ValueError
        If the bytes are not a little-endian CDR Temperature.
    """
    if data[:4] != CDR_LE_HEADER:
        raise ValueError(f"not little-endian CDR (encapsulation {data[:4]!r})")
    if len(data) < 16:
        raise ValueError(f"{len(data)} bytes are too few for a Temperature")
    sec, nanosec, length = _HEAD.unpack_from(data, 4)
    offset = values_offset(length)
    if length == 0 or offset + 16 > len(data):
        raise ValueError(f"{len(data)} bytes cannot hold a Temperature with a {length}-byte frame")
    temperature, variance = _VALUES.unpack_from(data, offset)
    frame_id = data[16 : 16 + length - 1].decode()
    return sec * 1_000_000_000 + nanosec, frame_id, temperature, variance


class Encoder:
    """Serializes Temperature messages with one frame id (the prefix is built once)."""

    def __init__(self, frame_id: str) -> None:
        encoded = frame_id.encode() + b"\x00"
        padding = values_offset(len(encoded)) - 4 - 12 - len(encoded)
        self.frame_id = frame_id
        self._frame = struct.pack("<I", len(encoded)) + encoded + b"\x00" * padding

    def encode(self, stamp_ns: int, temperature: float, variance: float = 0.0) -> bytes:
        """Serialized Temperature stamped ``stamp_ns`` (nanoseconds)."""
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        return (
            CDR_LE_HEADER
            + struct.pack("<iI", sec, nanosec)
            + self._frame
            + _VALUES.pack(temperature, variance)
        )


def encode(stamp_ns: int, frame_id: str, temperature: float, variance: float = 0.0) -> bytes:
    """Serialized Temperature (see :class:`Encoder` to encode many with one frame id)."""
    return Encoder(frame_id).encode(stamp_ns, temperature, variance)
