"""``tcomp process`` gives what the compensator node publishes for the same bag, sample for sample.

The node runs in-process with its timers replaced by the offline schedule (documented in
:mod:`tcomp_core.process.schedule`): every message of the bag goes through the node's own
subscription callback as the serialized bytes it would receive, the inbox is drained every
``batch_s`` of stamp time and τ re-estimated every ``update_period_s``; what the node hands to
its ``gas_temperature`` publisher is compared with the bag ``tcomp process`` writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rosbags.rosbag2 import Reader

from tcomp_core.online import OnlineConfig
from tcomp_core.process import ProcessConfig, process
from tcomp_ros.compensator import CompensatorNode
from tcomp_ros.temperature_cdr import decode

BAGS = Path(__file__).resolve().parents[2] / "bags"
TOPICS = ("/tc1/temperature", "/tc2/temperature")


def _messages(bag: Path) -> list[tuple[int, int, bytes]]:
    """(stamp ns, input index, serialized message) of tc1 and tc2, in log-time order."""
    found = []
    with Reader(bag) as reader:
        wanted = [c for c in reader.connections if c.topic in TOPICS]
        for connection, _, raw in reader.messages(wanted):
            stamp = decode(bytes(raw))[0]
            found.append((stamp, TOPICS.index(connection.topic), bytes(raw)))
    return found


def _node_outputs(node: CompensatorNode, messages, batch_s: float, update_s: float):
    published: list[bytes] = []
    node._gas_pub.publish = published.append  # what the node hands to its publisher
    t0 = min(stamp for stamp, _, _ in messages)
    batch_ns, update_ns = round(batch_s * 1e9), round(update_s * 1e9)
    next_update = t0 + update_ns
    batches: dict[int, list] = {}
    for stamp, index, raw in messages:
        batches.setdefault((stamp - t0) // batch_ns, []).append((stamp, index, raw))
    for key in sorted(batches):
        for _, index, raw in batches[key]:
            node._on_sample(index, raw)
        node._process()
        last = max(stamp for stamp, _, _ in batches[key])
        if last >= next_update:
            node.update_estimate()
            next_update = t0 + ((last - t0) // update_ns + 1) * update_ns
    decoded = [decode(data) for data in published]
    return (
        np.array([stamp for stamp, _, _, _ in decoded], dtype=np.int64),
        np.array([value for _, _, value, _ in decoded]),
    )


def _bag_outputs(bag: Path):
    with Reader(bag) as reader:
        wanted = [c for c in reader.connections if c.topic == "/gas_temperature"]
        decoded = [decode(bytes(raw)) for _, _, raw in reader.messages(wanted)]
    return (
        np.array([stamp for stamp, _, _, _ in decoded], dtype=np.int64),
        np.array([value for _, _, value, _ in decoded]),
    )


@pytest.mark.parametrize("reconstruction", ["difference", "kalman"])
def test_process_output_equals_the_node_sample_for_sample(ros_context, tmp_path, reconstruction):
    bag = BAGS / "ramp_500hz"
    config = ProcessConfig(diagnose=False, online=OnlineConfig(reconstruction=reconstruction))
    process(bag, tmp_path / "out", config)
    node = CompensatorNode(
        context=ros_context,
        parameter_overrides=[
            Parameter("window_s", value=config.online.window_s),
            Parameter("update_period_s", value=config.update_period_s),
            Parameter("reconstruction", value=reconstruction),
            Parameter("diagnosis_period_s", value=0.0),
        ],
    )
    try:
        node_stamps, node_gas = _node_outputs(
            node, _messages(bag), config.batch_s, config.update_period_s
        )
    finally:
        node.destroy_node()
    stamps, gas = _bag_outputs(tmp_path / "out")
    assert stamps.size == 4999  # every pair of the 10 s record but the last
    np.testing.assert_array_equal(stamps, node_stamps)
    np.testing.assert_array_equal(gas, node_gas)  # bit for bit
