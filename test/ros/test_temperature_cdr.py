"""The fixed-layout Temperature codec agrees with rclpy's serializer both ways."""

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Temperature

from tcomp_ros.temperature_cdr import Encoder, decode, encode


@pytest.mark.parametrize("frame_id", ["", "a", "probe", "abcdefg", "abcdefgh", "thermocouple_1"])
@pytest.mark.parametrize("stamp_ns", [0, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1])
def test_codec_matches_rclpy(frame_id, stamp_ns):
    message = Temperature()
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    message.header.frame_id = frame_id
    message.temperature = 301.25
    message.variance = 0.5
    assert decode(serialize_message(message)) == (stamp_ns, frame_id, 301.25, 0.5)
    ours = encode(stamp_ns, frame_id, 301.25, 0.5)
    back = deserialize_message(ours, Temperature)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == divmod(stamp_ns, 10**9)
    assert (back.header.frame_id, back.temperature, back.variance) == (frame_id, 301.25, 0.5)
    assert Encoder(frame_id).encode(stamp_ns, 301.25, 0.5) == ours


@pytest.mark.parametrize(
    "data",
    [b"\x00\x00\x00\x00" + bytes(32), b"\x00\x01\x00\x00" + bytes(8), b"\x00\x01\x00\x00"],
    ids=["big-endian", "short", "header-only"],
)
def test_other_layouts_are_refused(data):
    with pytest.raises(ValueError):
        decode(data)
