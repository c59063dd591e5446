"""The one Temperature codec (:mod:`tcomp_core.io.temperature`) agrees with rclpy both ways."""

import struct

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Temperature

from tcomp_core.errors import DataError
from tcomp_core.io import Encoder, decode_message, decode_rows, encode, encode_message


def _message(stamp_ns: int, frame_id: str) -> Temperature:
    message = Temperature()
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    message.header.frame_id = frame_id
    message.temperature = 301.25
    message.variance = 0.5
    return message


@pytest.mark.parametrize("frame_id", ["", "a", "probe", "abcdefg", "abcdefgh", "thermocouple_1"])
@pytest.mark.parametrize("stamp_ns", [0, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1])
def test_codec_matches_rclpy(frame_id, stamp_ns):
    data = serialize_message(_message(stamp_ns, frame_id))
    assert decode_message(data) == (stamp_ns, frame_id, 301.25, 0.5)
    ours = encode_message(stamp_ns, frame_id, 301.25, 0.5)
    back = deserialize_message(ours, Temperature)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == divmod(stamp_ns, 10**9)
    assert (back.header.frame_id, back.temperature, back.variance) == (frame_id, 301.25, 0.5)
    assert Encoder(frame_id).encode(stamp_ns, 301.25, 0.5) == ours  # rclpy leaves padding as is
    # the bulk encoder and decoder of tcomp process give the same bytes and values
    rows = encode([stamp_ns], [301.25], 0.5, frame_id)
    assert rows.tobytes() == ours
    batch = decode_rows(np.frombuffer(data, np.uint8)[None, :])
    assert (int(batch.stamps_ns[0]), batch.frame_id, float(batch.temperature[0])) == (
        stamp_ns,
        frame_id,
        301.25,
    )


def _big_endian(stamp_ns: int, frame_id: str, temperature: float, variance: float) -> bytes:
    """A big-endian CDR Temperature, built by hand from the CDR rules (not by our codec)."""
    sec, nanosec = divmod(stamp_ns, 10**9)
    frame = frame_id.encode() + b"\x00"
    body = struct.pack(">iII", sec, nanosec, len(frame)) + frame
    body += b"\x00" * (-len(body) % 8)
    return b"\x00\x00\x00\x00" + body + struct.pack(">dd", temperature, variance)


def test_other_layouts_fall_back_to_the_general_deserializer():
    data = _big_endian(1_700_000_000_000_000_042, "probe", -12.5, 0.25)
    assert decode_message(data) == (1_700_000_000_000_000_042, "probe", -12.5, 0.25)


@pytest.mark.parametrize(
    "data",
    [b"\x00\x01\x00\x00" + bytes(8), b"\x00\x01\x00\x00", b"\x07\x07"],
    ids=["short", "header-only", "garbage"],
)
def test_undecodable_bytes_are_a_data_error(data):
    with pytest.raises(DataError, match=r"cannot deserialize a \d+-byte sensor_msgs/msg/Temp"):
        decode_message(data)


def test_encoder_refuses_stamps_outside_the_time_message():
    with pytest.raises(DataError, match="outside the builtin_interfaces/msg/Time range"):
        Encoder("tc").encode(-1, 20.0)
